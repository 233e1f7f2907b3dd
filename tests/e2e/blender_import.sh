#!/usr/bin/env bash
# The tiny sample's glTF export opened in Blender (Debian's blender, headless): the import finds
# one mesh with a shape key per frame and every clip as actions; frame 100 of the timeline clip,
# played in Blender, is fourd-play's mesh of that frame, and frame 5 of take walk_fast is the
# mesh-sequence export's frame 5 (within 0.01 mm); a frame of the mesh sequence (PLY) imports
# with the asset's vertex count. The plain export: Debian's Blender 3.4 cannot read
# EXT_meshopt_compression. Skipped (exit 77) without blender.
# usage: blender_import.sh <tiny session> <work dir>   (FOURD_BIN: folder of the executables)
set -euo pipefail
command -v blender >/dev/null || { echo "SKIP: blender is not installed (scripts/setup.sh installs it)"; exit 77; }
source "$(dirname "$0")/export_common.sh"
tolerance_mm=0.01

echo "== export, play, sequence"
"$bin/fourd-export" "$asset" -o "$work/tiny.glb" --script "$script"
"$bin/fourd-play" "$asset" "$script" -o "$work/play"
"$bin/fourd-export" "$asset" --sequence "$work/walk_fast" --take walk_fast
clips=walk_slow,walk_fast,jump_short,jump_long,timeline
targets=$(python3 -c "import json,struct,sys; b=open(sys.argv[1],'rb').read(); \
n=struct.unpack('<I',b[12:16])[0]; j=json.loads(b[20:20+n]); \
print(len(j['meshes'][0]['primitives'][0]['targets']))" "$work/tiny.glb")
vertices=$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['vertices'])" \
  "$work/walk_fast/sequence.json")

run_blender() {  # clip frame out.json [extra args]
  local log="$work/blender_$1.log"
  if ! blender -b --factory-startup --python-exit-code 1 --python "$here/blender_check.py" -- \
       "$work/tiny.glb" "$@" --clips "$clips" --targets "$targets" > "$log" 2>&1; then
    cat "$log"
    echo "blender failed"
    exit 1
  fi
  grep -E "blender_check|Blender [0-9]" "$log" | head -3
}

echo "== Blender: timeline frame 100 vs fourd-play"
run_blender timeline 100 "$work/timeline_100.json" --ply "$work/walk_fast/frame_00005.ply"
"$bin/client_check" positions "$asset" "$work/play/meshes/frame_00100.ply" \
  "$work/timeline_100.json" "$tolerance_mm"
echo "== Blender: take walk_fast frame 5 vs the mesh sequence"
run_blender walk_fast 5 "$work/walk_fast_5.json"
"$bin/client_check" positions "$asset" "$work/walk_fast/frame_00005.ply" \
  "$work/walk_fast_5.json" "$tolerance_mm"
echo "== Blender: a frame of the mesh sequence"
python3 - "$work/timeline_100.json" "$vertices" <<'PY'
import json, sys
ply = json.load(open(sys.argv[1]))["ply"]
print(f"{ply['file']}: {ply['vertices']} vertices, {ply['faces']} faces in Blender")
assert ply["vertices"] == int(sys.argv[2]), f"{ply['vertices']} vertices, the asset has {sys.argv[2]}"
assert ply["faces"] > 0
PY
echo "blender import ok"
