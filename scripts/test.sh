#!/usr/bin/env bash
# Installs what is missing, builds, and runs every test (unit, integration, end-to-end).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
bash scripts/build.sh
cd build
status=0
ctest --output-on-failure -j"$(nproc)" "$@" || status=$?
# A test skipped for a missing package (exit 77: Blender, Chromium, puppeteer-core, emcc, xvfb)
# says why in its output, which ctest does not show: repeat those lines.
if [ -f Testing/Temporary/LastTest.log ]; then
  awk '/ Testing: / { name = $NF } /^SKIP/ { print "skipped: " name ": " $0 }' \
    Testing/Temporary/LastTest.log
fi
exit "$status"
