#!/usr/bin/env bash
# A synthetic session as a studio hands it over, and imported back: one lossless video per
# camera holding every take one after the other (FFV1, at the session's frame rate), the
# calibration in a foreign format and unit, and the plates of the empty studio per camera
# when the session has plates/ (an image, or a video of several). Then `fourd import` builds
# a new session from that hand-over alone (no stages.synth: a real capture to the driver),
# with the takes cut from the videos by frame range, and checks that the imported frames are
# the synthetic ones pixel for pixel and every camera's projection matrix within 1e-6
# relative. With --segment, segments the imported session and validates it against the
# synthetic session's ground truth (copied in: only validation reads it).
#
# Usage: bash scripts/handover.sh SYNTH_SESSION OUT [--format F] [--units U] [--yaml FILE]
#                                 [--segment]
#   SYNTH_SESSION  a session whose synth stage has run (capture/, calibration/, ground_truth/)
#   OUT            written: OUT/handover/ (videos/, plates/, calibration.*), OUT/imported/
#   --format F     calibration format: opencv (default), opencv-names, opencv-files, csv,
#                  csv-pixels, json, json-keyed, colmap
#   --units U      its length unit: m, cm or mm (default mm; colmap: m)
#   --yaml FILE    session.yaml of the imported session (default: SYNTH_SESSION's without
#                  its stages.synth section)
# Needs a build (scripts/build.sh, or FOURD_BIN naming the executables' folder), ffmpeg and
# python3 with PyYAML.
set -euo pipefail
usage() { sed -n '2,22p' "$0" | sed 's/^# \{0,1\}//'; exit "${1:-2}"; }
[[ "${1:-}" == -h || "${1:-}" == --help ]] && usage 0
[[ $# -ge 2 ]] || usage
[[ -d "$1" ]] || { echo "error: no session folder '$1'" >&2; exit 2; }
synth="$(cd "$1" && pwd)"
out="$2"
shift 2
format=opencv units=mm yaml="" segment=0
while [[ $# -gt 0 ]]; do
  case "$1" in
    --format) format="$2"; shift 2 ;;
    --units) units="$2"; shift 2 ;;
    --yaml) yaml="$(cd "$(dirname "$2")" && pwd)/$(basename "$2")"; shift 2 ;;
    --segment) segment=1; shift ;;
    *) echo "error: unknown argument '$1'" >&2; usage ;;
  esac
done
[[ "$format" == colmap ]] && units=m
repo="$(cd "$(dirname "$0")/.." && pwd)"
bin="${FOURD_BIN:-$repo/build/bin}"
[[ -x "$bin/fourd" ]] || { echo "error: $bin/fourd not found: run scripts/build.sh first" >&2; exit 3; }
for d in capture calibration; do
  [[ -d "$synth/$d" ]] || { echo "error: $synth has no $d/: run its synth stage first" >&2; exit 3; }
done
rm -rf "$out"
mkdir -p "$out/handover/videos" "$out/imported"
out="$(cd "$out" && pwd)"
studio="$out/handover"
session="$out/imported"

# The takes in session order with their frame counts, and the session.yaml to import into.
mapfile -t takes < <(python3 - "$synth" "$session/session.yaml" "$yaml" <<'PY'
import os, sys, yaml
synth, target, given = sys.argv[1:4]
config = yaml.safe_load(open(os.path.join(synth, "session.yaml")))
names = [t["take"] for t in config.get("stages", {}).get("synth", {}).get("takes", [])]
names = names or sorted(os.listdir(os.path.join(synth, "capture")))
print(config.get("fps", 25))
if given:
    text = open(given).read()
else:
    config.get("stages", {}).pop("synth", None)
    config["name"] = config.get("name", "session") + "_imported"
    text = yaml.safe_dump(config, sort_keys=False)
open(target, "w").write(text)
for name in names:
    cams = sorted(os.listdir(os.path.join(synth, "capture", name)))
    print(name, len(os.listdir(os.path.join(synth, "capture", name, cams[0]))))
PY
)
fps="${takes[0]}"
takes=("${takes[@]:1}")
cameras=$(ls "$synth/capture/${takes[0]%% *}")

echo "== hand-over: $(wc -w <<<"$cameras") videos, calibration as $format in $units"
for cam in $cameras; do
  seq_dir="$out/seq/$cam"
  mkdir -p "$seq_dir"
  i=0
  for entry in "${takes[@]}"; do
    for f in "$synth/capture/${entry%% *}/$cam"/*.png; do
      ln -s "$f" "$seq_dir/$(printf '%06d' $i).png"
      i=$((i + 1))
    done
  done
  ffmpeg -loglevel error -y -framerate "$fps" -i "$seq_dir/%06d.png" -c:v ffv1 \
    "$studio/videos/$cam.mkv"
  if [[ -d "$synth/plates/$cam" ]]; then
    # One plate: an image; several: a short video of the empty studio.
    mkdir -p "$studio/plates"
    if [[ $(ls "$synth/plates/$cam" | wc -l) -eq 1 ]]; then
      cp "$synth/plates/$cam/000000.png" "$studio/plates/$cam.png"
    else
      ffmpeg -loglevel error -y -framerate "$fps" -i "$synth/plates/$cam/%06d.png" -c:v ffv1 \
        "$studio/plates/$cam.mkv"
    fi
  fi
done
rm -rf "$out/seq"
case "$format" in
  colmap|opencv-files) calibration="$studio/calibration" ;;
  opencv|opencv-names) calibration="$studio/calibration.yml" ;;
  csv|csv-pixels) calibration="$studio/calibration.csv" ;;
  json|json-keyed) calibration="$studio/calibration.json" ;;
  *) echo "error: unknown --format '$format'" >&2; exit 2 ;;
esac
units_arg=(--export-units "$units")
"$bin/fourd-import" "$synth" --export-calibration "$format" "${units_arg[@]}" --output "$calibration"

echo "== import"
take_args=()
first=0
for entry in "${takes[@]}"; do
  name="${entry%% *}" count="${entry##* }"
  take_args+=(--take "$name=$first:$((first + count - 1))")
  first=$((first + count))
done
plate_args=()
[[ -d "$studio/plates" ]] && plate_args=(--plates "$studio/plates")
csv_args=()
[[ "$format" == csv* ]] && csv_args=(--units "$units")
"$bin/fourd" import "$session" --calibration "$calibration" --videos "$studio/videos" \
  "${take_args[@]}" "${plate_args[@]}" "${csv_args[@]}"

echo "== the imported session is the synthetic one"
# Both calibrations as fourd reads them (its own COLMAP reader, written as JSON in metres).
mkdir -p "$out/check"
for side in synth session; do
  "$bin/fourd-import" "${!side}" --export-calibration json --export-units m \
    --output "$out/check/$side.json" > /dev/null
done
python3 - "$out/check/synth.json" "$out/check/session.json" <<'PY'
import json, sys
def cameras(path):
    # Per camera name: P = K [R | t], flattened, and the distortion.
    out = {}
    for c in json.load(open(path))["cameras"]:
        Rt = [c["R"][i] + [c["t"][i]] for i in range(3)]
        P = [sum(c["K"][i][m] * Rt[m][j] for m in range(3)) for i in range(3) for j in range(4)]
        out[c["name"]] = (P, c["dist"])
    return out
a, b = (cameras(p) for p in sys.argv[1:3])
assert sorted(a) == sorted(b), f"cameras {sorted(a)} vs {sorted(b)}"
worst = 0.0
for name in a:
    pa, da = a[name]
    pb, db = b[name]
    scale = max(abs(v) for v in pa)
    worst = max([worst] + [abs(u - v) / scale for u, v in zip(pa, pb)] +
                [abs(u - v) for u, v in zip(da, db)])
print(f"{len(a)} cameras, projection matrices within {worst:.2e} relative")
assert worst < 1e-6, f"calibration round trip off by {worst}"
PY
for entry in "${takes[@]}"; do
  name="${entry%% *}" count="${entry##* }"
  for cam in $(sed -n '1p;$p' <<<"$cameras"); do
    for frame in 0 $((count - 1)); do
      f="$(printf '%06d' "$frame").png"
      a=$(ffmpeg -loglevel error -i "$synth/capture/$name/$cam/$f" -f framemd5 - | tail -1)
      b=$(ffmpeg -loglevel error -i "$session/capture/$name/$cam/$f" -f framemd5 - | tail -1)
      [[ "${a##*,}" == "${b##*,}" ]] || { echo "error: $name/$cam/$f: pixels differ" >&2; exit 1; }
    done
  done
  n=$(ls "$session/capture/$name/${cameras%%$'\n'*}" | wc -l)
  [[ "$n" -eq "$count" ]] || { echo "error: take $name has $n frames, not $count" >&2; exit 1; }
done
echo "frames: every take's first and last frame of the first and last camera pixel-identical"

if [[ "$segment" -eq 1 ]]; then
  echo "== segment and validate the imported session"
  cp -r "$synth/ground_truth" "$session/ground_truth"
  "$bin/fourd" run "$session" --only segment
  "$bin/fourd" run "$session" --only validate
  python3 - "$session" <<'PY'
import json, sys
s = sys.argv[1]
seg = json.load(open(f"{s}/segment/report.json"))
m = json.load(open(f"{s}/reports/metrics.json"))["segment"]
print(f"segment method {seg['method']} ({seg['reason']}): iou_mean {m['iou_mean']:.4f}, "
      f"iou_min {m['iou_min']:.4f}")
PY
fi
echo "handover ok: $out"
