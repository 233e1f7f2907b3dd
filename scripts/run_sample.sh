#!/usr/bin/env bash
# Installs what is missing, builds, and runs the main job on the default sample session:
# synthesises sample_capture/ and runs every stage on it, then prints where the report is.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
bash scripts/build.sh
./build/bin/fourd run sample_capture "$@"
echo "report: sample_capture/reports/report.md"
