#!/usr/bin/env bash
# Runs raykit's libFuzzer targets (tests/fuzz/fuzz_*.cpp) under ASan + UBSan for longer
# than the test suite's smoke runs:
#   bash scripts/fuzz.sh [SECONDS_PER_TARGET] [TARGET...]     (default 600 s, every target)
# New inputs go to build/fuzz-corpus/TARGET (kept between runs); crashes to build/fuzz-crashes/.
# A crash found here becomes a regression input: copy it to tests/fuzz/regressions/TARGET/.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
bash "$root/scripts/deps.sh"
seconds=${1:-600}
shift || true
build=${RAYKIT_BUILD_DIR:-$root/build}/fuzz
cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_COMPILER=clang++ \
      -DRAYKIT_BUILD_FUZZERS=ON -DRAYKIT_BUILD_TESTS=OFF -DRAYKIT_BUILD_BENCHMARKS=OFF \
      -DRAYKIT_BUILD_EXAMPLES=OFF -DRAYKIT_SANITIZE=OFF -DRAYKIT_NATIVE=OFF >/dev/null
cmake --build "$build" -j"$(nproc)"
targets=("$@")
if [ ${#targets[@]} -eq 0 ]; then
  for f in "$root"/tests/fuzz/fuzz_*.cpp; do t=$(basename "$f" .cpp); targets+=("${t#fuzz_}"); done
fi
crashes=${RAYKIT_BUILD_DIR:-$root/build}/fuzz-crashes
mkdir -p "$crashes"
for t in "${targets[@]}"; do
  corpus=${RAYKIT_BUILD_DIR:-$root/build}/fuzz-corpus/$t
  mkdir -p "$corpus"
  dirs=("$corpus")
  for d in "$root/tests/fuzz/corpus/$t" "$root/tests/fuzz/regressions/$t"; do [ -d "$d" ] && dirs+=("$d"); done
  echo "== fuzz_$t for ${seconds}s" >&2
  ASAN_OPTIONS=detect_leaks=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
    "$build/tests/fuzz/fuzz_$t" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=1024 \
    -malloc_limit_mb=1024 -print_final_stats=1 -artifact_prefix="$crashes/$t-" "${dirs[@]}"
done
