#include "store/schema.h"

#include <chrono>
#include <string>
#include <vector>

#include "store/sqlite_util.h"

namespace sightmap::store::internal {
namespace {

// Never edit a migration that has shipped: add a new one. Image blobs live in their own table so
// listing keyframes reads only small rows (the open time of a large model depends on it).
const std::vector<std::string>& Migrations() {
  static const std::vector<std::string> kMigrations = {
      // 1: the model as mapping writes it.
      R"sql(
CREATE TABLE sightmap_schema (
  version INTEGER PRIMARY KEY,
  applied_ns INTEGER NOT NULL);
CREATE TABLE sessions (
  id INTEGER PRIMARY KEY,
  start_time_ns INTEGER NOT NULL,
  end_time_ns INTEGER NOT NULL DEFAULT 0,
  source TEXT NOT NULL,
  device_name TEXT NOT NULL,
  device_serial TEXT NOT NULL,
  width INTEGER NOT NULL, height INTEGER NOT NULL,
  fx REAL NOT NULL, fy REAL NOT NULL, cx REAL NOT NULL, cy REAL NOT NULL,
  end_state INTEGER NOT NULL CHECK (end_state BETWEEN 0 AND 3),
  resumed_into INTEGER REFERENCES sessions(id),
  options_json TEXT NOT NULL);
CREATE TABLE keyframes (
  id INTEGER PRIMARY KEY,
  session_id INTEGER NOT NULL REFERENCES sessions(id),
  timestamp_ns INTEGER NOT NULL,
  tx REAL NOT NULL, ty REAL NOT NULL, tz REAL NOT NULL,
  qx REAL NOT NULL, qy REAL NOT NULL, qz REAL NOT NULL, qw REAL NOT NULL,
  odom_tx REAL NOT NULL, odom_ty REAL NOT NULL, odom_tz REAL NOT NULL,
  odom_qx REAL NOT NULL, odom_qy REAL NOT NULL, odom_qz REAL NOT NULL, odom_qw REAL NOT NULL,
  width INTEGER NOT NULL, height INTEGER NOT NULL,
  fx REAL NOT NULL, fy REAL NOT NULL, cx REAL NOT NULL, cy REAL NOT NULL,
  num_features INTEGER NOT NULL,
  color_bytes INTEGER NOT NULL,
  depth_bytes INTEGER NOT NULL);
CREATE INDEX keyframes_by_session ON keyframes(session_id);
CREATE TABLE keyframe_images (
  keyframe_id INTEGER PRIMARY KEY REFERENCES keyframes(id) ON DELETE CASCADE,
  color_jpeg BLOB NOT NULL,
  depth_png BLOB NOT NULL);
CREATE TABLE features (
  keyframe_id INTEGER PRIMARY KEY REFERENCES keyframes(id) ON DELETE CASCADE,
  count INTEGER NOT NULL,
  keypoints BLOB NOT NULL,
  descriptor_type INTEGER NOT NULL,
  descriptor_rows INTEGER NOT NULL,
  descriptor_cols INTEGER NOT NULL,
  descriptors BLOB NOT NULL,
  cam_points BLOB NOT NULL);
CREATE TABLE links (
  id INTEGER PRIMARY KEY,
  from_id INTEGER NOT NULL REFERENCES keyframes(id) ON DELETE CASCADE,
  to_id INTEGER NOT NULL REFERENCES keyframes(id) ON DELETE CASCADE,
  type INTEGER NOT NULL CHECK (type BETWEEN 0 AND 3),
  tx REAL NOT NULL, ty REAL NOT NULL, tz REAL NOT NULL,
  qx REAL NOT NULL, qy REAL NOT NULL, qz REAL NOT NULL, qw REAL NOT NULL,
  information BLOB NOT NULL);
CREATE INDEX links_by_from ON links(from_id);
CREATE INDEX links_by_to ON links(to_id);
CREATE TABLE labels (
  id INTEGER PRIMARY KEY,
  name TEXT NOT NULL UNIQUE,
  type TEXT NOT NULL,
  created_ns INTEGER NOT NULL,
  updated_ns INTEGER NOT NULL);
CREATE TABLE label_points (
  label_id INTEGER NOT NULL REFERENCES labels(id) ON DELETE CASCADE,
  idx INTEGER NOT NULL,
  x REAL NOT NULL, y REAL NOT NULL, z REAL NOT NULL,
  source INTEGER NOT NULL CHECK (source BETWEEN 0 AND 2),
  keyframe_id INTEGER REFERENCES keyframes(id) ON DELETE SET NULL,
  u REAL, v REAL,
  cam_x REAL, cam_y REAL, cam_z REAL,
  file TEXT,
  PRIMARY KEY (label_id, idx));
)sql",
      // 2: the visual vocabulary place recognition trains on a model (one per model).
      R"sql(
CREATE TABLE vocabulary (
  id INTEGER PRIMARY KEY CHECK (id = 1),
  format TEXT NOT NULL,
  data BLOB NOT NULL,
  updated_ns INTEGER NOT NULL);
)sql",
      // 3: a link the pose graph switched off as inconsistent (a false loop) is kept, marked
      // inactive, so a resumed session restores it switched off rather than trusting it again.
      R"sql(
ALTER TABLE links ADD COLUMN active INTEGER NOT NULL DEFAULT 1 CHECK (active IN (0, 1));
)sql",
      // 4: a prior link (type 4): the tracker's motion model across seconds where nothing
      // registered. SQLite cannot widen a CHECK in place, so the table is rebuilt.
      R"sql(
CREATE TABLE links_v4 (
  id INTEGER PRIMARY KEY,
  from_id INTEGER NOT NULL REFERENCES keyframes(id) ON DELETE CASCADE,
  to_id INTEGER NOT NULL REFERENCES keyframes(id) ON DELETE CASCADE,
  type INTEGER NOT NULL CHECK (type BETWEEN 0 AND 4),
  tx REAL NOT NULL, ty REAL NOT NULL, tz REAL NOT NULL,
  qx REAL NOT NULL, qy REAL NOT NULL, qz REAL NOT NULL, qw REAL NOT NULL,
  information BLOB NOT NULL,
  active INTEGER NOT NULL DEFAULT 1 CHECK (active IN (0, 1)));
INSERT INTO links_v4 (id, from_id, to_id, type, tx, ty, tz, qx, qy, qz, qw, information, active)
  SELECT id, from_id, to_id, type, tx, ty, tz, qx, qy, qz, qw, information, active FROM links;
DROP TABLE links;
ALTER TABLE links_v4 RENAME TO links;
CREATE INDEX links_by_from ON links(from_id);
CREATE INDEX links_by_to ON links(to_id);
)sql",
      // 5: views rendered from the model where the walk did not stand, for locating photos only
      // (never for mapping). Each is stored relative to the keyframe it was mostly rendered from,
      // so it moves with that keyframe when a later session's loops re-optimise the graph.
      R"sql(
CREATE TABLE synthetic_views (
  id INTEGER PRIMARY KEY,
  source_keyframe_id INTEGER NOT NULL REFERENCES keyframes(id) ON DELETE CASCADE,
  label_id INTEGER REFERENCES labels(id) ON DELETE SET NULL,
  tx REAL NOT NULL, ty REAL NOT NULL, tz REAL NOT NULL,
  qx REAL NOT NULL, qy REAL NOT NULL, qz REAL NOT NULL, qw REAL NOT NULL,
  width INTEGER NOT NULL, height INTEGER NOT NULL,
  fx REAL NOT NULL, fy REAL NOT NULL, cx REAL NOT NULL, cy REAL NOT NULL,
  created_ns INTEGER NOT NULL,
  color_jpeg BLOB NOT NULL,
  count INTEGER NOT NULL,
  keypoints BLOB NOT NULL,
  descriptor_type INTEGER NOT NULL,
  descriptor_rows INTEGER NOT NULL,
  descriptor_cols INTEGER NOT NULL,
  descriptors BLOB NOT NULL,
  cam_points BLOB NOT NULL);
CREATE INDEX synthetic_views_by_source ON synthetic_views(source_keyframe_id);
)sql",
      // 6: each keyframe's features for matching phone photos (RootSIFT), beside the ORB
      // features SLAM uses; a keyframe written before, or by a map run without them, has none.
      R"sql(
CREATE TABLE photo_features (
  keyframe_id INTEGER PRIMARY KEY REFERENCES keyframes(id) ON DELETE CASCADE,
  count INTEGER NOT NULL,
  keypoints BLOB NOT NULL,
  descriptor_type INTEGER NOT NULL,
  descriptor_rows INTEGER NOT NULL,
  descriptor_cols INTEGER NOT NULL,
  descriptors BLOB NOT NULL,
  cam_points BLOB NOT NULL);
)sql",
  };
  return kMigrations;
}

}  // namespace

int LatestSchemaVersion() { return static_cast<int>(Migrations().size()); }

void ApplyMigrations(sqlite3* db, int from_version, int to_version) {
  SIGHTMAP_CHECK(from_version >= 0 && to_version <= LatestSchemaVersion(),
                 "cannot migrate a model from schema " << from_version << " to " << to_version);
  const int64_t now_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(
                             std::chrono::system_clock::now().time_since_epoch())
                             .count();
  for (int version = from_version + 1; version <= to_version; ++version) {
    Exec(db, Migrations()[static_cast<size_t>(version - 1)]);
    Statement(db, "INSERT INTO sightmap_schema (version, applied_ns) VALUES (?, ?)")
        .Bind(1, version)
        .Bind(2, now_ns)
        .Run();
  }
  if (from_version == 0 && to_version > 0) {
    Exec(db, "PRAGMA application_id = " + std::to_string(kApplicationId));
  }
}

}  // namespace sightmap::store::internal
