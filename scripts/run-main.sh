#!/usr/bin/env bash
# The main job on a fresh Debian 12 machine: install what is missing, build, and run.
# Until the mapping command lands, the main job probes the real Kinect recording in ../shared
# (or a SOURCE given as the first argument) and lists attached sensors.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
scripts/build.sh
source_arg=${1:-../shared/data/oni/kinect-12f.oni}
build/sightmap devices
build/sightmap probe "$source_arg"
