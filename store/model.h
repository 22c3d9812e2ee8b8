// The building model: one SQLite file holding sessions, keyframes (poses, images, features), the
// pose graph's links, appliance labels and a visual vocabulary. Written by mapping, read by
// identification. Crash-safe: WAL journal, one transaction per keyframe with its features and
// links, one transaction per pose-graph update; images are decoded only when asked for.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Geometry>
#include <nlohmann/json_fwd.hpp>
#include <opencv2/core.hpp>

#include "core/camera.h"
#include "core/features.h"
#include "core/ids.h"
#include "core/link_type.h"
#include "core/rgbd_frame.h"

namespace sightmap::store {

// How a session ended. kRunning is also what a crashed session looks like until
// Model::MarkRunningSessionsInterrupted() is called by whoever resumes.
enum class SessionEnd { kRunning = 0, kFinished = 1, kInterrupted = 2, kResumedInto = 3 };
const char* SessionEndName(SessionEnd end);

struct SessionRecord {
  SessionId id;                   // set by the model
  TimestampNs start_time_ns = 0;  // wall clock, ns since the epoch
  TimestampNs end_time_ns = 0;    // 0 while running
  std::string source;             // e.g. "openni://", "tum:DIR"
  std::string device_name;
  std::string device_serial;
  Intrinsics intrinsics;
  SessionEnd end_state = SessionEnd::kRunning;
  SessionId resumed_into;    // the session that continued this one, for kResumedInto
  std::string options_json;  // every option the session ran with, so the model explains itself
};

struct LinkRecord {
  LinkId id;  // set by the model
  KeyframeId from;
  KeyframeId to;
  LinkType type = LinkType::kOdometry;
  // Pose of `to` in `from`'s camera frame: world_from_from^-1 * world_from_to.
  Eigen::Isometry3d to_in_from = Eigen::Isometry3d::Identity();
  Matrix6d information = Matrix6d::Identity();  // over (tx, ty, tz, rx, ry, rz) [1/m^2, 1/rad^2]
  // False once the pose graph switched it off as inconsistent with the rest (a false loop); kept
  // so that a resumed session does not trust it again.
  bool active = true;
};

// A link by its ends and type, for switching off a stored link whose id the caller never saw.
struct LinkKey {
  KeyframeId from;
  KeyframeId to;
  LinkType type = LinkType::kOdometry;
};

struct KeyframeRecord {
  SessionId session;
  TimestampNs timestamp_ns = 0;  // the frame's timestamp (source clock)
  Eigen::Isometry3d world_from_cam = Eigen::Isometry3d::Identity();       // optimised
  Eigen::Isometry3d odom_world_from_cam = Eigen::Isometry3d::Identity();  // raw odometry
  Intrinsics intrinsics;
  cv::Mat color;  // CV_8UC3 BGR, stored as JPEG
  cv::Mat depth;  // CV_16UC1 [mm], stored as lossless 16-bit PNG
  Features features;
  // Features for matching phone photos (RootSIFT, with 3D points). Without a value: not extracted
  // (none stored); empty: extracted and none found, stored so that nobody extracts them again.
  std::optional<Features> photo_features;
  // Links written in the same transaction. An invalid id at either end stands for this keyframe.
  std::vector<LinkRecord> links;
  // Stored links (found by their ends and type) whose measurement and information this keyframe
  // revised, replaced in the same transaction: a motion-model link across a blind run, bridged
  // once this keyframe measured the motion after the run. AddKeyframe throws, and stores
  // nothing, when one is not in the model.
  std::vector<LinkRecord> revised_links;
};

// A keyframe's metadata, listed without touching its image blobs.
struct KeyframeInfo {
  KeyframeId id;
  SessionId session;
  TimestampNs timestamp_ns = 0;
  Eigen::Isometry3d world_from_cam = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d odom_world_from_cam = Eigen::Isometry3d::Identity();
  Intrinsics intrinsics;  // its width/height are the image size
  int num_features = 0;
  int64_t color_bytes = 0;  // encoded sizes
  int64_t depth_bytes = 0;
};

// A view rendered from the model at a standpoint the walk missed (identify's view synthesis): its
// features help locate photos taken from there; mapping never reads it. It is stored relative to
// the real keyframe it was mostly rendered from, and moves with that keyframe when a later
// session's loop closures re-optimise the graph.
struct SyntheticViewRecord {
  SyntheticViewId id;  // set by the model
  KeyframeId source;   // must exist; deleting it deletes the view
  LabelId label;       // the appliance it was rendered for; invalid for none
  Eigen::Isometry3d source_from_cam = Eigen::Isometry3d::Identity();
  // Derived when read: the source keyframe's optimised world_from_cam * source_from_cam.
  Eigen::Isometry3d world_from_cam = Eigen::Isometry3d::Identity();
  Intrinsics intrinsics;    // its width/height are the image size
  cv::Mat color;            // CV_8UC3 BGR, stored as JPEG; read only by LoadSyntheticColor
  Features features;        // 3D points in this view's camera frame
  int64_t color_bytes = 0;  // encoded size, when read
};

enum class LabelPointSource { kKeyframePixel = 0, kImportedFile = 1, kTyped = 2 };

struct LabelPoint {
  Eigen::Vector3d world = Eigen::Vector3d::Zero();  // [m]
  LabelPointSource source = LabelPointSource::kTyped;
  // kKeyframePixel: the keyframe and pixel it was clicked on, and the point in that keyframe's
  // camera frame [m]. `world` is then derived from the keyframe's current optimised pose, so a
  // label follows its keyframe when a loop closure moves it.
  KeyframeId keyframe;
  Eigen::Vector2d pixel = Eigen::Vector2d::Zero();
  Eigen::Vector3d cam_point = Eigen::Vector3d::Zero();
  std::string file;  // kImportedFile: the file it came from
};

struct LabelRecord {
  LabelId id;                      // set by the model
  std::string name;                // unique in a model
  std::string type;                // free text: "lamp", "projector", ...
  std::vector<LabelPoint> points;  // at least one
  TimestampNs created_ns = 0;      // set by the model (wall clock)
  TimestampNs updated_ns = 0;
};

// Whether `text` can be a label's name (or its type, which may also be empty): it is what a
// person sees in lists, on the phone's page and as an exported file name, so it must be 1-100
// bytes with something besides spaces, no control characters (a newline or tab), and no spaces
// around it. `why` says what is wrong, quoting the text with its control characters escaped.
enum class LabelField { kName, kType };
bool ValidLabelText(const std::string& text, LabelField field, std::string* why);

struct ModelOptions {
  // Open without writing; the model must exist. For inspection and export.
  bool read_only = false;
  // Create the file when it does not exist (ignored with read_only).
  bool create_if_missing = true;
  // JPEG quality of colour images [1, 100].
  int jpeg_quality = 90;
  // PNG compression of depth images [0, 9]; lossless at every level, higher is smaller and slower.
  int png_compression = 1;
  // fsync the WAL at every commit, so a keyframe reported as written survives a power cut (a
  // process crash is survived either way). Off trades that for write speed.
  bool sync_every_commit = true;
  // How long a writer waits for another connection's lock before failing [ms].
  int busy_timeout_ms = 2000;

  bool Check(std::string* error) const;

  // Defaults, read-only: for inspection, export, serving and tests.
  static ModelOptions ReadOnly() {
    ModelOptions options;
    options.read_only = true;
    return options;
  }
};
void to_json(nlohmann::json& json, const ModelOptions& options);
void from_json(const nlohmann::json& json, ModelOptions& options);

// Counts for `sightmap info`.
struct ModelSummary {
  int schema_version = 0;
  int64_t sessions = 0;
  int64_t keyframes = 0;
  int64_t odometry_links = 0;
  int64_t loop_closures = 0;
  int64_t relocalisation_links = 0;
  int64_t user_links = 0;
  int64_t prior_links = 0;  // the motion model's, across blind stretches
  // Links switched off by the pose graph (not counted above).
  int64_t inactive_links = 0;
  // Connected parts of the pose graph: a new one starts when tracking was lost and not recovered.
  int64_t segments = 0;
  int64_t largest_segment_keyframes = 0;  // keyframes in the largest part
  // The largest part's share of the keyframes (0 without keyframes).
  double LargestPartRatio() const {
    return keyframes > 0
               ? static_cast<double>(largest_segment_keyframes) / static_cast<double>(keyframes)
               : 0.0;
  }
  int64_t labels = 0;
  int64_t synthetic_views = 0;
  // Their stored bytes (image, keypoints, descriptors, points), a share of size_bytes.
  int64_t synthetic_view_bytes = 0;
  // Keyframes stored with features for matching photos (RootSIFT), and those features' bytes.
  int64_t photo_feature_keyframes = 0;
  int64_t photo_feature_bytes = 0;
  int64_t size_bytes = 0;  // the database file plus its WAL
  // Axis-aligned box of keyframe positions and label points [m]; empty when there are none.
  bool has_bounding_box = false;
  Eigen::Vector3d bbox_min = Eigen::Vector3d::Zero();
  Eigen::Vector3d bbox_max = Eigen::Vector3d::Zero();
};

class Model {
 public:
  // Opens (or creates) a model file; ":memory:" for a throwaway one. Upgrades an older schema in
  // one transaction. Throws Error with one line saying what to do when the file is read-only, not
  // SQLite, another application's database, or from a newer sightmap.
  static Model Open(const std::string& path, const ModelOptions& options = {});
  // The schema version this build writes.
  static int LatestSchemaVersion();

  Model(Model&&) noexcept;
  Model& operator=(Model&&) noexcept;
  ~Model();

  const std::string& path() const;
  int SchemaVersion() const;

  // Sessions.
  SessionId BeginSession(const SessionRecord& session);
  void EndSession(SessionId id, SessionEnd end_state, TimestampNs end_time_ns,
                  SessionId resumed_into = SessionId());
  // Sessions still marked running (left by a crash) become interrupted; returns how many.
  int MarkRunningSessionsInterrupted(TimestampNs now_ns);
  // Removes a session that holds no keyframe and that no session was resumed into (a run that
  // mapped nothing leaves the model as it found it); returns false, removing nothing, otherwise.
  bool DeleteEmptySession(SessionId id);
  std::vector<SessionRecord> Sessions() const;

  // Keyframes. AddKeyframe writes the keyframe, its features and its links in one transaction.
  KeyframeId AddKeyframe(const KeyframeRecord& keyframe);
  // A pose-graph optimisation's result: every optimised world_from_cam in one transaction.
  void UpdatePoses(const std::vector<std::pair<KeyframeId, Eigen::Isometry3d>>& world_from_cam);
  // The same, with the links that optimisation switched off and those it switched back on, in one
  // transaction: the stored graph never has poses from one optimisation and link states from
  // another.
  void UpdateGraph(const std::vector<std::pair<KeyframeId, Eigen::Isometry3d>>& world_from_cam,
                   const std::vector<LinkKey>& deactivated_links,
                   const std::vector<LinkKey>& reactivated_links = {});
  std::vector<KeyframeInfo> Keyframes() const;  // ordered by id; no image is read
  KeyframeInfo Keyframe(KeyframeId id) const;
  int64_t NumKeyframes() const;
  cv::Mat LoadColor(KeyframeId id) const;  // CV_8UC3 BGR
  // Grey (CV_8UC1), decoded at 1 / `reduction` of its size (1, 2, 4 or 8: the JPEG decoder scales
  // as it decodes, faster than decoding whole).
  cv::Mat LoadGrey(KeyframeId id, int reduction = 1) const;
  cv::Mat LoadDepth(KeyframeId id) const;  // CV_16UC1 [mm]
  Features LoadFeatures(KeyframeId id) const;
  // A keyframe's features for matching photos, when it has them; SetPhotoFeatures adds or
  // replaces them (a 3D point slot per keypoint).
  std::optional<Features> LoadPhotoFeatures(KeyframeId id) const;
  void SetPhotoFeatures(KeyframeId id, const Features& features);
  bool HasPhotoFeatures(KeyframeId id) const;  // a row, if an empty one
  int64_t NumKeyframesWithPhotoFeatures() const;

  // Links of the pose graph.
  LinkId AddLink(const LinkRecord& link);
  std::vector<LinkRecord> Links() const;

  // Labels. Names are unique; AddLabel fails with Error on a duplicate.
  LabelId AddLabel(const LabelRecord& label);
  void UpdateLabel(const LabelRecord& label);  // by id; replaces type and points
  void DeleteLabel(LabelId id);
  std::optional<LabelRecord> FindLabel(const std::string& name) const;
  std::vector<LabelRecord> Labels() const;  // ordered by name

  // Synthetic views. AddSyntheticView writes one view in one transaction (features must have a 3D
  // point slot per keypoint); DeleteSyntheticViews removes those with an id up to `last` (all when
  // `last` is invalid) and returns how many, so a caller replacing them removes the old ones only
  // once the new ones are written.
  SyntheticViewId AddSyntheticView(const SyntheticViewRecord& view);
  int64_t DeleteSyntheticViews(SyntheticViewId last = SyntheticViewId());
  // Every synthetic view with its features and world pose, by id; no image is read.
  std::vector<SyntheticViewRecord> SyntheticViews() const;
  int64_t NumSyntheticViews() const;
  cv::Mat LoadSyntheticColor(SyntheticViewId id) const;  // CV_8UC3 BGR

  // The visual vocabulary place recognition trains (format names the library that reads it).
  void SetVocabulary(const std::string& format, const std::vector<uint8_t>& data);
  std::optional<std::pair<std::string, std::vector<uint8_t>>> LoadVocabulary() const;

  ModelSummary Summary() const;
  // `PRAGMA integrity_check`'s answer: "ok" for a sound file.
  std::string IntegrityCheck() const;

 private:
  struct Impl;
  explicit Model(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace sightmap::store
