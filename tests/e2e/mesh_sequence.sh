#!/usr/bin/env bash
# Mesh-sequence export of the tiny sample's asset (made by e2e_tiny_sample, the fixture): the
# timeline script's result (PLY + JPEG per frame) and one take (OBJ + PNG); the manifest lists
# every frame with its files and bounding box; a frame's mesh is fourd-play's mesh of that frame;
# bad requests are refused, and a refused run leaves the previous folder as it was.
# usage: mesh_sequence.sh <tiny session> <work dir>   (FOURD_BIN: folder of the executables)
set -euo pipefail
source "$(dirname "$0")/export_common.sh"

echo "== script result as PLY"
"$bin/fourd-export" "$asset" --sequence "$work/timeline" --script "$script" --texture-format jpeg
"$bin/fourd-play" "$asset" "$script" -o "$work/play"
echo "== take as OBJ"
"$bin/fourd-export" "$asset" --sequence "$work/walk_fast" --take walk_fast --sequence-format obj

echo "== manifests"
python3 - "$work" <<'PY'
import json, os, sys
work = sys.argv[1]
def check(folder, frames, mesh_ext, tex_ext, fps=None):
    m = json.load(open(os.path.join(work, folder, "sequence.json")))
    assert m["frame_count"] == frames == len(m["frames"]), (folder, m["frame_count"], frames)
    assert fps is None or abs(m["fps"] - fps) < 1e-9, (folder, m["fps"])
    times = [f["time"] for f in m["frames"]]
    assert all(b > a for a, b in zip(times, times[1:])), f"{folder}: times do not increase"
    lo, hi = m["bounding_box"]["min"], m["bounding_box"]["max"]
    for f in m["frames"]:
        for key, ext in (("mesh", mesh_ext), ("texture", tex_ext)):
            assert f[key].endswith(ext), (folder, f[key])
            assert os.path.getsize(os.path.join(work, folder, f[key])) > 0, f[key]
        b = f["bounding_box"]
        assert all(lo[k] <= b["min"][k] <= b["max"][k] <= hi[k] for k in range(3)), (folder, f)
        assert 1.0 < b["max"][2] - b["min"][2] < 2.5, f"{folder}: a frame {b} is not a person"
    print(f"{folder}: {m['frame_count']} frames at {m['fps']:.2f} fps, {m['vertices']} vertices, "
          f"box {lo} .. {hi}")
    return m
played = sum(1 for _ in open(os.path.join(work, "play", "frames.csv"))) - 1
check("timeline", played, ".ply", ".jpg", fps=30)
check("walk_fast", len(json.load(open(os.path.join(work, "walk_fast", "sequence.json")))["frames"]),
      ".obj", ".png")
assert os.path.exists(os.path.join(work, "walk_fast", "frame_00000.mtl"))
PY
echo "== frames are fourd-play's"
for f in 00000 00100 00240; do
  "$bin/client_check" meshes "$work/timeline/frame_$f.ply" "$work/play/meshes/frame_$f.ply" 0.001
done

echo "== bad requests"
before=$(ls "$work/walk_fast" | wc -l)
expect_failure 2 "--take nope" "$bin/fourd-export" "$asset" --sequence "$work/walk_fast" --take nope
expect_failure 2 "needs one of --take" "$bin/fourd-export" "$asset" --sequence "$work/walk_fast"
expect_failure 2 "--sequence-format stl" "$bin/fourd-export" "$asset" --sequence "$work/x" \
  --take walk_fast --sequence-format stl
[ "$(ls "$work/walk_fast" | wc -l)" -eq "$before" ] || { echo "a refused run changed the folder"; exit 1; }
test ! -e "$work/x" || { echo "a refused run made a folder"; exit 1; }
ls -a "$work" | grep -q staging && { echo "a staging folder was left"; exit 1; }
echo "mesh sequence ok"
