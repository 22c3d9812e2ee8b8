// Views rendered where the phone photos of a query set were taken (an oracle: the photos' true
// poses, so only for a model in the scene's frame, e.g. `map --ground-truth-poses`), stored as
// the model's synthetic views; then `sightmap eval identify` tells what a view rendered exactly
// where a person stood adds, the upper bound of what planned standpoints can add. Run by hand:
//   build/synthesis/synthesis_benchmark --model M --queries DIR
#include <chrono>
#include <iostream>
#include <map>

#include <CLI/CLI.hpp>

#include "core/check.h"
#include "core/timing.h"
#include "identify/identify_eval.h"
#include "store/model.h"
#include "synthesis/view_synthesis.h"

int main(int argc, char** argv) {
  using namespace sightmap;
  CLI::App app("Render and store synthetic views at the true poses of a query set's photos.");
  std::string model_path;
  std::string queries;
  app.add_option("--model", model_path, "a model in the scene's frame")->required();
  app.add_option("--queries", queries, "the query set (sim generate --queries)")->required();
  bool verbose = false;
  app.add_flag("--verbose", verbose, "a line per photo");
  CLI11_PARSE(app, argc, argv);
  try {
    store::Model model = store::Model::Open(model_path);
    std::map<std::string, Eigen::Vector3d> centres;
    for (const store::LabelRecord& label : model.Labels()) {
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      for (const store::LabelPoint& point : label.points) sum += point.world;
      centres[label.name] = sum / static_cast<double>(label.points.size());
    }
    synthesis::ViewSynthesisOptions options;
    synthesis::ViewSynthesizer synthesizer(model, options);
    model.DeleteSyntheticViews();
    int written = 0;
    int refused = 0;
    double drawn = 0.0;
    const auto start = std::chrono::steady_clock::now();
    const std::vector<identify::QueryTruth> truths = identify::ReadQueryTruths(queries);
    for (size_t i = 0; i < truths.size(); ++i) {
      const identify::QueryTruth& truth = truths[i];
      if (!truth.world_from_cam || !centres.count(truth.target)) continue;
      const auto result = synthesizer.Synthesize(*truth.world_from_cam, centres[truth.target]);
      if (verbose) {
        std::cout << "photo " << i << " " << truth.target << ": sources " << result.sources
                  << ", drawn " << result.drawn_share << ", features " << result.features
                  << (result.view ? ", stored\n" : ", refused: " + result.refusal + "\n");
      }
      drawn += result.drawn_share;
      if (result.view) {
        model.AddSyntheticView(*result.view);
        ++written;
      } else {
        ++refused;
      }
    }
    const double seconds = SecondsSince(start);
    std::cout << "written " << written << ", refused " << refused << ", mean drawn share "
              << drawn / std::max(1, written + refused) << ", " << seconds << " s\n";
  } catch (const Error& e) {
    std::cerr << "error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
