#!/usr/bin/env bash
# Builds the web player (docs/web.md) with Emscripten into OUT (default build/web): fourd_web.js,
# fourd_web.wasm, index.html and player.js, ready to serve (scripts/serve_web.sh). Optional:
# without emcc (Debian package emscripten; scripts/setup.sh installs it) it says so and exits
# 77. Extra arguments go to cmake's configure step.
# usage: build_web.sh [OUT] [cmake args...]
set -euo pipefail
cd "$(dirname "$0")/.."
out="$(realpath -m "${1:-build/web}")"
shift || true
if ! command -v emcmake >/dev/null || ! command -v emcc >/dev/null; then
  echo "fourd web: emcc is not installed (Debian package emscripten): web player not built"
  exit 77
fi
# Debian's emscripten runs its JavaScript tools with node and Debian's node modules (acorn).
export NODE_PATH="/usr/share/nodejs${NODE_PATH:+:$NODE_PATH}"
source scripts/ccache_env.sh
launcher=()
if command -v ccache >/dev/null; then launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache); fi
mkdir -p "$out"
emcmake cmake -S web -B "$out/cmake" -G Ninja -DCMAKE_BUILD_TYPE=Release "${launcher[@]}" "$@" \
  > "$out/cmake.log" 2>&1 || { cat "$out/cmake.log"; exit 1; }
cmake --build "$out/cmake" -j"$(nproc)"
for f in fourd_web.js fourd_web.wasm index.html player.js; do cp "$out/cmake/$f" "$out/$f"; done
echo "fourd web: $out/index.html ($(du -k "$out/fourd_web.wasm" | cut -f1) KiB of WebAssembly)"
