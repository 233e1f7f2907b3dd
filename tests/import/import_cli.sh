#!/usr/bin/env bash
# fourd-import from the command line on a studio capture made here: a 3-camera calibration in a
# y-up world in millimetres (JSON), one lossless video per camera (ffmpeg), and the errors a
# studio meets: exit codes as every fourd executable has them, nothing written on failure.
#
# usage: import_cli.sh WORK   (FOURD_BIN: the folder of the fourd executables)
set -euo pipefail
work="$1"
bin="${FOURD_BIN:?FOURD_BIN must name the folder of the fourd executables}"
rm -rf "$work"
mkdir -p "$work/studio/videos"
cd "$work"

fail() { echo "FAIL: $*" >&2; exit 1; }
# expect CODE COMMAND...: runs it, checks its exit code, keeps its output in $out.
expect() {
  local want="$1"; shift
  set +e; out="$("$@" 2>&1)"; local got=$?; set -e
  [ "$got" -eq "$want" ] || { echo "$out" >&2; fail "exit $got, expected $want: $*"; }
}

# Three cameras 3 m from the point (0, 1500, 0) mm they look at, horizontal, y up.
cat > studio/calibration.json <<'JSON'
{"unit": "mm", "cameras": [
 {"name": "cam_a", "width": 64, "height": 48, "K": [[60, 0, 31.5], [0, 60, 23.5], [0, 0, 1]],
  "dist": [0, 0, 0, 0], "R": [[0, 0, -1], [0, -1, 0], [-1, 0, 0]], "t": [0, 1500, 3000]},
 {"name": "cam_b", "width": 64, "height": 48, "K": [[60, 0, 31.5], [0, 60, 23.5], [0, 0, 1]],
  "dist": [0, 0, 0, 0], "R": [[0, 0, 1], [0, -1, 0], [1, 0, 0]], "t": [0, 1500, 3000]},
 {"name": "cam_c", "width": 64, "height": 48, "K": [[60, 0, 31.5], [0, 60, 23.5], [0, 0, 1]],
  "dist": [0, 0, 0, 0], "R": [[1, 0, 0], [0, -1, 0], [0, 0, -1]], "t": [0, 1500, 3000]}]}
JSON
for cam in cam_a cam_b cam_c; do
  ffmpeg -loglevel error -y -f lavfi -i testsrc=size=64x48:rate=10 -frames:v 20 -c:v ffv1 \
    -pix_fmt bgr0 "studio/videos/studio_${cam}.mkv"
done

expect 0 "$bin/fourd-import" --help
grep -q -- "--calibration" <<<"$out" || fail "--help does not list --calibration"

expect 0 "$bin/fourd-import" s1 --calibration studio/calibration.json --videos studio/videos \
  --take walk=0:9 --take run=10:
grep -q "rotated the world so that +y becomes +z" <<<"$out" || { echo "$out"; fail "the y-up rig was not turned"; }
grep -q "lengths in mm, declared by the file" <<<"$out" || fail "the unit was not reported"
for take in walk run; do
  for cam in cam_a cam_b cam_c; do
    n=$(ls "s1/capture/$take/$cam" | wc -l)
    [ "$n" -eq 10 ] || fail "capture/$take/$cam has $n frames, expected 10"
  done
done
for f in calibration/imported.json capture/imported.json session.yaml calibration/cameras.txt; do
  [ -f "s1/$f" ] || fail "s1/$f is missing"
done
grep -q '"what": "capture"' s1/capture/imported.json || fail "capture/imported.json says what it is not"

# A camera without video: exit 4, both lists named, nothing written.
expect 4 "$bin/fourd-import" s2 --calibration studio/calibration.json \
  --videos studio/videos/studio_cam_a.mkv studio/videos/studio_cam_b.mkv --take walk
grep -q "cameras with no video: cam_c" <<<"$out" || fail "the camera without video was not named"
[ ! -e s2/calibration ] && [ ! -e s2/capture ] && [ ! -e s2/session.yaml ] || fail "a failed import left files"
# More frames asked than the videos have: exit 4.
expect 4 "$bin/fourd-import" s2 --calibration studio/calibration.json --videos studio/videos --take walk=0:99
grep -q "20 frames, but take walk asks for frames 0:99" <<<"$out" || fail "too few frames not named"
# Bad command lines: exit 2; an unknown unit: exit 3.
expect 2 "$bin/fourd-import" s2 --calibration studio/calibration.json --videos studio/videos
expect 3 "$bin/fourd-import" s2 --calibration studio/calibration.json --units furlong
[ ! -e s2/calibration ] || fail "a failed import left calibration/"

# The session's calibration out as CSV, and in again: the same rig.
expect 0 "$bin/fourd-import" s1 --export-calibration csv --output rig.csv
expect 0 "$bin/fourd-import" s3 --calibration rig.csv
grep -q "lengths in m, inferred" <<<"$out" || { echo "$out"; fail "the CSV's unit was not inferred"; }
grep -q "none: the rig is z-up" <<<"$out" || fail "the exported rig is not z-up"
# An existing calibration is not replaced without --replace (exit 2), and is with it.
expect 2 "$bin/fourd-import" s3 --calibration rig.csv
expect 0 "$bin/fourd-import" s3 --calibration rig.csv --replace
echo "import_cli: all checks passed"
