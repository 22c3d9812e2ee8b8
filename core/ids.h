// The typed ids of what a model stores (sessions, keyframes, links, labels, synthetic views), for
// every layer that names them.
#pragma once

#include <cstdint>

namespace sightmap {

// A model's ids are its SQLite row ids: positive once stored; 0 is "none". A distinct type per
// table so a keyframe id cannot be passed where a label id is expected.
template <typename Tag>
class StoreId {
 public:
  constexpr StoreId() = default;
  constexpr explicit StoreId(int64_t value) : value_(value) {}
  constexpr int64_t value() const { return value_; }
  constexpr bool valid() const { return value_ > 0; }
  constexpr bool operator==(StoreId other) const { return value_ == other.value_; }
  constexpr bool operator!=(StoreId other) const { return value_ != other.value_; }
  constexpr bool operator<(StoreId other) const { return value_ < other.value_; }

 private:
  int64_t value_ = 0;
};

using SessionId = StoreId<struct SessionIdTag>;
using KeyframeId = StoreId<struct KeyframeIdTag>;
using LinkId = StoreId<struct LinkIdTag>;
using LabelId = StoreId<struct LabelIdTag>;
using SyntheticViewId = StoreId<struct SyntheticViewIdTag>;

}  // namespace sightmap
