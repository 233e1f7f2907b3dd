#!/usr/bin/env bash
# fourd-view under Xvfb (Mesa's software OpenGL): (1) a screenshot of the tiny session's character
# at a fixed frame, with the default camera, matches the committed reference render within a
# tolerance, and one at another frame does not; (2) the panels draw; (3) the renderer blends key
# textures on the GPU with the weights given (viewer_key_blend_check); (4) an asset without key
# textures is shaded from its normals; (5) corrupt and missing assets and an unwritable
# screenshot are refused with a message naming the file and their exit code.
# usage: viewer_test.sh <fourd-view> <viewer_key_blend_check> <tiny session asset> <tests dir>
#        <work dir>
# Exit 77 (skipped) when xvfb-run is missing.
set -euo pipefail
view="$1"
key_blend_check="$2"
asset="$3"
tests="$4"
work="$5"
reference="$tests/viewer/reference_tiny.png"
if ! command -v xvfb-run > /dev/null; then
  echo "SKIPPED: xvfb-run is missing (Debian package xvfb; scripts/setup.sh installs it)"
  exit 77
fi
test -f "$asset" || { echo "no asset $asset: the e2e_tiny_sample test makes it"; exit 1; }
rm -rf "$work"
mkdir -p "$work"
run() {  # a headless viewer at 640x360, the camera 2.5 m from the character
  xvfb-run -a -s "-screen 0 1280x720x24" "$view" --width 640 --height 360 --distance 2.5 "$@"
}
# Mean absolute error (0..1) and PSNR [dB] of two images, from OpenImageIO's idiff.
compare() {
  idiff -v -fail 1 "$1" "$2" | awk '/Mean error/ {m = $4} /Peak SNR/ {p = $4} END {print m, p}'
}
within() {  # within MEAN PSNR MAX_MEAN MIN_PSNR
  awk -v m="$1" -v p="$2" -v mm="$3" -v mp="$4" 'BEGIN {exit !(m <= mm && (p == "inf" || p >= mp))}'
}

echo "== the character at frame 45 against the reference render"
run "$asset" --no-ui --screenshot "$work/frame45.png" --frames 45 2>&1 | tee "$work/frame45.log"
test -s "$work/frame45.png" || { echo "no screenshot written"; exit 1; }
grep -q "key textures of .* blended on the GPU" "$work/frame45.log" ||
  { echo "the tiny asset's key textures were not uploaded"; exit 1; }
read -r mean psnr < <(compare "$work/frame45.png" "$reference")
echo "mean abs error $mean, PSNR $psnr dB (want <= 0.006 and >= 30 dB)"
within "$mean" "$psnr" 0.006 30 || { echo "the render differs from $reference"; exit 1; }

echo "== another frame does not pass for the reference (the comparison can fail)"
run "$asset" --no-ui --screenshot "$work/frame20.png" --frames 20 > /dev/null 2>&1
read -r mean psnr < <(compare "$work/frame20.png" "$reference")
echo "frame 20 against the reference: mean abs error $mean, PSNR $psnr dB"
if within "$mean" "$psnr" 0.006 30; then echo "frame 20 passed for frame 45"; exit 1; fi

echo "== the panels draw over the scene"
run "$asset" --screenshot "$work/ui.png" --frames 45 > /dev/null 2>&1
read -r mean psnr < <(compare "$work/ui.png" "$work/frame45.png")
echo "with panels against without: mean abs error $mean"
if within "$mean" "$psnr" 0.002 40; then echo "no panels drawn"; exit 1; fi

echo "== key textures blended on the GPU"
xvfb-run -a -s "-screen 0 1280x720x24" "$key_blend_check"

echo "== an asset without key textures is shaded from its normals"
plain="$tests/fuzz/corpus/asset/tube_graph_no_turns.fourd"
run "$plain" --no-ui --screenshot "$work/plain.png" --frames 5 2>&1 | tee "$work/plain.log"
grep -q "no key textures in the asset: shading from the blended normals" "$work/plain.log"
test -s "$work/plain.png"

echo "== bad input"
expect_failure() {  # expect_failure CODE TEXT args...
  local code="$1" text="$2"
  shift 2
  set +e
  run "$@" --screenshot "$work/never.png" --frames 2 > "$work/bad.log" 2>&1
  local got=$?
  set -e
  cat "$work/bad.log"
  [ "$got" -eq "$code" ] || { echo "exit code $got, expected $code"; exit 1; }
  grep -q -- "$text" "$work/bad.log" || { echo "no message naming '$text'"; exit 1; }
  [ ! -e "$work/never.png" ] || { echo "a screenshot was written"; exit 1; }
}
size=$(stat -c %s "$asset")
cp "$asset" "$work/flipped.fourd"
printf '\xff' | dd of="$work/flipped.fourd" bs=1 seek=$((size / 2)) conv=notrunc status=none
expect_failure 4 "$work/flipped.fourd" "$work/flipped.fourd"
head -c $((size / 3)) "$asset" > "$work/truncated.fourd"
expect_failure 4 "$work/truncated.fourd" "$work/truncated.fourd"
expect_failure 5 "$work/missing.fourd" "$work/missing.fourd"
set +e
run "$asset" --screenshot "$work/no/such/folder/shot.png" --frames 2 > "$work/bad.log" 2>&1
got=$?
set -e
cat "$work/bad.log"
[ "$got" -eq 5 ] && grep -q "no/such/folder/shot.png" "$work/bad.log" ||
  { echo "an unwritable screenshot path: exit code $got, expected 5 naming the file"; exit 1; }
echo "viewer ok"
