#!/usr/bin/env bash
# Installs the Debian 12 packages raykit's build, tests, benchmarks and demo use,
# skipping those already installed. Uses sudo when not run as root.
set -euo pipefail
pkgs=(
  cmake g++ make pkg-config
  libglm-dev                      # math
  libstb-dev                      # PNG writing; BMP/TGA texture decoding (after raykit checks the header)
  libpng-dev libturbojpeg0-dev    # PNG and JPEG texture decoding (fuzzed upstream)
  opencl-c-headers opencl-clhpp-headers ocl-icd-opencl-dev  # OpenCL device path
  pocl-opencl-icd                 # the default OpenCL device: PoCL on the CPU
  libgtest-dev libbenchmark-dev   # tests, benchmarks
  libcli11-dev                    # the raykit command line's argument parser (header-only; the CLI only)
  libtinyobjloader-dev            # test oracle for the OBJ loader
  assimp-testmodels               # real OBJ/SMD files for the loader tests
  libembree-dev                   # benchmark peer
  clang libclang-rt-14-dev        # libFuzzer targets (tests/fuzz), smoke-run by scripts/test.sh
)
missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  sudo=""
  [ "$(id -u)" -eq 0 ] || sudo="sudo"
  echo "raykit: installing ${missing[*]}" >&2
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >&2
fi
