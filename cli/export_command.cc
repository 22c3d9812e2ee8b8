// sightmap export MODEL [--ply FILE] [--voxel M] [--trajectory FILE] [--labels DIR]: the model's
// point cloud, keyframe trajectory (TUM) and labels (CloudCompare point lists).
#include <iostream>

#include "cli/command_util.h"
#include "cli/commands.h"
#include "store/label_files.h"
#include "store/model.h"
#include "store/point_cloud.h"
#include "store/trajectory.h"

namespace sightmap::cli {

int RunExport(int argc, char** argv) {
  CLI::App app("Export a model's point cloud (PLY), trajectory (TUM) and labels (point lists).",
               "sightmap export");
  std::string path;
  std::string ply_path;
  std::string trajectory_path;
  std::string labels_dir;
  bool odometry = false;
  store::PlyExportOptions ply;
  AddModelArgument(app, path);
  app.add_option("--ply", ply_path, "write the point cloud as binary PLY (x y z red green blue)");
  app.add_option("--voxel", ply.voxel_size_m, "voxel grid leaf size [m], 0 keeps every point")
      ->capture_default_str()
      ->check(Within(0, 10, "m"));
  app.add_option("--pixel-step", ply.pixel_step, "back-project every Nth depth pixel")
      ->capture_default_str()
      ->check(Within(1, 64));
  app.add_option("--max-depth", ply.max_depth_m, "ignore depth beyond this [m]")
      ->capture_default_str()
      ->check(Within(0.1, 100, "m"));
  app.add_flag("--remove-outliers", ply.remove_outliers,
               "drop isolated points (statistical outlier removal)");
  app.add_option("--trajectory", trajectory_path,
                 "write keyframe poses (world_from_cam) in TUM format");
  app.add_flag("--odometry", odometry, "with --trajectory: the raw odometry, not optimised poses");
  app.add_option("--labels", labels_dir, "write one point-list file per label to this folder");
  if (const int code = ParseOrExit(app, argc, argv); code >= 0) return code;
  if (const int code = RequireModelArgument(app, path); code >= 0) return code;
  if (ply_path.empty() && trajectory_path.empty() && labels_dir.empty()) {
    PrintError("nothing to export: pass --ply FILE, --trajectory FILE or --labels DIR");
    return kExitUsage;
  }
  CheckOutputFile(ply_path, "--ply");
  CheckOutputFile(trajectory_path, "--trajectory");
  CheckOutputFolder(labels_dir, "--labels");

  store::ModelOptions options;
  options.read_only = true;
  const store::Model model = store::Model::Open(path, options);
  if (!ply_path.empty()) {
    const store::PlyExportStats stats = store::ExportPly(model, ply_path, ply);
    std::cout << "point cloud    " << ply_path << ": " << stats.written_points << " points from "
              << stats.keyframes << " keyframes\n";
  }
  if (!trajectory_path.empty()) {
    const std::vector<StampedPose> poses = store::ModelTrajectory(model, odometry);
    WriteTumTrajectory(trajectory_path, poses);
    std::cout << "trajectory     " << trajectory_path << ": " << poses.size() << " poses\n";
  }
  if (!labels_dir.empty()) {
    const int count = store::ExportLabels(model, labels_dir);
    std::cout << "labels         " << labels_dir << ": " << count << " files\n";
  }
  return kExitSuccess;
}

}  // namespace sightmap::cli
