#!/usr/bin/env bash
# Installs the Debian 12 packages sightmap needs, only those that are missing. Idempotent; runs as
# root, or as a user with sudo. Nothing is downloaded except through apt.
set -euo pipefail

packages=(
  build-essential cmake ninja-build pkg-config git  # toolchain
  libopenni2-dev                            # OpenNI2: live sensors and .oni replay
  libusb-1.0-0-dev                          # USB sensor discovery (sightmap devices)
  libopencv-dev                             # image codecs, colour conversion
  libeigen3-dev                             # geometry
  libcli11-dev                              # command line
  nlohmann-json3-dev                        # JSON output and calibration files
  libsqlite3-dev                            # the model (store/)
  libnanoflann-dev                          # the PLY export's outlier filter (nearest neighbours)
  libosmesa6-dev                            # off-screen rendering (render/, the simulator)
  libceres-dev                              # pose-graph optimisation (slam/)
  libopengv-dev                             # P3P for the photo locator's PnP RANSAC (slam/)
  libglfw3-dev                              # the live preview window (render/)
  libcpp-httplib-dev                        # the HTTP server phones talk to (sightmap serve)
  libexif-dev                               # a photo's focal length from its EXIF (sightmap locate)
  libjpeg62-turbo-dev                       # phone photos decoded strictly (corrupt data refused)
  xvfb xauth                                # a virtual display for the preview's tests
  chromium chromium-driver python3-selenium # the web pages' tests in a real headless browser
  opencv-doc                                # real photographs the simulator textures its scene with
  libgtest-dev libbenchmark-dev             # tests and benchmarks
  clang-14 libclang-rt-14-dev libfuzzer-14-dev  # the fuzzers (fuzz/, scripts/fuzz.sh)
)

missing=()
for package in "${packages[@]}"; do
  status=$(dpkg-query -W -f='${Status}' "$package" 2>/dev/null || true)
  [[ "$status" == "install ok installed" ]] || missing+=("$package")
done

if [[ ${#missing[@]} -eq 0 ]]; then
  echo "setup: all ${#packages[@]} packages are installed"
  exit 0
fi

if [[ $EUID -eq 0 ]]; then
  sudo=()
elif command -v sudo >/dev/null 2>&1; then
  sudo=(sudo)
else
  echo "error: missing packages ${missing[*]} and no sudo: run this script as root" >&2
  exit 1
fi

echo "setup: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
"${sudo[@]}" apt-get update -q
"${sudo[@]}" apt-get install -y -q --no-install-recommends "${missing[@]}"
