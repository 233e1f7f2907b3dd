#!/usr/bin/env bash
# End-to-end from what a studio hands over: a small synthetic plate studio (a furnished room,
# no screen, plates of the empty room, flickering lights) is turned into what a studio gives
# fourd by scripts/handover.sh - one lossless video per camera holding both takes one after
# the other, the calibration as OpenCV FileStorage in millimetres, the plates of the empty
# room as a short video per camera - then imported into a new session (no stages.synth: a
# real capture to the driver), segmented and reconstructed. Checks: the imported frames are the synthetic ones pixel for pixel, segment
# picked the plates, validation (given the synthetic session's ground truth) finds the
# silhouettes about right, reconstruct flags the frames it could not do well, and a second
# run skips what is up to date.
# usage: import_plate_studio.sh <work dir>   (FOURD_BIN: folder of the fourd executables)
set -euo pipefail
work="$1"
bin="${FOURD_BIN:?FOURD_BIN must name the folder of the fourd executables}"
source_dir="$(cd "$(dirname "$0")/../.." && pwd)"
rm -rf "$work"
mkdir -p "$work"
synth="$work/synthetic"
mkdir -p "$synth"

# The workflow test's two walks, filmed in the room studio.
python3 - "$source_dir/tests/workflow/session.yaml" "$synth/session.yaml" <<'PY'
import sys
text = open(sys.argv[1]).read()
text = text.replace("studio: {samples_per_pixel: 1, noise_sigma: 2.0}",
                    "studio: {samples_per_pixel: 1, noise_sigma: 2.0, backdrop: room}")
assert "backdrop: room" in text
open(sys.argv[2], "w").write(text)
PY
echo "== synth (room studio)"
"$bin/fourd" run "$synth" --only synth

echo "== the studio's hand-over (videos, calibration in mm, plates) and its import"
# The motion classes are the studio's to declare; session.yaml has no stages.synth section.
cat > "$work/imported.yaml" <<'YAML'
name: imported_plate_studio
fps: 8
motions:
  - {name: locomotion, takes: [walk_slow, walk_fast], parameter: speed, cyclic: true}
stages:
  reconstruct:
    visual_hull: {voxel_size: 0.009}
    calibration_check: {enabled: false}
    remesh: {target_vertices: 3000}
    isosurface_step: 3
  align: {template_vertices: 1500, handle_voxel: 0.006, reparent_attempts: 1,
          registration: {graph_nodes: 150, limb_fraction: 0}}
  timewarp: {max_closure_ratio: 0.7}
  texture: {resolution: 128}
oracle: []
YAML
# Checks that the imported frames are the synthetic ones pixel for pixel and the calibration
# the same to 1e-6.
FOURD_BIN="$bin" bash "$source_dir/scripts/handover.sh" "$synth" "$work/studio" \
  --format opencv --units mm --yaml "$work/imported.yaml"
session="$work/studio/imported"
for f in calibration capture plates; do
  test -f "$session/$f/imported.json" || { echo "no $f/imported.json"; exit 1; }
done

echo "== segment and reconstruct the imported session"
# Segment and reconstruct only, to keep the test short. On these 320x240 frames the plate key
# reached segment.iou_mean 0.968 and the meshes completeness 0.81 at 0.6 % of the height (one
# pixel is about 12 mm at the subject) when this was written. Validation compares with the
# synthetic session's truth (only validation reads it).
cp -r "$synth/ground_truth" "$session/ground_truth"
"$bin/fourd" run "$session" --only segment
"$bin/fourd" run "$session" --only reconstruct
"$bin/fourd" run "$session" --only validate
python3 - "$session" <<'PY'
import json, sys
s = sys.argv[1]
seg = json.load(open(f"{s}/segment/report.json"))
assert seg["method"] == "plate", f"segment used {seg['method']}, not the plates"
m = json.load(open(f"{s}/reports/metrics.json"))
iou = m["segment"]["iou_mean"]
rec = m["reconstruct"]["pipeline"]
print(f"segment.iou_mean {iou:.4f} (method {seg['method']}: {seg['reason']}); reconstruct "
      f"completeness_0p6pct_height {rec['completeness_0p6pct_height']:.3f}, "
      f"frames_flagged {rec['frames_flagged']}")
assert iou > 0.95, f"segment.iou_mean {iou}"
report = json.load(open(f"{s}/reconstruct/report.json"))
# What reconstruct could not do well it says, frame by frame. At 320x240 a pixel is about
# 12 mm at the subject, more than the 0.6 %-of-height tolerance: the green-screen tiny studio
# reaches 0.89 there, this one 0.79; below 0.7 a mesh misses much of the surface.
if rec["completeness_0p6pct_height"] < 0.7:
    assert report["summary"]["frames_flagged"] > 0, "poor meshes, but no frame flagged"
    assert len(report["warnings"]) > 0, "no warnings listed"
print("imported session ok")
PY
status=$("$bin/fourd" status "$session")
echo "$status"
grep -q "^synth .*not used" <<<"$status" || { echo "synth should not be used"; exit 1; }
grep -q "^segment .*done" <<<"$status" || { echo "segment should be done"; exit 1; }
again=$("$bin/fourd" run "$session" --only segment 2>&1)
grep -q "ran 0 stage(s)" <<<"$again" || { echo "a second segment run was not a no-op: $again"; exit 1; }
echo "import_plate_studio ok"
