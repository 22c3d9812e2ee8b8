#include "capture/openni_source.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstring>
#include <sstream>
#include <thread>
#include <utility>

#include <OpenNI.h>
#include <PS1080.h>
#include <opencv2/imgproc.hpp>

#include "capture/calibration.h"
#include "capture/depth_registration.h"
#include "capture/frame_gaps.h"
#include "capture/frame_pairer.h"
#include "capture/oni_file.h"
#include "capture/openni_runtime.h"
#include "core/check.h"
#include "core/format.h"

namespace sightmap::capture {
namespace {

// PrimeSense reference design (Kinect v1, Xtion, Carmine): 58 x 45 degree depth field of view and
// 2.5 cm between the depth and colour cameras. Used only when the stream reports nothing better.
constexpr double kPrimeSenseHfovRad = 1.0145;
constexpr double kPrimeSenseVfovRad = 0.7898;
constexpr double kPrimeSenseBaselineM = 0.025;
constexpr std::chrono::milliseconds kStopGrace(150);

std::string OpenNiError() {
  std::string text = openni::OpenNI::getExtendedError();
  // OpenNI2 prefixes messages with tabs and ends them with newlines; a one-line error needs
  // neither.
  std::replace(text.begin(), text.end(), '\n', ' ');
  std::replace(text.begin(), text.end(), '\t', ' ');
  text.erase(0, text.find_first_not_of(' '));
  text.erase(text.find_last_not_of(' ') + 1);
  return text.empty() ? "no reason given" : text;
}

bool IsDepthFormat(openni::PixelFormat format) {
  return format == openni::PIXEL_FORMAT_DEPTH_1_MM || format == openni::PIXEL_FORMAT_DEPTH_100_UM;
}

bool IsColorFormat(openni::PixelFormat format) {
  return format == openni::PIXEL_FORMAT_RGB888 || format == openni::PIXEL_FORMAT_YUV422 ||
         format == openni::PIXEL_FORMAT_YUYV || format == openni::PIXEL_FORMAT_GRAY8;
}

// The device mode closest to the request: right pixel format first, then size, then rate.
std::optional<openni::VideoMode> ChooseMode(const openni::SensorInfo& info, bool depth,
                                            const SourceOptions& options) {
  const openni::Array<openni::VideoMode>& modes = info.getSupportedVideoModes();
  std::optional<openni::VideoMode> best;
  double best_cost = 0.0;
  for (int i = 0; i < modes.getSize(); ++i) {
    const openni::VideoMode& mode = modes[i];
    const openni::PixelFormat format = mode.getPixelFormat();
    if (depth ? !IsDepthFormat(format) : !IsColorFormat(format)) continue;
    const bool preferred_format =
        depth ? format == openni::PIXEL_FORMAT_DEPTH_1_MM : format == openni::PIXEL_FORMAT_RGB888;
    const double cost = (preferred_format ? 0.0 : 1e6) +
                        std::abs(mode.getResolutionX() - options.width) +
                        std::abs(mode.getResolutionY() - options.height) +
                        0.1 * std::abs(mode.getFps() - options.fps);
    if (!best || cost < best_cost) {
      best = mode;
      best_cost = cost;
    }
  }
  return best;
}

cv::Mat DepthToMat(const openni::VideoFrameRef& frame) {
  const cv::Mat view(frame.getHeight(), frame.getWidth(), CV_16UC1,
                     const_cast<void*>(frame.getData()), frame.getStrideInBytes());
  if (frame.getVideoMode().getPixelFormat() == openni::PIXEL_FORMAT_DEPTH_100_UM) {
    cv::Mat mm;
    view.convertTo(mm, CV_16UC1, 0.1);
    return mm;
  }
  return view.clone();
}

cv::Mat ColorToBgr(const openni::VideoFrameRef& frame) {
  void* data = const_cast<void*>(frame.getData());
  const int w = frame.getWidth();
  const int h = frame.getHeight();
  const size_t stride = frame.getStrideInBytes();
  cv::Mat bgr;
  switch (frame.getVideoMode().getPixelFormat()) {
    case openni::PIXEL_FORMAT_RGB888:
      cv::cvtColor(cv::Mat(h, w, CV_8UC3, data, stride), bgr, cv::COLOR_RGB2BGR);
      break;
    case openni::PIXEL_FORMAT_YUV422:
      cv::cvtColor(cv::Mat(h, w, CV_8UC2, data, stride), bgr, cv::COLOR_YUV2BGR_UYVY);
      break;
    case openni::PIXEL_FORMAT_YUYV:
      cv::cvtColor(cv::Mat(h, w, CV_8UC2, data, stride), bgr, cv::COLOR_YUV2BGR_YUYV);
      break;
    case openni::PIXEL_FORMAT_GRAY8:
      cv::cvtColor(cv::Mat(h, w, CV_8UC1, data, stride), bgr, cv::COLOR_GRAY2BGR);
      break;
    default:
      SIGHTMAP_THROW(Error, "unsupported colour pixel format "
                                << frame.getVideoMode().getPixelFormat()
                                << ": sightmap reads RGB888, YUV422, YUYV and GRAY8");
  }
  return bgr;
}

// A stream's field of view, or nothing when the stream does not report one (OpenNI 1 recordings
// store 0 for colour; the dummy driver for both).
std::optional<std::pair<double, double>> FieldOfView(openni::VideoStream& stream) {
  const double hfov = stream.getHorizontalFieldOfView();
  const double vfov = stream.getVerticalFieldOfView();
  if (!(hfov > 0.05 && hfov < 3.0)) return std::nullopt;
  return std::make_pair(hfov, vfov > 0.05 && vfov < 3.0 ? vfov : 0.0);
}

// OpenNI's recorders (1 and 2) number a recording's frames from 1; a live device numbers from
// wherever its count stands.
std::optional<int64_t> FirstFrameNumber(bool is_file) {
  return is_file ? std::optional<int64_t>(1) : std::nullopt;
}

class OpenNiSource final : public RgbdSource {
 public:
  OpenNiSource(const std::string& location, bool is_file, const SourceOptions& options)
      : options_(options),
        is_file_(is_file),
        pairer_(options.sync_tolerance_ns),
        depth_gaps_(FirstFrameNumber(is_file)),
        color_gaps_(FirstFrameNumber(is_file)) {
    SIGHTMAP_CHECK_OPTIONS(options_);
    if (is_file_) oni_info_ = ReadOniFileInfo(location);
    runtime_ = OpenNiRuntime::Acquire();
    OpenDevice(location);
    CreateStreams();
    if (is_file_)
      ConfigurePlayback();
    else
      ConfigureLiveDevice();
    DeriveGeometry();
    Start();
  }

  ~OpenNiSource() override {
    // The device goes before the runtime (member order handles that).
    depth_.stop();
    color_.stop();
    // Drivers deliver frames from threads of their own and check "started" only before they
    // begin a delivery: one that began before stop() still runs into the stream's buffers
    // (Debian's DummyDevice; OpenNI2's file player, which a read triggers one frame ahead).
    // Tearing the stream down under it crashes the process. A source ends once, so a short grace
    // for that last delivery costs nothing.
    std::this_thread::sleep_for(kStopGrace);
    if (is_file_) {
      // The file player's thread also walks its stream list without a lock, and destroying a
      // stream unlinks and frees it from that list. Closing the device first joins the thread;
      // streams destroyed afterwards no longer reach the driver (their device handle is gone),
      // which leaks two small driver objects per recording instead of risking a crash.
      device_.close();
      depth_.destroy();
      color_.destroy();
      return;
    }
    depth_.destroy();
    color_.destroy();
    device_.close();
  }

  const SourceMetadata& metadata() const override { return metadata_; }
  SourceStats stats() const override {
    SourceStats stats = stats_;
    stats.unpaired_frames = pairer_.unpaired_depth_frames();
    stats.missed_depth_frames = depth_gaps_.missed();
    stats.missed_color_frames = color_gaps_.missed();
    return stats;
  }

  std::optional<RgbdFrame> Next() override {
    // A live sensor whose colour stream stalls while depth keeps coming (or the reverse) never
    // times out in ReadOneFrame and would loop here for ever: no pair for frame_timeout_ms is
    // the same failure as no frame.
    const auto give_up =
        std::chrono::steady_clock::now() + std::chrono::milliseconds(options_.frame_timeout_ms);
    while (true) {
      if (auto pair = pairer_.PopPair()) return MakeFrame(std::move(pair->first), pair->second);
      if (finished_) return std::nullopt;
      if (is_file_ && stats_.depth_frames + depth_gaps_.missed() >= *metadata_.depth_frame_count &&
          stats_.color_frames + color_gaps_.missed() >= *metadata_.color_frame_count) {
        // Every frame the file holds was read or passed (a replay at the recorded pace misses
        // frames when the reader falls behind); OpenNI2 would only time out from here on.
        pairer_.Finish();
        finished_ = true;
        continue;
      }
      if (!is_file_ && std::chrono::steady_clock::now() > give_up) {
        SIGHTMAP_THROW(Error, "no depth frame of " << metadata_.uri << " found a colour frame for "
                                                   << options_.frame_timeout_ms << " ms ("
                                                   << stats_.depth_frames << " depth and "
                                                   << stats_.color_frames
                                                   << " colour frames so far): one stream "
                                                      "stalled — reconnect the sensor and run "
                                                      "'sightmap devices'");
      }
      ReadOneFrame();
    }
  }

 private:
  void OpenDevice(const std::string& location) {
    std::string uri = location;
    if (!is_file_ && uri.empty()) {
      openni::Array<openni::DeviceInfo> devices;
      openni::OpenNI::enumerateDevices(&devices);
      SIGHTMAP_CHECK(devices.getSize() > 0, "no RGB-D sensor found — run 'sightmap devices'");
      uri = devices[0].getUri();
    }
    if (device_.open(uri.c_str()) != openni::STATUS_OK) {
      if (is_file_) {
        SIGHTMAP_THROW(Error, "OpenNI2 cannot play "
                                  << location << " (" << OpenNiError()
                                  << "): the recording is damaged or of a format "
                                     "OpenNI2 does not read");
      }
      SIGHTMAP_THROW(Error, "cannot open OpenNI2 device '" << uri << "' (" << OpenNiError()
                                                           << ") — run 'sightmap devices'");
    }
    const openni::DeviceInfo& info = device_.getDeviceInfo();
    metadata_.kind = is_file_ ? "oni" : "openni";
    metadata_.uri = is_file_ ? location : std::string(info.getUri());
    metadata_.device_name = info.getName();
    metadata_.vendor = info.getVendor();
    if (!is_file_) {
      std::array<char, 64> serial{};
      int size = static_cast<int>(serial.size());
      if (device_.getProperty(openni::DEVICE_PROPERTY_SERIAL_NUMBER, serial.data(), &size) ==
          openni::STATUS_OK) {
        metadata_.serial = std::string(serial.data(), strnlen(serial.data(), serial.size()));
      }
    }
  }

  void CreateStreams() {
    const std::string what = is_file_ ? "recording " + metadata_.uri : "device " + metadata_.uri;
    SIGHTMAP_CHECK(device_.hasSensor(openni::SENSOR_DEPTH) &&
                       depth_.create(device_, openni::SENSOR_DEPTH) == openni::STATUS_OK,
                   what << " has no depth stream: sightmap needs RGB-D (" << OpenNiError() << ")");
    SIGHTMAP_CHECK(device_.hasSensor(openni::SENSOR_COLOR) &&
                       color_.create(device_, openni::SENSOR_COLOR) == openni::STATUS_OK,
                   what << " has no colour stream: sightmap needs RGB-D, not depth alone");
  }

  void ConfigurePlayback() {
    openni::PlaybackControl* playback = device_.getPlaybackControl();
    SIGHTMAP_CHECK(playback, "OpenNI2 gives no playback control for " << metadata_.uri);
    playback->setRepeatEnabled(false);
    playback->setSpeed(options_.realtime ? 1.0f : -1.0f);
    metadata_.depth_frame_count = playback->getNumberOfFrames(depth_);
    metadata_.color_frame_count = playback->getNumberOfFrames(color_);
    SIGHTMAP_CHECK(*metadata_.depth_frame_count > 0 && *metadata_.color_frame_count > 0,
                   metadata_.uri << " holds " << *metadata_.depth_frame_count << " depth and "
                                 << *metadata_.color_frame_count
                                 << " colour frames: sightmap needs both");
  }

  void ConfigureLiveDevice() {
    std::array<std::pair<openni::VideoStream*, bool>, 2> streams = {std::make_pair(&depth_, true),
                                                                    std::make_pair(&color_, false)};
    for (auto [stream, is_depth] : streams) {
      const char* what = is_depth ? "depth" : "colour";
      std::optional<openni::VideoMode> mode =
          ChooseMode(stream->getSensorInfo(), is_depth, options_);
      const openni::VideoMode current = stream->getVideoMode();
      if (!mode || stream->setVideoMode(*mode) != openni::STATUS_OK) {
        // Some drivers list no modes or refuse to switch; their current mode may still serve.
        const bool usable = is_depth ? IsDepthFormat(current.getPixelFormat())
                                     : IsColorFormat(current.getPixelFormat());
        SIGHTMAP_CHECK(usable, "device " << metadata_.uri << " offers no usable " << what
                                         << " mode (" << OpenNiError() << ")");
        mode = current;
      }
      if (mode->getResolutionX() != options_.width || mode->getResolutionY() != options_.height ||
          mode->getFps() != options_.fps) {
        metadata_.notes.push_back(
            std::string(what) + " runs at " + std::to_string(mode->getResolutionX()) + "x" +
            std::to_string(mode->getResolutionY()) + " @ " + std::to_string(mode->getFps()) +
            " Hz: the device has no " + std::to_string(options_.width) + "x" +
            std::to_string(options_.height) + " @ " + std::to_string(options_.fps) + " Hz mode");
      }
      // Mirrored images would describe a mirrored world; ask the device for the real one.
      stream->setMirroringEnabled(false);
    }
    if (device_.isImageRegistrationModeSupported(openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR)) {
      device_.setImageRegistrationMode(openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR);
    }
    if (device_.setDepthColorSyncEnabled(true) != openni::STATUS_OK) {
      metadata_.notes.push_back(
          "the device has no hardware frame sync: frames are paired by timestamp");
    }
  }

  // The streams' sizes and rate, mirroring, intrinsics and how depth is registered to colour.
  void DeriveGeometry() {
    const openni::VideoMode depth_mode = depth_.getVideoMode();
    const openni::VideoMode color_mode = color_.getVideoMode();
    metadata_.depth_width = depth_mode.getResolutionX();
    metadata_.depth_height = depth_mode.getResolutionY();
    metadata_.color_width = color_mode.getResolutionX();
    metadata_.color_height = color_mode.getResolutionY();
    metadata_.nominal_fps = depth_mode.getFps();
    SIGHTMAP_CHECK(IsDepthFormat(depth_mode.getPixelFormat()),
                   metadata_.uri << ": depth pixel format " << depth_mode.getPixelFormat()
                                 << " is not millimetres or 100 um");
    SIGHTMAP_CHECK(metadata_.depth_width > 0 && metadata_.color_width > 0,
                   metadata_.uri << " reports an empty image size");

    // Mirroring the device could not switch off is undone in software, with the intrinsics.
    mirror_ = depth_.getMirroringEnabled() || color_.getMirroringEnabled();
    metadata_.mirrored_in_software = mirror_;
    if (mirror_) {
      metadata_.notes.push_back(
          std::string(is_file_ ? "the recording was made" : "the device streams") +
          " mirrored: frames are flipped back left-right");
    }
    IntrinsicsFromFieldsOfView();
    const std::optional<Eigen::Isometry3d> color_from_depth = ApplyCalibration();
    ChooseRegistration(color_from_depth);
    if (metadata_.depth_width != metadata_.color_width ||
        metadata_.depth_height != metadata_.color_height) {
      metadata_.depth_resized_to_color = true;
      metadata_.notes.push_back("depth is " + std::to_string(metadata_.depth_width) + "x" +
                                std::to_string(metadata_.depth_height) + " and colour " +
                                std::to_string(metadata_.color_width) + "x" +
                                std::to_string(metadata_.color_height) +
                                ": depth is mapped onto the colour image size");
    }
  }

  // Both cameras' intrinsics from the fields of view: colour's when reported, else depth's, else
  // the PrimeSense nominal one.
  void IntrinsicsFromFieldsOfView() {
    const auto depth_fov = FieldOfView(depth_);
    const auto color_fov = FieldOfView(color_);
    std::pair<double, double> nominal(kPrimeSenseHfovRad, kPrimeSenseVfovRad);
    if (!depth_fov && !color_fov) {
      metadata_.notes.push_back("no field of view reported: assumed the PrimeSense nominal " +
                                Fixed(kPrimeSenseHfovRad, 4) + " x " +
                                Fixed(kPrimeSenseVfovRad, 4) +
                                " rad; pass --calib for real intrinsics");
    }
    const auto depth_fov_used = depth_fov.value_or(color_fov.value_or(nominal));
    const auto color_fov_used = color_fov.value_or(depth_fov_used);
    depth_intrinsics_ = Intrinsics::FromFieldOfView(metadata_.depth_width, metadata_.depth_height,
                                                    depth_fov_used.first, depth_fov_used.second);
    metadata_.intrinsics = Intrinsics::FromFieldOfView(
        metadata_.color_width, metadata_.color_height, color_fov_used.first, color_fov_used.second);
    metadata_.intrinsics_origin = "field-of-view";
    if (depth_fov && !color_fov) {
      metadata_.notes.push_back(
          "the colour stream reports no field of view: colour intrinsics use "
          "the depth stream's (" +
          Fixed(depth_fov->first, 4) + " rad horizontal)");
    }
  }

  // A calibration file's intrinsics replace the fields of view's; returns its color_from_depth.
  std::optional<Eigen::Isometry3d> ApplyCalibration() {
    if (options_.calibration_file.empty()) return std::nullopt;
    const RgbdCalibration calibration = ReadCalibrationFile(options_.calibration_file);
    if (calibration.color) {
      metadata_.intrinsics =
          calibration.color->Scaled(metadata_.color_width, metadata_.color_height);
    }
    if (calibration.depth) {
      depth_intrinsics_ = calibration.depth->Scaled(metadata_.depth_width, metadata_.depth_height);
    }
    metadata_.intrinsics_origin = "calibration-file";
    metadata_.notes.push_back("calibration from " + options_.calibration_file);
    return calibration.color_from_depth;
  }

  // Depth the device (or the recording) registered to colour is used as it is, resized when the
  // sizes differ; otherwise it is registered in software with the calibration file's
  // color_from_depth (an explicit request to do so), or the PrimeSense-family model.
  void ChooseRegistration(const std::optional<Eigen::Isometry3d>& color_from_depth) {
    registration_.color = metadata_.intrinsics;
    const bool recorded_registered = oni_info_.depth_registered_to_color.value_or(false);
    if (recorded_registered) {
      metadata_.notes.push_back(
          "the recording says depth was registered to colour by the device "
          "(OpenNI 1 AlternativeViewPoint)");
    }
    const bool device_registered =
        recorded_registered ||
        device_.getImageRegistrationMode() == openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR;
    if (device_registered && !color_from_depth) {
      // Registered depth is already in the colour camera; only its size may differ.
      metadata_.registration = DepthRegistration::kDevice;
      registration_.depth =
          metadata_.intrinsics.Scaled(metadata_.depth_width, metadata_.depth_height);
      registration_.color_from_depth = Eigen::Isometry3d::Identity();
      reproject_ = metadata_.depth_width != metadata_.color_width ||
                   metadata_.depth_height != metadata_.color_height;
      return;
    }
    metadata_.registration = DepthRegistration::kSoftware;
    registration_.depth = depth_intrinsics_;
    reproject_ = true;
    if (color_from_depth) {
      registration_.color_from_depth = *color_from_depth;
      metadata_.notes.push_back(
          "depth registered to colour in software with the calibration file's "
          "color_from_depth");
      return;
    }
    // The PS1080 driver records the camera baseline [cm]; older files and other drivers don't.
    double baseline_cm = 0.0;
    const bool recorded = depth_.getProperty(XN_STREAM_PROPERTY_DCMOS_RCMOS_DISTANCE,
                                             &baseline_cm) == openni::STATUS_OK &&
                          baseline_cm > 0.5 && baseline_cm < 10.0;
    const double baseline_m = recorded ? baseline_cm * 1e-2 : kPrimeSenseBaselineM;
    registration_.color_from_depth = PrimeSenseColorFromDepth(baseline_m);
    metadata_.notes.push_back(
        std::string(is_file_ ? "the recording's depth is not registered to colour"
                             : "the device cannot register depth to colour") +
        ": registered in software with the PrimeSense-family model (parallel cameras, colour " +
        Fixed(baseline_m * 100.0, 2) + " cm to the right of depth" +
        (recorded ? ", baseline recorded by the driver" : ", nominal baseline") +
        "); pass --calib to override");
  }

  void Start() {
    SIGHTMAP_CHECK(depth_.start() == openni::STATUS_OK, "cannot start the depth stream of "
                                                            << metadata_.uri << " ("
                                                            << OpenNiError() << ")");
    SIGHTMAP_CHECK(color_.start() == openni::STATUS_OK, "cannot start the colour stream of "
                                                            << metadata_.uri << " ("
                                                            << OpenNiError() << ")");
  }

  void ReadOneFrame() {
    std::array<openni::VideoStream*, 2> streams = {&depth_, &color_};
    int ready = -1;
    const openni::Status status = openni::OpenNI::waitForAnyStream(
        streams.data(), static_cast<int>(streams.size()), &ready, options_.frame_timeout_ms);
    if (status != openni::STATUS_OK || ready < 0) {
      if (is_file_) {
        SIGHTMAP_THROW(Error, metadata_.uri
                                  << " ends after " << stats_.depth_frames << " of "
                                  << *metadata_.depth_frame_count << " depth and "
                                  << stats_.color_frames << " of " << *metadata_.color_frame_count
                                  << " colour frames: the recording is truncated or damaged");
      }
      SIGHTMAP_THROW(Error, "no frames from " << metadata_.uri << " for "
                                              << options_.frame_timeout_ms
                                              << " ms: the sensor was unplugged or stopped — "
                                                 "reconnect it and run 'sightmap devices'");
    }
    openni::VideoFrameRef frame;
    SIGHTMAP_CHECK(streams[ready]->readFrame(&frame) == openni::STATUS_OK && frame.isValid(),
                   "cannot read a frame from " << metadata_.uri << " (" << OpenNiError() << ")");
    // OpenNI2 timestamps are microseconds.
    TimedImage image{static_cast<TimestampNs>(frame.getTimestamp()) * 1000, cv::Mat()};
    if (ready == 0) {
      ++stats_.depth_frames;
      depth_gaps_.Add(frame.getFrameIndex());
      image.image = DepthToMat(frame);
      if (mirror_) cv::flip(image.image, image.image, 1);
      pairer_.AddDepth(std::move(image));
    } else {
      ++stats_.color_frames;
      color_gaps_.Add(frame.getFrameIndex());
      image.image = ColorToBgr(frame);
      if (mirror_) cv::flip(image.image, image.image, 1);
      pairer_.AddColor(std::move(image));
    }
  }

  RgbdFrame MakeFrame(TimedImage depth, const TimedImage& color) {
    RgbdFrame frame;
    frame.index = stats_.paired_frames++;
    frame.timestamp_ns = depth.timestamp_ns;
    frame.color = color.image;
    frame.depth = reproject_ ? RegisterDepthToColor(depth.image, registration_) : depth.image;
    return frame;
  }

  SourceOptions options_;
  bool is_file_;
  std::shared_ptr<OpenNiRuntime> runtime_;  // outlives the device and streams below
  openni::Device device_;
  openni::VideoStream depth_;
  openni::VideoStream color_;
  SourceMetadata metadata_;
  SourceStats stats_;
  FramePairer pairer_;
  FrameGaps depth_gaps_;
  FrameGaps color_gaps_;
  bool finished_ = false;
  bool mirror_ = false;
  bool reproject_ = false;
  Intrinsics depth_intrinsics_;
  DepthToColorModel registration_;
  OniFileInfo oni_info_;
};

}  // namespace

std::unique_ptr<RgbdSource> OpenOpenNiDevice(const std::string& uri, const SourceOptions& options) {
  return std::make_unique<OpenNiSource>(uri, /*is_file=*/false, options);
}

std::unique_ptr<RgbdSource> OpenOniFile(const std::string& path, const SourceOptions& options) {
  return std::make_unique<OpenNiSource>(path, /*is_file=*/true, options);
}

}  // namespace sightmap::capture
