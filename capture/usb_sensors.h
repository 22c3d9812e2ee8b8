// The RGB-D sensors sightmap knows by USB vendor:product ID, and what is attached right now: USB
// devices through libusb (present even when no driver can use them) and the devices OpenNI2 lists.
// `sightmap devices` compares the two (capture/devices_report.h). udev/ holds one access rule per
// ID of the same table; usb_sensors_test fails when they disagree.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace sightmap::capture {

// What one USB device of a sensor does. A Kinect v1 is three USB devices behind its own hub
// (camera, audio, motor); a PrimeSense-family sensor is a single device.
enum class UsbSensorRole {
  kCamera,  // depth + colour streams: the device OpenNI2 opens
  kAudio,   // Kinect microphone array (also drives the motor/LED on Kinect model 1473)
  kMotor,   // Kinect tilt motor, LED and accelerometer
};
const char* ToString(UsbSensorRole role);

struct KnownSensor {
  uint16_t vendor_id;
  uint16_t product_id;
  const char* model;   // what is known to use this ID; "(uncertain)" where sources disagree
  const char* family;  // "Kinect v1" or "PrimeSense"
  UsbSensorRole role;
  // Which OpenNI2 driver lists this ID: "PS1080", "PSLink" (both shipped by Debian's
  // libopenni2-0), "libFreenectDriver" (libfreenect, not shipped by Debian), or "" when no
  // OpenNI2 driver lists it. Only meaningful for the camera role.
  const char* openni2_driver;
  // True for the Kinect v1 cameras: OpenNI2 lists them only with libfreenect's driver.
  bool openni2_needs_freenect_driver;
};

// The single list of known IDs, sorted by (vendor_id, product_id) without duplicates.
const std::vector<KnownSensor>& KnownRgbdSensors();

// The table entry for vendor:product, or nullptr for an ID sightmap does not know.
const KnownSensor* FindKnownSensor(uint16_t vendor_id, uint16_t product_id);

// "045e:02ae": four lower-case hex digits each, as lsusb and udev print them.
std::string FormatUsbId(uint16_t vendor_id, uint16_t product_id);
std::string FormatHex4(uint16_t value);

// One attached USB device whose ID is in KnownRgbdSensors().
struct UsbSensor {
  uint8_t bus = 0;
  uint8_t address = 0;
  // Ports from the root hub down ("1-4.2" in sysfs is {4, 2} on bus 1); empty when libusb cannot
  // tell. Devices of one Kinect share all but the last port.
  std::vector<uint8_t> port_path;
  uint16_t vendor_id = 0;
  uint16_t product_id = 0;
  std::string model;
  std::string family;
  UsbSensorRole role = UsbSensorRole::kCamera;
  // iSerialNumber / iProduct strings: read from the device when it could be opened, else from
  // sysfs; "" when the device has none.
  std::string serial;
  std::string product;
  // libusb_open() succeeded: the current user may open the device. Opening does not claim an
  // interface, so a device streaming in another program still counts as accessible.
  bool accessible = false;
  // When !accessible: the libusb error name, e.g. "LIBUSB_ERROR_ACCESS".
  std::string open_error;
  // The open failed for lack of permission (LIBUSB_ERROR_ACCESS), i.e. udev rules are missing.
  bool permission_denied = false;
};

// "1-4.2" (bus-port.port...), the sysfs name of a device; "bus 1 address 7" when the port path
// is unknown.
std::string UsbLocation(const UsbSensor& sensor);

// Lists the attached USB devices that are in KnownRgbdSensors(), ordered by bus, port path and
// address. Never throws for an environment without USB (a container without /dev/bus/usb, libusb
// failing to initialise): it returns what it could list and appends a sentence to `notes` (when
// given) saying why the list may be incomplete.
std::vector<UsbSensor> EnumerateUsbSensors(std::vector<std::string>* notes = nullptr);

// One entry of OpenNI2's device list (openni::OpenNI::enumerateDevices).
struct OpenNiDeviceInfo {
  std::string
      uri;  // PS1080/PSLink: "1d27/0601@1/7" (vid/pid@bus/address); freenect: "freenect://0"
  std::string name;
  std::string vendor;
  uint16_t usb_vendor_id = 0;  // 0 when the driver does not say (older libFreenectDriver)
  uint16_t usb_product_id = 0;
};

// The bus and address in a PrimeSense driver URI "vvvv/pppp@bus/address", if it has that form.
struct UsbBusAddress {
  uint8_t bus = 0;
  uint8_t address = 0;
};
std::optional<UsbBusAddress> ParseOpenNiUsbUri(const std::string& uri);

// The devices OpenNI2 lists (openni::OpenNI::enumerateDevices), through OpenNiRuntime. Throws
// sightmap::Error when OpenNI2 cannot initialise; an empty list means OpenNI2 works and lists none.
std::vector<OpenNiDeviceInfo> ListOpenNiDevices();

// The folder OpenNI2 loads its drivers from: "OpenNI2/Drivers" beside libOpenNI2.so (Debian:
// /usr/lib/x86_64-linux-gnu/OpenNI2/Drivers). The libfreenect driver must be copied there.
std::string OpenNiDriversDir();

// Debian's OpenNI2 loads only files named lib*.so.0 from its Drivers folder (its log says "Found
// no files matching '.../Drivers/lib*.so.0'"), while libfreenect builds libFreenectDriver.so,
// .so.0.N and .so.0.N.M: the driver only counts when it is there as libFreenectDriver.so.0.
enum class FreenectDriverState {
  kMissing,    // no libFreenectDriver.so* in the folder
  kInstalled,  // libFreenectDriver.so.0 is there
  kMisnamed,   // only other names (e.g. libFreenectDriver.so), which Debian's OpenNI2 ignores
};
const char* ToString(FreenectDriverState state);
FreenectDriverState FindFreenectDriver(const std::string& drivers_dir);

}  // namespace sightmap::capture
