// sightmap eval trajectory --gt FILE --est FILE [--json] [--plot PNG] [--max-time-diff S]
// [--rpe-distance M] [--rpe-interval S] [--up AXIS] [--plot-size WxH]: ATE and RPE of an
// estimated TUM trajectory against ground truth (ARCHITECTURE.md, "Measuring it"), and a top-down
// plot. Scripts read the --json keys; they are stable.
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <iomanip>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "cli/command_util.h"
#include "cli/commands.h"
#include "cli/eval_identify.h"
#include "core/check.h"
#include "core/format.h"
#include "render/image_file.h"
#include "slam/trajectory_eval.h"
#include "slam/trajectory_plot.h"
#include "store/trajectory.h"

namespace sightmap::cli {
namespace {

std::vector<StampedPose> ReadPoses(const std::string& path, const char* what) {
  std::vector<StampedPose> poses = ReadTumTrajectory(path);
  SIGHTMAP_CHECK(!poses.empty(), what << " " << path
                                      << " has no poses: expected lines 'timestamp tx ty tz qx qy "
                                         "qz qw' (TUM trajectory format)");
  return poses;
}

void PrintTable(const std::string& gt_path, const std::string& est_path, size_t gt_poses,
                size_t est_poses, const slam::TrajectoryEvalOptions& options,
                const slam::TrajectoryError& error, const slam::ErrorSources& sources) {
  const auto row = [](const std::string& metric, const std::string& value, const std::string& unit,
                      const std::string& note = "") {
    std::ostringstream line;
    line << std::left << std::setw(22) << metric << std::right << std::setw(10) << value << "  "
         << std::left << std::setw(6) << unit << "  " << note;
    std::string text = line.str();
    text.erase(text.find_last_not_of(' ') + 1);
    std::cout << text << "\n";
  };
  std::cout << "ground truth   " << gt_path << " (" << gt_poses << " poses)\n";
  std::cout << "estimate       " << est_path << " (" << est_poses << " poses)\n\n";
  row("metric", "value", "unit");
  row("matched poses", std::to_string(error.matched_poses), "",
      "within " + Fixed(options.max_time_difference_ns * 1e-6, 1) + " ms");
  row("ATE rmse", Fixed(error.ate_rmse_m, 4), "m", "after SE(3) alignment");
  row("ATE mean", Fixed(error.ate_mean_m, 4), "m");
  row("ATE median", Fixed(error.ate_median_m, 4), "m");
  row("ATE max", Fixed(error.ate_max_m, 4), "m");
  const double percent_small = 100.0 * (error.sim3_scale - 1.0);
  row("scale", Fixed(error.sim3_scale, 5), "",
      "Sim(3): the estimate is " + Fixed(std::abs(percent_small), 2) + "% " +
          (percent_small >= 0.0 ? "small" : "large"));
  row("ATE rmse, Sim(3)", Fixed(error.sim3_ate_rmse_m, 4), "m", "after a similarity alignment");
  row("worst poses' share", Fixed(100.0 * sources.concentration.worst_share, 1), "%",
      "of the squared error, the worst " + std::to_string(sources.concentration.worst_poses) +
          (sources.concentration.worst_poses == 1 ? " pose" : " poses") + "; rmse " +
          Fixed(sources.concentration.rest_rmse_m, 4) + " m without them");
  for (const slam::ErrorStretch& stretch : sources.stretches) {
    row("worst stretch", Fixed(stretch.mean_m, 4), "m",
        "mean over t = " + Fixed(stretch.start_s, 1) + "-" + Fixed(stretch.end_s, 1) + " s (" +
            std::to_string(stretch.poses) + " poses, max " + Fixed(stretch.max_m, 4) + " m)");
  }
  const std::string over_distance = "over " + Fixed(options.rpe_distance_m, 2) + " m, " +
                                    std::to_string(error.rpe_pairs_distance) + " pairs";
  const std::string over_time = "over " + Fixed(options.rpe_interval_s, 2) + " s, " +
                                std::to_string(error.rpe_pairs_time) + " pairs";
  if (error.rpe_pairs_distance > 0) {
    row("RPE translation / m", Fixed(error.rpe_trans_per_m, 4), "m/m", over_distance);
    row("RPE rotation / m", Fixed(error.rpe_rot_deg_per_m, 3), "deg/m");
  } else {
    row("RPE per metre", "-", "",
        "ground truth shorter than " + Fixed(options.rpe_distance_m, 2) + " m");
  }
  if (error.rpe_pairs_time > 0) {
    row("RPE translation / s", Fixed(error.rpe_trans_per_s, 4), "m/s", over_time);
    row("RPE rotation / s", Fixed(error.rpe_rot_deg_per_s, 3), "deg/s");
  } else {
    row("RPE per second", "-", "",
        "estimate shorter than " + Fixed(options.rpe_interval_s, 2) + " s");
  }
}

struct EvalTrajectoryArgs {
  std::string gt_path;
  std::string est_path;
  std::string plot_path;
  std::string plot_size = "1000x800";
  std::string up = "z";
  bool json = false;
  bool no_error_segments = false;
  double max_time_diff_s = slam::TrajectoryEvalOptions().max_time_difference_ns * 1e-9;
  double stretch_s = 10.0;
  slam::TrajectoryEvalOptions options;
};

CLI::App* AddEvalTrajectory(CLI::App& app, EvalTrajectoryArgs& args) {
  CLI::App* trajectory = app.add_subcommand(
      "trajectory",
      "ATE (after SE(3) Umeyama alignment) and RPE of an estimated TUM trajectory, and a plot");
  trajectory
      ->add_option("--gt", args.gt_path,
                   "ground truth, TUM format (timestamp tx ty tz qx qy qz qw)")
      ->required();
  trajectory->add_option("--est", args.est_path, "estimated trajectory, TUM format")->required();
  trajectory->add_flag("--json", args.json, "print one JSON object (stable keys) instead of text");
  trajectory->add_option("--plot", args.plot_path,
                         "write a top-down plot of the ground truth and aligned estimate (PNG)");
  trajectory->add_option("--plot-size", args.plot_size, "plot size WxH [px]")
      ->capture_default_str();
  trajectory
      ->add_option("--up", args.up,
                   "the ground truth's up axis, dropped in the plot: z (default; simulator, motion "
                   "capture) or e.g. -y for a world anchored at a camera (y down)")
      ->check(CLI::IsMember({"x", "-x", "y", "-y", "z", "-z", "+x", "+y", "+z"}));
  trajectory->add_flag("--no-error-segments", args.no_error_segments,
                       "plot without the segments joining matched poses");
  trajectory
      ->add_option("--max-time-diff", args.max_time_diff_s,
                   "match poses whose timestamps differ by at most this [s]")
      ->capture_default_str()
      ->check(Within(0, 1e6, "s"));
  trajectory
      ->add_option("--rpe-distance", args.options.rpe_distance_m,
                   "RPE per metre compares motions over this ground-truth distance [m]")
      ->capture_default_str()
      ->check(Within(1e-6, 1e6, "m"));
  trajectory
      ->add_option("--stretch", args.stretch_s,
                   "report the worst stretches of this length, from the first matched pose [s]")
      ->capture_default_str()
      ->check(Within(1e-3, 1e6, "s"));
  trajectory
      ->add_option("--rpe-interval", args.options.rpe_interval_s,
                   "RPE per second compares motions over this time [s]")
      ->capture_default_str()
      ->check(Within(1e-6, 1e6, "s"));
  return trajectory;
}

// The plot's options from --up, --no-error-segments and --plot-size (checked when plotting).
slam::TrajectoryPlotOptions PlotOptions(const EvalTrajectoryArgs& args) {
  slam::TrajectoryPlotOptions plot;
  plot.draw_error_segments = !args.no_error_segments;
  plot.up_sign = args.up[0] == '-' ? -1 : 1;
  plot.up_axis = args.up.back() - 'x';
  if (!args.plot_path.empty()) {
    const ImageSize size = ParseImageSize(args.plot_size, "--plot-size", {200, 200}, 8000);
    plot.width_px = size.width;
    plot.height_px = size.height;
    SIGHTMAP_CHECK_OPTIONS(plot);
    CheckOutputFile(args.plot_path, "--plot");
  }
  return plot;
}

nlohmann::json TrajectoryJson(const EvalTrajectoryArgs& args, size_t gt_poses, size_t est_poses,
                              const slam::TrajectoryEvalOptions& options,
                              const slam::TrajectoryError& error,
                              const slam::ErrorSources& sources) {
  const Eigen::Quaterniond rotation(error.gt_from_est.rotation());
  const Eigen::Vector3d translation = error.gt_from_est.translation();
  nlohmann::json out;
  out["gt_poses"] = gt_poses;
  out["est_poses"] = est_poses;
  out["matched_poses"] = error.matched_poses;
  out["ate_rmse_m"] = error.ate_rmse_m;
  out["ate_mean_m"] = error.ate_mean_m;
  out["ate_median_m"] = error.ate_median_m;
  out["ate_max_m"] = error.ate_max_m;
  out["rpe_trans_per_m"] = error.rpe_trans_per_m;
  out["rpe_rot_deg_per_m"] = error.rpe_rot_deg_per_m;
  out["rpe_trans_per_s"] = error.rpe_trans_per_s;
  out["rpe_rot_deg_per_s"] = error.rpe_rot_deg_per_s;
  out["sim3_scale"] = error.sim3_scale;
  out["sim3_ate_rmse_m"] = error.sim3_ate_rmse_m;
  out["worst_poses"] = sources.concentration.worst_poses;
  out["worst_poses_share"] = sources.concentration.worst_share;
  out["rmse_without_worst_poses_m"] = sources.concentration.rest_rmse_m;
  out["stretch_s"] = args.stretch_s;
  out["worst_stretches"] = nlohmann::json::array();
  for (const slam::ErrorStretch& stretch : sources.stretches) {
    out["worst_stretches"].push_back({{"start_s", stretch.start_s},
                                      {"end_s", stretch.end_s},
                                      {"poses", stretch.poses},
                                      {"mean_m", stretch.mean_m},
                                      {"max_m", stretch.max_m}});
  }
  out["rpe_pairs_distance"] = error.rpe_pairs_distance;
  out["rpe_pairs_time"] = error.rpe_pairs_time;
  out["max_time_diff_s"] = options.max_time_difference_ns * 1e-9;
  out["rpe_distance_m"] = options.rpe_distance_m;
  out["rpe_interval_s"] = options.rpe_interval_s;
  out["gt_from_est"] = {
      {"translation", {translation.x(), translation.y(), translation.z()}},
      {"quaternion_xyzw", {rotation.x(), rotation.y(), rotation.z(), rotation.w()}}};
  out["plot"] = args.plot_path.empty() ? nlohmann::json(nullptr) : nlohmann::json(args.plot_path);
  return out;
}

int RunEvalTrajectory(const EvalTrajectoryArgs& args) {
  slam::TrajectoryEvalOptions options = args.options;
  options.max_time_difference_ns = static_cast<int64_t>(std::llround(args.max_time_diff_s * 1e9));
  const slam::TrajectoryPlotOptions plot = PlotOptions(args);
  const std::vector<StampedPose> ground_truth = ReadPoses(args.gt_path, "ground truth");
  const std::vector<StampedPose> estimate = ReadPoses(args.est_path, "estimate");
  const slam::TrajectoryError error = slam::EvaluateTrajectory(ground_truth, estimate, options);
  if (!args.plot_path.empty()) {
    render::WriteImageAtomically(args.plot_path, slam::DrawTrajectoryPlot(error, plot));
  }
  const slam::ErrorSources sources = slam::FindErrorSources(error, args.stretch_s);
  if (args.json) {
    std::cout << TrajectoryJson(args, ground_truth.size(), estimate.size(), options, error, sources)
                     .dump(2)
              << "\n";
    return kExitSuccess;
  }
  PrintTable(args.gt_path, args.est_path, ground_truth.size(), estimate.size(), options, error,
             sources);
  if (!args.plot_path.empty()) {
    std::cout << "\nplot           " << args.plot_path << " (" << plot.width_px << "x"
              << plot.height_px << ", top view: up is " << (args.up[0] == '-' ? "-" : "+")
              << args.up.back() << ", dropped)\n";
  }
  return kExitSuccess;
}

}  // namespace

int RunEval(int argc, char** argv) {
  CLI::App app("Evaluate results against ground truth.", "sightmap eval");
  app.require_subcommand(1);
  EvalTrajectoryArgs trajectory_args;
  CLI::App* trajectory = AddEvalTrajectory(app, trajectory_args);
  EvalIdentifyArgs identify_args;
  CLI::App* identify = AddEvalIdentify(app, identify_args);
  if (const int code = ParseOrExit(app, argc, argv); code >= 0) return code;
  if (identify->parsed()) return RunEvalIdentify(identify_args);
  if (trajectory->parsed()) return RunEvalTrajectory(trajectory_args);
  return kExitUsage;
}

}  // namespace sightmap::cli
