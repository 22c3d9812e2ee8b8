// Resuming a model: the keyframes, links and vocabulary it holds, given to a Mapper (and drawn in
// the map view) before a new session maps on. Restored keyframes are not registered again.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/camera.h"
#include "core/rgbd_frame.h"
#include "mapping/map_view_feed.h"
#include "slam/mapper.h"
#include "store/model.h"

namespace sightmap::mapping {

struct RestoredModel {
  // Model id of each restored keyframe, by mapper id (0, 1, ...).
  std::vector<KeyframeId> store_ids;
  // One restored keyframe (mapper id) of each part of the stored map: a new session that ends up
  // in the segment of one of them joined the stored map.
  std::vector<int64_t> segment_members;
  bool vocabulary_restored = false;
  // Source time of the newest restored keyframe, the mapper's last [ns]; 0 when none.
  TimestampNs last_timestamp_ns = 0;
};

// Gives `mapper` (which holds no keyframe yet) everything `model` holds, and `view` (may be null)
// every keyframe and loop; the mapper's next keyframe starts a new segment, to be relocalised into
// the stored map (a new session). The keyframes' colour is read only with `load_color` or a view (a
// JPEG to decode per keyframe). Throws sightmap::Error when the model's camera size differs from
// `camera`'s or its vocabulary has another format, saying what to do.
RestoredModel RestoreModel(const store::Model& model, const Intrinsics& camera, bool load_color,
                           slam::Mapper* mapper, MapViewFeed* view);

// The newest restored keyframe as a frame (colour as the model stores it, JPEG; index -1, as the
// model keeps no frame index), for a tracker that continues its walk. Throws sightmap::Error when
// nothing was restored or its images do not decode.
RgbdFrame NewestKeyframeFrame(const store::Model& model, const RestoredModel& restored);

}  // namespace sightmap::mapping
