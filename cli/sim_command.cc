// sightmap sim generate --scene office --trajectory handheld --session 1 --seed 7 --out DIR
// [--frames N] [--queries N] [--fps F] [--query-size WxH]: writes the synthetic building's walk as
// a TUM RGB-D folder plus phone photos with ground truth (see sim/dataset_writer.h).
#include <cstdint>
#include <cstdio>
#include <iostream>
#include <limits>
#include <string>

#include "cli/command_util.h"
#include "cli/commands.h"
#include "core/check.h"
#include "core/input_file.h"
#include "identify/photo.h"
#include "sim/dataset_writer.h"

namespace sightmap::cli {

int RunSim(int argc, char** argv) {
  CLI::App app("The synthetic building: a ground-truth RGB-D walk and phone photos.",
               "sightmap sim");
  app.require_subcommand(1);
  CLI::App* generate =
      app.add_subcommand("generate", "write a walk (TUM RGB-D folder) and phone photos to --out");
  sim::GenerateOptions options;
  std::string trajectory = "handheld";
  std::string query_size = "1280x960";
  generate
      ->add_option("--scene", options.simulator.scene, "'office' (embedded) or a scene JSON file")
      ->capture_default_str();
  generate->add_option("--trajectory", trajectory, "handheld | robot | survey (one lap by default)")
      ->check(CLI::IsMember({"handheld", "robot", "survey"}))
      ->capture_default_str();
  generate
      ->add_option("--session", options.simulator.session,
                   "another day: lighting, chairs and start differ")
      ->check(Within(1, 1000))
      ->capture_default_str();
  generate->add_option("--seed", options.simulator.seed, "same arguments and seed, same bytes")
      ->check(WholeNumberUpTo(std::numeric_limits<uint64_t>::max()))
      ->capture_default_str();
  generate->add_option("--out", options.out_dir, "output folder (created)")->required();
  generate
      ->add_option("--frames", options.simulator.frames,
                   "frames to write (default: 300 s of walk at --fps; a survey: one lap)")
      ->check(Within(0, 1e7));
  generate->add_option("--queries", options.queries, "phone photos to write")
      ->check(Within(0, 1e6))
      ->capture_default_str();
  generate
      ->add_option("--fps", options.simulator.fps,
                   "frame rate [Hz]; 1 renders only the frames a 1 Hz capture keeps")
      ->check(Within(0.01, 120, "Hz"))
      ->capture_default_str();
  generate->add_option("--query-size", query_size, "phone photo size WxH")->capture_default_str();
  if (const int code = ParseOrExit(app, argc, argv); code >= 0) return code;

  options.simulator.trajectory = sim::ParseTrajectoryKind(trajectory);
  // No smaller than `locate` and `eval identify` take a photo.
  const ImageSize photo_size = ParseImageSize(
      query_size, "--query-size", {identify::kMinPhotoSidePx, identify::kMinPhotoSidePx}, 8000);
  options.query.width = photo_size.width;
  options.query.height = photo_size.height;
  if (options.simulator.scene != "office") RefuseFolder(options.simulator.scene, "--scene");
  CheckOutputFolder(options.out_dir, "--out");
  const sim::GenerateSummary summary = sim::GenerateDataset(options, &std::cerr);
  std::cout << "wrote " << summary.frames << " frames and " << summary.queries << " photos to "
            << options.out_dir << " in " << summary.seconds << " s (" << summary.frames_per_second
            << " frames/s); play back with: sightmap probe tum:" << options.out_dir << "\n";
  return 0;
}

}  // namespace sightmap::cli
