#include "capture/openni_source.h"

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <thread>

#include <OpenNI.h>
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "capture/oni_file.h"
#include "capture/openni_runtime.h"
#include "core/check.h"
#include "core/timing.h"
#include "tests/test_data.h"

namespace sightmap::capture {
namespace {

struct ReadAll {
  std::vector<RgbdFrame> frames;
  bool timestamps_increase = true;
};

ReadAll Drain(RgbdSource& source) {
  ReadAll all;
  while (auto frame = source.Next()) {
    if (!all.frames.empty() && frame->timestamp_ns <= all.frames.back().timestamp_ns) {
      all.timestamps_increase = false;
    }
    all.frames.push_back(std::move(*frame));
  }
  return all;
}

double MedianValidDepthMm(const cv::Mat& depth) {
  std::vector<uint16_t> values;
  for (auto it = depth.begin<uint16_t>(); it != depth.end<uint16_t>(); ++it) {
    if (*it) values.push_back(*it);
  }
  if (values.empty()) return 0.0;
  std::nth_element(values.begin(), values.begin() + values.size() / 2, values.end());
  return values[values.size() / 2];
}

TEST(OniFile, ReadsTheRecordedRegistrationFlag) {
  SIGHTMAP_REQUIRE_SHARED_DATA(kinect, "oni/kinect-12f.oni");
  SIGHTMAP_REQUIRE_SHARED_DATA(openni2, "oni/openni2-24f.oni");
  const OniFileInfo kinect_info = ReadOniFileInfo(kinect);
  EXPECT_EQ(kinect_info.version_maintenance, 1);
  EXPECT_EQ(kinect_info.max_timestamp_us, 378742u);
  ASSERT_TRUE(kinect_info.depth_registered_to_color.has_value());
  EXPECT_TRUE(*kinect_info.depth_registered_to_color);
  // The OpenNI2 recorder writes no registration flag at all.
  EXPECT_FALSE(ReadOniFileInfo(openni2).depth_registered_to_color.has_value());
}

TEST(OpenNiSource, KinectRecordingYieldsTwelveRegisteredFrames) {
  SIGHTMAP_REQUIRE_SHARED_DATA(path, "oni/kinect-12f.oni");
  auto source = OpenOniFile(path, SourceOptions());
  const SourceMetadata& meta = source->metadata();
  EXPECT_EQ(meta.kind, "oni");
  EXPECT_EQ(meta.depth_width, 640);
  EXPECT_EQ(meta.depth_height, 480);
  EXPECT_EQ(meta.color_width, 640);
  EXPECT_EQ(meta.color_height, 480);
  EXPECT_EQ(meta.depth_frame_count, 12);
  EXPECT_EQ(meta.color_frame_count, 12);
  EXPECT_EQ(meta.registration, DepthRegistration::kDevice);
  EXPECT_TRUE(meta.mirrored_in_software);
  EXPECT_FALSE(meta.depth_resized_to_color);
  EXPECT_FALSE(meta.has_ground_truth);
  // Colour reports no field of view in this OpenNI 1 recording: depth's 1.0145 rad is used.
  const double expected_fx = 640.0 / (2.0 * std::tan(1.0145 / 2.0));
  EXPECT_NEAR(meta.intrinsics.fx, expected_fx, 0.01 * expected_fx);
  EXPECT_NEAR(meta.intrinsics.cx, 319.5, 1e-9);

  const ReadAll all = Drain(*source);
  ASSERT_EQ(all.frames.size(), 12u);
  EXPECT_TRUE(all.timestamps_increase);
  for (const RgbdFrame& frame : all.frames) {
    EXPECT_EQ(frame.color.type(), CV_8UC3);
    EXPECT_EQ(frame.depth.type(), CV_16UC1);
    EXPECT_EQ(frame.color.size(), cv::Size(640, 480));
    EXPECT_EQ(frame.depth.size(), cv::Size(640, 480));
    // A room seen from ~2.6 m (measured: 76% of pixels valid, median ~2.6 m).
    EXPECT_GT(ValidDepthFraction(frame.depth), 0.6);
    EXPECT_NEAR(MedianValidDepthMm(frame.depth), 2600.0, 800.0);
  }
  // Recorded at 30 Hz: 11 intervals of 33.4 ms.
  EXPECT_NEAR((all.frames.back().timestamp_ns - all.frames.front().timestamp_ns) * 1e-9, 0.367,
              0.01);
  const SourceStats stats = source->stats();
  EXPECT_EQ(stats.depth_frames, 12);
  EXPECT_EQ(stats.color_frames, 12);
  EXPECT_EQ(stats.unpaired_frames, 0);
  EXPECT_FALSE(source->Next().has_value());  // stays at the end
}

TEST(OpenNiSource, MirroredRecordingIsFlippedBack) {
  SIGHTMAP_REQUIRE_SHARED_DATA(path, "oni/kinect-12f.oni");
  // The first depth frame as OpenNI2 hands it out, mirrored.
  cv::Mat raw;
  {
    auto runtime = OpenNiRuntime::Acquire();
    openni::Device device;
    ASSERT_EQ(device.open(path.c_str()), openni::STATUS_OK);
    openni::VideoStream depth;
    ASSERT_EQ(depth.create(device, openni::SENSOR_DEPTH), openni::STATUS_OK);
    device.getPlaybackControl()->setSpeed(-1.0f);
    ASSERT_EQ(depth.start(), openni::STATUS_OK);
    openni::VideoFrameRef frame;
    ASSERT_EQ(depth.readFrame(&frame), openni::STATUS_OK);
    raw = cv::Mat(frame.getHeight(), frame.getWidth(), CV_16UC1, const_cast<void*>(frame.getData()),
                  frame.getStrideInBytes())
              .clone();
  }
  auto source = OpenOniFile(path, SourceOptions());
  const auto first = source->Next();
  ASSERT_TRUE(first.has_value());
  cv::Mat unflipped;
  cv::flip(first->depth, unflipped, 1);
  EXPECT_EQ(cv::norm(unflipped, raw, cv::NORM_INF), 0.0);
  EXPECT_GT(cv::norm(first->depth, raw, cv::NORM_L1), 0.0);
}

TEST(OpenNiSource, OpenNi2RecordingMapsDepthOntoTheSmallerColourImage) {
  SIGHTMAP_REQUIRE_SHARED_DATA(path, "oni/openni2-24f.oni");
  auto source = OpenOniFile(path, SourceOptions());
  const SourceMetadata& meta = source->metadata();
  EXPECT_EQ(meta.depth_width, 640);
  EXPECT_EQ(meta.color_width, 320);
  EXPECT_EQ(meta.color_height, 240);
  EXPECT_EQ(meta.depth_frame_count, 24);
  EXPECT_EQ(meta.color_frame_count, 23);
  EXPECT_TRUE(meta.depth_resized_to_color);
  EXPECT_EQ(meta.registration, DepthRegistration::kSoftware);
  EXPECT_EQ(meta.intrinsics.width, 320);
  EXPECT_NEAR(meta.intrinsics.fx, 320.0 / (2.0 * std::tan(1.0226 / 2.0)), 0.5);
  bool notes_say_resized = false;
  for (const std::string& note : meta.notes) {
    notes_say_resized |= note.find("mapped onto the colour image size") != std::string::npos;
  }
  EXPECT_TRUE(notes_say_resized);

  const ReadAll all = Drain(*source);
  EXPECT_TRUE(all.timestamps_increase);
  // The last depth frame is 30 ms from the last colour frame: beyond the 20 ms pairing tolerance.
  ASSERT_EQ(all.frames.size(), 23u);
  for (const RgbdFrame& frame : all.frames) {
    EXPECT_EQ(frame.depth.size(), cv::Size(320, 240));
    EXPECT_EQ(frame.color.size(), cv::Size(320, 240));
    EXPECT_GT(ValidDepthFraction(frame.depth), 0.5);
    EXPECT_NEAR(MedianValidDepthMm(frame.depth), 1540.0, 500.0);
  }
  const SourceStats stats = source->stats();
  EXPECT_EQ(stats.depth_frames, 24);
  EXPECT_EQ(stats.color_frames, 23);
  EXPECT_EQ(stats.unpaired_frames, 1);
}

TEST(OpenNiSource, RealtimeReplayKeepsTheRecordedPace) {
  SIGHTMAP_REQUIRE_SHARED_DATA(path, "oni/kinect-12f.oni");
  SourceOptions options;
  options.realtime = true;
  auto source = OpenOniFile(path, options);
  const auto start = std::chrono::steady_clock::now();
  const ReadAll all = Drain(*source);
  const double elapsed_s = SecondsSince(start);
  // A busy machine can make the reader miss frames (OpenNI2 keeps a stream's newest frame only);
  // each is counted.
  const SourceStats stats = source->stats();
  EXPECT_EQ(static_cast<int64_t>(all.frames.size()) + stats.missed_depth_frames, 12);
  // A lower bound only: a busy machine can make it slower, never faster than the recording.
  EXPECT_GT(elapsed_s, 0.8 * 0.367);
}

// A reader slower than the recording misses frames, as behind a live sensor: they are counted from
// the gaps in the frame numbers, and the replay still ends at the end of the file, not with a
// "truncated" error for the frames it never saw.
TEST(OpenNiSource, ARealtimeReaderThatFallsBehindCountsTheFramesItMissed) {
  SIGHTMAP_REQUIRE_SHARED_DATA(path, "oni/kinect-12f.oni");
  SourceOptions options;
  options.realtime = true;
  auto source = OpenOniFile(path, options);
  int64_t frames = 0;
  while (source->Next()) {
    ++frames;
    // Four frame periods behind after the second frame.
    if (frames == 2) std::this_thread::sleep_for(std::chrono::milliseconds(140));
  }
  const SourceStats stats = source->stats();
  EXPECT_GE(stats.missed_depth_frames, 2);
  EXPECT_GE(stats.missed_color_frames, 2);
  EXPECT_EQ(frames + stats.missed_depth_frames + stats.unpaired_frames, 12);
  EXPECT_EQ(stats.depth_frames + stats.missed_depth_frames, 12);
  EXPECT_EQ(stats.color_frames + stats.missed_color_frames, 12);
}

// Every bad input gives a one-line Error quickly: no crash, no hang.
void ExpectRefused(const std::string& path, const std::string& fragment) {
  const auto start = std::chrono::steady_clock::now();
  try {
    auto source = OpenOniFile(path, SourceOptions());
    while (source->Next()) {
    }
    ADD_FAILURE() << path << " was accepted";
  } catch (const Error& e) {
    const std::string message = e.what();
    EXPECT_EQ(message.find('\n'), std::string::npos) << message;
    EXPECT_NE(message.find(fragment), std::string::npos) << message;
  }
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(10)) << path;
}

TEST(OpenNiSource, RefusesRecordingsOpenNi2CannotPlay) {
  SIGHTMAP_REQUIRE_SHARED_DATA(legacy, "oni/legacy-v1-40f.oni");
  SIGHTMAP_REQUIRE_SHARED_DATA(header_only, "oni/header-only-0f.oni");
  ExpectRefused(legacy, "ONI 1.0.0");
  ExpectRefused(header_only, "holds no frames");
}

TEST(OpenNiSource, RefusesBrokenFiles) {
  SIGHTMAP_REQUIRE_SHARED_DATA(good, "oni/kinect-12f.oni");
  const std::string dir = testing::MakeTempDir("broken");

  // A good recording cut in half, as an interrupted copy leaves it.
  std::ifstream in(good, std::ios::binary);
  std::vector<char> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::ofstream(dir + "/truncated.oni", std::ios::binary)
      .write(bytes.data(), static_cast<std::streamsize>(bytes.size() / 2));
  ExpectRefused(dir + "/truncated.oni", "truncated");

  std::ofstream(dir + "/empty.oni").close();
  ExpectRefused(dir + "/empty.oni", "empty");

  cv::Mat picture(48, 64, CV_8UC3, cv::Scalar(10, 200, 30));
  ASSERT_TRUE(cv::imwrite(dir + "/photo.jpg", picture));
  std::filesystem::rename(dir + "/photo.jpg", dir + "/photo.oni");
  ExpectRefused(dir + "/photo.oni", "not an OpenNI recording");

  ExpectRefused(dir + "/missing.oni", "no such recording");
  ExpectRefused(dir, "not a file");
}

TEST(OpenNiSource, LiveDevicePathRunsOnOpenNisDummyDriver) {
  // Debian's libopenni2-0 ships a real OpenNI2 driver, DummyDevice, that streams a synthetic
  // 320x240 scene: it exercises the live path (mode choice, mirroring, sync, pairing) without a
  // sensor.
  auto source = OpenOpenNiDevice("Dummy", SourceOptions());
  const SourceMetadata& meta = source->metadata();
  EXPECT_EQ(meta.kind, "openni");
  EXPECT_EQ(meta.uri, "Dummy");
  EXPECT_EQ(meta.depth_width, 320);
  EXPECT_EQ(meta.color_width, 320);
  EXPECT_FALSE(meta.depth_frame_count.has_value());
  bool notes_mode = false;
  bool notes_fov = false;
  for (const std::string& note : meta.notes) {
    notes_mode |= note.find("has no 640x480 @ 30 Hz mode") != std::string::npos;
    notes_fov |= note.find("no field of view reported") != std::string::npos;
  }
  EXPECT_TRUE(notes_mode);
  EXPECT_TRUE(notes_fov);
  TimestampNs last = -1;
  for (int i = 0; i < 5; ++i) {
    const auto frame = source->Next();
    ASSERT_TRUE(frame.has_value());
    EXPECT_GT(frame->timestamp_ns, last);
    last = frame->timestamp_ns;
    EXPECT_EQ(frame->depth.size(), cv::Size(320, 240));
    EXPECT_EQ(frame->color.size(), cv::Size(320, 240));
  }
}

TEST(OpenNiSource, NoSensorAttachedSaysWhatToDo) {
  {
    auto runtime = OpenNiRuntime::Acquire();
    openni::Array<openni::DeviceInfo> devices;
    openni::OpenNI::enumerateDevices(&devices);
    if (devices.getSize() > 0) GTEST_SKIP() << "a sensor is attached to this machine";
  }
  try {
    OpenOpenNiDevice("", SourceOptions());
    ADD_FAILURE() << "opened a device that is not there";
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "no RGB-D sensor found — run 'sightmap devices'");
  }
  EXPECT_THROW(OpenOpenNiDevice("usb://no/such/device", SourceOptions()), Error);
}

}  // namespace
}  // namespace sightmap::capture
