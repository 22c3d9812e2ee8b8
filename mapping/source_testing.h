// For tests: sources that wrap a real one to fail, count or lose frames as a sensor would.
#pragma once

#include <memory>
#include <optional>
#include <utility>

#include "capture/rgbd_source.h"
#include "core/check.h"

namespace sightmap::testing {

// Forwards everything to `inner`: a test source overrides only what it changes.
class ForwardingSource : public capture::RgbdSource {
 public:
  explicit ForwardingSource(std::unique_ptr<capture::RgbdSource> inner)
      : inner_(std::move(inner)) {}
  const capture::SourceMetadata& metadata() const override { return inner_->metadata(); }
  std::optional<RgbdFrame> Next() override { return inner_->Next(); }
  std::optional<FrameStamp> PeekStamp() const override { return inner_->PeekStamp(); }
  void SkipNext() override { inner_->SkipNext(); }
  capture::SourceStats stats() const override { return inner_->stats(); }

 private:
  std::unique_ptr<capture::RgbdSource> inner_;
};

// `inner`'s frames, then "the sensor stopped sending frames (unplugged?)" after `fail_after`.
class FailingSource : public ForwardingSource {
 public:
  FailingSource(std::unique_ptr<capture::RgbdSource> inner, int fail_after)
      : ForwardingSource(std::move(inner)), fail_after_(fail_after) {}
  std::optional<RgbdFrame> Next() override {
    if (delivered_++ == fail_after_) {
      SIGHTMAP_THROW(Error, "the sensor stopped sending frames (unplugged?)");
    }
    return ForwardingSource::Next();
  }

 private:
  int fail_after_;
  int delivered_ = 0;
};

}  // namespace sightmap::testing
