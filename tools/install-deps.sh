#!/usr/bin/env bash
# Installs what facemorph needs to build and test, from Debian's packages only, and nothing that is
# already there. Idempotent: a second run changes nothing and does not touch the network.
set -euo pipefail

packages=(
  g++ cmake ninja-build pkgconf        # toolchain
  ccache                               # the test command's builds share their objects (quickstart.sh)
  clang libclang-rt-14-dev             # the sanitizer pass (float-cast-overflow, which g++ lacks)
  libeigen3-dev                        # sparse linear algebra
  libopenexr-dev                       # H and λ fields as EXR images
  libzstd-dev                          # container payloads
  libavif-dev libwebp-dev libpng-dev   # the decoder's images: textures (AVIF, WebP), pictures (PNG)
  libopencv-dev                        # texture images (encoder and tools only)
  opencv-data                          # the frontal-face cascade --landmarks auto runs on rendered views of a textured scan
  libsuitesparse-dev                   # CHOLMOD: the conformal map's sparse Cholesky
  libopenblas0-pthread                 # the BLAS CHOLMOD runs on (4x faster than reference BLAS)
  libcli11-dev                         # command lines
  nlohmann-json3-dev                   # capture.json
  libgtest-dev                         # tests
  abigail-tools                        # the player API's ABI check (abidiff; the test skips without it)
  python3                              # optional real-data tests (ICT capture script)
  python3-dev python3-numpy            # the Python package (python/): its modules' headers, its arrays
  pybind11-dev python3-pybind11        # ... its bindings (CMake package; pip install --no-build-isolation ./python)
  python3-setuptools python3-pip python3-venv  # ... its offline pip install (setup.py), into a venv
  draco ffmpeg                         # the rate bench's baselines: draco_encoder per frame, JPEG/H.264 (libx264) textures
  emscripten dpkg-dev nodejs           # the browser's decoder: web/build.sh (emcc; dpkg-source unpacks Debian's zstd source), its tests under node
  libmeshoptimizer-dev                 # glTF clips for the web: EXT_meshopt_compression (fmdec -o CLIP.glb)
  chromium                             # the player page's test in a real browser (tests/web/browser.sh, headless)
  slurm-wlm munge                      # the cluster encode's test: a one-node Slurm cluster (tests/tools/slurm_test.sh)
  blender                              # the Blender add-on's test (python/blender, tests/blender: Blender 3.4 on the system Python 3.11)
)

missing=()
for package in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$package" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$package")
  fi
done
# npm comes with some builds of nodejs (NodeSource's) and is a package of its own in Debian's.
if ! command -v npm >/dev/null && ! dpkg-query -W -f='${Status}' npm 2>/dev/null | grep -q "install ok installed"; then
  missing+=(npm)
fi
if ((${#missing[@]} > 0)); then
  sudo=""
  if [[ "$(id -u)" -ne 0 ]]; then
    sudo="sudo"
  fi
  echo "install-deps: installing ${missing[*]}" >&2
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi
# The browser side's npm packages (three, puppeteer-core), pinned, in a folder of the build's.
"$(dirname "$0")/../web/install-npm.sh"
