#include "store/model.h"

#include <sys/stat.h>
#include <unistd.h>

#include <cctype>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <map>
#include <numeric>
#include <optional>

#include <opencv2/imgcodecs.hpp>

#include "core/check.h"
#include "core/options_json.h"
#include "store/schema.h"
#include "store/sqlite_util.h"
#include "store/writer_lock.h"

namespace sightmap::store {

namespace {
// No building is 20 km across: a coordinate beyond this is a typo or a unit mix-up [m].
constexpr double kMaxLabelCoordinateM = 10000.0;
constexpr size_t kMaxLabelNameBytes = 100;

std::string Escaped(const std::string& text) {
  std::string out;
  for (const char c : text) {
    const auto byte = static_cast<unsigned char>(c);
    if (c == '\n') {
      out += "\\n";
    } else if (c == '\t') {
      out += "\\t";
    } else if (byte < 0x20 || byte == 0x7F) {
      static const char kHex[] = "0123456789abcdef";
      out += std::string("\\x") + kHex[byte >> 4] + kHex[byte & 15];
    } else {
      out += c;
    }
  }
  return out;
}
}  // namespace

bool ValidLabelText(const std::string& name, LabelField field, std::string* why) {
  auto fail = [&](const std::string& reason) {
    if (why)
      *why = std::string("a label ") + (field == LabelField::kName ? "name " : "type ") + reason;
    return false;
  };
  const std::string quoted = "'" + Escaped(name) + "'";
  if (name.empty()) return field == LabelField::kType || fail("cannot be empty");
  if (name.size() > kMaxLabelNameBytes) {
    return fail("is limited to " + std::to_string(kMaxLabelNameBytes) + " bytes, " +
                quoted.substr(0, 40) + "... has " + std::to_string(name.size()));
  }
  for (const char c : name) {
    const auto byte = static_cast<unsigned char>(c);
    if (byte < 0x20 || byte == 0x7F) {
      return fail("cannot hold control characters (a newline, a tab): " + quoted);
    }
  }
  if (name.find_first_not_of(' ') == std::string::npos) return fail("cannot be only spaces");
  if (name.front() == ' ' || name.back() == ' ') {
    return fail("cannot start or end with a space: " + quoted);
  }
  return true;
}

using internal::Exec;
using internal::Statement;
using internal::Transaction;

namespace {

TimestampNs NowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

// Binds tx ty tz qx qy qz qw starting at `first`.
void BindPose(Statement& statement, int first, const Eigen::Isometry3d& pose) {
  const Eigen::Vector3d t = pose.translation();
  const Eigen::Quaterniond q(pose.rotation());
  statement.Bind(first, t.x()).Bind(first + 1, t.y()).Bind(first + 2, t.z());
  statement.Bind(first + 3, q.x()).Bind(first + 4, q.y()).Bind(first + 5, q.z());
  statement.Bind(first + 6, q.w());
}

Eigen::Isometry3d ColumnPose(const Statement& statement, int first) {
  Eigen::Quaterniond q(statement.Double(first + 6), statement.Double(first + 3),
                       statement.Double(first + 4), statement.Double(first + 5));
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = q.normalized().toRotationMatrix();
  pose.translation() = Eigen::Vector3d(statement.Double(first), statement.Double(first + 1),
                                       statement.Double(first + 2));
  return pose;
}

void BindIntrinsics(Statement& statement, int first, const Intrinsics& k) {
  statement.Bind(first, k.width).Bind(first + 1, k.height).Bind(first + 2, k.fx);
  statement.Bind(first + 3, k.fy).Bind(first + 4, k.cx).Bind(first + 5, k.cy);
}

Intrinsics ColumnIntrinsics(const Statement& statement, int first) {
  Intrinsics k;
  k.width = static_cast<int>(statement.Int(first));
  k.height = static_cast<int>(statement.Int(first + 1));
  k.fx = statement.Double(first + 2);
  k.fy = statement.Double(first + 3);
  k.cx = statement.Double(first + 4);
  k.cy = statement.Double(first + 5);
  return k;
}

// Keypoints as packed little-endian records (x, y, size, angle, response as float32; octave,
// class_id as int32): 28 bytes each, no per-feature rows (1,000 rows per keyframe would dominate
// write time).
constexpr size_t kKeypointBytes = 5 * sizeof(float) + 2 * sizeof(int32_t);

std::vector<uint8_t> EncodeKeypoints(const std::vector<cv::KeyPoint>& keypoints) {
  std::vector<uint8_t> blob(keypoints.size() * kKeypointBytes);
  uint8_t* out = blob.data();
  for (const cv::KeyPoint& kp : keypoints) {
    const float floats[5] = {kp.pt.x, kp.pt.y, kp.size, kp.angle, kp.response};
    const int32_t ints[2] = {kp.octave, kp.class_id};
    std::memcpy(out, floats, sizeof(floats));
    std::memcpy(out + sizeof(floats), ints, sizeof(ints));
    out += kKeypointBytes;
  }
  return blob;
}

std::vector<cv::KeyPoint> DecodeKeypoints(const std::vector<uint8_t>& blob) {
  SIGHTMAP_CHECK(blob.size() % kKeypointBytes == 0,
                 "corrupt keypoints blob in the model: restore it from a backup");
  std::vector<cv::KeyPoint> keypoints(blob.size() / kKeypointBytes);
  const uint8_t* in = blob.data();
  for (cv::KeyPoint& kp : keypoints) {
    float floats[5];
    int32_t ints[2];
    std::memcpy(floats, in, sizeof(floats));
    std::memcpy(ints, in + sizeof(floats), sizeof(ints));
    kp = cv::KeyPoint(floats[0], floats[1], floats[2], floats[3], floats[4], ints[0], ints[1]);
    in += kKeypointBytes;
  }
  return keypoints;
}

// Each keypoint's camera-frame point as three float32, NaN where it has none (the mapper's double
// precision is more than depth noise of millimetres needs); no points at all for a photo.
std::vector<Eigen::Vector3f> EncodePoints(const Features& features) {
  std::vector<Eigen::Vector3f> points;
  points.reserve(features.points_cam.size());
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (size_t i = 0; i < features.points_cam.size(); ++i) {
    points.push_back(features.has_point[i] ? Eigen::Vector3f(features.points_cam[i].cast<float>())
                                           : Eigen::Vector3f(nan, nan, nan));
  }
  return points;
}

void DecodePoints(const std::vector<uint8_t>& blob, Features* features) {
  const size_t count = blob.size() / sizeof(float[3]);
  features->points_cam.reserve(count);
  features->has_point.reserve(count);
  for (size_t i = 0; i < count; ++i) {
    float xyz[3];
    std::memcpy(xyz, blob.data() + i * sizeof(xyz), sizeof(xyz));
    const Eigen::Vector3f point(xyz[0], xyz[1], xyz[2]);
    const bool valid = point.allFinite();
    features->has_point.push_back(valid);
    features->points_cam.push_back(valid ? Eigen::Vector3d(point.cast<double>())
                                         : Eigen::Vector3d::Zero());
  }
}

template <typename Row>
Statement& BindRowAsBlob(Statement& statement, int index, const std::vector<Row>& rows) {
  return statement.BindBlob(index, rows.data(), rows.size() * sizeof(Row));
}

// Features from the columns count, keypoints, descriptor_type, descriptor_rows,
// descriptor_cols, descriptors, cam_points starting at `first`; `what` names the owner in errors.
Features ColumnFeatures(const Statement& query, int first, const std::string& what) {
  Features features;
  features.keypoints = DecodeKeypoints(query.Blob(first + 1));
  const int type = static_cast<int>(query.Int(first + 2));
  const int rows = static_cast<int>(query.Int(first + 3));
  const int cols = static_cast<int>(query.Int(first + 4));
  const std::vector<uint8_t> descriptors = query.Blob(first + 5);
  if (rows > 0 && cols > 0) {
    features.descriptors.create(rows, cols, type);
    const size_t bytes = features.descriptors.total() * features.descriptors.elemSize();
    SIGHTMAP_CHECK(bytes == descriptors.size(), "corrupt descriptors of " << what);
    std::memcpy(features.descriptors.data, descriptors.data(), bytes);
  }
  const std::vector<uint8_t> points = query.Blob(first + 6);
  SIGHTMAP_CHECK(points.size() % sizeof(Eigen::Vector3f) == 0, "corrupt 3D points of " << what);
  DecodePoints(points, &features);
  SIGHTMAP_CHECK(features.PointsMatchKeypoints(),
                 what << " has " << features.points_cam.size() << " 3D points for "
                      << features.keypoints.size() << " keypoints");
  SIGHTMAP_CHECK(
      static_cast<int64_t>(features.keypoints.size()) == query.Int(first),
      what << " lists " << query.Int(first) << " features but has " << features.keypoints.size());
  return features;
}

// The encoded blobs of one image's features, bound as count, keypoints, descriptor_type,
// descriptor_rows, descriptor_cols, descriptors, cam_points from `first`.
struct EncodedFeatures {
  explicit EncodedFeatures(const Features& features)
      : count(static_cast<int64_t>(features.keypoints.size())),
        keypoints(EncodeKeypoints(features.keypoints)),
        cam_points(EncodePoints(features)),
        descriptors(features.descriptors.isContinuous() ? features.descriptors
                                                        : features.descriptors.clone()) {}
  void Bind(Statement& statement, int first) const {
    statement.Bind(first, count);
    BindRowAsBlob(statement, first + 1, keypoints);
    statement.Bind(first + 2, descriptors.type())
        .Bind(first + 3, descriptors.rows)
        .Bind(first + 4, descriptors.cols);
    statement.BindBlob(first + 5, descriptors.data, descriptors.total() * descriptors.elemSize());
    BindRowAsBlob(statement, first + 6, cam_points);
  }
  int64_t count;
  std::vector<uint8_t> keypoints;
  std::vector<Eigen::Vector3f> cam_points;
  cv::Mat descriptors;
};

// Photo features are stored with a descriptor row and a 3D point slot per keypoint.
void CheckPhotoFeatures(const Features& features) {
  SIGHTMAP_CHECK(
      features.keypoints.empty() ||
          (features.IsConsistent() && features.points_cam.size() == features.keypoints.size()),
      "photo features need a descriptor row and a 3D point slot per keypoint");
}

// One keyframe's row of `table` ("features" or "photo_features": the same columns), replacing
// the one it has.
void InsertFeatures(sqlite3* db, const std::string& table, KeyframeId id,
                    const EncodedFeatures& encoded) {
  Statement insert(db, "INSERT OR REPLACE INTO " + table +
                           " (keyframe_id, count, keypoints, descriptor_type, descriptor_rows, "
                           "descriptor_cols, descriptors, cam_points) VALUES (?, ?, ?, ?, ?, ?, "
                           "?, ?)");
  insert.Bind(1, id.value());
  encoded.Bind(insert, 2);
  insert.Run();
}

// One keyframe's row of `table` ("features" or "photo_features"), when it has one; `what` names
// it in errors.
std::optional<Features> SelectFeatures(sqlite3* db, const std::string& table, KeyframeId id,
                                       const std::string& what) {
  Statement query(db,
                  "SELECT count, keypoints, descriptor_type, descriptor_rows, descriptor_cols, "
                  "descriptors, cam_points FROM " +
                      table + " WHERE keyframe_id = ?");
  query.Bind(1, id.value());
  if (!query.Step()) return std::nullopt;
  return ColumnFeatures(query, 0, what);
}

std::string FileDescription(const std::string& path) { return "'" + path + "'"; }

bool IsMemoryPath(const std::string& path) { return path == ":memory:" || path.empty(); }

// For a file: URI, every byte outside the unreserved set and '/' is escaped.
std::string PercentEncode(const std::string& path) {
  static const char kHex[] = "0123456789ABCDEF";
  std::string out;
  for (const char c : path) {
    const auto byte = static_cast<unsigned char>(c);
    if (std::isalnum(byte) || c == '/' || c == '-' || c == '_' || c == '.' || c == '~') {
      out += c;
    } else {
      out += '%';
      out += kHex[byte >> 4];
      out += kHex[byte & 15];
    }
  }
  return out;
}

}  // namespace

const char* SessionEndName(SessionEnd end) {
  switch (end) {
    case SessionEnd::kRunning:
      return "running";
    case SessionEnd::kFinished:
      return "finished";
    case SessionEnd::kInterrupted:
      return "interrupted";
    case SessionEnd::kResumedInto:
      return "resumed-into";
  }
  return "unknown";
}

bool ModelOptions::Check(std::string* error) const {
  auto fail = [error](const std::string& message) {
    if (error) *error = message;
    return false;
  };
  if (jpeg_quality < 1 || jpeg_quality > 100) return fail("jpeg_quality must be in [1, 100]");
  if (png_compression < 0 || png_compression > 9) return fail("png_compression must be in [0, 9]");
  if (busy_timeout_ms < 0) return fail("busy_timeout_ms must be >= 0");
  return true;
}

struct Model::Impl {
  std::string path;
  ModelOptions options;
  std::optional<WriterLock> writer_lock;  // held while open for writing (a file, not :memory:)
  sqlite3* db = nullptr;
  int schema_version = 0;

  ~Impl() {
    // sqlite3_close_v2 checkpoints the WAL when this is the last connection.
    if (db) sqlite3_close_v2(db);
  }

  void CheckWritable() const {
    SIGHTMAP_CHECK(!options.read_only,
                   "model " << FileDescription(path)
                            << " was opened read-only; open it without read_only to change it");
  }

  void InsertLink(const LinkRecord& link, KeyframeId self) {
    const KeyframeId from = link.from.valid() ? link.from : self;
    const KeyframeId to = link.to.valid() ? link.to : self;
    SIGHTMAP_CHECK(from.valid() && to.valid(), "a link needs keyframe ids at both ends");
    Statement insert(db,
                     "INSERT INTO links (from_id, to_id, type, tx, ty, tz, qx, qy, qz, qw, "
                     "information, active) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)");
    insert.Bind(1, from.value()).Bind(2, to.value()).Bind(3, static_cast<int>(link.type));
    BindPose(insert, 4, link.to_in_from);
    // Eigen stores column-major; the 6x6 is symmetric so the order does not matter to readers.
    insert.BindBlob(11, link.information.data(), sizeof(double) * 36);
    insert.Bind(12, link.active ? 1 : 0);
    insert.Run();
  }

  // Replaces a stored link's measurement and information (found by its ends and type).
  void ReviseLink(const LinkRecord& link) {
    SIGHTMAP_CHECK(link.from.valid() && link.to.valid(),
                   "a revised link needs keyframe ids at both ends");
    Statement update(db,
                     "UPDATE links SET tx = ?, ty = ?, tz = ?, qx = ?, qy = ?, qz = ?, qw = ?, "
                     "information = ? WHERE from_id = ? AND to_id = ? AND type = ?");
    BindPose(update, 1, link.to_in_from);
    update.BindBlob(8, link.information.data(), sizeof(double) * 36);
    update.Bind(9, link.from.value()).Bind(10, link.to.value());
    update.Bind(11, static_cast<int>(link.type));
    update.Run();
    SIGHTMAP_CHECK(sqlite3_changes(db) >= 1,
                   "no " << LinkTypeName(link.type) << " link from keyframe " << link.from.value()
                         << " to " << link.to.value() << " in model " << FileDescription(path)
                         << " to revise; nothing was changed");
  }

  void InsertLabelPoints(LabelId id, const std::vector<LabelPoint>& points) {
    Statement insert(db,
                     "INSERT INTO label_points (label_id, idx, x, y, z, source, keyframe_id, u, v, "
                     "cam_x, cam_y, cam_z, file) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)");
    for (size_t i = 0; i < points.size(); ++i) {
      const LabelPoint& p = points[i];
      insert.Bind(1, id.value()).Bind(2, static_cast<int64_t>(i));
      insert.Bind(3, p.world.x()).Bind(4, p.world.y()).Bind(5, p.world.z());
      insert.Bind(6, static_cast<int>(p.source));
      if (p.source == LabelPointSource::kKeyframePixel) {
        SIGHTMAP_CHECK(p.keyframe.valid(), "a label point clicked on a keyframe needs its id");
        insert.Bind(7, p.keyframe.value()).Bind(8, p.pixel.x()).Bind(9, p.pixel.y());
        insert.Bind(10, p.cam_point.x()).Bind(11, p.cam_point.y()).Bind(12, p.cam_point.z());
      } else {
        for (int column = 7; column <= 12; ++column) insert.BindNull(column);
      }
      if (p.file.empty()) {
        insert.BindNull(13);
      } else {
        insert.Bind(13, p.file);
      }
      insert.Run();
    }
  }

  void CheckLabel(const LabelRecord& label) const {
    std::string why;
    if (!ValidLabelText(label.name, LabelField::kName, &why) ||
        !ValidLabelText(label.type, LabelField::kType, &why)) {
      SIGHTMAP_THROW(InvalidArgument, why);
    }
    if (label.points.empty()) {
      SIGHTMAP_THROW(InvalidArgument, "label '" << label.name << "' needs at least one point");
    }
    for (const LabelPoint& point : label.points) {
      if (!point.world.allFinite() || point.world.cwiseAbs().maxCoeff() > kMaxLabelCoordinateM) {
        SIGHTMAP_THROW(InvalidArgument, "label '" << label.name
                                                  << "': a point's coordinates must be "
                                                  << "finite and within " << kMaxLabelCoordinateM
                                                  << " m of the model's origin");
      }
    }
  }

  std::vector<LabelRecord> QueryLabels(const std::string& where, const std::string* name) const {
    std::vector<LabelRecord> labels;
    Statement query(db, "SELECT id, name, type, created_ns, updated_ns FROM labels " + where +
                            " ORDER BY name");
    if (name) query.Bind(1, *name);
    while (query.Step()) {
      LabelRecord label;
      label.id = LabelId(query.Int(0));
      label.name = query.Text(1);
      label.type = query.Text(2);
      label.created_ns = query.Int(3);
      label.updated_ns = query.Int(4);
      labels.push_back(std::move(label));
    }
    // Keyframe-relative points take the keyframe's current pose, so labels follow loop closures.
    Statement points(db,
                     "SELECT p.x, p.y, p.z, p.source, p.keyframe_id, p.u, p.v, p.cam_x, p.cam_y, "
                     "p.cam_z, p.file, k.tx, k.ty, k.tz, k.qx, k.qy, k.qz, k.qw, k.id "
                     "FROM label_points p LEFT JOIN keyframes k ON k.id = p.keyframe_id "
                     "WHERE p.label_id = ? ORDER BY p.idx");
    for (LabelRecord& label : labels) {
      points.Bind(1, label.id.value());
      while (points.Step()) {
        LabelPoint p;
        p.world = Eigen::Vector3d(points.Double(0), points.Double(1), points.Double(2));
        p.source = static_cast<LabelPointSource>(points.Int(3));
        if (!points.IsNull(4)) {
          p.keyframe = KeyframeId(points.Int(4));
          p.pixel = Eigen::Vector2d(points.Double(5), points.Double(6));
          p.cam_point = Eigen::Vector3d(points.Double(7), points.Double(8), points.Double(9));
          if (!points.IsNull(18)) p.world = ColumnPose(points, 11) * p.cam_point;
        }
        if (!points.IsNull(10)) p.file = points.Text(10);
        label.points.push_back(std::move(p));
      }
      points.Reset();
    }
    return labels;
  }

  KeyframeInfo RowToKeyframeInfo(const Statement& row) const {
    KeyframeInfo info;
    info.id = KeyframeId(row.Int(0));
    info.session = SessionId(row.Int(1));
    info.timestamp_ns = row.Int(2);
    info.world_from_cam = ColumnPose(row, 3);
    info.odom_world_from_cam = ColumnPose(row, 10);
    info.intrinsics = ColumnIntrinsics(row, 17);
    info.num_features = static_cast<int>(row.Int(23));
    info.color_bytes = row.Int(24);
    info.depth_bytes = row.Int(25);
    return info;
  }

  std::vector<uint8_t> LoadImageBlob(KeyframeId id, const char* column) const {
    Statement query(
        db, std::string("SELECT ") + column + " FROM keyframe_images WHERE keyframe_id = ?");
    query.Bind(1, id.value());
    SIGHTMAP_CHECK(query.Step(),
                   "keyframe " << id.value() << " is not in model " << FileDescription(path));
    return query.Blob(0);
  }
};

static constexpr const char* kKeyframeColumns =
    "id, session_id, timestamp_ns, tx, ty, tz, qx, qy, qz, qw, odom_tx, odom_ty, odom_tz, "
    "odom_qx, odom_qy, odom_qz, odom_qw, width, height, fx, fy, cx, cy, num_features, "
    "color_bytes, depth_bytes";

int Model::LatestSchemaVersion() { return internal::LatestSchemaVersion(); }

Model::Model(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Model::Model(Model&&) noexcept = default;
Model& Model::operator=(Model&&) noexcept = default;
Model::~Model() = default;

namespace {

// Whether the model's file exists; throws when it must and does not, or is not a file.
bool CheckModelPath(const std::string& path, bool memory, const std::string& what,
                    const ModelOptions& options) {
  std::error_code ec;
  const bool exists = !memory && std::filesystem::exists(path, ec);
  if (!memory && !exists) {
    SIGHTMAP_CHECK(!options.read_only && options.create_if_missing,
                   "model " << what << " does not exist: check the path");
  }
  if (exists) {
    SIGHTMAP_CHECK(std::filesystem::is_regular_file(path, ec),
                   what << " is not a file: pass the model's .db file");
  }
  return exists;
}

// Opens `name` into *db (closing the connection there first) and reads the number of schema
// objects into *num_objects. Returns that first read's result code: it decides whether this is
// SQLite at all.
int Connect(const std::string& name, int flags, const std::string& what,
            const ModelOptions& options, sqlite3** db, int64_t* num_objects) {
  if (*db) sqlite3_close_v2(*db);
  *db = nullptr;
  const int open_rc = sqlite3_open_v2(name.c_str(), db, flags | SQLITE_OPEN_NOMUTEX, nullptr);
  if (open_rc != SQLITE_OK) {
    const std::string detail = *db ? sqlite3_errmsg(*db) : sqlite3_errstr(open_rc);
    SIGHTMAP_THROW(Error, "cannot open model " << what << ": " << detail
                                               << "; check the path and its permissions");
  }
  sqlite3_extended_result_codes(*db, 1);
  SIGHTMAP_SQLITE3_CALL(*db, sqlite3_busy_timeout(*db, options.busy_timeout_ms));
  sqlite3_stmt* probe = nullptr;
  int rc = sqlite3_prepare_v2(*db, "SELECT count(*) FROM sqlite_master", -1, &probe, nullptr);
  if (rc == SQLITE_OK) {
    rc = sqlite3_step(probe);
    if (rc == SQLITE_ROW) *num_objects = sqlite3_column_int64(probe, 0);
  }
  sqlite3_finalize(probe);
  return rc == SQLITE_ROW ? SQLITE_OK : sqlite3_extended_errcode(*db);
}

[[noreturn]] void ThrowReadOnly(const std::string& what) {
  SIGHTMAP_THROW(Error, "model " << what
                                 << " is read-only: make it writable (chmod u+w) or copy it to a "
                                    "writable folder");
}

// Connects for writing, holding the writer lock (`lock`) from before the first read.
int ConnectToWrite(const std::string& path, bool exists, const std::string& what,
                   const ModelOptions& options, std::optional<WriterLock>* lock, sqlite3** db,
                   int64_t* num_objects) {
  if (exists && access(path.c_str(), W_OK) != 0) ThrowReadOnly(what);
  lock->emplace(path);
  const int rc =
      Connect(path, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE, what, options, db, num_objects);
  // SQLite silently falls back to read-only when the OS refuses writes; say so now rather than at
  // the first keyframe.
  if (sqlite3_db_readonly(*db, "main") == 1) ThrowReadOnly(what);
  return rc;
}

// Connects read-only. A WAL model in a folder we cannot write (a shared or archived model) cannot
// create its shared-memory file. With no WAL left behind, nobody is writing it and the main file
// is the whole model, so it is then read as immutable.
int ConnectToRead(const std::string& path, const std::string& what, const ModelOptions& options,
                  sqlite3** db, int64_t* num_objects) {
  const int rc = Connect(path, SQLITE_OPEN_READONLY, what, options, db, num_objects);
  const int primary = rc & 0xff;
  if (primary != SQLITE_READONLY && primary != SQLITE_CANTOPEN) return rc;
  std::error_code wal_error;
  const auto wal_size = std::filesystem::file_size(path + "-wal", wal_error);
  SIGHTMAP_CHECK(wal_error || wal_size == 0,
                 "cannot read model " << what
                                      << ": its folder is not writable and it has an unmerged "
                                         "-wal file; copy the model with its -wal file to a "
                                         "writable folder");
  return Connect("file:" + PercentEncode(std::filesystem::absolute(path).string()) + "?immutable=1",
                 SQLITE_OPEN_READONLY | SQLITE_OPEN_URI, what, options, db, num_objects);
}

int ReadApplicationId(sqlite3* db) {
  Statement query(db, "PRAGMA application_id");
  query.Step();
  return static_cast<int>(query.Int(0));
}

int ReadSchemaVersion(sqlite3* db) {
  Statement query(db, "SELECT COALESCE(MAX(version), 0) FROM sightmap_schema");
  query.Step();
  return static_cast<int>(query.Int(0));
}

// A database with objects must carry sightmap's application id.
void CheckOurs(sqlite3* db, const std::string& what, int64_t objects) {
  if (ReadApplicationId(db) != internal::kApplicationId && objects > 0) {
    SIGHTMAP_THROW(Error, what << " is a SQLite database of another application, not a sightmap "
                                  "model: pass a sightmap model, or a new file name to create "
                                  "one");
  }
}

void CheckNotNewer(int version, const std::string& what) {
  const int latest = internal::LatestSchemaVersion();
  if (version > latest) {
    SIGHTMAP_THROW(Error, "model " << what << " has schema version " << version
                                   << ", newer than this sightmap reads (" << latest
                                   << "): update sightmap");
  }
}

// Switches a writable model to WAL and its sync mode, then creates or migrates its schema to the
// latest version, which it returns. Decided and upgraded under the write lock, so two processes
// opening a new file do not both create the schema.
int PrepareToWrite(sqlite3* db, bool memory, const std::string& what, const ModelOptions& options) {
  if (!memory) {
    Statement journal(db, "PRAGMA journal_mode=WAL");
    journal.Step();
    SIGHTMAP_CHECK(journal.Text(0) == "wal", "cannot switch model "
                                                 << what << " to WAL mode (got '" << journal.Text(0)
                                                 << "'); put the model on a local filesystem");
  }
  Exec(db, options.sync_every_commit ? "PRAGMA synchronous=FULL" : "PRAGMA synchronous=NORMAL");
  Transaction transaction(db);
  // Finalised before migrating: a statement still reading sqlite_master keeps a migration from
  // dropping a table ("database table is locked").
  const int64_t objects = [db] {
    Statement count(db, "SELECT count(*) FROM sqlite_master");
    count.Step();
    return count.Int(0);
  }();
  CheckOurs(db, what, objects);
  const int version = objects == 0 ? 0 : ReadSchemaVersion(db);
  CheckNotNewer(version, what);
  const int latest = internal::LatestSchemaVersion();
  if (version < latest) internal::ApplyMigrations(db, version, latest);
  transaction.Commit();
  return latest;
}

}  // namespace

Model Model::Open(const std::string& path, const ModelOptions& options) {
  SIGHTMAP_CHECK_OPTIONS(options);
  auto impl = std::make_unique<Impl>();
  impl->path = path;
  impl->options = options;
  const std::string what = FileDescription(path);
  const bool memory = IsMemoryPath(path);
  const bool exists = CheckModelPath(path, memory, what, options);

  int64_t num_objects = 0;
  int rc = SQLITE_OK;
  if (memory) {
    rc = Connect(":memory:", SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE, what, options, &impl->db,
                 &num_objects);
  } else if (!options.read_only) {
    rc = ConnectToWrite(path, exists, what, options, &impl->writer_lock, &impl->db, &num_objects);
  } else {
    rc = ConnectToRead(path, what, options, &impl->db, &num_objects);
  }
  sqlite3* db = impl->db;
  if ((rc & 0xff) == SQLITE_NOTADB) {
    SIGHTMAP_THROW(Error, what << " is not a sightmap model (not a SQLite database): pass the "
                                  ".db file that sightmap wrote");
  }
  if (rc != SQLITE_OK) internal::ThrowSqliteError(db, rc, "open", __FILE__, __LINE__);

  CheckOurs(db, what, num_objects);
  if (options.read_only) {
    SIGHTMAP_CHECK(num_objects > 0, what << " is an empty database, not a sightmap model");
    impl->schema_version = ReadSchemaVersion(db);
    CheckNotNewer(impl->schema_version, what);
    if (impl->schema_version < internal::LatestSchemaVersion()) {
      SIGHTMAP_THROW(Error, "model "
                                << what << " has the older schema version " << impl->schema_version
                                << ": upgrade it once with 'sightmap info --upgrade " << impl->path
                                << "'");
    }
  } else {
    impl->schema_version = PrepareToWrite(db, memory, what, options);
  }
  Exec(db, "PRAGMA foreign_keys=ON");
  return Model(std::move(impl));
}

const std::string& Model::path() const { return impl_->path; }

int Model::SchemaVersion() const { return impl_->schema_version; }

SessionId Model::BeginSession(const SessionRecord& session) {
  impl_->CheckWritable();
  Statement insert(impl_->db,
                   "INSERT INTO sessions (start_time_ns, end_time_ns, source, device_name, "
                   "device_serial, width, height, fx, fy, cx, cy, end_state, resumed_into, "
                   "options_json) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, NULL, ?)");
  insert.Bind(1, session.start_time_ns ? session.start_time_ns : NowNs());
  insert.Bind(2, session.end_time_ns).Bind(3, session.source).Bind(4, session.device_name);
  insert.Bind(5, session.device_serial);
  BindIntrinsics(insert, 6, session.intrinsics);
  insert.Bind(12, static_cast<int>(session.end_state));
  insert.Bind(13, session.options_json.empty() ? std::string("{}") : session.options_json);
  insert.Run();
  return SessionId(sqlite3_last_insert_rowid(impl_->db));
}

void Model::EndSession(SessionId id, SessionEnd end_state, TimestampNs end_time_ns,
                       SessionId resumed_into) {
  impl_->CheckWritable();
  SIGHTMAP_CHECK(end_state != SessionEnd::kResumedInto || resumed_into.valid(),
                 "a session resumed into another needs that session's id");
  Statement update(
      impl_->db,
      "UPDATE sessions SET end_state = ?, end_time_ns = ?, resumed_into = ? WHERE id = "
      "?");
  update.Bind(1, static_cast<int>(end_state)).Bind(2, end_time_ns);
  if (resumed_into.valid()) {
    update.Bind(3, resumed_into.value());
  } else {
    update.BindNull(3);
  }
  update.Bind(4, id.value()).Run();
  SIGHTMAP_CHECK(sqlite3_changes(impl_->db) == 1,
                 "session " << id.value() << " is not in model " << FileDescription(impl_->path));
}

int Model::MarkRunningSessionsInterrupted(TimestampNs now_ns) {
  impl_->CheckWritable();
  Statement update(impl_->db,
                   "UPDATE sessions SET end_state = ?, end_time_ns = ? WHERE end_state = ?");
  update.Bind(1, static_cast<int>(SessionEnd::kInterrupted)).Bind(2, now_ns);
  update.Bind(3, static_cast<int>(SessionEnd::kRunning)).Run();
  return sqlite3_changes(impl_->db);
}

bool Model::DeleteEmptySession(SessionId id) {
  impl_->CheckWritable();
  Statement remove(impl_->db,
                   "DELETE FROM sessions WHERE id = ?1 AND NOT EXISTS (SELECT 1 FROM keyframes "
                   "WHERE session_id = ?1) AND NOT EXISTS (SELECT 1 FROM sessions WHERE "
                   "resumed_into = ?1)");
  remove.Bind(1, id.value()).Run();
  return sqlite3_changes(impl_->db) == 1;
}

std::vector<SessionRecord> Model::Sessions() const {
  Statement query(impl_->db,
                  "SELECT id, start_time_ns, end_time_ns, source, device_name, device_serial, "
                  "width, height, fx, fy, cx, cy, end_state, resumed_into, options_json FROM "
                  "sessions ORDER BY id");
  std::vector<SessionRecord> sessions;
  while (query.Step()) {
    SessionRecord s;
    s.id = SessionId(query.Int(0));
    s.start_time_ns = query.Int(1);
    s.end_time_ns = query.Int(2);
    s.source = query.Text(3);
    s.device_name = query.Text(4);
    s.device_serial = query.Text(5);
    s.intrinsics = ColumnIntrinsics(query, 6);
    s.end_state = static_cast<SessionEnd>(query.Int(12));
    if (!query.IsNull(13)) s.resumed_into = SessionId(query.Int(13));
    s.options_json = query.Text(14);
    sessions.push_back(std::move(s));
  }
  return sessions;
}

KeyframeId Model::AddKeyframe(const KeyframeRecord& keyframe) {
  impl_->CheckWritable();
  const Features& features = keyframe.features;
  SIGHTMAP_CHECK(keyframe.session.valid(), "a keyframe needs the session that made it");
  SIGHTMAP_CHECK(keyframe.color.type() == CV_8UC3 && keyframe.depth.type() == CV_16UC1 &&
                     keyframe.color.size() == keyframe.depth.size(),
                 "a keyframe needs 8-bit BGR colour and 16-bit depth of the same size");
  SIGHTMAP_CHECK(features.descriptors.empty() ||
                     features.descriptors.rows == static_cast<int>(features.size()),
                 "a keyframe needs one descriptor row per keypoint");
  SIGHTMAP_CHECK(features.PointsMatchKeypoints(),
                 "a keyframe needs a 3D point slot per keypoint, or none");
  if (keyframe.photo_features) CheckPhotoFeatures(*keyframe.photo_features);

  // Encode before taking the write lock: the lock is held only for the inserts.
  std::vector<uint8_t> jpeg;
  std::vector<uint8_t> png;
  SIGHTMAP_CHECK(cv::imencode(".jpg", keyframe.color, jpeg,
                              {cv::IMWRITE_JPEG_QUALITY, impl_->options.jpeg_quality}),
                 "cannot encode a keyframe's colour image as JPEG");
  SIGHTMAP_CHECK(cv::imencode(".png", keyframe.depth, png,
                              {cv::IMWRITE_PNG_COMPRESSION, impl_->options.png_compression}),
                 "cannot encode a keyframe's depth image as PNG");
  const EncodedFeatures encoded(features);
  std::optional<EncodedFeatures> photo_encoded;
  if (keyframe.photo_features) photo_encoded.emplace(*keyframe.photo_features);

  sqlite3* db = impl_->db;
  Transaction transaction(db);
  Statement insert(db,
                   "INSERT INTO keyframes (session_id, timestamp_ns, tx, ty, tz, qx, qy, qz, qw, "
                   "odom_tx, odom_ty, odom_tz, odom_qx, odom_qy, odom_qz, odom_qw, width, height, "
                   "fx, fy, cx, cy, num_features, color_bytes, depth_bytes) VALUES (?, ?, ?, ?, ?, "
                   "?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)");
  insert.Bind(1, keyframe.session.value()).Bind(2, keyframe.timestamp_ns);
  BindPose(insert, 3, keyframe.world_from_cam);
  BindPose(insert, 10, keyframe.odom_world_from_cam);
  Intrinsics k = keyframe.intrinsics;
  k.width = keyframe.color.cols;
  k.height = keyframe.color.rows;
  BindIntrinsics(insert, 17, k);
  insert.Bind(23, static_cast<int64_t>(features.keypoints.size()));
  insert.Bind(24, static_cast<int64_t>(jpeg.size())).Bind(25, static_cast<int64_t>(png.size()));
  insert.Run();
  const KeyframeId id(sqlite3_last_insert_rowid(db));

  Statement images(db,
                   "INSERT INTO keyframe_images (keyframe_id, color_jpeg, depth_png) VALUES (?, ?, "
                   "?)");
  images.Bind(1, id.value());
  BindRowAsBlob(images, 2, jpeg);
  BindRowAsBlob(images, 3, png);
  images.Run();

  InsertFeatures(db, "features", id, encoded);
  if (photo_encoded) InsertFeatures(db, "photo_features", id, *photo_encoded);

  for (const LinkRecord& link : keyframe.links) impl_->InsertLink(link, id);
  for (const LinkRecord& link : keyframe.revised_links) impl_->ReviseLink(link);
  transaction.Commit();
  return id;
}

void Model::UpdatePoses(
    const std::vector<std::pair<KeyframeId, Eigen::Isometry3d>>& world_from_cam) {
  UpdateGraph(world_from_cam, {});
}

void Model::UpdateGraph(const std::vector<std::pair<KeyframeId, Eigen::Isometry3d>>& world_from_cam,
                        const std::vector<LinkKey>& deactivated_links,
                        const std::vector<LinkKey>& reactivated_links) {
  impl_->CheckWritable();
  Transaction transaction(impl_->db);
  Statement set_active(impl_->db,
                       "UPDATE links SET active = ? WHERE from_id = ? AND to_id = ? AND type = ?");
  for (const auto& [links, active] :
       {std::pair(&deactivated_links, 0), std::pair(&reactivated_links, 1)}) {
    for (const LinkKey& link : *links) {
      set_active.Bind(1, active).Bind(2, link.from.value()).Bind(3, link.to.value());
      set_active.Bind(4, static_cast<int>(link.type));
      set_active.Run();
      SIGHTMAP_CHECK(sqlite3_changes(impl_->db) >= 1,
                     "no " << LinkTypeName(link.type) << " link from keyframe " << link.from.value()
                           << " to " << link.to.value() << " in model "
                           << FileDescription(impl_->path) << "; nothing was changed");
    }
  }
  Statement update(impl_->db,
                   "UPDATE keyframes SET tx = ?, ty = ?, tz = ?, qx = ?, qy = ?, qz = ?, qw = ? "
                   "WHERE id = ?");
  for (const auto& [id, pose] : world_from_cam) {
    BindPose(update, 1, pose);
    update.Bind(8, id.value());
    update.Run();
    SIGHTMAP_CHECK(sqlite3_changes(impl_->db) == 1, "keyframe " << id.value() << " is not in model "
                                                                << FileDescription(impl_->path)
                                                                << "; no pose was changed");
  }
  transaction.Commit();
}

std::vector<KeyframeInfo> Model::Keyframes() const {
  Statement query(impl_->db,
                  std::string("SELECT ") + kKeyframeColumns + " FROM keyframes ORDER BY id");
  std::vector<KeyframeInfo> keyframes;
  while (query.Step()) keyframes.push_back(impl_->RowToKeyframeInfo(query));
  return keyframes;
}

KeyframeInfo Model::Keyframe(KeyframeId id) const {
  Statement query(impl_->db,
                  std::string("SELECT ") + kKeyframeColumns + " FROM keyframes WHERE id = ?");
  query.Bind(1, id.value());
  SIGHTMAP_CHECK(query.Step(),
                 "keyframe " << id.value() << " is not in model " << FileDescription(impl_->path));
  return impl_->RowToKeyframeInfo(query);
}

int64_t Model::NumKeyframes() const {
  Statement query(impl_->db, "SELECT count(*) FROM keyframes");
  query.Step();
  return query.Int(0);
}

cv::Mat Model::LoadColor(KeyframeId id) const {
  const std::vector<uint8_t> jpeg = impl_->LoadImageBlob(id, "color_jpeg");
  cv::Mat color = cv::imdecode(jpeg, cv::IMREAD_COLOR);
  SIGHTMAP_CHECK(!color.empty(), "keyframe " << id.value() << "'s colour image in model "
                                             << FileDescription(impl_->path)
                                             << " does not decode: restore it from a backup");
  return color;
}

cv::Mat Model::LoadGrey(KeyframeId id, int reduction) const {
  int flag = cv::IMREAD_GRAYSCALE;
  switch (reduction) {
    case 1:
      break;
    case 2:
      flag = cv::IMREAD_REDUCED_GRAYSCALE_2;
      break;
    case 4:
      flag = cv::IMREAD_REDUCED_GRAYSCALE_4;
      break;
    case 8:
      flag = cv::IMREAD_REDUCED_GRAYSCALE_8;
      break;
    default:
      SIGHTMAP_THROW(InvalidArgument,
                     "LoadGrey: reduction must be 1, 2, 4 or 8, not " << reduction);
  }
  const std::vector<uint8_t> jpeg = impl_->LoadImageBlob(id, "color_jpeg");
  cv::Mat grey = cv::imdecode(jpeg, flag);
  SIGHTMAP_CHECK(!grey.empty(), "keyframe " << id.value() << "'s colour image in model "
                                            << FileDescription(impl_->path)
                                            << " does not decode: restore it from a backup");
  return grey;
}

cv::Mat Model::LoadDepth(KeyframeId id) const {
  const std::vector<uint8_t> png = impl_->LoadImageBlob(id, "depth_png");
  cv::Mat depth = cv::imdecode(png, cv::IMREAD_UNCHANGED);
  SIGHTMAP_CHECK(depth.type() == CV_16UC1, "keyframe " << id.value() << "'s depth image in model "
                                                       << FileDescription(impl_->path)
                                                       << " does not decode to 16-bit depth");
  return depth;
}

Features Model::LoadFeatures(KeyframeId id) const {
  std::optional<Features> features =
      SelectFeatures(impl_->db, "features", id, "keyframe " + std::to_string(id.value()));
  SIGHTMAP_CHECK(features, "keyframe " << id.value() << " has no features in model "
                                       << FileDescription(impl_->path));
  return std::move(*features);
}

std::optional<Features> Model::LoadPhotoFeatures(KeyframeId id) const {
  return SelectFeatures(impl_->db, "photo_features", id,
                        "keyframe " + std::to_string(id.value()) + "'s photo features");
}

void Model::SetPhotoFeatures(KeyframeId id, const Features& features) {
  impl_->CheckWritable();
  CheckPhotoFeatures(features);
  const EncodedFeatures encoded(features);
  Transaction transaction(impl_->db);
  Statement exists(impl_->db, "SELECT 1 FROM keyframes WHERE id = ?");
  exists.Bind(1, id.value());
  SIGHTMAP_CHECK(exists.Step(),
                 "keyframe " << id.value() << " is not in model " << FileDescription(impl_->path));
  InsertFeatures(impl_->db, "photo_features", id, encoded);
  transaction.Commit();
}

bool Model::HasPhotoFeatures(KeyframeId id) const {
  Statement query(impl_->db, "SELECT 1 FROM photo_features WHERE keyframe_id = ?");
  query.Bind(1, id.value());
  return query.Step();
}

int64_t Model::NumKeyframesWithPhotoFeatures() const {
  Statement query(impl_->db, "SELECT COUNT(*) FROM photo_features");
  SIGHTMAP_CHECK(query.Step(), "cannot count photo features");
  return query.Int(0);
}

SyntheticViewId Model::AddSyntheticView(const SyntheticViewRecord& view) {
  impl_->CheckWritable();
  SIGHTMAP_CHECK(view.source.valid(), "a synthetic view needs the keyframe it was rendered from");
  SIGHTMAP_CHECK(view.color.type() == CV_8UC3 && view.color.cols == view.intrinsics.width &&
                     view.color.rows == view.intrinsics.height,
                 "a synthetic view needs 8-bit BGR colour of its intrinsics' size");
  SIGHTMAP_CHECK(
      view.features.IsConsistent() && view.features.points_cam.size() == view.features.size(),
      "a synthetic view needs one descriptor row and one 3D point slot per keypoint");
  std::vector<uint8_t> jpeg;
  SIGHTMAP_CHECK(cv::imencode(".jpg", view.color, jpeg,
                              {cv::IMWRITE_JPEG_QUALITY, impl_->options.jpeg_quality}),
                 "cannot encode a synthetic view's colour image as JPEG");
  const EncodedFeatures encoded(view.features);
  sqlite3* db = impl_->db;
  Transaction transaction(db);
  Statement insert(db,
                   "INSERT INTO synthetic_views (source_keyframe_id, label_id, tx, ty, tz, qx, qy, "
                   "qz, qw, width, height, fx, fy, cx, cy, created_ns, color_jpeg, count, "
                   "keypoints, descriptor_type, descriptor_rows, descriptor_cols, descriptors, "
                   "cam_points) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, "
                   "?, ?, ?, ?, ?)");
  insert.Bind(1, view.source.value());
  if (view.label.valid()) {
    insert.Bind(2, view.label.value());
  } else {
    insert.BindNull(2);
  }
  BindPose(insert, 3, view.source_from_cam);
  BindIntrinsics(insert, 10, view.intrinsics);
  insert.Bind(16, NowNs());
  BindRowAsBlob(insert, 17, jpeg);
  encoded.Bind(insert, 18);
  insert.Run();
  const SyntheticViewId id(sqlite3_last_insert_rowid(db));
  transaction.Commit();
  return id;
}

int64_t Model::DeleteSyntheticViews(SyntheticViewId last) {
  impl_->CheckWritable();
  Statement remove(impl_->db, "DELETE FROM synthetic_views WHERE id <= ?");
  remove.Bind(1, last.valid() ? last.value() : std::numeric_limits<int64_t>::max());
  remove.Run();
  return sqlite3_changes(impl_->db);
}

std::vector<SyntheticViewRecord> Model::SyntheticViews() const {
  Statement query(impl_->db,
                  "SELECT v.id, v.source_keyframe_id, v.label_id, v.tx, v.ty, v.tz, v.qx, v.qy, "
                  "v.qz, v.qw, v.width, v.height, v.fx, v.fy, v.cx, v.cy, length(v.color_jpeg), "
                  "v.count, v.keypoints, v.descriptor_type, v.descriptor_rows, "
                  "v.descriptor_cols, v.descriptors, v.cam_points, k.tx, k.ty, k.tz, k.qx, k.qy, "
                  "k.qz, k.qw FROM synthetic_views v JOIN keyframes k ON "
                  "k.id = v.source_keyframe_id ORDER BY v.id");
  std::vector<SyntheticViewRecord> views;
  while (query.Step()) {
    SyntheticViewRecord view;
    view.id = SyntheticViewId(query.Int(0));
    view.source = KeyframeId(query.Int(1));
    if (!query.IsNull(2)) view.label = LabelId(query.Int(2));
    view.source_from_cam = ColumnPose(query, 3);
    view.intrinsics = ColumnIntrinsics(query, 10);
    view.color_bytes = query.Int(16);
    view.features = ColumnFeatures(query, 17, "synthetic view " + std::to_string(view.id.value()));
    view.world_from_cam = ColumnPose(query, 24) * view.source_from_cam;
    views.push_back(std::move(view));
  }
  return views;
}

int64_t Model::NumSyntheticViews() const {
  Statement query(impl_->db, "SELECT count(*) FROM synthetic_views");
  query.Step();
  return query.Int(0);
}

cv::Mat Model::LoadSyntheticColor(SyntheticViewId id) const {
  Statement query(impl_->db, "SELECT color_jpeg FROM synthetic_views WHERE id = ?");
  query.Bind(1, id.value());
  SIGHTMAP_CHECK(query.Step(), "synthetic view " << id.value() << " is not in model "
                                                 << FileDescription(impl_->path));
  const std::vector<uint8_t> jpeg = query.Blob(0);
  cv::Mat color = cv::imdecode(jpeg, cv::IMREAD_COLOR);
  SIGHTMAP_CHECK(!color.empty(), "corrupt image of synthetic view " << id.value());
  return color;
}

LinkId Model::AddLink(const LinkRecord& link) {
  impl_->CheckWritable();
  SIGHTMAP_CHECK(link.from.valid() && link.to.valid(), "a link needs keyframe ids at both ends");
  impl_->InsertLink(link, KeyframeId());
  return LinkId(sqlite3_last_insert_rowid(impl_->db));
}

std::vector<LinkRecord> Model::Links() const {
  Statement query(impl_->db,
                  "SELECT id, from_id, to_id, type, tx, ty, tz, qx, qy, qz, qw, information, "
                  "active FROM links ORDER BY id");
  std::vector<LinkRecord> links;
  while (query.Step()) {
    LinkRecord link;
    link.id = LinkId(query.Int(0));
    link.from = KeyframeId(query.Int(1));
    link.to = KeyframeId(query.Int(2));
    link.type = static_cast<LinkType>(query.Int(3));
    link.to_in_from = ColumnPose(query, 4);
    const std::vector<uint8_t> information = query.Blob(11);
    SIGHTMAP_CHECK(information.size() == sizeof(double) * 36,
                   "corrupt information matrix of link " << link.id.value());
    std::memcpy(link.information.data(), information.data(), information.size());
    link.active = query.Int(12) != 0;
    links.push_back(link);
  }
  return links;
}

LabelId Model::AddLabel(const LabelRecord& label) {
  impl_->CheckWritable();
  impl_->CheckLabel(label);
  Transaction transaction(impl_->db);
  {
    Statement existing(impl_->db, "SELECT 1 FROM labels WHERE name = ?");
    existing.Bind(1, label.name);
    SIGHTMAP_CHECK(!existing.Step(), "a label named '" << label.name
                                                       << "' already exists: pick another name "
                                                          "or update that label");
  }
  const TimestampNs now = NowNs();
  Statement insert(impl_->db,
                   "INSERT INTO labels (name, type, created_ns, updated_ns) VALUES (?, ?, ?, ?)");
  insert.Bind(1, label.name).Bind(2, label.type).Bind(3, now).Bind(4, now).Run();
  const LabelId id(sqlite3_last_insert_rowid(impl_->db));
  impl_->InsertLabelPoints(id, label.points);
  transaction.Commit();
  return id;
}

void Model::UpdateLabel(const LabelRecord& label) {
  impl_->CheckWritable();
  impl_->CheckLabel(label);
  Transaction transaction(impl_->db);
  Statement update(impl_->db, "UPDATE labels SET name = ?, type = ?, updated_ns = ? WHERE id = ?");
  update.Bind(1, label.name).Bind(2, label.type).Bind(3, NowNs()).Bind(4, label.id.value()).Run();
  SIGHTMAP_CHECK(sqlite3_changes(impl_->db) == 1,
                 "label " << label.id.value() << " ('" << label.name << "') is not in the model");
  Statement remove(impl_->db, "DELETE FROM label_points WHERE label_id = ?");
  remove.Bind(1, label.id.value()).Run();
  impl_->InsertLabelPoints(label.id, label.points);
  transaction.Commit();
}

void Model::DeleteLabel(LabelId id) {
  impl_->CheckWritable();
  Statement remove(impl_->db, "DELETE FROM labels WHERE id = ?");
  remove.Bind(1, id.value()).Run();
  SIGHTMAP_CHECK(sqlite3_changes(impl_->db) == 1, "label " << id.value() << " is not in the model");
}

std::optional<LabelRecord> Model::FindLabel(const std::string& name) const {
  std::vector<LabelRecord> labels = impl_->QueryLabels("WHERE name = ?", &name);
  if (labels.empty()) return std::nullopt;
  return std::move(labels.front());
}

std::vector<LabelRecord> Model::Labels() const { return impl_->QueryLabels("", nullptr); }

void Model::SetVocabulary(const std::string& format, const std::vector<uint8_t>& data) {
  impl_->CheckWritable();
  Statement upsert(impl_->db,
                   "INSERT OR REPLACE INTO vocabulary (id, format, data, updated_ns) VALUES (1, ?, "
                   "?, ?)");
  upsert.Bind(1, format);
  BindRowAsBlob(upsert, 2, data);
  upsert.Bind(3, NowNs()).Run();
}

std::optional<std::pair<std::string, std::vector<uint8_t>>> Model::LoadVocabulary() const {
  Statement query(impl_->db, "SELECT format, data FROM vocabulary WHERE id = 1");
  if (!query.Step()) return std::nullopt;
  return std::make_pair(query.Text(0), query.Blob(1));
}

namespace {

int64_t CountOf(sqlite3* db, const std::string& sql) {
  Statement query(db, sql);
  query.Step();
  return query.Int(0);
}

// The active links by type, and how many were switched off.
void CountLinks(sqlite3* db, ModelSummary* summary) {
  summary->inactive_links = CountOf(db, "SELECT count(*) FROM links WHERE active = 0");
  Statement query(db, "SELECT type, count(*) FROM links WHERE active = 1 GROUP BY type");
  while (query.Step()) {
    switch (static_cast<LinkType>(query.Int(0))) {
      case LinkType::kOdometry:
        summary->odometry_links = query.Int(1);
        break;
      case LinkType::kLoopClosure:
        summary->loop_closures = query.Int(1);
        break;
      case LinkType::kRelocalisation:
        summary->relocalisation_links = query.Int(1);
        break;
      case LinkType::kUser:
        summary->user_links = query.Int(1);
        break;
      case LinkType::kPrior:
        summary->prior_links = query.Int(1);
        break;
    }
  }
}

// Segments: connected components of the pose graph (union-find over keyframe ids, every link
// whether active or not), and the largest one's keyframes.
void CountSegments(sqlite3* db, ModelSummary* summary) {
  std::vector<int64_t> ids;
  {
    Statement query(db, "SELECT id FROM keyframes ORDER BY id");
    while (query.Step()) ids.push_back(query.Int(0));
  }
  std::vector<size_t> parent(ids.size());
  std::iota(parent.begin(), parent.end(), size_t{0});
  auto index_of = [&ids](int64_t id) {
    return static_cast<size_t>(std::lower_bound(ids.begin(), ids.end(), id) - ids.begin());
  };
  auto find = [&parent](size_t i) {
    while (parent[i] != i) i = parent[i] = parent[parent[i]];
    return i;
  };
  {
    Statement query(db, "SELECT from_id, to_id FROM links");
    while (query.Step()) {
      const size_t a = find(index_of(query.Int(0)));
      const size_t b = find(index_of(query.Int(1)));
      if (a != b) parent[a] = b;
    }
  }
  std::vector<int64_t> keyframes_in(parent.size(), 0);
  for (size_t i = 0; i < parent.size(); ++i) {
    summary->segments += find(i) == i;
    summary->largest_segment_keyframes =
        std::max(summary->largest_segment_keyframes, ++keyframes_in[find(i)]);
  }
}

// The bounding box of the camera positions and `labels`' points.
void BoundCamerasAndLabels(sqlite3* db, const std::vector<LabelRecord>& labels,
                           ModelSummary* summary) {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d hi = -lo;
  auto extend = [&](const Eigen::Vector3d& p) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
    summary->has_bounding_box = true;
  };
  {
    Statement query(db, "SELECT tx, ty, tz FROM keyframes");
    while (query.Step()) {
      extend(Eigen::Vector3d(query.Double(0), query.Double(1), query.Double(2)));
    }
  }
  for (const LabelRecord& label : labels) {
    for (const LabelPoint& point : label.points) extend(point.world);
  }
  if (summary->has_bounding_box) {
    summary->bbox_min = lo;
    summary->bbox_max = hi;
  }
}

}  // namespace

ModelSummary Model::Summary() const {
  sqlite3* db = impl_->db;
  ModelSummary summary;
  summary.schema_version = impl_->schema_version;
  summary.sessions = CountOf(db, "SELECT count(*) FROM sessions");
  summary.keyframes = CountOf(db, "SELECT count(*) FROM keyframes");
  summary.labels = CountOf(db, "SELECT count(*) FROM labels");
  summary.synthetic_views = CountOf(db, "SELECT count(*) FROM synthetic_views");
  summary.synthetic_view_bytes =
      CountOf(db,
              "SELECT coalesce(sum(length(color_jpeg) + length(keypoints) + length(descriptors) + "
              "length(cam_points)), 0) FROM synthetic_views");
  summary.photo_feature_keyframes = CountOf(db, "SELECT count(*) FROM photo_features");
  summary.photo_feature_bytes = CountOf(
      db,
      "SELECT coalesce(sum(length(keypoints) + length(descriptors) + length(cam_points)), 0) "
      "FROM photo_features");
  CountLinks(db, &summary);
  CountSegments(db, &summary);
  BoundCamerasAndLabels(db, Labels(), &summary);
  if (IsMemoryPath(impl_->path)) {
    summary.size_bytes = CountOf(db, "PRAGMA page_count") * CountOf(db, "PRAGMA page_size");
  } else {
    std::error_code ec;
    for (const std::string& file : {impl_->path, impl_->path + "-wal"}) {
      const auto size = std::filesystem::file_size(file, ec);
      if (!ec) summary.size_bytes += static_cast<int64_t>(size);
    }
  }
  return summary;
}

std::string Model::IntegrityCheck() const {
  Statement query(impl_->db, "PRAGMA integrity_check");
  std::string result;
  while (query.Step()) {
    if (!result.empty()) result += "; ";
    result += query.Text(0);
  }
  Statement foreign(impl_->db, "PRAGMA foreign_key_check");
  if (foreign.Step()) result += "; foreign key violation in table " + foreign.Text(0);
  return result;
}

SIGHTMAP_OPTIONS_JSON(ModelOptions, read_only, create_if_missing, jpeg_quality, png_compression,
                      sync_every_commit, busy_timeout_ms)

}  // namespace sightmap::store
