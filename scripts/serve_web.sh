#!/usr/bin/env bash
# Serves the web player (build/web, scripts/build_web.sh) with a session's asset on
# http://127.0.0.1:PORT/ (default 8000) until Ctrl-C: the page opens with the asset loaded. The
# asset is served as its web package (fourd-export --web: quantised, delta-coded geometry in
# gzip, docs/web.md), made beside the served files; --plain serves the asset file itself. A file
# that is already a web package is served as it is.
# usage: serve_web.sh [--plain] SESSION|ASSET.fourd [PORT]
set -euo pipefail
cd "$(dirname "$0")/.."
plain=0
if [ "${1:-}" = "--plain" ]; then plain=1; shift; fi
target="${1:?usage: serve_web.sh [--plain] SESSION|ASSET.fourd [PORT]}"
port="${2:-8000}"
asset="$target"
[ -d "$target" ] && asset="$target/asset/motion_graph.fourd"
test -f "$asset" || { echo "no asset $asset (run the session's graph stage first)"; exit 1; }
test -f build/web/fourd_web.wasm || { echo "no build/web: run scripts/build_web.sh first"; exit 1; }
root="$(mktemp -d)"
trap 'rm -rf "$root"' EXIT
for f in index.html player.js fourd_web.js fourd_web.wasm; do ln -s "$PWD/build/web/$f" "$root/$f"; done
if [ "$plain" = 1 ] || [ "$(head -c 2 "$asset" | od -An -tx1 | tr -d ' ')" = "1f8b" ]; then
  ln -s "$(realpath "$asset")" "$root/asset.fourd"
else
  test -x build/bin/fourd-export || { echo "no build/bin/fourd-export: run scripts/build.sh first"; exit 1; }
  build/bin/fourd-export "$asset" --web "$root/asset.fourd"
fi
echo "fourd web: open http://127.0.0.1:$port/index.html?asset=asset.fourd ($asset," \
  "$(du -kL "$root/asset.fourd" | cut -f1) KiB to download)"
# Cross-origin isolated (COOP and COEP headers): performance.now() then ticks in 5 us rather
# than 100 us steps, and the HUD's time of a runtime step means something.
python3 - "$port" "$root" <<'PY'
import functools, http.server, sys
class Handler(http.server.SimpleHTTPRequestHandler):
    def end_headers(self):
        self.send_header("Cross-Origin-Opener-Policy", "same-origin")
        self.send_header("Cross-Origin-Embedder-Policy", "require-corp")
        super().end_headers()
handler = functools.partial(Handler, directory=sys.argv[2])
http.server.ThreadingHTTPServer(("127.0.0.1", int(sys.argv[1])), handler).serve_forever()
PY
