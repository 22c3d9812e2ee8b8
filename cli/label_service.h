// What the labelling page (`GET /label` of `sightmap serve`) reads and writes: the model's
// keyframes and their images, the labels drawn on the keyframes that see them, and label edits
// made through the same code as `sightmap label add --keyframe --pixel` (identify/labels.h).
// Knows nothing of HTTP: every answer is JSON or JPEG bytes, every refusal a ServiceError
// carrying the HTTP status it stands for. The model is opened per call (read-only to read), so a
// `sightmap label` run on the same file meanwhile is seen at once.
#pragma once

#include <cstdint>
#include <functional>
#include <mutex>
#include <string>

#include <nlohmann/json.hpp>

#include "core/check.h"
#include "identify/labels.h"
#include "store/model.h"

namespace sightmap::cli {

// A refused request: `status` is the HTTP status it stands for (400 bad input, 403 read-only,
// 404 no such keyframe or label, 409 a name already taken).
class ServiceError : public Error {
 public:
  ServiceError(int status, const std::string& message) : Error(message), status_(status) {}
  int status() const { return status_; }

 private:
  int status_;
};

struct LabelServiceOptions {
  // False: every write is refused with 403 and `read_only_reason`.
  bool editable = true;
  std::string read_only_reason;
  int max_image_side_px = 1280;  // larger image requests are refused [px]
  int jpeg_quality = 85;         // of the keyframe images sent [1, 100]
  size_t seen_by_max = 8;        // keyframes listed per label as seeing it
  identify::PixelLabelOptions pixel;
  identify::LabelViewOptions view;

  bool Check(std::string* error) const;
};
void to_json(nlohmann::json& json, const LabelServiceOptions& options);
void from_json(const nlohmann::json& json, LabelServiceOptions& options);

class LabelService {
 public:
  // `labels_changed` is called with the model after every write (the server reloads the labels
  // its Locator reports). Throws Error when the model cannot be opened.
  LabelService(std::string model_path, const LabelServiceOptions& options,
               std::function<void(const store::Model&)> labels_changed);

  // {"editable", "read_only_reason"?, "model", "keyframes", "labels"}
  nlohmann::json Status() const;
  // {"sessions": [{"id", "number", "source", "start_time_ns", "keyframes"}], "keyframes": [{"id",
  // "session", "time_s" (since its session's first keyframe), "width", "height"}]}
  nlohmann::json Keyframes() const;
  // The keyframe's colour image as a JPEG, scaled to fit `max_side` px (its own size when 0).
  std::string KeyframeJpeg(int64_t keyframe, int max_side) const;
  // {"keyframe", "width", "height", "labels": [{"id", "name", "type", "points": [{"index",
  // "pixel": [u, v], "depth_m", "hidden"}]}]}
  nlohmann::json KeyframeLabels(int64_t keyframe) const;
  // LabelsToJson, each label with "seen_by": the ids of the keyframes that see it, nearest first.
  nlohmann::json Labels() const;

  // {"name", "type"?, "keyframe", "pixel": [u, v]}: adds the clicked point to label `name`
  // (created when new). Answers {"label", "created", "point": {"world", "depth_m",
  // "depth_offset_px", "depth_pixel"}, "message"}.
  nlohmann::json AddPoint(const nlohmann::json& request);
  // {"name"?, "type"?}: renames and/or retypes label `id`. Answers {"label"}.
  nlohmann::json Edit(int64_t id, const nlohmann::json& request);
  // Deletes label `id`. Answers {"removed": name}.
  nlohmann::json Remove(int64_t id);

 private:
  store::Model OpenForReading() const;
  store::Model OpenForWriting() const;
  store::LabelRecord FindLabel(const store::Model& model, int64_t id) const;
  store::KeyframeInfo FindKeyframe(const store::Model& model, int64_t id) const;

  std::string model_path_;
  LabelServiceOptions options_;
  std::function<void(const store::Model&)> labels_changed_;
  std::mutex write_mutex_;  // one edit at a time: read, check, write
};

}  // namespace sightmap::cli
