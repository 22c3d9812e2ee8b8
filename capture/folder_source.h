// Image-folder datasets as RGB-D sources: TUM RGB-D sequences (tum:DIR) and 3DMatch / 7-Scenes
// sequences (3dmatch:DIR). They deliver registered depth with ground-truth poses, which makes them
// the reference inputs for evaluating the mapper.
//
// Both sources read only the text files (lists, poses, intrinsics) and image headers when opened;
// each image is decoded when Next() reaches it, so folders of many thousand frames open instantly.
// SourceOptions::width/height/fps/frame_timeout_ms do not apply; `realtime` paces Next() by the
// frame timestamps. metadata().has_ground_truth is set when any frame carries ground truth; the
// notes count the frames that do not (mocap drop-outs, missing pose files).
#pragma once

#include <memory>
#include <string>

#include "capture/rgbd_source.h"

namespace sightmap::capture {

// A TUM RGB-D folder (https://cvg.cit.tum.de/data/datasets/rgbd-dataset/file_formats):
//   rgb.txt, depth.txt    lines "timestamp filename" (seconds; '#' starts a comment)
//   groundtruth.txt       optional, lines "timestamp tx ty tz qx qy qz qw" (world_from_cam)
// Depth PNGs hold 5000 units per metre and are converted to millimetres. Each depth frame is paired
// with the nearest unused colour frame within options.sync_tolerance_ns, greedily by smallest time
// difference like TUM's associate.py; frames come out in depth-time order, stamped with the depth
// time. Ground truth is interpolated at the depth time between the two bracketing poses when they
// are at most 100 ms apart (mocap drop-outs leave the frame without ground truth). The folder has
// no intrinsics: the TUM ROS default (fx = fy = 525, cx = 319.5, cy = 239.5 at 640x480) is used
// unless options.calibration_file gives the colour camera.
// stats().unpaired_frames counts every listed frame left without a partner, from the start.
std::unique_ptr<RgbdSource> OpenTumFolder(const std::string& dir, const SourceOptions& options);

// A 3DMatch / 7-Scenes sequence: frame-NNNNNN.color.png (8-bit), frame-NNNNNN.depth.png (16-bit
// mm), frame-NNNNNN.pose.txt (4x4 world_from_cam), with camera-intrinsics.txt (3x3 K) in DIR or its
// parent. DIR may also be the scene folder when it holds a single seq-* sequence. Frames come out
// sorted by N (gaps allowed), stamped N / 30 s because the format has no timestamps. Depth 65535
// (7-Scenes' "no measurement") becomes 0. A frame missing its colour or depth image is skipped and
// counted in stats().unpaired_frames.
std::unique_ptr<RgbdSource> OpenThreeDMatchFolder(const std::string& dir,
                                                  const SourceOptions& options);

// The same layout written (`sightmap probe --dump`): frame-NNNNNN.color.png and .depth.png
// (millimetres) with N the frame's index, and .pose.txt when the frame has ground truth; with
// camera-intrinsics.txt, the folder plays back as `3dmatch:DIR`. Every file is written
// atomically. Throws Error naming the file that could not be written.
void WriteThreeDMatchFrame(const std::string& dir, const RgbdFrame& frame);
void WriteThreeDMatchIntrinsics(const std::string& dir, const Intrinsics& intrinsics);

}  // namespace sightmap::capture
