# Opens fourd-export's .glb in Blender, headless, the way a user imports it (File > Import >
# glTF 2.0), and checks what a user finds there: one mesh whose shape keys are the frames, every
# clip as actions (the shape-key action and the object's root-motion action carry the clip's
# name). Then plays frame FRAME of clip CLIP: mutes the NLA tracks the importer makes, makes the
# clip's two actions the active ones, goes to the Blender frame where the clip's key of that
# frame weighs 1, and writes the evaluated mesh's world vertices (converted back to glTF axes:
# Blender imports glTF's y-up as its z-up) to OUT.json, for client_check to compare with
# fourd-play's mesh of the same frame. With --ply FILE it also imports a PLY (a frame of
# fourd-export --sequence) and writes its vertex count.
# usage: blender -b --factory-startup --python blender_check.py -- GLB CLIP FRAME OUT.json
#            [--clips NAME,...] [--targets N] [--ply FILE]
# Exits 1 naming what is missing.
import json
import sys

import warnings

import bpy
import numpy

# Debian's Blender 3.4 glTF importer still calls numpy.bool, which numpy 1.24 (Debian 12)
# removed: give it back the builtin it aliased.
with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    if not hasattr(numpy, "bool"):
        numpy.bool = bool


def fail(message):
    print(f"blender_check: {message}", file=sys.stderr)
    sys.exit(1)


argv = sys.argv[sys.argv.index("--") + 1:]
glb, clip, frame, out = argv[0], argv[1], int(argv[2]), argv[3]
options = dict(zip(argv[4::2], argv[5::2]))

bpy.ops.wm.read_factory_settings(use_empty=True)
result = bpy.ops.import_scene.gltf(filepath=glb)
if result != {"FINISHED"}:
    fail(f"{glb}: the glTF importer returned {result}")
meshes = [o for o in bpy.data.objects if o.type == "MESH"]
if len(meshes) != 1:
    fail(f"{glb}: {len(meshes)} mesh objects, expected one")
obj = meshes[0]
keys = obj.data.shape_keys
if keys is None:
    fail(f"{glb}: the mesh has no shape keys")
num_keys = len(keys.key_blocks) - 1  # less the Basis
if "--targets" in options and num_keys != int(options["--targets"]):
    fail(f"{glb}: {num_keys} shape keys, expected {options['--targets']}")

# Every clip is two actions: the object's (root motion) and the shape keys'.
actions = {"OBJECT": {}, "KEY": {}}
for action in bpy.data.actions:
    for name in options.get("--clips", clip).split(",") + [clip]:
        if action.name.startswith(name + "_") and action.id_root in actions:
            actions[action.id_root].setdefault(name, action)
clips = sorted(set(actions["OBJECT"]) & set(actions["KEY"]))
for name in options.get("--clips", clip).split(","):
    if name not in clips:
        fail(f"{glb}: clip '{name}' is not an object and a shape-key action "
             f"(actions: {[a.name for a in bpy.data.actions]})")

# Play frame `frame` of the clip alone.
for data in (obj, keys):
    if data.animation_data:
        for track in data.animation_data.nla_tracks:
            track.mute = True
obj.animation_data.action = actions["OBJECT"][clip]
keys.animation_data.action = actions["KEY"][clip]
key_name = f"{clip}.{frame:04d}"
curve = actions["KEY"][clip].fcurves.find(f'key_blocks["{key_name}"].value')
if curve is None:
    fail(f"{glb}: no animation of shape key {key_name}")
at = [k.co.x for k in curve.keyframe_points if abs(k.co.y - 1) < 1e-6]
if not at:
    fail(f"{glb}: shape key {key_name} never weighs 1")
scene = bpy.context.scene
scene.frame_set(int(at[0] // 1), subframe=at[0] - at[0] // 1)
depsgraph = bpy.context.evaluated_depsgraph_get()
evaluated = obj.evaluated_get(depsgraph)
mesh = evaluated.to_mesh()
world = evaluated.matrix_world
positions = []
for v in mesh.vertices:
    p = world @ v.co
    positions += [p.x, p.z, -p.y]  # Blender z-up -> glTF y-up
report = {
    "client": f"Blender {bpy.app.version_string}",
    "glb": glb,
    "clip": clip,
    "frame": frame,
    "blender_frame": at[0],
    "clips": clips,
    "shape_keys": num_keys,
    "vertices": len(mesh.vertices),
    "positions": positions,
}
evaluated.to_mesh_clear()

if "--ply" in options:
    before = set(bpy.data.objects)
    bpy.ops.import_mesh.ply(filepath=options["--ply"])
    added = [o for o in bpy.data.objects if o not in before and o.type == "MESH"]
    if len(added) != 1:
        fail(f"{options['--ply']}: the PLY importer made {len(added)} meshes")
    report["ply"] = {"file": options["--ply"], "vertices": len(added[0].data.vertices),
                     "faces": len(added[0].data.polygons)}

with open(out, "w") as f:
    json.dump(report, f)
print(f"blender_check: {glb}: {num_keys} shape keys, clips {', '.join(clips)}; "
      f"{clip} frame {frame} at Blender frame {at[0]:.3f}: {report['vertices']} vertices -> {out}")
