#!/usr/bin/env bash
# How reconstruction depends on the rig, and what COLMAP's refinement does for a wrong
# calibration. Synthesises small sessions (three takes of the default sample: a walk, a high
# jump, a low reach) into OUT/ and prints a markdown summary (also OUT/summary.md):
#   - rigs of 6, 8 and 12 cameras: synth, segment, reconstruct, validate; the reconstruct.*
#     and segment.* metrics of each;
#   - 8 cameras with a perturbed calibration (synth's calibration_noise): the COLMAP
#     calibration check before and after bundle-adjustment refinement, the reprojection error
#     on held-out frames with the perturbed, the refined and the true calibration, and the
#     refined poses against the true ones.
# Usage: bash scripts/reconstruct_study.sh OUT [--threads N]   (needs a build: scripts/build.sh)
set -euo pipefail
if [[ $# -lt 1 || "$1" == -h || "$1" == --help ]]; then
  sed -n '2,9p' "$0" | sed 's/^# \{0,1\}//'
  exit 2
fi
out="$1"
shift
repo="$(cd "$(dirname "$0")/.." && pwd)"
bin="$repo/build/bin"
[[ -x "$bin/fourd" ]] || { echo "error: $bin/fourd not found: run scripts/build.sh first" >&2; exit 3; }
mkdir -p "$out"
out="$(cd "$out" && pwd)"

# One session: $1 folder, $2 extra lines for stages.synth.
write_session() {
  mkdir -p "$1"
  cat > "$1/session.yaml" <<EOF
# Written by scripts/reconstruct_study.sh: three takes of the default sample.
name: $(basename "$1")
fps: 12
motions:
  - {name: walk, takes: [walk_mid], parameter: speed, cyclic: true}
  - {name: jump, takes: [jump_high], parameter: height}
  - {name: reach, takes: [reach_low], parameter: reach}
stages:
  synth:
    seed: 2012
    rig: {count: $2, radius: 3.5, height: 1.6, width: 640, height_px: 480, focal_px: 560,
          k1: -0.02, k2: 0.004}
    studio: {samples_per_pixel: 4, noise_sigma: 2.0}
$3
    takes:
      - {take: walk_mid,  kind: walk,  frames: 18, speed: 1.3}
      - {take: jump_high, kind: jump,  frames: 29, jump_length: 0.3, jump_height: 0.4}
      - {take: reach_low, kind: reach, frames: 20, reach_target: [0.45, -0.25, 0.5]}
EOF
}

metric() {  # $1 metrics.json, $2 jq path
  jq -r "$2 // \"-\" | if type == \"number\" then (. * 1000 | round / 1000) else . end" "$1"
}

summary="$out/summary.md"
{
  echo "## Reconstruction against the number of cameras"
  echo
  echo "| cameras | segment IoU | hull acc. median [mm] | acc. median [mm] | acc. p90 [mm] | completeness 10 mm | hull completeness | F-score 5 mm | s/frame |"
  echo "|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
} > "$summary"

for n in 6 8 12; do
  s="$out/cameras_$n"
  write_session "$s" "$n" ""
  echo "== $n cameras: $s" >&2
  for stage in synth segment reconstruct validate; do
    "$bin/fourd" run "$s" --only "$stage" "$@" >&2
  done
  m="$s/reports/metrics.json"
  printf '| %s | %s | %s | %s | %s | %s | %s | %s | %s |\n' "$n" \
    "$(metric "$m" .segment.iou_mean)" \
    "$(metric "$m" '.reconstruct.pipeline["visual_hull.accuracy_median_mm"]')" \
    "$(metric "$m" .reconstruct.pipeline.accuracy_median_mm)" \
    "$(metric "$m" .reconstruct.pipeline.accuracy_p90_mm)" \
    "$(metric "$m" .reconstruct.pipeline.completeness_10mm)" \
    "$(metric "$m" '.reconstruct.pipeline["visual_hull.completeness_10mm"]')" \
    "$(metric "$m" .reconstruct.pipeline.fscore_5mm)" \
    "$(metric "$m" .reconstruct.pipeline.seconds_per_frame)" >> "$summary"
done

s="$out/perturbed"
write_session "$s" 8 "    calibration_noise: {rotation_deg: 0.3, translation_mm: 10, focal_pct: 1}"
echo "== perturbed calibration: $s" >&2
"$bin/fourd" run "$s" --only synth "$@" >&2
"$bin/fourd" run "$s" --only segment "$@" >&2
"$bin/fourd-reconstruct" "$s" --check-calibration --refine-calibration >&2
r="$s/reconstruct/calibration_check/report.json"
# The same check on the same images with the true calibration: the error floor of the features.
t="$out/perturbed_true_calibration"
rm -rf "$t" && mkdir -p "$t/reconstruct"
cp "$s/session.yaml" "$t/" && cp -al "$s/capture" "$s/segment" "$t/"
cp -r "$s/ground_truth/calibration" "$t/calibration"
"$bin/fourd-reconstruct" "$t" --check-calibration --refine-calibration >&2
rt="$t/reconstruct/calibration_check/report.json"
{
  echo
  echo "## COLMAP calibration check, 8 cameras, calibration perturbed by synth"
  echo "(rotation 0.3°, translation 10 mm, focal length 1 %, standard deviations)"
  echo
  echo "Checked frames ($(jq -r '"\(.frames), the first take \(.take) frame \(.frame)"' "$r")), then the"
  echo "refinement's frames spread through the session: its errors are over the frames it was"
  echo "fitted to."
  echo
  echo "| camera | points | median reprojection error [px] | points after refinement | after refinement [px] |"
  echo "|---|---:|---:|---:|---:|"
  jq -r '
    def err(e): if (e.observations // 0) > 0 then (e.median_error_px * 1000 | round / 1000 | tostring) else "-" end;
    .refined as $r | .cameras | to_entries[] |
    "| \(.key) | \(.value.observations) | \(err(.value)) | \($r[.key].observations // 0) | \(err($r[.key] // {})) |"' "$r"
  echo
  echo "Frames the refinement never saw (every third of its frames), triangulated with each"
  echo "calibration at the same error bound:"
  echo
  echo "| calibration | points | mean reprojection error [px] |"
  echo "|---|---:|---:|"
  jq -r '.refinement | "| written (perturbed) | \(.held_out_before.points) | \(.held_out_before.mean_error_px * 1000 | round / 1000) |",
    "| refined (\(.fit_frames) frames, \(.fit_points) points; \(if .accepted then "accepted" else "rejected" end)) | \(.held_out_after.points) | \(.held_out_after.mean_error_px * 1000 | round / 1000) |"' "$r"
  jq -r '.refinement | "| true | \(.held_out_before.points) | \(.held_out_before.mean_error_px * 1000 | round / 1000) |"' "$rt"
  echo
  echo "Camera poses against the true calibration (ground_truth/calibration), as written by synth"
  echo "and after refinement: centre distance [mm] and rotation angle [deg]."
  echo
  python3 - "$s/ground_truth/calibration" "$s/calibration" \
    "$s/reconstruct/calibration_check/refined" <<'PY'
import math, os, sys
def poses(folder):
    out = {}
    if not os.path.exists(folder + "/images.txt"):  # the check did not refine (see its warnings)
        return out
    with open(folder + "/images.txt") as f:
        lines = [l.split() for l in f if not l.startswith("#")]
    for r in lines[::2]:  # an image line, then its (maybe empty) points line
        if len(r) < 10:
            continue
        qw, qx, qy, qz, tx, ty, tz = map(float, r[1:8])
        R = [[1 - 2*(qy*qy + qz*qz), 2*(qx*qy - qz*qw), 2*(qx*qz + qy*qw)],
             [2*(qx*qy + qz*qw), 1 - 2*(qx*qx + qz*qz), 2*(qy*qz - qx*qw)],
             [2*(qx*qz - qy*qw), 2*(qy*qz + qx*qw), 1 - 2*(qx*qx + qy*qy)]]
        c = [-sum(R[j][i] * t for j, t in enumerate((tx, ty, tz))) for i in range(3)]
        out[r[9]] = (R, c)
    return out
def angle(a, b):  # rotation angle of a^T b [deg]
    tr = sum(a[k][i] * b[k][i] for i in range(3) for k in range(3))
    return math.degrees(math.acos(max(-1.0, min(1.0, (tr - 1) / 2))))
truth, written, refined = (poses(d) for d in sys.argv[1:4])
print("| camera | written: centre [mm] | rotation [deg] | refined: centre [mm] | rotation [deg] |")
print("|---|---:|---:|---:|---:|")
for name in sorted(truth):
    row = [name.replace(".png", "")]
    for model in (written, refined):
        if name not in model:
            row += ["-", "-"]
            continue
        R, c = model[name]
        row += ["%.1f" % (1e3 * math.dist(c, truth[name][1])), "%.3f" % angle(R, truth[name][0])]
    print("| " + " | ".join(row) + " |")
PY
} >> "$summary"
cat "$summary"
