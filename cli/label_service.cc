#include "cli/label_service.h"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <map>
#include <sstream>
#include <utility>
#include <vector>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "core/format.h"
#include "core/options_json.h"

namespace sightmap::cli {
namespace {

constexpr int kBadRequest = 400;
constexpr int kForbidden = 403;
constexpr int kNotFound = 404;
constexpr int kConflict = 409;

// `request[key]` as a string, or nothing when absent; 400 when it is there but not a string.
std::optional<std::string> OptionalText(const nlohmann::json& request, const char* key) {
  if (!request.contains(key) || request.at(key).is_null()) return std::nullopt;
  if (!request.at(key).is_string()) {
    throw ServiceError(kBadRequest, std::string("\"") + key + "\" must be a string");
  }
  return request.at(key).get<std::string>();
}

void CheckText(const std::string& text, store::LabelField field) {
  std::string why;
  if (!store::ValidLabelText(text, field, &why)) throw ServiceError(kBadRequest, why);
}

void CheckObject(const nlohmann::json& request) {
  if (!request.is_object()) {
    throw ServiceError(kBadRequest, "the request body must be a JSON object");
  }
}

}  // namespace

bool LabelServiceOptions::Check(std::string* error) const {
  std::string why;
  if (max_image_side_px < 16 || max_image_side_px > 8192) {
    why = "max_image_side_px must be in [16, 8192]";
  } else if (jpeg_quality < 1 || jpeg_quality > 100) {
    why = "jpeg_quality must be in [1, 100]";
  } else if (!pixel.Check(&why) || !view.Check(&why)) {
  }
  if (why.empty()) return true;
  if (error) *error = why;
  return false;
}

LabelService::LabelService(std::string model_path, const LabelServiceOptions& options,
                           std::function<void(const store::Model&)> labels_changed)
    : model_path_(std::move(model_path)),
      options_(options),
      labels_changed_(std::move(labels_changed)) {
  SIGHTMAP_CHECK_OPTIONS(options_);
  OpenForReading();  // fails now, not at the first request
}

store::Model LabelService::OpenForReading() const {
  return store::Model::Open(model_path_, store::ModelOptions::ReadOnly());
}

store::Model LabelService::OpenForWriting() const {
  if (!options_.editable) throw ServiceError(kForbidden, options_.read_only_reason);
  store::ModelOptions model_options;
  model_options.create_if_missing = false;
  return store::Model::Open(model_path_, model_options);
}

store::KeyframeInfo LabelService::FindKeyframe(const store::Model& model, int64_t id) const {
  try {
    return model.Keyframe(KeyframeId(id));
  } catch (const Error&) {
    throw ServiceError(kNotFound, "no keyframe " + std::to_string(id) + " in the model");
  }
}

store::LabelRecord LabelService::FindLabel(const store::Model& model, int64_t id) const {
  for (store::LabelRecord& label : model.Labels()) {
    if (label.id.value() == id) return std::move(label);
  }
  throw ServiceError(kNotFound, "no label " + std::to_string(id) +
                                    " in the model (removed meanwhile?): reload the page");
}

nlohmann::json LabelService::Status() const {
  const store::Model model = OpenForReading();
  nlohmann::json status = {{"editable", options_.editable},
                           {"model", model_path_},
                           {"keyframes", model.NumKeyframes()},
                           {"labels", model.Labels().size()}};
  if (!options_.editable) status["read_only_reason"] = options_.read_only_reason;
  return status;
}

nlohmann::json LabelService::Keyframes() const {
  const store::Model model = OpenForReading();
  const std::vector<store::SessionRecord> sessions = model.Sessions();
  const std::vector<store::KeyframeInfo> keyframes = model.Keyframes();
  std::map<int64_t, TimestampNs> first_stamp;
  std::map<int64_t, int64_t> counts;
  for (const store::KeyframeInfo& keyframe : keyframes) {
    const int64_t session = keyframe.session.value();
    const auto [it, inserted] = first_stamp.emplace(session, keyframe.timestamp_ns);
    if (!inserted) it->second = std::min(it->second, keyframe.timestamp_ns);
    ++counts[session];
  }
  nlohmann::json session_list = nlohmann::json::array();
  for (size_t i = 0; i < sessions.size(); ++i) {
    const int64_t id = sessions[i].id.value();
    session_list.push_back({{"id", id},
                            {"number", i + 1},
                            {"source", sessions[i].source},
                            {"start_time_ns", sessions[i].start_time_ns},
                            {"keyframes", counts[id]}});
  }
  nlohmann::json keyframe_list = nlohmann::json::array();
  for (const store::KeyframeInfo& keyframe : keyframes) {
    const int64_t session = keyframe.session.value();
    keyframe_list.push_back(
        {{"id", keyframe.id.value()},
         {"session", session},
         {"time_s", 1e-9 * static_cast<double>(keyframe.timestamp_ns - first_stamp[session])},
         {"width", keyframe.intrinsics.width},
         {"height", keyframe.intrinsics.height}});
  }
  return {{"sessions", std::move(session_list)}, {"keyframes", std::move(keyframe_list)}};
}

std::string LabelService::KeyframeJpeg(int64_t keyframe, int max_side) const {
  if (max_side < 0 || max_side > options_.max_image_side_px) {
    throw ServiceError(kBadRequest, "max_side must be in [0, " +
                                        std::to_string(options_.max_image_side_px) +
                                        "] px (0: the keyframe's own size)");
  }
  const store::Model model = OpenForReading();
  FindKeyframe(model, keyframe);
  cv::Mat image = model.LoadColor(KeyframeId(keyframe));
  const cv::Size size = SizeAtMostOfSide(image.size(), max_side);
  if (size != image.size()) cv::resize(image, image, size, 0.0, 0.0, cv::INTER_AREA);
  std::vector<uint8_t> bytes;
  cv::imencode(".jpg", image, bytes, {cv::IMWRITE_JPEG_QUALITY, options_.jpeg_quality});
  return std::string(bytes.begin(), bytes.end());
}

nlohmann::json LabelService::KeyframeLabels(int64_t keyframe) const {
  const store::Model model = OpenForReading();
  const store::KeyframeInfo info = FindKeyframe(model, keyframe);
  const std::vector<store::LabelRecord> labels = model.Labels();
  nlohmann::json seen = nlohmann::json::array();
  for (const identify::LabelInKeyframe& in_view :
       identify::LabelsInKeyframe(model, KeyframeId(keyframe), labels, options_.view)) {
    nlohmann::json points = nlohmann::json::array();
    for (const identify::LabelPointInKeyframe& point : in_view.points) {
      points.push_back({{"index", point.point_index},
                        {"pixel", {point.pixel.x(), point.pixel.y()}},
                        {"depth_m", point.depth_m},
                        {"hidden", point.hidden}});
    }
    seen.push_back({{"id", in_view.label->id.value()},
                    {"name", in_view.label->name},
                    {"type", in_view.label->type},
                    {"points", std::move(points)}});
  }
  return {{"keyframe", keyframe},
          {"width", info.intrinsics.width},
          {"height", info.intrinsics.height},
          {"labels", std::move(seen)}};
}

nlohmann::json LabelService::Labels() const {
  const store::Model model = OpenForReading();
  const std::vector<store::LabelRecord> labels = model.Labels();
  const std::vector<store::KeyframeInfo> keyframes = model.Keyframes();
  nlohmann::json answer = identify::LabelsToJson(labels);
  for (size_t i = 0; i < labels.size(); ++i) {
    nlohmann::json seen_by = nlohmann::json::array();
    for (const KeyframeId id : identify::KeyframesSeeingLabel(
             keyframes, labels[i], options_.seen_by_max, options_.view)) {
      seen_by.push_back(id.value());
    }
    answer["labels"][i]["seen_by"] = std::move(seen_by);
  }
  return answer;
}

nlohmann::json LabelService::AddPoint(const nlohmann::json& request) {
  CheckObject(request);
  const std::optional<std::string> name = OptionalText(request, "name");
  if (!name) throw ServiceError(kBadRequest, "\"name\" is required: the appliance's label");
  CheckText(*name, store::LabelField::kName);
  std::optional<std::string> type = OptionalText(request, "type");
  if (type && type->empty()) type.reset();
  if (type) CheckText(*type, store::LabelField::kType);
  if (!request.contains("keyframe") || !request.at("keyframe").is_number_integer()) {
    throw ServiceError(kBadRequest, "\"keyframe\" must be a keyframe id (an integer)");
  }
  const nlohmann::json& pixel = request.contains("pixel") ? request.at("pixel") : nlohmann::json();
  if (!pixel.is_array() || pixel.size() != 2 || !pixel[0].is_number() || !pixel[1].is_number()) {
    throw ServiceError(kBadRequest, "\"pixel\" must be [u, v]: the clicked pixel [px]");
  }
  const int64_t keyframe = request.at("keyframe").get<int64_t>();
  const Eigen::Vector2d uv(pixel[0].get<double>(), pixel[1].get<double>());

  const std::lock_guard<std::mutex> lock(write_mutex_);
  store::Model model = OpenForWriting();
  FindKeyframe(model, keyframe);
  identify::PixelLabelPoint clicked;
  try {
    clicked = identify::LabelPointFromPixel(model, KeyframeId(keyframe), uv, options_.pixel);
  } catch (const Error& e) {
    throw ServiceError(kBadRequest, e.what());
  }
  const bool created = !model.FindLabel(*name).has_value();
  const store::LabelRecord label = identify::AddPointsToLabel(model, *name, {clicked.point}, type);
  labels_changed_(model);

  std::ostringstream message;
  message << (created ? "created " : "added to ") << "'" << label.name << "' (" << label.type
          << "): point " << label.points.size() << " at " << Fixed(clicked.depth_m, 2) << " m";
  if (clicked.depth_offset_px > 0.0) {
    message << ", depth from " << Fixed(clicked.depth_offset_px, 1)
            << " px away (the clicked pixel has none)";
  }
  const Eigen::Vector3d& world = label.points.back().world;
  return {{"label", identify::LabelsToJson({label})["labels"][0]},
          {"created", created},
          {"point",
           {{"world", {world.x(), world.y(), world.z()}},
            {"depth_m", clicked.depth_m},
            {"depth_offset_px", clicked.depth_offset_px},
            {"depth_pixel", {clicked.depth_pixel.x(), clicked.depth_pixel.y()}}}},
          {"message", message.str()}};
}

nlohmann::json LabelService::Edit(int64_t id, const nlohmann::json& request) {
  CheckObject(request);
  const std::optional<std::string> name = OptionalText(request, "name");
  const std::optional<std::string> type = OptionalText(request, "type");
  if (!name && !type) {
    throw ServiceError(kBadRequest, "give \"name\" (rename) and/or \"type\" (retype)");
  }
  if (name) CheckText(*name, store::LabelField::kName);
  if (type) CheckText(*type, store::LabelField::kType);

  const std::lock_guard<std::mutex> lock(write_mutex_);
  store::Model model = OpenForWriting();
  store::LabelRecord label = FindLabel(model, id);
  if (name && *name != label.name) {
    if (model.FindLabel(*name)) {
      throw ServiceError(kConflict, "a label named '" + *name +
                                        "' already exists: pick another name, or remove it first");
    }
    label.name = *name;
  }
  if (type) label.type = *type;
  model.UpdateLabel(label);
  labels_changed_(model);
  return {{"label", identify::LabelsToJson({FindLabel(model, id)})["labels"][0]}};
}

nlohmann::json LabelService::Remove(int64_t id) {
  const std::lock_guard<std::mutex> lock(write_mutex_);
  store::Model model = OpenForWriting();
  const store::LabelRecord label = FindLabel(model, id);
  model.DeleteLabel(label.id);
  labels_changed_(model);
  return {{"removed", label.name}};
}

// editable and read_only_reason are the server's (LocateServerOptions::read_only).
SIGHTMAP_OPTIONS_JSON(LabelServiceOptions, max_image_side_px, jpeg_quality, seen_by_max, pixel,
                      view)

}  // namespace sightmap::cli
