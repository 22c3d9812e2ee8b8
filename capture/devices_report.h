// What `sightmap devices` reports: each RGB-D sensor on USB, whether the current user may open it,
// whether OpenNI2 lists it, and for each problem one sentence saying what to do.
//
// BuildDevicesReport() is a pure function of the USB and OpenNI2 listings (capture/usb_sensors.h)
// so every case can be tested without hardware; ScanDevices() feeds it the real listings.
//
// A sensor is one camera-role USB device. A Kinect v1's audio and motor devices are folded into
// the sensor whose camera sits beside them on the same hub (as libfreenect pairs them), because
// OpenNI2 streams from the camera alone but udev permissions concern all three. Kinect audio/motor
// devices without a camera beside them still make a sensor entry: that is what a Kinect without
// its power adapter looks like.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "capture/usb_sensors.h"

namespace sightmap::capture {

struct DeviceProblem {
  std::string problem;  // what is wrong, one sentence
  std::string fix;      // what to do about it, one sentence
};

struct SensorStatus {
  std::string model;
  std::string family;
  // The camera device's ID, or the first USB device's when the camera is missing.
  uint16_t vendor_id = 0;
  uint16_t product_id = 0;
  bool camera_present = false;
  // The camera first (when present), then the Kinect's audio and motor devices.
  std::vector<UsbSensor> usb_devices;
  // Every USB device of the sensor could be opened by the current user.
  bool accessible = false;
  bool openni_listed = false;
  std::string openni_uri;  // set when openni_listed
  std::vector<DeviceProblem> problems;

  // Usable for capture: present, accessible, listed by OpenNI2.
  bool ready() const { return problems.empty(); }
};

struct OpenNiListing {
  OpenNiDeviceInfo info;
  bool usb_matched = false;  // a sensor in DevicesReport::sensors is this device
};

// Facts about the machine that BuildDevicesReport() cannot find out by itself.
struct DevicesEnvironment {
  // OpenNI2 initialised, so its (possibly empty) device list means something. When false, no
  // sensor gets an "OpenNI2 does not list it" problem; the reason belongs in `notes`.
  bool openni_available = true;
  std::string openni_drivers_dir = "/usr/lib/x86_64-linux-gnu/OpenNI2/Drivers";
  FreenectDriverState freenect_driver = FreenectDriverState::kMissing;
  // Carried into the report as is (e.g. why the USB listing may be incomplete).
  std::vector<std::string> notes;
};

struct DevicesReport {
  std::vector<SensorStatus> sensors;
  std::vector<OpenNiListing> openni_devices;  // everything OpenNI2 lists, in its order
  bool openni_available = true;
  std::string openni_drivers_dir;
  FreenectDriverState freenect_driver = FreenectDriverState::kMissing;
  std::vector<std::string> notes;
};

// Matches OpenNI2 entries to USB cameras: first by the bus/address in a PrimeSense URI
// ("1d27/0601@1/7"), then by vendor:product, then, for a Kinect, by a "freenect://" URI without
// USB IDs (older libFreenectDriver builds leave them 0). Each entry matches at most one sensor.
DevicesReport BuildDevicesReport(const std::vector<UsbSensor>& usb,
                                 const std::vector<OpenNiDeviceInfo>& openni,
                                 const DevicesEnvironment& environment = {});

// Lists USB and OpenNI2 devices on this machine and builds the report. Does not throw for a
// machine without USB access or a broken OpenNI2: the report's notes say what could not be checked.
DevicesReport ScanDevices();

// Stable keys for scripts: "sensors" (array of {vendor_id: "045e", product_id: "02ae", model,
// family, status: "ready" | "not ready", camera_present, bus, address, location, serial,
// accessible, openni_listed, openni_uri, usb_devices: [{vendor_id, product_id, role, bus,
// address, location, accessible, open_error, serial}], problems: [{problem, fix}]}),
// "openni_devices" (array of {uri, name, vendor, vendor_id, product_id, usb_matched}),
// "openni_available", "openni_drivers_dir", "freenect_driver" ("missing" | "installed" |
// "misnamed", see FreenectDriverState), "notes".
nlohmann::json DevicesReportToJson(const DevicesReport& report);

// Human-readable text, ending in a newline. With no sensor it says "no RGB-D sensor found" and how
// to check the connection.
std::string FormatDevicesReport(const DevicesReport& report);

// The command that installs sightmap's udev rules and applies them to attached devices.
extern const char* const kInstallUdevRulesCommand;

}  // namespace sightmap::capture
