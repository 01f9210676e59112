#!/usr/bin/env bash
# Builds raykit and runs every test three ways: a Release build, the same suite under
# AddressSanitizer + UndefinedBehaviorSanitizer, and a short run of every libFuzzer target
# (clang, ASan + UBSan) on its seed corpus and regression inputs. Installs what is missing.
# Every option each build needs is set here (CMake caches options per build folder, and
# scripts/demo.sh shares build/release with tests off); ctest fails when no test ran.
#
# The sanitizer build compiles at -O1 with line tables only (-g1): at RelWithDebInfo's -O2 -g
# one test file (test_blocks, every SIMD level's packet walk) took 9 m 45 s to compile and the
# whole build about an hour on two cores, and CI has 90 minutes for everything; at -O1 -g1
# the same file takes 4 m and ASan's reports still name file and line. GCC's -Wmaybe-uninitialized
# is off there: at -O1 it flags libstdc++'s own <regex> (the Release build keeps the warning).
set -euo pipefail
start=$(date +%s)
phase() { echo "raykit test.sh: $1 (+$(( $(date +%s) - start )) s)"; }
root=$(cd "$(dirname "$0")/.." && pwd)
bash "$root/scripts/deps.sh"
jobs=$(nproc)
build=${RAYKIT_BUILD_DIR:-$root/build}

cmake -S "$root" -B "$build/release" -DCMAKE_BUILD_TYPE=Release -DRAYKIT_BUILD_TESTS=ON \
      -DRAYKIT_BUILD_EXAMPLES=ON -DRAYKIT_BUILD_BENCHMARKS=ON -DRAYKIT_SANITIZE=OFF -DRAYKIT_NATIVE=ON \
      -DRAYKIT_BUILD_FUZZERS=OFF
cmake --build "$build/release" -j"$jobs"
phase "release build done"
ctest --test-dir "$build/release" --output-on-failure --no-tests=error -j"$jobs"
phase "release tests passed"

cmake -S "$root" -B "$build/asan" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1 -DNDEBUG -Wno-maybe-uninitialized" \
      -DRAYKIT_SANITIZE=ON \
      -DRAYKIT_BUILD_TESTS=ON -DRAYKIT_BUILD_EXAMPLES=ON -DRAYKIT_BUILD_BENCHMARKS=OFF -DRAYKIT_NATIVE=OFF \
      -DRAYKIT_BUILD_FUZZERS=OFF
cmake --build "$build/asan" -j"$jobs"
phase "sanitizer build done"
ctest --test-dir "$build/asan" --output-on-failure --no-tests=error -j"$jobs" -LE package
phase "sanitizer tests passed"

cmake -S "$root" -B "$build/fuzz" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_COMPILER=clang++ \
      -DRAYKIT_BUILD_FUZZERS=ON -DRAYKIT_BUILD_TESTS=OFF -DRAYKIT_BUILD_EXAMPLES=OFF \
      -DRAYKIT_BUILD_BENCHMARKS=OFF -DRAYKIT_SANITIZE=OFF -DRAYKIT_NATIVE=OFF
cmake --build "$build/fuzz" -j"$jobs"
ctest --test-dir "$build/fuzz" --output-on-failure --no-tests=error -j"$jobs" -L fuzz
phase "fuzz targets passed"
