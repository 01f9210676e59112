#!/usr/bin/env bash
# Redraws the charts in docs/ from the benchmark results kept there (docs/*.json, docs/*.csv),
# installing matplotlib (Debian's python3-matplotlib) when it is missing. To chart a new run,
# run the benchmark as each plot script's docstring says, then this or that script alone.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
if ! /usr/bin/python3 -c "import matplotlib" 2>/dev/null; then
  sudo=""
  [ "$(id -u)" -eq 0 ] || sudo="sudo"
  echo "raykit: installing python3-matplotlib" >&2
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends python3-matplotlib >&2
fi
cd "$root"
/usr/bin/python3 benchmarks/plot_tests.py docs/bench_tests.json docs/
/usr/bin/python3 benchmarks/plot_anim.py docs/anim_interp_error.csv docs/anim_sah_growth.csv docs/
/usr/bin/python3 benchmarks/plot_render.py docs/render_spp_error.csv docs/
