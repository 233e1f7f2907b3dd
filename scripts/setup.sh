#!/usr/bin/env bash
# Installs fourd's build and run dependencies from Debian 12 packages (needs root or sudo).
set -euo pipefail
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
PACKAGES=(
  build-essential cmake ninja-build ccache pkg-config git python3
  libeigen3-dev libopencv-dev libcgal-dev libopenmesh-dev libembree-dev
  libopenimageio-dev openimageio-tools libyaml-cpp-dev nlohmann-json3-dev libcli11-dev
  libtbb-dev libfmt-dev libxxhash-dev libtinygltf-dev libmeshoptimizer-dev libsqlite3-dev
  zlib1g-dev  # gzip of the web package (runtime/asset_packing.h)
  libgtest-dev libgmock-dev libbenchmark-dev
  libglfw3-dev libimgui-dev libepoxy-dev xvfb xauth libgl1-mesa-dri
  clang libclang-rt-14-dev
  colmap
  snakemake
  ffmpeg
  nodejs
  blender python3-numpy chromium  # real glTF clients the export tests open the .glb in
  emscripten  # the web player (scripts/build_web.sh): the runtime in WebAssembly
)
missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
# Debian's npm, unless a node.js that bundles its own npm is installed (it conflicts with it).
command -v npm >/dev/null || missing+=(npm)
if [ ${#missing[@]} -gt 0 ]; then
  echo "fourd setup: installing ${missing[*]}"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
else
  echo "fourd setup: all Debian packages present"
fi

# npm packages the export tests use, installed globally outside the repository at pinned
# versions: the Khronos glTF validator (run on fourd-export's output), three.js (GLTFLoader and
# MeshoptDecoder open the .glb in a browser) and puppeteer-core (drives Debian's chromium).
NPM_PACKAGES=(gltf-validator@2.0.0-dev.3.10 three@0.187.0 puppeteer-core@24.43.1)
for spec in "${NPM_PACKAGES[@]}"; do
  name="${spec%@*}"
  if [ "$(npm ls -g --depth=0 "$name" 2>/dev/null | grep -o "$name@.*")" != "$spec" ]; then
    echo "fourd setup: installing $spec (npm)"
    $SUDO npm install -g --no-fund --no-audit "$spec"
  fi
done
