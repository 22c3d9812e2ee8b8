#include "capture/devices_report.h"

#include <map>
#include <optional>
#include <sstream>
#include <tuple>
#include <utility>

#include <nlohmann/json.hpp>

#include "core/check.h"

namespace sightmap::capture {

const char* const kInstallUdevRulesCommand =
    "sudo cmake --install build --component udev && sudo udevadm control --reload-rules && "
    "sudo udevadm trigger";

namespace {

constexpr uint16_t kMicrosoftVendorId = 0x045e;

bool IsKinect(const UsbSensor& device) { return device.vendor_id == kMicrosoftVendorId; }

std::vector<uint8_t> ParentPorts(const UsbSensor& device) {
  if (device.port_path.empty()) return {};
  return std::vector<uint8_t>(device.port_path.begin(), device.port_path.end() - 1);
}

// Devices of one Kinect hang off the Kinect's internal hub: same bus, same parent port path.
bool SameParentHub(const UsbSensor& a, const UsbSensor& b) {
  return a.bus == b.bus && !a.port_path.empty() && !b.port_path.empty() &&
         ParentPorts(a) == ParentPorts(b);
}

std::string DeviceLabel(const UsbSensor& device) {
  return std::string(ToString(device.role)) + " " +
         FormatUsbId(device.vendor_id, device.product_id) + " at " + UsbLocation(device);
}

std::string JoinLabels(const std::vector<const UsbSensor*>& devices) {
  std::string text;
  for (size_t i = 0; i < devices.size(); ++i) {
    if (i > 0) text += (i + 1 == devices.size()) ? " and " : ", ";
    text += DeviceLabel(*devices[i]);
  }
  return text;
}

SensorStatus NewSensor(const UsbSensor& first) {
  SensorStatus sensor;
  sensor.vendor_id = first.vendor_id;
  sensor.product_id = first.product_id;
  sensor.family = first.family;
  sensor.camera_present = first.role == UsbSensorRole::kCamera;
  sensor.model = sensor.camera_present ? first.model : "Kinect v1 without its camera on USB";
  sensor.usb_devices.push_back(first);
  return sensor;
}

// Groups the USB devices into sensors: one per camera, with each Kinect audio/motor device folded
// into the Kinect camera beside it; leftover Kinect parts form camera-less sensors per hub.
std::vector<SensorStatus> GroupSensors(const std::vector<UsbSensor>& usb) {
  std::vector<SensorStatus> sensors;
  for (const UsbSensor& device : usb) {
    if (device.role == UsbSensorRole::kCamera) sensors.push_back(NewSensor(device));
  }
  const size_t camera_count = sensors.size();
  std::map<std::tuple<uint8_t, std::vector<uint8_t>>, size_t> orphan_groups;
  for (const UsbSensor& device : usb) {
    if (device.role == UsbSensorRole::kCamera) continue;
    std::optional<size_t> owner;
    for (size_t i = 0; i < camera_count && !owner; ++i) {
      if (IsKinect(sensors[i].usb_devices.front()) &&
          SameParentHub(sensors[i].usb_devices.front(), device)) {
        owner = i;
      }
    }
    if (!owner && device.port_path.empty()) {
      // Without port paths (unusual platforms) libfreenect also pairs by bus when that is
      // unambiguous.
      std::vector<size_t> on_bus;
      for (size_t i = 0; i < camera_count; ++i) {
        const UsbSensor& camera = sensors[i].usb_devices.front();
        if (IsKinect(camera) && camera.bus == device.bus) on_bus.push_back(i);
      }
      if (on_bus.size() == 1) owner = on_bus.front();
    }
    if (!owner) {
      const auto key = std::make_tuple(device.bus, ParentPorts(device));
      const auto group = orphan_groups.find(key);
      if (group == orphan_groups.end()) {
        orphan_groups[key] = sensors.size();
        sensors.push_back(NewSensor(device));
        continue;
      }
      owner = group->second;
    }
    sensors[*owner].usb_devices.push_back(device);
  }
  return sensors;
}

// Assigns OpenNI2 entries to camera sensors; returns which entries were used.
std::vector<bool> MatchOpenNi(const std::vector<OpenNiDeviceInfo>& openni,
                              std::vector<SensorStatus>* sensors) {
  std::vector<bool> used(openni.size(), false);
  auto assign = [&](SensorStatus& sensor, size_t entry) {
    used[entry] = true;
    sensor.openni_listed = true;
    sensor.openni_uri = openni[entry].uri;
  };
  auto same_ids = [](const OpenNiDeviceInfo& info, const UsbSensor& camera) {
    return info.usb_vendor_id == camera.vendor_id && info.usb_product_id == camera.product_id;
  };
  // 1. The PrimeSense drivers name the exact USB device in their URI.
  for (SensorStatus& sensor : *sensors) {
    if (!sensor.camera_present) continue;
    const UsbSensor& camera = sensor.usb_devices.front();
    for (size_t e = 0; e < openni.size() && !sensor.openni_listed; ++e) {
      const std::optional<UsbBusAddress> where = ParseOpenNiUsbUri(openni[e].uri);
      if (!used[e] && where && where->bus == camera.bus && where->address == camera.address &&
          (openni[e].usb_vendor_id == 0 || same_ids(openni[e], camera))) {
        assign(sensor, e);
      }
    }
  }
  // 2. Same vendor:product, unless the URI names a different USB device.
  for (SensorStatus& sensor : *sensors) {
    if (!sensor.camera_present || sensor.openni_listed) continue;
    const UsbSensor& camera = sensor.usb_devices.front();
    for (size_t e = 0; e < openni.size() && !sensor.openni_listed; ++e) {
      if (!used[e] && same_ids(openni[e], camera) && !ParseOpenNiUsbUri(openni[e].uri)) {
        assign(sensor, e);
      }
    }
  }
  // 3. A freenect URI without USB IDs can only be a Kinect camera.
  for (SensorStatus& sensor : *sensors) {
    if (!sensor.camera_present || sensor.openni_listed || !IsKinect(sensor.usb_devices.front())) {
      continue;
    }
    for (size_t e = 0; e < openni.size() && !sensor.openni_listed; ++e) {
      if (!used[e] && openni[e].usb_vendor_id == 0 && openni[e].uri.rfind("freenect://", 0) == 0) {
        assign(sensor, e);
      }
    }
  }
  return used;
}

void AddProblems(const DevicesEnvironment& environment, SensorStatus* sensor) {
  std::vector<const UsbSensor*> denied;
  std::vector<const UsbSensor*> failed;
  for (const UsbSensor& device : sensor->usb_devices) {
    if (device.accessible) continue;
    (device.permission_denied ? denied : failed).push_back(&device);
  }
  sensor->accessible = denied.empty() && failed.empty();

  if (!sensor->camera_present) {
    std::vector<const UsbSensor*> parts;
    for (const UsbSensor& device : sensor->usb_devices) parts.push_back(&device);
    sensor->problems.push_back(
        {"Only the Kinect's " + JoinLabels(parts) + (parts.size() > 1 ? " are" : " is") +
             " on USB, not its camera.",
         "Connect the Kinect's own power adapter (USB alone powers only its hub and motor), then "
         "replug it."});
  }
  if (!denied.empty()) {
    sensor->problems.push_back(
        {"The current user may not open USB " + JoinLabels(denied) + " (LIBUSB_ERROR_ACCESS).",
         std::string("Install sightmap's udev rules with `") + kInstallUdevRulesCommand +
             "`, then replug the sensor and make sure you are in group plugdev "
             "(`sudo usermod -aG plugdev $USER`, then log in again)."});
  }
  for (const UsbSensor* device : failed) {
    sensor->problems.push_back(
        {"USB " + DeviceLabel(*device) + " could not be opened (" + device->open_error + ").",
         "Replug the sensor into a USB 2.0 port of the computer itself (not a hub) and check "
         "`dmesg` for USB errors."});
  }
  if (!sensor->camera_present || sensor->openni_listed || !environment.openni_available) return;

  const UsbSensor& camera = sensor->usb_devices.front();
  const std::string id = FormatUsbId(camera.vendor_id, camera.product_id);
  const KnownSensor* known = FindKnownSensor(camera.vendor_id, camera.product_id);
  if (known != nullptr && known->openni2_needs_freenect_driver) {
    const std::string copy_command =
        "sudo cp -L build/lib/OpenNI2-FreenectDriver/libFreenectDriver.so " +
        environment.openni_drivers_dir + "/libFreenectDriver.so.0";
    if (environment.freenect_driver == FreenectDriverState::kMissing) {
      sensor->problems.push_back(
          {"OpenNI2 does not list this Kinect v1: it needs the libfreenect OpenNI2 driver "
           "(libFreenectDriver.so), which Debian does not ship.",
           "Build libfreenect (https://github.com/OpenKinect/libfreenect) with "
           "-DBUILD_OPENNI2_DRIVER=ON and copy the driver into OpenNI2's Drivers folder under the "
           "only name Debian's OpenNI2 loads, lib*.so.0: `" +
               copy_command + "` (from libfreenect's folder)."});
    } else if (environment.freenect_driver == FreenectDriverState::kMisnamed) {
      sensor->problems.push_back(
          {"OpenNI2 does not list this Kinect v1: libFreenectDriver is in " +
               environment.openni_drivers_dir +
               " but not as libFreenectDriver.so.0, and Debian's OpenNI2 loads only lib*.so.0 "
               "files there.",
           "Copy it under that name: `" + copy_command + "` (from libfreenect's folder)."});
    } else {
      sensor->problems.push_back(
          {"OpenNI2 does not list this Kinect v1 although libFreenectDriver is installed in " +
               environment.openni_drivers_dir + ".",
           (denied.empty() ? std::string("Replug the Kinect with its power adapter connected; ")
                           : std::string("Fix the USB permission above first (the driver lists "
                                         "only Kinects it can open), then replug it; ")) +
               "if it stays unlisted, set LogToConsole=1 under [Log] in /etc/openni2/OpenNI.ini "
               "to see why the driver skipped it."});
    }
    return;
  }
  if (known != nullptr && known->openni2_driver[0] != '\0') {
    sensor->problems.push_back(
        {std::string("OpenNI2 does not list it although its ") + known->openni2_driver +
             " driver supports " + id + ".",
         (denied.empty() ? std::string("Check")
                         : std::string("Fix the USB permission above, then check")) +
             " that lib" + known->openni2_driver + ".so* is in " + environment.openni_drivers_dir +
             " (`sudo apt install --reinstall libopenni2-0` if not) and replug the sensor."});
    return;
  }
  sensor->problems.push_back(
      {"No OpenNI2 driver supports " + id + " (" + sensor->model +
           "), so OpenNI2 cannot stream from it.",
       "Use a supported sensor (Kinect v1 with libfreenect's driver, ASUS Xtion, PrimeSense "
       "Carmine), or report `lsusb -v -d " +
           id + "` to the sightmap developers."});
}

nlohmann::json UsbDeviceToJson(const UsbSensor& device) {
  return {{"vendor_id", FormatHex4(device.vendor_id)},
          {"product_id", FormatHex4(device.product_id)},
          {"role", ToString(device.role)},
          {"model", device.model},
          {"bus", device.bus},
          {"address", device.address},
          {"location", UsbLocation(device)},
          {"accessible", device.accessible},
          {"open_error", device.open_error},
          {"serial", device.serial}};
}

std::string AccessText(const UsbSensor& device) {
  if (device.accessible) return "accessible";
  if (device.permission_denied) return "no permission";
  return device.open_error;
}

}  // namespace

DevicesReport BuildDevicesReport(const std::vector<UsbSensor>& usb,
                                 const std::vector<OpenNiDeviceInfo>& openni,
                                 const DevicesEnvironment& environment) {
  DevicesReport report;
  report.openni_available = environment.openni_available;
  report.openni_drivers_dir = environment.openni_drivers_dir;
  report.freenect_driver = environment.freenect_driver;
  report.notes = environment.notes;

  report.sensors = GroupSensors(usb);
  const std::vector<bool> used = MatchOpenNi(openni, &report.sensors);
  for (SensorStatus& sensor : report.sensors) AddProblems(environment, &sensor);
  for (size_t e = 0; e < openni.size(); ++e) report.openni_devices.push_back({openni[e], used[e]});
  return report;
}

DevicesReport ScanDevices() {
  DevicesEnvironment environment;
  const std::vector<UsbSensor> usb = EnumerateUsbSensors(&environment.notes);
  std::vector<OpenNiDeviceInfo> openni;
  try {
    openni = ListOpenNiDevices();
  } catch (const Error& error) {
    environment.openni_available = false;
    environment.notes.push_back(std::string("whether OpenNI2 lists the sensors is unknown: ") +
                                error.what());
  }
  environment.openni_drivers_dir = OpenNiDriversDir();
  environment.freenect_driver = FindFreenectDriver(environment.openni_drivers_dir);
  return BuildDevicesReport(usb, openni, environment);
}

nlohmann::json DevicesReportToJson(const DevicesReport& report) {
  nlohmann::json sensors = nlohmann::json::array();
  for (const SensorStatus& sensor : report.sensors) {
    const UsbSensor& first = sensor.usb_devices.front();
    nlohmann::json usb_devices = nlohmann::json::array();
    for (const UsbSensor& device : sensor.usb_devices)
      usb_devices.push_back(UsbDeviceToJson(device));
    nlohmann::json problems = nlohmann::json::array();
    for (const DeviceProblem& problem : sensor.problems) {
      problems.push_back({{"problem", problem.problem}, {"fix", problem.fix}});
    }
    sensors.push_back({{"vendor_id", FormatHex4(sensor.vendor_id)},
                       {"product_id", FormatHex4(sensor.product_id)},
                       {"model", sensor.model},
                       {"family", sensor.family},
                       {"status", sensor.ready() ? "ready" : "not ready"},
                       {"camera_present", sensor.camera_present},
                       {"bus", first.bus},
                       {"address", first.address},
                       {"location", UsbLocation(first)},
                       {"serial", first.serial},
                       {"accessible", sensor.accessible},
                       {"openni_listed", sensor.openni_listed},
                       {"openni_uri", sensor.openni_uri},
                       {"usb_devices", std::move(usb_devices)},
                       {"problems", std::move(problems)}});
  }
  nlohmann::json openni_devices = nlohmann::json::array();
  for (const OpenNiListing& listing : report.openni_devices) {
    openni_devices.push_back({{"uri", listing.info.uri},
                              {"name", listing.info.name},
                              {"vendor", listing.info.vendor},
                              {"vendor_id", FormatHex4(listing.info.usb_vendor_id)},
                              {"product_id", FormatHex4(listing.info.usb_product_id)},
                              {"usb_matched", listing.usb_matched}});
  }
  return {{"sensors", std::move(sensors)},
          {"openni_devices", std::move(openni_devices)},
          {"openni_available", report.openni_available},
          {"openni_drivers_dir", report.openni_drivers_dir},
          {"freenect_driver", ToString(report.freenect_driver)},
          {"notes", report.notes}};
}

std::string FormatDevicesReport(const DevicesReport& report) {
  std::ostringstream out;
  if (report.sensors.empty()) {
    out << "no RGB-D sensor found on USB (looked for Kinect v1, ASUS Xtion and PrimeSense "
           "Carmine IDs)\n"
        << "  hint: plug the sensor in (a Kinect v1 also needs its power adapter), then check "
           "that `lsusb` lists it (045e:02ae Kinect, 1d27:06xx Xtion / Carmine)\n";
  }
  for (const SensorStatus& sensor : report.sensors) {
    const UsbSensor& first = sensor.usb_devices.front();
    out << sensor.model << " (" << sensor.family << ") "
        << FormatUsbId(sensor.vendor_id, sensor.product_id) << " at " << UsbLocation(first);
    if (!first.serial.empty()) out << ", serial " << first.serial;
    out << ": " << (sensor.ready() ? "ready" : "not ready") << "\n";
    out << "  USB: ";
    for (size_t i = 0; i < sensor.usb_devices.size(); ++i) {
      const UsbSensor& device = sensor.usb_devices[i];
      out << (i > 0 ? ", " : "") << ToString(device.role) << " "
          << FormatUsbId(device.vendor_id, device.product_id) << " (" << AccessText(device) << ")";
    }
    out << "\n  OpenNI2: ";
    if (sensor.openni_listed) {
      out << "listed as " << sensor.openni_uri;
    } else if (!report.openni_available) {
      out << "not checked";
    } else {
      out << "not listed";
    }
    out << "\n";
    for (const DeviceProblem& problem : sensor.problems) {
      out << "  problem: " << problem.problem << "\n"
          << "    fix: " << problem.fix << "\n";
    }
  }
  bool header_written = false;
  for (const OpenNiListing& listing : report.openni_devices) {
    if (listing.usb_matched) continue;
    if (!header_written) {
      out << "OpenNI2 also lists (no matching USB sensor found):\n";
      header_written = true;
    }
    out << "  " << listing.info.uri << ": " << listing.info.name << " (" << listing.info.vendor
        << ")";
    if (listing.info.usb_vendor_id != 0 || listing.info.usb_product_id != 0) {
      out << " " << FormatUsbId(listing.info.usb_vendor_id, listing.info.usb_product_id);
    }
    out << "\n";
  }
  for (const std::string& note : report.notes) out << "note: " << note << "\n";
  return out.str();
}

}  // namespace sightmap::capture
