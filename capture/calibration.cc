#include "capture/calibration.h"

#include <fstream>

#include <nlohmann/json.hpp>

#include "core/atomic_file.h"
#include "core/check.h"
#include "core/input_file.h"
#include "core/options_json.h"

namespace sightmap::capture {
namespace {

using nlohmann::json;

Intrinsics ReadIntrinsics(const json& block, const std::string& path, const char* name) {
  Intrinsics k;
  const std::string needs = path + ": \"" + name + "\" needs numbers width, height, fx, fy, cx, cy";
  SIGHTMAP_CHECK(block.is_object(), needs);
  // ReadNumber, not get<int>(): nlohmann casts 1e20 to int unchecked, which is undefined.
  const auto read = [&](const char* key, auto& value) {
    try {
      options_json::ReadNumber(block.at(key), value);
    } catch (const json::exception& e) {
      SIGHTMAP_THROW(Error, needs << " (" << options_json::PlainMessage(e) << ")");
    } catch (const OptionsJsonError& e) {
      SIGHTMAP_THROW(Error, path << ": \"" << name << "\": " << key << " " << e.reason());
    }
  };
  read("width", k.width);
  read("height", k.height);
  read("fx", k.fx);
  read("fy", k.fy);
  read("cx", k.cx);
  read("cy", k.cy);
  std::string error;
  SIGHTMAP_CHECK(k.Check(&error), path << ": \"" << name << "\": " << error);
  return k;
}

Eigen::Isometry3d ReadTransform(const json& block, const std::string& path) {
  std::vector<double> r;
  std::vector<double> t;
  try {
    r = block.at("rotation").get<std::vector<double>>();
    t = block.at("translation_m").get<std::vector<double>>();
  } catch (const json::exception& e) {
    SIGHTMAP_THROW(Error,
                   path << ": \"color_from_depth\" needs \"rotation\" (9 numbers, row-major) and "
                        << "\"translation_m\" (3 numbers) (" << e.what() << ")");
  }
  SIGHTMAP_CHECK(r.size() == 9 && t.size() == 3,
                 path << ": \"color_from_depth\" rotation must have 9 numbers and translation_m 3");
  Eigen::Matrix3d rotation;
  rotation << r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[7], r[8];
  // A hand-typed matrix is rarely exactly orthonormal; refuse only what is clearly not a rotation.
  SIGHTMAP_CHECK((rotation * rotation.transpose() - Eigen::Matrix3d::Identity()).norm() < 1e-3 &&
                     rotation.determinant() > 0.0,
                 path << ": \"color_from_depth\" rotation is not a rotation matrix");
  Eigen::Isometry3d color_from_depth = Eigen::Isometry3d::Identity();
  color_from_depth.linear() = Eigen::Quaterniond(rotation).normalized().toRotationMatrix();
  color_from_depth.translation() = Eigen::Vector3d(t[0], t[1], t[2]);
  return color_from_depth;
}

json IntrinsicsToJson(const Intrinsics& k) {
  return {{"width", k.width}, {"height", k.height}, {"fx", k.fx},
          {"fy", k.fy},       {"cx", k.cx},         {"cy", k.cy}};
}

}  // namespace

RgbdCalibration ReadCalibrationFile(const std::string& path) {
  std::ifstream in = OpenInputFile(path, "calibration file");
  SIGHTMAP_CHECK(in, "cannot read calibration file " << path << ": check the path");
  json root;
  try {
    root = json::parse(in);
  } catch (const json::exception& e) {
    SIGHTMAP_THROW(Error, path << " is not valid JSON (" << e.what() << ")");
  }
  SIGHTMAP_CHECK(root.is_object(),
                 path << " must hold a JSON object with color, depth, color_from_depth");
  RgbdCalibration calibration;
  if (root.contains("color")) calibration.color = ReadIntrinsics(root["color"], path, "color");
  if (root.contains("depth")) calibration.depth = ReadIntrinsics(root["depth"], path, "depth");
  if (root.contains("color_from_depth")) {
    calibration.color_from_depth = ReadTransform(root["color_from_depth"], path);
  }
  SIGHTMAP_CHECK(calibration.color || calibration.depth || calibration.color_from_depth,
                 path << " has none of \"color\", \"depth\", \"color_from_depth\"");
  return calibration;
}

void WriteCalibrationFile(const std::string& path, const RgbdCalibration& calibration) {
  json root = json::object();
  if (calibration.color) root["color"] = IntrinsicsToJson(*calibration.color);
  if (calibration.depth) root["depth"] = IntrinsicsToJson(*calibration.depth);
  if (calibration.color_from_depth) {
    const Eigen::Matrix3d r = calibration.color_from_depth->linear();
    const Eigen::Vector3d t = calibration.color_from_depth->translation();
    root["color_from_depth"] = {
        {"rotation",
         {r(0, 0), r(0, 1), r(0, 2), r(1, 0), r(1, 1), r(1, 2), r(2, 0), r(2, 1), r(2, 2)}},
        {"translation_m", {t.x(), t.y(), t.z()}}};
  }
  WriteFileAtomically(path, root.dump(2) + "\n");
}

}  // namespace sightmap::capture
