#!/usr/bin/env bash
# Serves the web player (build/web, scripts/build_web.sh) with a session's asset on
# http://127.0.0.1:PORT/ (default 8000) until Ctrl-C: the page opens with the asset loaded.
# usage: serve_web.sh SESSION|ASSET.fourd [PORT]
set -euo pipefail
cd "$(dirname "$0")/.."
target="${1:?usage: serve_web.sh SESSION|ASSET.fourd [PORT]}"
port="${2:-8000}"
asset="$target"
[ -d "$target" ] && asset="$target/asset/motion_graph.fourd"
test -f "$asset" || { echo "no asset $asset (run the session's graph stage first)"; exit 1; }
test -f build/web/fourd_web.wasm || { echo "no build/web: run scripts/build_web.sh first"; exit 1; }
root="$(mktemp -d)"
trap 'rm -rf "$root"' EXIT
for f in index.html player.js fourd_web.js fourd_web.wasm; do ln -s "$PWD/build/web/$f" "$root/$f"; done
ln -s "$(realpath "$asset")" "$root/asset.fourd"
echo "fourd web: open http://127.0.0.1:$port/index.html?asset=asset.fourd ($asset)"
python3 -m http.server "$port" --bind 127.0.0.1 --directory "$root"
