#include "capture/usb_sensors.h"

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <optional>
#include <regex>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "capture/devices_report.h"
#include "core/check.h"
#include "tests/test_data.h"

namespace sightmap::capture {
namespace {

using UsbId = std::pair<uint16_t, uint16_t>;

struct UdevRule {
  int line = 0;
  std::string comment_above;                       // the comment line directly above, "" if none
  std::map<std::string, std::string> assignments;  // "KEY op" -> value, e.g. "MODE=" -> "0660"
};

// Parses `KEY op "value"` pairs of every rule line; comments and blank lines carry no rule.
std::vector<UdevRule> ReadUdevRules(const std::string& path) {
  std::ifstream in(path);
  EXPECT_TRUE(in.good()) << "cannot read " << path;
  const std::regex pair_regex(
      R"re(\s*([A-Za-z_]+(?:\{[A-Za-z_]+\})?)\s*(==|!=|\+=|:=|=)\s*"([^"]*)"\s*)re");
  std::vector<UdevRule> rules;
  std::string line;
  std::string previous;
  int number = 0;
  while (std::getline(in, line)) {
    ++number;
    const std::string trimmed = line.substr(0, line.find_last_not_of(" \t\r") + 1);
    if (trimmed.empty() || trimmed.front() == '#') {
      previous = trimmed;
      continue;
    }
    UdevRule rule;
    rule.line = number;
    rule.comment_above = (!previous.empty() && previous.front() == '#') ? previous : "";
    size_t start = 0;
    while (start <= trimmed.size()) {
      const size_t comma = trimmed.find(',', start);
      const std::string field =
          trimmed.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
      std::smatch match;
      EXPECT_TRUE(std::regex_match(field, match, pair_regex))
          << path << ":" << number << ": cannot parse '" << field << "'";
      if (!match.empty()) {
        const std::string key = match[1].str() + match[2].str();
        EXPECT_EQ(rule.assignments.count(key), 0u) << path << ":" << number << ": repeats " << key;
        rule.assignments[key] = match[3].str();
      }
      if (comma == std::string::npos) break;
      start = comma + 1;
    }
    rules.push_back(std::move(rule));
    previous = trimmed;
  }
  return rules;
}

uint16_t ParseHexId(const std::string& text) {
  EXPECT_TRUE(std::regex_match(text, std::regex("[0-9a-f]{4}"))) << "bad USB ID '" << text << "'";
  return static_cast<uint16_t>(std::stoul(text, nullptr, 16));
}

TEST(UdevRules, MatchTheTableBothWays) {
  const std::vector<UdevRule> rules = ReadUdevRules(SIGHTMAP_UDEV_RULES_FILE);
  ASSERT_FALSE(rules.empty());
  std::set<UsbId> rule_ids;
  for (const UdevRule& rule : rules) {
    SCOPED_TRACE("rules line " + std::to_string(rule.line));
    const auto value = [&](const std::string& key) {
      const auto it = rule.assignments.find(key);
      return it == rule.assignments.end() ? std::string("<missing>") : it->second;
    };
    EXPECT_EQ(value("SUBSYSTEM=="), "usb");
    EXPECT_EQ(value("MODE="), "0660");
    EXPECT_EQ(value("GROUP="), "plugdev");
    EXPECT_EQ(value("TAG+="), "uaccess");
    EXPECT_EQ(rule.assignments.size(), 6u) << "a rule has exactly the six expected keys";
    EXPECT_FALSE(rule.comment_above.empty())
        << "each rule is preceded by a comment naming the model";
    const UsbId id{ParseHexId(value("ATTR{idVendor}==")), ParseHexId(value("ATTR{idProduct}=="))};
    EXPECT_TRUE(rule_ids.insert(id).second)
        << "duplicate rule for " << FormatUsbId(id.first, id.second);
    EXPECT_NE(FindKnownSensor(id.first, id.second), nullptr)
        << "the rules grant " << FormatUsbId(id.first, id.second)
        << ", which KnownRgbdSensors() does not list";
  }
  for (const KnownSensor& sensor : KnownRgbdSensors()) {
    EXPECT_EQ(rule_ids.count({sensor.vendor_id, sensor.product_id}), 1u)
        << "no udev rule for " << FormatUsbId(sensor.vendor_id, sensor.product_id) << " ("
        << sensor.model << ")";
  }
  EXPECT_EQ(rule_ids.size(), KnownRgbdSensors().size());
}

TEST(UdevRules, CoverDebiansOpenNi2Rules) {
  // Everything Debian's libopenni2-0 grants access to is a sensor sightmap should know.
  const std::string debian_rules = "/lib/udev/rules.d/60-libopenni2-0.rules";
  if (!std::filesystem::exists(debian_rules)) GTEST_SKIP() << debian_rules << " not installed";
  std::ifstream in(debian_rules);
  const std::regex id_regex(
      R"re(ATTR\{idProduct\}=="([0-9a-f]{4})", ATTR\{idVendor\}=="([0-9a-f]{4})")re");
  std::string line;
  int found = 0;
  while (std::getline(in, line)) {
    std::smatch match;
    if (!std::regex_search(line, match, id_regex)) continue;
    ++found;
    const uint16_t product = ParseHexId(match[1]);
    const uint16_t vendor = ParseHexId(match[2]);
    EXPECT_NE(FindKnownSensor(vendor, product), nullptr)
        << FormatUsbId(vendor, product) << " from " << debian_rules;
  }
  EXPECT_GT(found, 0);
}

TEST(KnownSensors, TableIsSortedUniqueAndConsistent) {
  const std::vector<KnownSensor>& table = KnownRgbdSensors();
  ASSERT_FALSE(table.empty());
  for (size_t i = 0; i < table.size(); ++i) {
    const KnownSensor& sensor = table[i];
    SCOPED_TRACE(FormatUsbId(sensor.vendor_id, sensor.product_id));
    if (i > 0) {
      EXPECT_LT(std::make_pair(table[i - 1].vendor_id, table[i - 1].product_id),
                std::make_pair(sensor.vendor_id, sensor.product_id));
    }
    EXPECT_TRUE(sensor.vendor_id == 0x045e || sensor.vendor_id == 0x1d27);
    EXPECT_NE(std::string(sensor.model), "");
    EXPECT_NE(std::string(sensor.family), "");
    // Only Kinect cameras need libfreenect's driver, and every Kinect camera does.
    EXPECT_EQ(sensor.openni2_needs_freenect_driver,
              sensor.vendor_id == 0x045e && sensor.role == UsbSensorRole::kCamera);
    if (sensor.role != UsbSensorRole::kCamera) {
      EXPECT_STREQ(sensor.openni2_driver, "");
    }
    if (sensor.vendor_id == 0x1d27) {
      EXPECT_EQ(sensor.role, UsbSensorRole::kCamera);
    }
  }
}

TEST(KnownSensors, Lookup) {
  const KnownSensor* kinect = FindKnownSensor(0x045e, 0x02ae);
  ASSERT_NE(kinect, nullptr);
  EXPECT_EQ(kinect->role, UsbSensorRole::kCamera);
  EXPECT_TRUE(kinect->openni2_needs_freenect_driver);
  EXPECT_STREQ(kinect->family, "Kinect v1");

  const KnownSensor* motor = FindKnownSensor(0x045e, 0x02b0);
  ASSERT_NE(motor, nullptr);
  EXPECT_EQ(motor->role, UsbSensorRole::kMotor);
  EXPECT_EQ(FindKnownSensor(0x045e, 0x02ad)->role, UsbSensorRole::kAudio);

  const KnownSensor* xtion = FindKnownSensor(0x1d27, 0x0601);
  ASSERT_NE(xtion, nullptr);
  EXPECT_STREQ(xtion->openni2_driver, "PS1080");
  EXPECT_FALSE(xtion->openni2_needs_freenect_driver);
  EXPECT_NE(std::string(xtion->model).find("Xtion"), std::string::npos);
  EXPECT_NE(std::string(FindKnownSensor(0x1d27, 0x0600)->model).find("Carmine"), std::string::npos);

  EXPECT_EQ(FindKnownSensor(0x046d, 0x085b), nullptr);  // a webcam
  EXPECT_EQ(FindKnownSensor(0x045e, 0x02d9), nullptr);  // Kinect v2: not an OpenNI2 sensor
  EXPECT_EQ(FormatUsbId(0x045e, 0x02ae), "045e:02ae");
  EXPECT_EQ(FormatUsbId(0x1d27, 0xf9db), "1d27:f9db");
  EXPECT_STREQ(ToString(UsbSensorRole::kMotor), "motor");
}

TEST(KnownSensors, ParsesPrimeSenseUris) {
  const std::optional<UsbBusAddress> where = ParseOpenNiUsbUri("1d27/0601@1/7");
  ASSERT_TRUE(where.has_value());
  EXPECT_EQ(where->bus, 1);
  EXPECT_EQ(where->address, 7);
  EXPECT_FALSE(ParseOpenNiUsbUri("freenect://0").has_value());
  EXPECT_FALSE(ParseOpenNiUsbUri("1d27/0601@1/7/extra").has_value());
  EXPECT_FALSE(ParseOpenNiUsbUri("").has_value());
}

TEST(UsbEnumeration, RunsWithoutSensorsOrUsbAccess) {
  std::vector<std::string> notes;
  std::vector<UsbSensor> sensors;
  ASSERT_NO_THROW(sensors = EnumerateUsbSensors(&notes));
  for (const UsbSensor& sensor : sensors) {
    EXPECT_NE(FindKnownSensor(sensor.vendor_id, sensor.product_id), nullptr);
    EXPECT_EQ(sensor.accessible, sensor.open_error.empty());
  }
  for (const std::string& note : notes) std::cout << "note: " << note << "\n";
  EXPECT_NO_THROW(EnumerateUsbSensors());  // notes are optional
}

TEST(UsbEnumeration, ScanDevicesReportsThisMachine) {
  DevicesReport report;
  ASSERT_NO_THROW(report = ScanDevices());
  const std::string text = FormatDevicesReport(report);
  std::cout << text;
  if (report.sensors.empty()) {
    EXPECT_NE(text.find("no RGB-D sensor found"), std::string::npos);
  }
  EXPECT_FALSE(report.openni_drivers_dir.empty());
  EXPECT_TRUE(DevicesReportToJson(report).contains("sensors"));
}

TEST(OpenNiListing, DriversDirIsWhereDebiansDriversAre) {
  const std::string dir = OpenNiDriversDir();
  EXPECT_NE(dir.find("OpenNI2"), std::string::npos) << dir;
  if (!std::filesystem::exists("/usr/lib/x86_64-linux-gnu/OpenNI2/Drivers/libPS1080.so.0")) {
    GTEST_SKIP() << "Debian's libopenni2-0 is not installed";
  }
  EXPECT_TRUE(std::filesystem::exists(std::filesystem::path(dir) / "libPS1080.so.0")) << dir;
  EXPECT_EQ(FindFreenectDriver("/nonexistent"), FreenectDriverState::kMissing);
}

TEST(OpenNiListing, ListsWithoutThrowingOrSaysWhy) {
  try {
    const std::vector<OpenNiDeviceInfo> devices = ListOpenNiDevices();
    for (const OpenNiDeviceInfo& device : devices) EXPECT_FALSE(device.uri.empty());
  } catch (const Error& error) {
    // Allowed: OpenNI2 may fail to initialise in a stripped-down environment.
    EXPECT_NE(std::string(error.what()), "");
  }
}

// --- BuildDevicesReport, fed with hand-made listings: stand-ins for hardware not plugged in ---

UsbSensor MakeUsb(uint16_t vendor, uint16_t product, uint8_t bus, uint8_t address,
                  std::vector<uint8_t> ports, const std::string& open_error = "") {
  const KnownSensor* known = FindKnownSensor(vendor, product);
  EXPECT_NE(known, nullptr);
  UsbSensor sensor;
  sensor.vendor_id = vendor;
  sensor.product_id = product;
  sensor.bus = bus;
  sensor.address = address;
  sensor.port_path = std::move(ports);
  sensor.model = known->model;
  sensor.family = known->family;
  sensor.role = known->role;
  sensor.accessible = open_error.empty();
  sensor.open_error = open_error;
  sensor.permission_denied = open_error == "LIBUSB_ERROR_ACCESS";
  return sensor;
}

OpenNiDeviceInfo MakeOpenNi(const std::string& uri, uint16_t vendor, uint16_t product,
                            const std::string& name = "PS1080",
                            const std::string& vendor_name = "PrimeSense") {
  return {uri, name, vendor_name, vendor, product};
}

std::vector<UsbSensor> AKinect(const std::string& camera_error = "") {
  // Camera, audio and motor on the Kinect's internal hub behind port 1-4.
  return {MakeUsb(0x045e, 0x02ae, 1, 9, {4, 2}, camera_error),
          MakeUsb(0x045e, 0x02ad, 1, 10, {4, 3}), MakeUsb(0x045e, 0x02b0, 1, 8, {4, 1})};
}

bool Contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

TEST(DevicesReport, NoSensorSaysSoWithAHint) {
  const DevicesReport report = BuildDevicesReport({}, {});
  EXPECT_TRUE(report.sensors.empty());
  const std::string text = FormatDevicesReport(report);
  EXPECT_TRUE(Contains(text, "no RGB-D sensor found")) << text;
  EXPECT_TRUE(Contains(text, "lsusb")) << text;
  const nlohmann::json json = DevicesReportToJson(report);
  EXPECT_TRUE(json.at("sensors").is_array());
  EXPECT_TRUE(json.at("sensors").empty());
  EXPECT_TRUE(json.at("openni_devices").empty());
}

TEST(DevicesReport, XtionListedHasNoProblems) {
  const DevicesReport report = BuildDevicesReport({MakeUsb(0x1d27, 0x0601, 2, 5, {1})},
                                                  {MakeOpenNi("1d27/0601@2/5", 0x1d27, 0x0601)});
  ASSERT_EQ(report.sensors.size(), 1u);
  const SensorStatus& xtion = report.sensors[0];
  EXPECT_TRUE(xtion.ready());
  EXPECT_TRUE(xtion.problems.empty());
  EXPECT_TRUE(xtion.accessible);
  EXPECT_TRUE(xtion.openni_listed);
  EXPECT_EQ(xtion.openni_uri, "1d27/0601@2/5");
  EXPECT_TRUE(report.openni_devices.at(0).usb_matched);
  const std::string text = FormatDevicesReport(report);
  EXPECT_TRUE(Contains(text, "ready")) << text;
  EXPECT_FALSE(Contains(text, "problem")) << text;
  EXPECT_FALSE(Contains(text, "no RGB-D sensor found")) << text;
}

TEST(DevicesReport, MissingPermissionAsksForTheUdevRules) {
  const DevicesReport report =
      BuildDevicesReport({MakeUsb(0x1d27, 0x0600, 1, 7, {2}, "LIBUSB_ERROR_ACCESS")},
                         {MakeOpenNi("1d27/0600@1/7", 0x1d27, 0x0600)});
  ASSERT_EQ(report.sensors.size(), 1u);
  const SensorStatus& sensor = report.sensors[0];
  EXPECT_FALSE(sensor.ready());
  EXPECT_FALSE(sensor.accessible);
  EXPECT_TRUE(sensor.openni_listed);  // PS1080 lists devices it may not open
  ASSERT_EQ(sensor.problems.size(), 1u);
  EXPECT_TRUE(Contains(sensor.problems[0].problem, "may not open")) << sensor.problems[0].problem;
  const std::string& fix = sensor.problems[0].fix;
  EXPECT_TRUE(Contains(fix,
                       "sudo cmake --install build --component udev && sudo udevadm control "
                       "--reload-rules && sudo udevadm trigger"))
      << fix;
  EXPECT_TRUE(Contains(fix, "replug")) << fix;
  EXPECT_TRUE(Contains(fix, "plugdev")) << fix;
  EXPECT_TRUE(Contains(FormatDevicesReport(report), "no permission"));
}

TEST(DevicesReport, KinectNotListedNeedsTheFreenectDriver) {
  DevicesEnvironment environment;
  environment.openni_drivers_dir = "/usr/lib/x86_64-linux-gnu/OpenNI2/Drivers";
  const DevicesReport report = BuildDevicesReport(AKinect(), {}, environment);
  // Audio and motor are folded into the camera's sensor.
  ASSERT_EQ(report.sensors.size(), 1u);
  const SensorStatus& kinect = report.sensors[0];
  EXPECT_EQ(kinect.product_id, 0x02ae);
  EXPECT_TRUE(kinect.camera_present);
  ASSERT_EQ(kinect.usb_devices.size(), 3u);
  EXPECT_EQ(kinect.usb_devices[0].role, UsbSensorRole::kCamera);
  EXPECT_TRUE(kinect.accessible);
  EXPECT_FALSE(kinect.openni_listed);
  ASSERT_EQ(kinect.problems.size(), 1u);
  EXPECT_TRUE(Contains(kinect.problems[0].problem, "libFreenectDriver.so"));
  EXPECT_TRUE(Contains(kinect.problems[0].problem, "Debian does not ship"));
  const std::string& fix = kinect.problems[0].fix;
  EXPECT_TRUE(Contains(fix, "-DBUILD_OPENNI2_DRIVER=ON")) << fix;
  EXPECT_TRUE(Contains(fix, "/usr/lib/x86_64-linux-gnu/OpenNI2/Drivers/libFreenectDriver.so.0"))
      << fix;
}

TEST(DevicesReport, FreenectDriverUnderANameDebianIgnores) {
  DevicesEnvironment environment;
  environment.freenect_driver = FreenectDriverState::kMisnamed;
  const DevicesReport report = BuildDevicesReport(AKinect(), {}, environment);
  ASSERT_EQ(report.sensors.at(0).problems.size(), 1u);
  EXPECT_TRUE(Contains(report.sensors[0].problems[0].problem, "lib*.so.0"));
  EXPECT_TRUE(Contains(report.sensors[0].problems[0].fix, "libFreenectDriver.so.0"));
}

TEST(OpenNiListing, FindsTheFreenectDriverOnlyUnderItsLoadableName) {
  const std::filesystem::path dir = testing::MakeTempDir("Drivers");
  EXPECT_EQ(FindFreenectDriver(dir.string()), FreenectDriverState::kMissing);
  std::ofstream(dir / "libPS1080.so.0") << "x";
  std::ofstream(dir / "libFreenectDriver.so") << "x";
  EXPECT_EQ(FindFreenectDriver(dir.string()), FreenectDriverState::kMisnamed);
  std::ofstream(dir / "libFreenectDriver.so.0") << "x";
  EXPECT_EQ(FindFreenectDriver(dir.string()), FreenectDriverState::kInstalled);
}

TEST(DevicesReport, KinectWithoutPermissionGetsBothProblems) {
  const DevicesReport report = BuildDevicesReport(AKinect("LIBUSB_ERROR_ACCESS"), {});
  ASSERT_EQ(report.sensors.size(), 1u);
  ASSERT_EQ(report.sensors[0].problems.size(), 2u);
  EXPECT_TRUE(Contains(report.sensors[0].problems[0].fix, "--component udev"));
  EXPECT_TRUE(Contains(report.sensors[0].problems[1].fix, "-DBUILD_OPENNI2_DRIVER=ON"));
}

TEST(DevicesReport, KinectListedByAnOldFreenectDriverWithoutUsbIds) {
  DevicesEnvironment environment;
  environment.freenect_driver = FreenectDriverState::kInstalled;
  const DevicesReport report = BuildDevicesReport(
      AKinect(), {MakeOpenNi("freenect://0", 0, 0, "Kinect", "Microsoft")}, environment);
  ASSERT_EQ(report.sensors.size(), 1u);
  EXPECT_TRUE(report.sensors[0].ready());
  EXPECT_EQ(report.sensors[0].openni_uri, "freenect://0");
}

TEST(DevicesReport, KinectUnlistedDespiteInstalledDriver) {
  DevicesEnvironment environment;
  environment.freenect_driver = FreenectDriverState::kInstalled;
  const DevicesReport report = BuildDevicesReport(AKinect(), {}, environment);
  ASSERT_EQ(report.sensors.at(0).problems.size(), 1u);
  EXPECT_TRUE(Contains(report.sensors[0].problems[0].problem, "although libFreenectDriver"));
  EXPECT_FALSE(Contains(report.sensors[0].problems[0].fix, "BUILD_OPENNI2_DRIVER"));
}

TEST(DevicesReport, KinectWithoutPowerShowsOnlyItsMotor) {
  const DevicesReport report = BuildDevicesReport({MakeUsb(0x045e, 0x02b0, 1, 8, {4, 1})}, {});
  ASSERT_EQ(report.sensors.size(), 1u);
  const SensorStatus& kinect = report.sensors[0];
  EXPECT_FALSE(kinect.camera_present);
  EXPECT_FALSE(kinect.openni_listed);
  ASSERT_EQ(kinect.problems.size(), 1u);
  EXPECT_TRUE(Contains(kinect.problems[0].fix, "power adapter")) << kinect.problems[0].fix;
  EXPECT_FALSE(Contains(FormatDevicesReport(report), "no RGB-D sensor found"));
}

TEST(DevicesReport, TwoKinectsKeepTheirOwnParts) {
  std::vector<UsbSensor> usb = AKinect();
  usb.push_back(MakeUsb(0x045e, 0x02ae, 2, 4, {1, 2}));
  usb.push_back(MakeUsb(0x045e, 0x02b0, 2, 3, {1, 1}));
  const DevicesReport report = BuildDevicesReport(usb, {});
  ASSERT_EQ(report.sensors.size(), 2u);
  EXPECT_EQ(report.sensors[0].usb_devices.size(), 3u);
  ASSERT_EQ(report.sensors[1].usb_devices.size(), 2u);
  EXPECT_EQ(report.sensors[1].usb_devices[1].bus, 2);
}

TEST(DevicesReport, SameModelsAreMatchedByBusAndAddress) {
  const DevicesReport report = BuildDevicesReport(
      {MakeUsb(0x1d27, 0x0600, 1, 3, {1}), MakeUsb(0x1d27, 0x0600, 1, 9, {2})},
      {MakeOpenNi("1d27/0600@1/9", 0x1d27, 0x0600), MakeOpenNi("1d27/0600@1/3", 0x1d27, 0x0600)});
  ASSERT_EQ(report.sensors.size(), 2u);
  EXPECT_EQ(report.sensors[0].openni_uri, "1d27/0600@1/3");
  EXPECT_EQ(report.sensors[1].openni_uri, "1d27/0600@1/9");
}

TEST(DevicesReport, OpenNiDevicesWithoutUsbMatchAreStillShown) {
  const DevicesReport report =
      BuildDevicesReport({}, {MakeOpenNi("1d27/0600@3/4", 0x1d27, 0x0600)});
  ASSERT_EQ(report.openni_devices.size(), 1u);
  EXPECT_FALSE(report.openni_devices[0].usb_matched);
  const std::string text = FormatDevicesReport(report);
  EXPECT_TRUE(Contains(text, "1d27/0600@3/4")) << text;
  EXPECT_FALSE(DevicesReportToJson(report)["openni_devices"][0]["usb_matched"].get<bool>());
}

TEST(DevicesReport, UnsupportedPrimeSenseIdSaysNoDriver) {
  const DevicesReport report = BuildDevicesReport({MakeUsb(0x1d27, 0x2100, 1, 2, {3})}, {});
  ASSERT_EQ(report.sensors.at(0).problems.size(), 1u);
  EXPECT_TRUE(Contains(report.sensors[0].problems[0].problem, "No OpenNI2 driver supports"));
}

TEST(DevicesReport, BrokenOpenNiIsANoteNotASensorProblem) {
  DevicesEnvironment environment;
  environment.openni_available = false;
  environment.notes.push_back("OpenNI2 failed to initialise");
  const DevicesReport report = BuildDevicesReport(AKinect(), {}, environment);
  EXPECT_TRUE(report.sensors.at(0).problems.empty());
  const std::string text = FormatDevicesReport(report);
  EXPECT_TRUE(Contains(text, "not checked")) << text;
  EXPECT_TRUE(Contains(text, "note: OpenNI2 failed to initialise")) << text;
}

TEST(DevicesReport, JsonKeys) {
  DevicesEnvironment environment;
  environment.notes.push_back("a note");
  UsbSensor xtion = MakeUsb(0x1d27, 0x0601, 2, 5, {1, 3}, "LIBUSB_ERROR_ACCESS");
  const DevicesReport report = BuildDevicesReport(
      {xtion}, {MakeOpenNi("1d27/0601@2/5", 0x1d27, 0x0601), MakeOpenNi("other", 0, 0)},
      environment);
  const nlohmann::json json = DevicesReportToJson(report);
  for (const char* key : {"sensors", "openni_devices", "notes", "openni_available",
                          "openni_drivers_dir", "freenect_driver"}) {
    EXPECT_TRUE(json.contains(key)) << key;
  }
  ASSERT_EQ(json["sensors"].size(), 1u);
  const nlohmann::json& sensor = json["sensors"][0];
  EXPECT_EQ(sensor["vendor_id"], "1d27");
  EXPECT_EQ(sensor["product_id"], "0601");
  EXPECT_EQ(sensor["family"], "PrimeSense");
  EXPECT_EQ(sensor["model"], xtion.model);
  EXPECT_EQ(sensor["bus"], 2);
  EXPECT_EQ(sensor["address"], 5);
  EXPECT_EQ(sensor["location"], "2-1.3");
  EXPECT_EQ(sensor["accessible"], false);
  EXPECT_EQ(sensor["openni_listed"], true);
  EXPECT_EQ(sensor["openni_uri"], "1d27/0601@2/5");
  EXPECT_EQ(sensor["status"], "not ready");
  ASSERT_EQ(sensor["problems"].size(), 1u);
  EXPECT_TRUE(sensor["problems"][0].contains("problem"));
  EXPECT_TRUE(sensor["problems"][0].contains("fix"));
  ASSERT_EQ(sensor["usb_devices"].size(), 1u);
  EXPECT_EQ(sensor["usb_devices"][0]["role"], "camera");
  EXPECT_EQ(sensor["usb_devices"][0]["open_error"], "LIBUSB_ERROR_ACCESS");
  ASSERT_EQ(json["openni_devices"].size(), 2u);
  EXPECT_EQ(json["openni_devices"][0]["usb_matched"], true);
  EXPECT_EQ(json["openni_devices"][1]["usb_matched"], false);
  EXPECT_EQ(json["openni_devices"][1]["uri"], "other");
  EXPECT_EQ(json["notes"][0], "a note");
}

}  // namespace
}  // namespace sightmap::capture
