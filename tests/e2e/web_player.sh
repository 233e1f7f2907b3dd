#!/usr/bin/env bash
# The web player (web/, docs/web.md) on the tiny sample's asset: built with Emscripten
# (scripts/build_web.sh into build/web), opened in headless Chromium (Debian's, software WebGL)
# with puppeteer-core. The page runs a control script through its API (window.fourd.runScript:
# fourd-play's own player in WebAssembly) and the world positions of every 5th frame match
# fourd-play's meshes of the same script within 0.1 mm; its render of frame 20 through studio
# camera 0 (the blended key textures, unlit) matches fourd-play's render of that frame (PSNR over
# the character's pixels >= 30 dB); live play at 1280x720 is measured (frames per second) and
# the runtime step benchmark in the browser is compared with the same benchmark natively
# (web_step_bench). The asset's web package (fourd-export --web: quantised geometry in gzip,
# which the page inflates with DecompressionStream) plays the same script in the page within
# 0.1 mm of fourd-play's meshes of the original asset, and renders frame 20 as well.
# Skipped (exit 77) without emcc, node, chromium or puppeteer-core.
# usage: web_player.sh <tiny session> <work dir>   (FOURD_BIN: folder of the executables)
set -euo pipefail
command -v node >/dev/null || { echo "SKIP: node is not installed"; exit 77; }
source "$(dirname "$0")/export_common.sh"
repo="$(cd "$here/../.." && pwd)"
web="$(dirname "$work")/web"
controls="$here/web/controls.txt"
frame=20
frame5=$(printf %05d $frame)

echo "== build the web player into $web"
set +e
bash "$repo/scripts/build_web.sh" "$web"
status=$?
set -e
[ "$status" -eq 77 ] && { echo "SKIP: emcc is not installed (scripts/setup.sh installs it)"; exit 77; }
[ "$status" -eq 0 ] || exit 1

echo "== fourd-play: meshes, and the render of frame $frame through studio camera 0"
"$bin/fourd-play" "$asset" "$controls" -o "$work/play" --render "$work/render" --render-every 10 \
  --camera studio:0 --calibration "$session/calibration" --image-size 640x480
"$bin/client_check" camera "$session/calibration" 0 640 480 "$work/camera.json"

echo "== the page in headless Chromium"
set +e
node "$here/web/check.js" "$web" "$asset" "$controls" "$work/camera.json" "$frame" 5 5 \
  "$work/web.json" "$work/web.png" --screenshot "$work/page.png"
status=$?
set -e
[ "$status" -eq 0 ] || exit "$status"  # 77: skipped

echo "== positions: the page's script run against fourd-play's meshes"
"$bin/client_check" frames "$work/play/meshes" "$work/web.json" 0.1
echo "== the page's render against fourd-play's"
"$bin/client_check" image "$work/render/frame_$frame5.png" "$work/web.png" 30 "$work/web_diff.png"

echo "== the web package: the same script in the page against fourd-play on the original asset"
"$bin/fourd-export" "$asset" --web "$work/asset.web.fourd"
set +e
node "$here/web/check.js" "$web" "$work/asset.web.fourd" "$controls" "$work/camera.json" "$frame" 5 \
  2 "$work/web_package.json" "$work/web_package.png"
status=$?
set -e
[ "$status" -eq 0 ] || exit "$status"
"$bin/client_check" frames "$work/play/meshes" "$work/web_package.json" 0.1
"$bin/client_check" image "$work/render/frame_$frame5.png" "$work/web_package.png" 30 \
  "$work/web_package_diff.png"

echo "== frame rate and step time"
"$bin/web_step_bench" "$asset" 10000 > "$work/native_bench.json"
python3 - "$work/web.json" "$work/native_bench.json" "$work/play/summary.json" \
  "$work/web_package.json" "$asset" "$work/asset.web.fourd" <<'PY'
import json, os, sys
web = json.load(open(sys.argv[1]))
native = json.load(open(sys.argv[2]))
play = json.load(open(sys.argv[3]))
package = json.load(open(sys.argv[4]))
for run in (web, package):
    assert run["summary"]["frames"] == play["frames"], (run["summary"], play["frames"])
    assert run["summary"]["transitions"] == play["transitions"], (run["summary"], play["transitions"])
asset_mb, package_mb = os.path.getsize(sys.argv[5]) / 1e6, os.path.getsize(sys.argv[6]) / 1e6
print(f"web package: {package_mb:.2f} MB to download instead of {asset_mb:.2f} MB; inflated and "
      f"loaded in {package['info']['load_ms'] / 1e3:.2f} s ({package['info']['inflate_ms']:.0f} ms "
      f"to inflate)")
assert package_mb < asset_mb, "the web package is not smaller than the asset"
fps, bench = web["fps"], web["benchmark"]
ratio = bench["mean_us"] / native["mean_us"]
print(f"{web['summary']['frames']} frames played, {web['summary']['transitions']} transitions, as "
      f"fourd-play")
print(f"live play at {fps['width']}x{fps['height']}: {fps['fps']:.1f} FPS ({fps['frames']} frames in "
      f"{fps['seconds']:.1f} s; goal >= 30), {fps['frame_work_ms']:.2f} ms of JavaScript per frame")
print(f"runtime step, {bench['vertices']} vertices, fastest of {bench['rounds']} runs of "
      f"{bench['steps']} steps: {bench['mean_us']:.1f} us in the browser, {native['mean_us']:.1f} us "
      f"natively: {ratio:.2f}x (goal <= 3x); median runs {bench['median_us']:.1f} and "
      f"{native['median_us']:.1f} us")
# Floors that catch a broken player, well below the goals (the machine may be shared).
assert fps["fps"] >= 5, "the page draws fewer than 5 frames per second"
assert ratio <= 10, "the WebAssembly step is more than 10x the native one"
PY
echo "web player ok"
