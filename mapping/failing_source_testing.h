// For tests: a source that fails like an unplugged sensor after a number of frames.
#pragma once

#include <memory>
#include <optional>
#include <utility>

#include "capture/rgbd_source.h"
#include "core/check.h"

namespace sightmap::testing {

// `inner`'s frames, then "the sensor stopped sending frames (unplugged?)" after `fail_after`.
class FailingSource : public capture::RgbdSource {
 public:
  FailingSource(std::unique_ptr<capture::RgbdSource> inner, int fail_after)
      : inner_(std::move(inner)), fail_after_(fail_after) {}
  const capture::SourceMetadata& metadata() const override { return inner_->metadata(); }
  std::optional<RgbdFrame> Next() override {
    if (delivered_++ == fail_after_) {
      SIGHTMAP_THROW(Error, "the sensor stopped sending frames (unplugged?)");
    }
    return inner_->Next();
  }
  capture::SourceStats stats() const override { return inner_->stats(); }

 private:
  std::unique_ptr<capture::RgbdSource> inner_;
  int fail_after_;
  int delivered_ = 0;
};

}  // namespace sightmap::testing
