#!/usr/bin/env bash
# The tiny sample's glTF export opened with three.js (npm) in headless Chromium (Debian's, software
# WebGL), plain and compressed (--compress, JPEG texture: GLTFLoader + MeshoptDecoder): the clips
# and morph targets are there; playing the timeline clip to frame 20 gives one-hot weights and the
# evaluated vertices of fourd-play's frame 20 (within 0.01 mm plain, 1 mm compressed: the 0.8 mm
# position grid); the render through studio camera 0 matches fourd-play's render of that frame
# (PSNR over the character's pixels >= 30 dB with the frame's blended key textures, which the
# mesh sequence writes; >= 20 dB with the .glb's single texture, the template frame's).
# Skipped (exit 77) without chromium, three or puppeteer-core.
# usage: threejs_import.sh <tiny session> <work dir>   (FOURD_BIN: folder of the executables)
set -euo pipefail
command -v node >/dev/null || { echo "SKIP: node is not installed"; exit 77; }
source "$(dirname "$0")/export_common.sh"
frame=20
frame5=$(printf %05d $frame)

echo "== export, play, render, the frame's texture"
"$bin/fourd-export" "$asset" -o "$work/tiny.glb" --script "$script"
"$bin/fourd-export" "$asset" -o "$work/tiny_compressed.glb" --script "$script" --compress \
  --texture-format jpeg
"$bin/fourd-play" "$asset" "$script" -o "$work/play" --render "$work/render" --render-every 10 \
  --camera studio:0 --calibration "$session/calibration" --image-size 640x480
"$bin/fourd-export" "$asset" --sequence "$work/sequence" --script "$script" --duration 0.7
"$bin/client_check" camera "$session/calibration" 0 640 480 "$work/camera.json"
reference="$work/render/frame_$frame5.png"
texture="$work/sequence/frame_$frame5.png"

run_page() {  # glb out-stem [check.js options]
  local glb="$1" out="$2"
  shift 2
  set +e
  node "$here/threejs/check.js" "$glb" timeline "$frame" "$work/camera.json" "$out.json" "$out.png" "$@"
  local status=$?
  set -e
  [ "$status" -eq 0 ] || exit "$status"  # 77: skipped
  python3 - "$out.json" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
assert r["clips"] == ["walk_slow", "walk_fast", "jump_short", "jump_long", "timeline"], r["clips"]
assert r["targets"] == 331, r["targets"]
assert abs(r["max_weight"] - 1) < 1e-6 and abs(r["weight_sum"] - 1) < 1e-6, "weights are not one-hot"
PY
}

echo "== three.js: plain"
run_page "$work/tiny.glb" "$work/plain" --texture "$texture"
"$bin/client_check" positions "$asset" "$work/play/meshes/frame_$frame5.ply" "$work/plain.json" 0.01
"$bin/client_check" image "$reference" "$work/plain.png" 30
run_page "$work/tiny.glb" "$work/plain_glb_texture"
"$bin/client_check" image "$reference" "$work/plain_glb_texture.png" 20

echo "== three.js: compressed"
run_page "$work/tiny_compressed.glb" "$work/compressed" --compressed --texture "$texture"
"$bin/client_check" positions "$asset" "$work/play/meshes/frame_$frame5.ply" "$work/compressed.json" 1.0
"$bin/client_check" image "$reference" "$work/compressed.png" 30
run_page "$work/tiny_compressed.glb" "$work/compressed_glb_texture" --compressed
"$bin/client_check" image "$reference" "$work/compressed_glb_texture.png" 20
echo "three.js import ok"
