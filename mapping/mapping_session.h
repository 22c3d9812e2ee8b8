// One mapping run, `sightmap map` end to end (ARCHITECTURE.md, "The product"): a source's frames,
// sampled to keyframes, registered by the Mapper with loop-closure checks, written to the model
// keyframe by keyframe, drawn by the preview or the progress images, and at the end the PLY, the
// trajectory and a summary.
//
// A pipeline of stages, each a class with its own thread (but the map stage) and its own test,
// joined by bounded queues:
//   capture (capture_stage.h)  source -> frames. A live sensor never waits (frames the tracker
//                              cannot take are dropped and counted); a replay waits for room.
//   track (track_stage.h)      frames -> Tracker -> keyframes (waits: keyframes are never dropped).
//   map (map_stage.h)          keyframes -> Mapper -> write tasks, on the thread that calls Run(),
//                              which polls the stop conditions between keyframes.
//   write (write_stage.h)      write tasks -> Model, each in one transaction, then the map view
//                              (which draws on its own thread and never blocks).
//
// Stopping (every reason ends the same way): the keyframe in hand is finished, frames still
// queued are discarded, the writer commits what it holds and the final poses, the session is
// ended (finished, or interrupted when the source failed), and the PLY and trajectory are
// written from the model.
//
// Resuming (model_restore.h): a model that already holds keyframes gives the Mapper its vocabulary,
// keyframes and links; sessions left running by a crash are marked interrupted; the new session's
// keyframes start a new segment that the Mapper relocalises into the stored map (or keeps apart,
// reported).
#pragma once

#include <atomic>
#include <cstdint>
#include <exception>
#include <functional>
#include <optional>
#include <ostream>
#include <string>

#include <nlohmann/json_fwd.hpp>

#include "capture/keyframe_sampler.h"
#include "capture/rgbd_source.h"
#include "mapping/map_view_feed.h"
#include "mapping/track_stage.h"
#include "slam/mapper.h"
#include "store/model.h"
#include "store/point_cloud.h"

namespace sightmap::mapping {

struct MappingOptions {
  std::string source;           // SOURCE string (see capture/rgbd_source.h OpenSource)
  std::string model_path;       // created when missing; resumed when it holds keyframes
  std::string ply_path;         // point cloud written at the end; empty = none
  std::string trajectory_path;  // TUM trajectory of every keyframe in the model; empty = none
  // Frames of the source skipped before mapping starts (continue a recording from frame N).
  int64_t start_frame = 0;
  // Resuming a model from a recording, folder or simulated walk (not a live sensor) that it already
  // holds keyframes of (the same SOURCE string): skip the frames up to the last one stored, so a
  // walk interrupted by a crash is continued, not mapped twice. Off when a start frame is chosen.
  bool continue_replay = true;
  // Stop after this many keyframes of this session; 0 = until the source ends or a stop.
  int64_t max_keyframes = 0;
  // Treat the source as live (drop keyframes the mapper cannot keep up with) even when it is a
  // recording: set with source_options.realtime so a .oni plays at its recorded pace.
  bool live = false;
  // A source with ground truth (the simulator, a TUM folder with groundtruth.txt) places a new
  // model's first keyframe at its true pose, so the model shares the scene's frame: the scene's
  // appliance labels and the photos' true poses can be used as they are.
  bool anchor_to_ground_truth = true;
  // Keyframes take their ground-truth poses instead of being registered (no odometry, no loop
  // search; features and place recognition as usual). Builds a model for evaluating photo
  // localisation apart from SLAM; the source must have ground truth.
  bool ground_truth_poses = false;
  // Frames between capture and SLAM: small, a queued frame only adds latency [keyframes].
  int frame_queue_capacity = 2;
  // Keyframes between tracking and SLAM: small, the tracker waits while they are full [keyframes].
  int keyframe_queue_capacity = 2;
  // Keyframes and pose updates between SLAM and the writer [items].
  int write_queue_capacity = 8;

  capture::SourceOptions source_options;
  capture::KeyframeSamplerOptions sampler;  // rate_hz: keyframes per second of source time [Hz]
  // Tracking every frame (tracking.track) between capture and mapping. Its features, registration
  // and depth downscale are the mapper's, and its keyframe rate is sampler.rate_hz, whatever is
  // set here: the mapper takes the tracker's features as they are.
  TrackStageOptions tracking;
  // Track every Nth frame of the source (1: all of them) [frames].
  int track_every = 1;
  // A replay's capture thread (reading, decoding, the simulator's rendering) runs this much lower
  // (nice, 0-19; CaptureStageOptions::replay_nice_increment): a replay is read as fast as the
  // stages take its frames, and on two cores it took them from tracking and mapping. The 600 s
  // hand-held walk (`sim:office?fps=10&frames=6000&seed=11`, headless, alone on this machine,
  // five runs at 0, three at 10): keyframe p95 121-150 ms (median 136) -> 108-118 (114), keyframe
  // median 53-59 -> 47 ms, tracking median 13-15 -> 11-12 ms, wall time 171-185 -> 181-192 s
  // (3.1-3.3x real time), the same map (ATE 0.0116 m); 5 was between (118-133 ms). README:
  // "Checked on 2026-11-27", the keyframe p95 of `map`.
  int replay_nice_increment = 10;
  // A replay's writer thread (RootSIFT for photos, the model's writes, the progress image) runs
  // this much lower (nice, 0-19); a live session's keeps its priority. The main command (`sim:
  // office?fps=10`) at 0 and 5 alternating, four runs each on the Zen 3: keyframe p95 170-195 ms
  // (median 171) -> 151-160 (156), tracking p95 46-50 -> 41-44 ms, wall 2:37-2:50 either way, the
  // same map.
  int replay_write_nice_increment = 5;
  slam::MapperOptions mapper;
  // Each keyframe is stored with RootSIFT features for matching phone photos (`sightmap locate`'s
  // RootSIFT matcher reads them rather than extracting them at load), extracted by the writer
  // off the tracking thread from the keyframe downscaled to photo_feature_side_px [px]. 480
  // rather than the photo matcher's 640: OpenCV's SIFT doubles the image first and takes 25
  // instead of 50 ms a keyframe, and on 200 session-2 photos the survey and hand-held SLAM models
  // gave as many right answers (116 and 97 against 115 and 97) and no more wrong ones (10 and 6
  // against 10 and 8); in a 10 Hz replay, where every stage runs flat out on two cores, the
  // mapper's keyframe p95 went 176 -> 152 ms.
  bool photo_features = true;
  slam::FeatureOptions photo_feature_options = slam::RootSiftForPhotos();
  int photo_feature_side_px = 480;
  store::ModelOptions model;
  store::PlyExportOptions ply;
  MapViewFeedOptions view;
  // false: no preview and no progress images at all (tests, benchmarks). `sightmap map` sets it
  // from view: a view is shown when there is a window or an image file to draw into.
  bool show_view = true;

  bool Check(std::string* error) const;
};
void to_json(nlohmann::json& json, const MappingOptions& options);
void from_json(const nlohmann::json& json, MappingOptions& options);

enum class StopReason {
  kSourceEnded,   // the recording, folder or walk ended
  kSignal,        // Ctrl-C or SIGTERM
  kUserStop,      // `q` or closing the preview window
  kSourceFailed,  // the sensor stopped delivering (unplugged) or the file is damaged
  kMaxKeyframes,  // MappingOptions::max_keyframes reached
};
const char* ToString(StopReason reason);

// What the status line shows; passed to the progress callback after every keyframe (and about
// once a second while waiting).
struct MappingProgress {
  int64_t keyframes = 0;        // this session's
  int64_t model_keyframes = 0;  // restored + this session's
  int64_t loops = 0;            // accepted loop closures in the map
  int64_t dropped_frames = 0;
  int64_t frames_passed = 0;            // how far through the source (CaptureStage::frames_passed)
  std::optional<int64_t> frames_total;  // when the source's length is known
  TrackingState tracking = TrackingState::kTracking;
  bool resumed = false;
  bool joined_stored_map = false;  // a resumed session relocalised into the stored map
  bool paused = false;
  double elapsed_s = 0.0;
  double keyframes_per_s = 0.0;
  // Mapping stopped and the whole map is being optimised once more (seconds on a long capture,
  // more when loops switched off while mapping are judged again); `finished` comes after it.
  bool optimising_whole_map = false;
  bool finished = false;  // the last call: mapping stopped, the files are being written
};

struct MappingSummary {
  StopReason reason = StopReason::kSourceEnded;
  std::string reason_detail;   // e.g. the source's error message
  std::string source_kind;     // "openni", "oni", "sim", ...
  int64_t session = 0;         // SessionId of this run
  int64_t session_number = 0;  // 1 for the model's first session
  bool resumed = false;
  int64_t restored_keyframes = 0;
  int64_t interrupted_sessions_marked = 0;  // crashed sessions found and marked interrupted
  bool joined_stored_map = false;           // resumed and relocalised into the stored map
  int64_t keyframes = 0;                    // this session's
  int64_t model_keyframes = 0;
  int64_t loops = 0;                      // accepted and active loop closures in the map
  int64_t segments = 0;                   // unjoined parts of the map
  int64_t largest_segment_keyframes = 0;  // keyframes in the largest of them (the model's count)
  double largest_part_ratio = 0.0;        // largest_segment_keyframes / model keyframes
  int64_t prior_links = 0;                // links made by the motion model across blind stretches
  int64_t axes_keyframes = 0;             // keyframes whose depth showed the building's axes
  int64_t tracked_frames = 0;             // frames the tracker placed (0 without tracking)
  int64_t dense_frames = 0;               // of them, placed by the dense fallback
  int64_t dense_at_rest_frames = 0;       // of those, unmoved (TrackerOptions::dense_prefer_rest)
  int64_t blind_frames = 0;               // of them, placed by the motion model alone
  int64_t early_keyframes = 0;            // keyframes taken off the rate's clock (overlap lost)
  // Frames read before one could anchor the map (TrackerOptions::start_max_wait_s), never placed.
  int64_t frames_before_start = 0;
  double track_median_ms = 0.0;  // tracking time per frame
  double track_p95_ms = 0.0;
  double keyframe_median_ms = 0.0;  // mapping time per keyframe
  double keyframe_p95_ms = 0.0;
  int64_t dropped_frames = 0;   // lost behind a live source (CaptureStage::dropped_frames)
  int64_t unpaired_frames = 0;  // depth frames without a colour frame in time
  int64_t frames_read = 0;
  int64_t frames_skipped = 0;  // read before the start frame or the continued replay's start
  // The source time this session continued after (the last stored frame of the same replay) [s].
  std::optional<double> continued_after_s;
  int64_t links_rejected_after_commit = 0;  // loop links switched off after being stored
  // Loop links switched off while mapping (stored or not yet) that the end's solve switched on.
  int64_t links_reactivated_at_end = 0;
  double final_optimisation_s = 0.0;  // the end's whole-map optimisation (wall) [s]
  std::optional<double> ate_rmse_m;   // this session's keyframes vs. ground truth
  std::optional<double> ate_max_m;
  int64_t ate_poses = 0;
  double elapsed_s = 0.0;
  double keyframes_per_s = 0.0;
  int64_t model_bytes = 0;
  int64_t ply_points = 0;
  std::string ply_path;
  std::string trajectory_path;
  std::string view;  // where progress went
  double peak_rss_mib = 0.0;
};

class MappingSession {
 public:
  using ProgressCallback = std::function<void(const MappingProgress&)>;

  // Checks the options; opens nothing yet.
  explicit MappingSession(const MappingOptions& options);

  // Runs until the source ends or a stop is requested; returns the summary. `notices` receives
  // one-line notices (the view's fallback, a resumed model); may be null. Throws sightmap::Error
  // when the source or model cannot be opened, a write fails, or nothing could be mapped.
  MappingSummary Run(std::ostream* notices = nullptr);

  // Thread-safe, callable from anywhere (a signal watcher): stop gracefully.
  void RequestStop(StopReason reason);
  // Polled between keyframes; a non-null flag set to true acts as RequestStop(kSignal) (for a
  // signal handler, which can only set a lock-free atomic).
  void SetInterruptFlag(const std::atomic<bool>* flag) { interrupt_flag_ = flag; }
  // Called on the SLAM thread after each keyframe and about once a second while waiting, and
  // once more (finished = true) when mapping stopped, before the PLY and trajectory are written.
  void SetProgressCallback(ProgressCallback callback) { progress_ = std::move(callback); }

 private:
  struct Pipeline;
  MappingProgress Progress(const Pipeline& pipeline) const;
  bool StopRequested(const Pipeline& pipeline);
  // The map stage's loop on this thread: keyframes -> Mapper -> writer, until the keyframes end,
  // a stop is requested or the writer failed.
  void MapKeyframes(const Pipeline& pipeline);
  // Stops and joins every stage in order, the writer last with the final poses; returns the
  // tracking stage's error, if any.
  std::exception_ptr DrainStages(const Pipeline& pipeline);
  // Ends the model's session (interrupted after a failure) and rethrows the first failure; nothing
  // mapped from a failed source is its error.
  void EndSession(const Pipeline& pipeline, store::Model* model, SessionId session,
                  const std::exception_ptr& map_error, StopReason reason);

  MappingOptions options_;
  const std::atomic<bool>* interrupt_flag_ = nullptr;
  ProgressCallback progress_;
  std::atomic<int> stop_reason_{-1};  // a StopReason once requested
};

}  // namespace sightmap::mapping
