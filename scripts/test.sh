#!/usr/bin/env bash
# Builds raykit and runs every test twice: a Release build, then the same suite
# under AddressSanitizer + UndefinedBehaviorSanitizer. Installs what is missing.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
bash "$root/scripts/deps.sh"
jobs=$(nproc)
build=${RAYKIT_BUILD_DIR:-$root/build}

cmake -S "$root" -B "$build/release" -DCMAKE_BUILD_TYPE=Release
cmake --build "$build/release" -j"$jobs"
ctest --test-dir "$build/release" --output-on-failure -j"$jobs"

cmake -S "$root" -B "$build/asan" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DRAYKIT_SANITIZE=ON \
      -DRAYKIT_BUILD_BENCHMARKS=OFF -DRAYKIT_NATIVE=OFF
cmake --build "$build/asan" -j"$jobs"
ctest --test-dir "$build/asan" --output-on-failure -j"$jobs" -LE package
