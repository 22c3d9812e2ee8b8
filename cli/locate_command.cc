// sightmap locate --model M PHOTO [--intrinsics FX,FY,CX,CY | --calib FILE] [--json]: locates one
// phone photo against the model and lists the labelled appliances in view, nearest first. The
// --json answer is identify/locator.h's ToJson (the same as `serve`'s POST /locate).
#include <cstdio>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "capture/calibration.h"
#include "cli/command_util.h"
#include "cli/commands.h"
#include "core/check.h"
#include "identify/locator.h"
#include "store/model.h"

namespace sightmap::cli {
namespace {

// "FX,FY,CX,CY" [px] for an image of width x height.
Intrinsics ParseIntrinsics(const std::string& text, int width, int height) {
  std::vector<double> values;
  std::stringstream stream(text);
  std::string item;
  while (std::getline(stream, item, ',')) {
    try {
      size_t used = 0;
      values.push_back(std::stod(item, &used));
      if (used != item.size()) values.clear();
    } catch (const std::exception&) {
      values.clear();
    }
    if (values.empty()) break;
  }
  if (values.size() != 4) {
    SIGHTMAP_THROW(InvalidArgument,
                   "--intrinsics expects FX,FY,CX,CY in pixels (four numbers), "
                   "got '"
                       << text << "'");
  }
  const Intrinsics k =
      Intrinsics::FromPinhole(width, height, values[0], values[1], values[2], values[3]);
  std::string error;
  if (!k.Check(&error)) SIGHTMAP_THROW(InvalidArgument, "--intrinsics: " << error);
  return k;
}

// "<heading>N in view[, M hidden behind a surface][, nearest first:]", then one line each.
void PrintAppliances(const char* heading,
                     const std::vector<identify::ApplianceInView>& appliances) {
  int visible = 0;
  for (const identify::ApplianceInView& appliance : appliances) visible += !appliance.occluded;
  std::cout << heading << visible << " in view";
  if (visible != static_cast<int>(appliances.size())) {
    std::cout << ", " << appliances.size() - static_cast<size_t>(visible)
              << " hidden behind a surface";
  }
  std::cout << (appliances.empty() ? "\n" : ", nearest first:\n");
  for (const identify::ApplianceInView& appliance : appliances) {
    std::cout << "  " << std::left << std::setw(22) << appliance.name << std::setw(14)
              << appliance.type << std::right << std::setprecision(2) << std::setw(6)
              << appliance.distance_m << " m  ";
    if (appliance.occluded) {
      std::cout << "occluded\n";
    } else {
      std::cout << std::setprecision(0) << "pixel (" << appliance.pixel.x() << ", "
                << appliance.pixel.y() << ")\n";
    }
  }
}

void PrintHuman(const identify::LocateResult& result, const std::string& photo_path) {
  std::cout << std::fixed;
  if (!result.matched) {
    std::cout << "not matched    " << photo_path << ": " << result.reason << "\n";
  } else {
    const Eigen::Vector3d t = result.world_from_cam.translation();
    const Eigen::Quaterniond q(result.world_from_cam.linear());
    std::cout << "matched        " << photo_path << " (keyframe " << result.keyframe.value() << ", "
              << result.inliers << " PnP inliers of " << result.matches << " 2D-3D matches)\n";
    std::cout << std::setprecision(3) << "position       " << t.x() << " " << t.y() << " " << t.z()
              << " m (world_from_cam)\n";
    std::cout << std::setprecision(4) << "orientation    " << q.x() << " " << q.y() << " " << q.z()
              << " " << q.w() << " (quaternion x y z w)\n";
  }
  const Intrinsics& k = result.intrinsics;
  std::cout << std::setprecision(1) << "intrinsics     fx " << k.fx << " fy " << k.fy << " cx "
            << k.cx << " cy " << k.cy << " at " << k.width << "x" << k.height << " ("
            << ToString(result.intrinsics_source) << ")\n";
  if (result.matched) PrintAppliances("appliances     ", result.appliances);
  for (size_t p = 0; p < result.possible_places.size(); ++p) {
    const identify::PossiblePlace& place = result.possible_places[p];
    const Eigen::Vector3d t = place.world_from_cam.translation();
    std::cout << "possible place " << p + 1 << " (keyframe " << place.keyframe.value() << ", "
              << place.inliers << " PnP inliers) at " << std::setprecision(3) << t.x() << " "
              << t.y() << " " << t.z() << " m\n";
    PrintAppliances("  appliances   ", place.appliances);
  }
  const identify::LocateTimings& t = result.timings;
  std::cout << std::setprecision(1) << "time           " << t.total_ms << " ms (features "
            << t.features_ms << ", retrieval " << t.retrieval_ms << ", matching " << t.matching_ms
            << ", PnP " << t.pnp_ms << ", visibility " << t.visibility_ms << ")\n";
}

}  // namespace

int RunLocate(int argc, char** argv) {
  CLI::App app(
      "Locate a phone photo against a model and list the labelled appliances in view, nearest "
      "first. Intrinsics: --intrinsics, --calib, else the photo's EXIF focal length, else "
      "estimated.",
      "sightmap locate");
  std::string model_path;
  std::string photo_path;
  std::string intrinsics_text;
  std::string calib_path;
  bool json = false;
  auto* model_option = app.add_option("--model", model_path, "the model's SQLite file");
  auto* photo_option = app.add_option("PHOTO", photo_path, "the photo (JPEG or PNG)");
  auto* intrinsics_option = app.add_option(
      "--intrinsics", intrinsics_text,
      "FX,FY,CX,CY of the photo as a viewer shows it (EXIF orientation applied), at its "
      "own resolution [px]");
  app.add_option("--calib", calib_path,
                 "calibration file (JSON, see capture/calibration.h); its colour intrinsics (the "
                 "sensor's, as the file stores the pixels) are scaled to the photo and turned with "
                 "its EXIF orientation")
      ->excludes(intrinsics_option);
  app.add_flag("--json", json, "print the answer as one JSON object (stable keys)");
  identify::LocatorOptions options;
  bool print_config = false;
  AddConfigOptions(app, options, print_config);
  if (const int code = ParseOrExit(app, argc, argv); code >= 0) return code;
  if (print_config) return PrintConfig(options);
  if (const int code = RequireGiven(app, {model_option, photo_option}); code >= 0) return code;
  SIGHTMAP_CHECK_OPTIONS(options);

  // The photo first: a typo in its name should not wait for the model to load.
  const identify::Photo photo = identify::ReadPhotoFile(photo_path, identify::kMaxPhotoMegapixels);
  identify::IntrinsicsHint hint;
  if (!intrinsics_text.empty()) {
    hint.upright = ParseIntrinsics(intrinsics_text, photo.width(), photo.height());
  } else if (!calib_path.empty()) {
    const capture::RgbdCalibration calibration = capture::ReadCalibrationFile(calib_path);
    SIGHTMAP_CHECK(calibration.color.has_value(),
                   "calibration file " << calib_path
                                       << " has no \"color\" block: the photo's intrinsics go "
                                          "there");
    hint.sensor = calibration.color;
  }

  store::ModelOptions model_options;
  model_options.read_only = true;
  model_options.create_if_missing = false;
  const store::Model model = store::Model::Open(model_path, model_options);
  // Loading decodes every keyframe's images (seconds on a building's model): say so, on stderr so
  // the answer on stdout stays the answer.
  std::cerr << "sightmap locate: loading " << model_path << "\n" << std::flush;
  const identify::Locator locator(model, options,
                                  TenthsProgress("sightmap locate: loaded", "keyframes"));
  if (!locator.LoadWarning().empty()) std::cerr << "sightmap: " << locator.LoadWarning() << "\n";
  const identify::LocateResult result = locator.Locate(photo, hint);
  if (json) {
    std::cout << identify::ToJson(result).dump(2) << "\n";
  } else {
    PrintHuman(result, photo_path);
  }
  return kExitSuccess;
}

}  // namespace sightmap::cli
