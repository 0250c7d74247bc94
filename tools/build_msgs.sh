#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Build an interface package (default skynav_msgs; the Makefile also builds
# vendor/tf2_msgs) with plain CMake and install it into a virtualenv that holds
# the ROS 2 Jazzy wheels from PyPI.
#
#   tools/build_msgs.sh VENV BUILD_DIR [PACKAGE_DIR]
#
# colcon is not needed: one ament_cmake package configures, builds and installs
# like any CMake project once AMENT_PREFIX_PATH names the venv (ament's index
# ignores CMAKE_PREFIX_PATH). On a robot with a full ROS 2 install use colcon.
set -euo pipefail
venv=$(realpath "$1")
build=$2
root=$(cd "$(dirname "$0")/.." && pwd)
source=$(realpath "${3:-$root/skynav_msgs}")
package=$(basename "$source")

export AMENT_PREFIX_PATH="$venv"
export PATH="$venv/bin:$PATH"
log="$build.log"
mkdir -p "$(dirname "$build")"
echo "building $package into $venv (log: $log)"
{
  cmake -S "$source" -B "$build" -G Ninja \
    -DCMAKE_BUILD_TYPE=Release \
    -DCMAKE_INSTALL_PREFIX="$venv" \
    -DCMAKE_PREFIX_PATH="$venv" \
    -DPython3_EXECUTABLE="$venv/bin/python" \
    -DBUILD_TESTING=OFF \
    -DCMAKE_PROJECT_INCLUDE="$root/cmake/strip_wheel_include_dirs.cmake" &&
  cmake --build "$build" &&
  cmake --install "$build"
} >"$log" 2>&1 || { tail -n 30 "$log" >&2; echo "$package failed to build; full log: $log" >&2; exit 1; }
