#include "capture/usb_sensors.h"

#include <dlfcn.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <system_error>
#include <tuple>

#include <OpenNI.h>
#include <libusb.h>

#include "capture/openni_runtime.h"
#include "core/check.h"

namespace sightmap::capture {
namespace {

// Sources, in order of authority:
//   [PS]  the product lists compiled into Debian's libopenni2-0 drivers, read from the installed
//         binaries: libPS1080.so lists 1d27:0500/0600/0601/0609, libPSLink.so lists
//         1d27:1250/1260/1270/1280/1290/f9db (OpenNI2 2.2's XnDeviceEnumeration.cpp and
//         LinkDeviceEnumeration.cpp say the same).
//   [DEB] /lib/udev/rules.d/60-libopenni2-0.rules: 1d27:0200/0300/0400/0401/0500/0600/0601/0609/
//         1280/2100/2200/f9db and 045e:02ad/02ae/02b0/02be/02bf/02c2 (it omits 1250/1260/1270/1290,
//         which upstream OpenNI2's primesense-usb.rules has).
//   [FN]  libfreenect (freenect_internal.h, usb_libusb10.c): 045e:02ae camera, 02ad audio, 02b0
//         motor (Kinect for Xbox 360), 02bf camera and 02be audio (Kinect for Windows), which
//         re-enumerates as 02c3 or 02bb once the SDK / beta-SDK audio firmware is loaded.
//   [IDS] usb.ids names: 02ad "Xbox NUI Audio", 02ae "Xbox NUI Camera", 02b0 "Xbox NUI Motor",
//         02bb "Kinect Audio", 02be/02bf/02c2 "Kinect for Windows NUI Audio/Camera/Motor". Vendor
//         1d27 is named "ASUS" there, so lsusb prints "ASUS" for PrimeSense sensors too.
// Model names for the PrimeSense IDs are not documented by PrimeSense; where only the ID's presence
// in a driver list is known, the model says "(uncertain)" or "(model unknown)".
const std::vector<KnownSensor> kKnownSensors = {
    // --- Microsoft Kinect v1 ---
    // Xbox 360 Kinect audio [FN, IDS, DEB].
    {0x045e, 0x02ad, "Kinect for Xbox 360 (audio)", "Kinect v1", UsbSensorRole::kAudio, "", false},
    // Xbox 360 Kinect depth + colour camera [FN, IDS, DEB]; OpenNI2 needs libFreenectDriver.
    {0x045e, 0x02ae, "Kinect for Xbox 360", "Kinect v1", UsbSensorRole::kCamera,
     "libFreenectDriver", true},
    // Xbox 360 Kinect (model 1414) tilt motor, LED, accelerometer [FN, IDS, DEB].
    {0x045e, 0x02b0, "Kinect for Xbox 360 (motor)", "Kinect v1", UsbSensorRole::kMotor, "", false},
    // Kinect for Windows audio after the beta-SDK firmware is loaded [FN "PID_K4W_AUDIO_ALT_2",
    // IDS "Kinect Audio"]; not in Debian's rules.
    {0x045e, 0x02bb, "Kinect for Windows (audio, beta-SDK firmware)", "Kinect v1",
     UsbSensorRole::kAudio, "", false},
    // Kinect for Windows audio as first plugged in [FN, IDS, DEB].
    {0x045e, 0x02be, "Kinect for Windows (audio)", "Kinect v1", UsbSensorRole::kAudio, "", false},
    // Kinect for Windows depth + colour camera [FN, IDS, DEB]; libfreenect treats it as 02ae.
    {0x045e, 0x02bf, "Kinect for Windows", "Kinect v1", UsbSensorRole::kCamera, "libFreenectDriver",
     true},
    // "Kinect for Windows NUI Motor" in usb.ids [IDS, DEB], but user listings show it beside
    // 02ae/02ad on Xbox 360 Kinects of model 1473 too, whose motor libfreenect drives through the
    // audio device; libfreenect's code has no constant for it. Role "motor" is the usb.ids name.
    {0x045e, 0x02c2, "Kinect v1 model 1473 / Kinect for Windows (motor)", "Kinect v1",
     UsbSensorRole::kMotor, "", false},
    // Kinect for Windows audio after the SDK firmware is loaded [FN "PID_K4W_AUDIO_ALT_1"]; not in
    // Debian's rules or usb.ids.
    {0x045e, 0x02c3, "Kinect for Windows (audio, SDK firmware)", "Kinect v1", UsbSensorRole::kAudio,
     "", false},

    // --- PrimeSense family (PS1080: ASUS Xtion, PrimeSense Carmine; PS1200 "Capri") ---
    // [DEB] only. Early PrimeSense reference / development hardware; model unknown, and no OpenNI2
    // driver lists 0200, 0300, 0400 or 0401.
    {0x1d27, 0x0200, "PrimeSense reference sensor (model unknown)", "PrimeSense",
     UsbSensorRole::kCamera, "", false},
    {0x1d27, 0x0300, "PrimeSense reference sensor (model unknown)", "PrimeSense",
     UsbSensorRole::kCamera, "", false},
    {0x1d27, 0x0400, "PrimeSense reference sensor (model unknown)", "PrimeSense",
     UsbSensorRole::kCamera, "", false},
    {0x1d27, 0x0401, "PrimeSense reference sensor (model unknown)", "PrimeSense",
     UsbSensorRole::kCamera, "", false},
    // [PS, DEB]. The PrimeSensor reference design of the PS1080 SDK (uncertain).
    {0x1d27, 0x0500, "PrimeSensor reference design (uncertain)", "PrimeSense",
     UsbSensorRole::kCamera, "PS1080", false},
    // [PS, DEB]. The common PS1080 ID: PrimeSense Carmine 1.08 and 1.09, ASUS Xtion PRO and Xtion
    // PRO LIVE with their original firmware.
    {0x1d27, 0x0600, "ASUS Xtion PRO / PRO LIVE, PrimeSense Carmine 1.08 / 1.09", "PrimeSense",
     UsbSensorRole::kCamera, "PS1080", false},
    // [PS, DEB]. ASUS Xtion PRO LIVE (and Xtion PRO) after ASUS's firmware update for USB 3.0
    // ports ("xtion with new firmware" in the xtion kernel driver). Whether updated Carmines also
    // report 0601 is uncertain.
    {0x1d27, 0x0601, "ASUS Xtion PRO LIVE / Xtion PRO (updated firmware)", "PrimeSense",
     UsbSensorRole::kCamera, "PS1080", false},
    // [PS, DEB]. Reported by later ASUS Xtion units (lsusb "ASUS"); added to the PS1080 list in
    // OpenNI2 2.2. Which Xtion revision is uncertain.
    {0x1d27, 0x0609, "ASUS Xtion, later revision (uncertain)", "PrimeSense", UsbSensorRole::kCamera,
     "PS1080", false},
    // [PS] (upstream OpenNI2 rules, not Debian's). PS1200 "Capri" devices served by the PSLink
    // driver; which product each ID is, is unknown.
    {0x1d27, 0x1250, "PrimeSense Capri (PS1200) device (model unknown)", "PrimeSense",
     UsbSensorRole::kCamera, "PSLink", false},
    {0x1d27, 0x1260, "PrimeSense Capri (PS1200) device (model unknown)", "PrimeSense",
     UsbSensorRole::kCamera, "PSLink", false},
    {0x1d27, 0x1270, "PrimeSense Capri (PS1200) device (model unknown)", "PrimeSense",
     UsbSensorRole::kCamera, "PSLink", false},
    // [PS, DEB].
    {0x1d27, 0x1280, "PrimeSense Capri (PS1200) device (model unknown)", "PrimeSense",
     UsbSensorRole::kCamera, "PSLink", false},
    // [PS].
    {0x1d27, 0x1290, "PrimeSense Capri (PS1200) device (model unknown)", "PrimeSense",
     UsbSensorRole::kCamera, "PSLink", false},
    // [DEB] only; model unknown and no OpenNI2 driver lists them.
    {0x1d27, 0x2100, "PrimeSense device (model unknown)", "PrimeSense", UsbSensorRole::kCamera, "",
     false},
    {0x1d27, 0x2200, "PrimeSense device (model unknown)", "PrimeSense", UsbSensorRole::kCamera, "",
     false},
    // [PS, DEB]. Listed by PSLink; model unknown.
    {0x1d27, 0xf9db, "PrimeSense PSLink device (model unknown)", "PrimeSense",
     UsbSensorRole::kCamera, "PSLink", false},
};

struct ContextDeleter {
  void operator()(libusb_context* context) const { libusb_exit(context); }
};
using UsbContext = std::unique_ptr<libusb_context, ContextDeleter>;

struct HandleDeleter {
  void operator()(libusb_device_handle* handle) const { libusb_close(handle); }
};
using UsbHandle = std::unique_ptr<libusb_device_handle, HandleDeleter>;

// libusb_get_device_list's array, freed (and its devices unreferenced) on scope exit.
class UsbDeviceList {
 public:
  explicit UsbDeviceList(libusb_context* context)
      : count_(libusb_get_device_list(context, &devices_)) {}
  ~UsbDeviceList() {
    if (count_ >= 0) libusb_free_device_list(devices_, 1);
  }
  UsbDeviceList(const UsbDeviceList&) = delete;
  UsbDeviceList& operator=(const UsbDeviceList&) = delete;

  // Negative: a libusb error code.
  ssize_t size() const { return count_; }
  libusb_device* operator[](ssize_t i) const { return devices_[i]; }

 private:
  libusb_device** devices_ = nullptr;
  ssize_t count_;
};

std::string ReadStringDescriptor(libusb_device_handle* handle, uint8_t index) {
  if (index == 0) return "";
  std::array<unsigned char, 256> buffer{};
  const int length = libusb_get_string_descriptor_ascii(handle, index, buffer.data(),
                                                        static_cast<int>(buffer.size()));
  if (length <= 0) return "";
  return std::string(reinterpret_cast<const char*>(buffer.data()), static_cast<size_t>(length));
}

// sysfs attributes are world-readable, so the serial and product name of a device the user may not
// open can still be shown (Linux only; "" elsewhere or when the attribute is absent).
std::string ReadSysfsAttribute(const UsbSensor& sensor, const char* attribute) {
  if (sensor.port_path.empty()) return "";
  std::ifstream in("/sys/bus/usb/devices/" + UsbLocation(sensor) + "/" + attribute);
  std::string value;
  std::getline(in, value);
  return value;
}

void AddNote(std::vector<std::string>* notes, const std::string& note) {
  if (notes != nullptr) notes->push_back(note);
}

}  // namespace

const char* ToString(UsbSensorRole role) {
  switch (role) {
    case UsbSensorRole::kCamera:
      return "camera";
    case UsbSensorRole::kAudio:
      return "audio";
    case UsbSensorRole::kMotor:
      return "motor";
  }
  return "unknown";
}

const std::vector<KnownSensor>& KnownRgbdSensors() { return kKnownSensors; }

const KnownSensor* FindKnownSensor(uint16_t vendor_id, uint16_t product_id) {
  for (const KnownSensor& sensor : kKnownSensors) {
    if (sensor.vendor_id == vendor_id && sensor.product_id == product_id) return &sensor;
  }
  return nullptr;
}

std::string FormatHex4(uint16_t value) {
  char text[8];
  std::snprintf(text, sizeof(text), "%04x", static_cast<unsigned>(value));
  return text;
}

std::string FormatUsbId(uint16_t vendor_id, uint16_t product_id) {
  return FormatHex4(vendor_id) + ":" + FormatHex4(product_id);
}

std::string UsbLocation(const UsbSensor& sensor) {
  std::ostringstream out;
  if (sensor.port_path.empty()) {
    out << "bus " << static_cast<int>(sensor.bus) << " address "
        << static_cast<int>(sensor.address);
    return out.str();
  }
  out << static_cast<int>(sensor.bus) << "-";
  for (size_t i = 0; i < sensor.port_path.size(); ++i) {
    if (i > 0) out << ".";
    out << static_cast<int>(sensor.port_path[i]);
  }
  return out.str();
}

std::vector<UsbSensor> EnumerateUsbSensors(std::vector<std::string>* notes) {
  std::vector<UsbSensor> sensors;
  libusb_context* raw_context = nullptr;
  const int init_status = libusb_init(&raw_context);
  if (init_status != LIBUSB_SUCCESS) {
    AddNote(notes, std::string("USB devices could not be listed: libusb failed to initialise (") +
                       libusb_error_name(init_status) +
                       "); inside a container, pass the host's /dev/bus/usb through");
    return sensors;
  }
  const UsbContext context(raw_context);

  const UsbDeviceList devices(context.get());
  if (devices.size() < 0) {
    AddNote(notes, std::string("USB devices could not be listed: ") +
                       libusb_error_name(static_cast<int>(devices.size())));
    return sensors;
  }
  if (devices.size() == 0) {
    // Even a machine without sensors has root hubs, so an empty list means no USB access at all.
    AddNote(notes,
            "libusb sees no USB device at all (not even a root hub): /dev/bus/usb is probably not "
            "available here, e.g. inside a container");
  }

  for (ssize_t i = 0; i < devices.size(); ++i) {
    libusb_device* device = devices[i];
    libusb_device_descriptor descriptor{};
    if (libusb_get_device_descriptor(device, &descriptor) != LIBUSB_SUCCESS) continue;
    const KnownSensor* known = FindKnownSensor(descriptor.idVendor, descriptor.idProduct);
    if (known == nullptr) continue;

    UsbSensor sensor;
    sensor.bus = libusb_get_bus_number(device);
    sensor.address = libusb_get_device_address(device);
    std::array<uint8_t, 8> ports{};  // USB 3 allows at most 7 tiers
    const int port_count =
        libusb_get_port_numbers(device, ports.data(), static_cast<int>(ports.size()));
    if (port_count > 0) sensor.port_path.assign(ports.begin(), ports.begin() + port_count);
    sensor.vendor_id = descriptor.idVendor;
    sensor.product_id = descriptor.idProduct;
    sensor.model = known->model;
    sensor.family = known->family;
    sensor.role = known->role;

    libusb_device_handle* raw_handle = nullptr;
    const int open_status = libusb_open(device, &raw_handle);
    if (open_status == LIBUSB_SUCCESS) {
      const UsbHandle handle(raw_handle);
      sensor.accessible = true;
      sensor.serial = ReadStringDescriptor(handle.get(), descriptor.iSerialNumber);
      sensor.product = ReadStringDescriptor(handle.get(), descriptor.iProduct);
    } else {
      sensor.open_error = libusb_error_name(open_status);
      sensor.permission_denied = open_status == LIBUSB_ERROR_ACCESS;
      sensor.serial = ReadSysfsAttribute(sensor, "serial");
      sensor.product = ReadSysfsAttribute(sensor, "product");
    }
    sensors.push_back(std::move(sensor));
  }

  std::sort(sensors.begin(), sensors.end(), [](const UsbSensor& a, const UsbSensor& b) {
    return std::tie(a.bus, a.port_path, a.address) < std::tie(b.bus, b.port_path, b.address);
  });
  return sensors;
}

std::optional<UsbBusAddress> ParseOpenNiUsbUri(const std::string& uri) {
  unsigned vendor = 0;
  unsigned product = 0;
  unsigned bus = 0;
  unsigned address = 0;
  int consumed = 0;
  if (std::sscanf(uri.c_str(), "%4x/%4x@%u/%u%n", &vendor, &product, &bus, &address, &consumed) !=
          4 ||
      static_cast<size_t>(consumed) != uri.size() || bus > 255 || address > 255) {
    return std::nullopt;
  }
  return UsbBusAddress{static_cast<uint8_t>(bus), static_cast<uint8_t>(address)};
}

std::vector<OpenNiDeviceInfo> ListOpenNiDevices() {
  const std::shared_ptr<OpenNiRuntime> runtime = OpenNiRuntime::Acquire();
  openni::Array<openni::DeviceInfo> list;
  openni::OpenNI::enumerateDevices(&list);
  std::vector<OpenNiDeviceInfo> devices;
  devices.reserve(static_cast<size_t>(list.getSize()));
  for (int i = 0; i < list.getSize(); ++i) {
    OpenNiDeviceInfo info;
    info.uri = list[i].getUri();
    info.name = list[i].getName();
    info.vendor = list[i].getVendor();
    info.usb_vendor_id = list[i].getUsbVendorId();
    info.usb_product_id = list[i].getUsbProductId();
    devices.push_back(std::move(info));
  }
  return devices;
}

std::string OpenNiDriversDir() {
  // OpenNI2 looks for "OpenNI2/Drivers" beside its own library (see libOpenNI2's "Using '%s' as
  // driver path"), so ask the dynamic linker where libOpenNI2 was loaded from.
  Dl_info info{};
  if (dladdr(reinterpret_cast<void*>(&oniInitialize), &info) != 0 && info.dli_fname != nullptr) {
    std::error_code error;
    const std::filesystem::path library = std::filesystem::weakly_canonical(info.dli_fname, error);
    if (!error) return (library.parent_path() / "OpenNI2" / "Drivers").string();
  }
  return "/usr/lib/x86_64-linux-gnu/OpenNI2/Drivers";
}

const char* ToString(FreenectDriverState state) {
  switch (state) {
    case FreenectDriverState::kMissing:
      return "missing";
    case FreenectDriverState::kInstalled:
      return "installed";
    case FreenectDriverState::kMisnamed:
      return "misnamed";
  }
  return "unknown";
}

FreenectDriverState FindFreenectDriver(const std::string& drivers_dir) {
  FreenectDriverState state = FreenectDriverState::kMissing;
  std::error_code error;
  for (auto it = std::filesystem::directory_iterator(drivers_dir, error);
       !error && it != std::filesystem::directory_iterator(); it.increment(error)) {
    const std::string name = it->path().filename().string();
    if (name == "libFreenectDriver.so.0") return FreenectDriverState::kInstalled;
    if (name.rfind("libFreenectDriver.so", 0) == 0) state = FreenectDriverState::kMisnamed;
  }
  return state;
}

}  // namespace sightmap::capture
