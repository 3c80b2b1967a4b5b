#!/usr/bin/env bash
# Build and install agents_interfaces into the active virtual environment with plain CMake
# (the same build that `pip install --no-build-isolation ./interfaces` runs through
# scikit-build-core). Usage: interfaces/build.sh [build-dir]
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
prefix="${VIRTUAL_ENV:?activate the virtual environment that has the ros2 extra first}"
build="${1:-$here/build}"
cmake -S "$here" -B "$build" -DCMAKE_BUILD_TYPE=Release \
  -DCMAKE_INSTALL_PREFIX="$prefix" -DPython3_EXECUTABLE="$prefix/bin/python" \
  -DBUILD_TESTING=OFF
cmake --build "$build" -j "$(nproc)"
cmake --install "$build"
