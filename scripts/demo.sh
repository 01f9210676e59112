#!/usr/bin/env bash
# The main job: builds the raykit command line, then reports on and checks a
# generated 1M-triangle scene and, when the shared data is present, the
# Stanford bunny. Installs what is missing.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
bash "$root/scripts/deps.sh"
build=${RAYKIT_BUILD_DIR:-$root/build}/release
cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=Release -DRAYKIT_BUILD_TESTS=OFF -DRAYKIT_BUILD_BENCHMARKS=OFF >/dev/null
cmake --build "$build" -j"$(nproc)" --target raykit_cli
rk="$build/bin/raykit"
out="$root/out"
mkdir -p "$out"
"$rk" generate torus "$out/torus_1m.obj" --tris 1000000
"$rk" info "$out/torus_1m.obj"
"$rk" check "$out/torus_1m.obj" --rays 200
bunny="$root/../shared/data/obj/stanford_bunny/stanford-bunny.obj"
if [ -f "$bunny" ]; then
  "$rk" info "$bunny" --json
  "$rk" check "$bunny" --rays 2000
else
  echo "raykit: shared data not found; skipping the bunny" >&2
fi
