#!/usr/bin/env bash
# Configures and builds fourd in ./build (Release, Ninja, ccache). Extra args go to cmake;
# FOURD_WERROR=ON in the environment makes warnings errors (CI).
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/ccache_env.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release \
  ${FOURD_WERROR:+-DFOURD_WERROR="$FOURD_WERROR"} "$@" > build.cmake.log 2>&1 || { cat build.cmake.log; exit 1; }
ninja -C build -j"$(nproc)"
