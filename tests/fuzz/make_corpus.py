#!/usr/bin/env python3
"""Regenerates the seed corpora of the fuzz targets (tests/fuzz/corpus/<target>/).

usage: make_corpus.py FUZZ_WRITE_SEEDS   (build/bin/fuzz_write_seeds)

The COLMAP model, the glTF character, the BVH motion, the binary stage files (.twarp,
.mspace) and assets come from the real writers through fuzz_write_seeds (write_seeds.cpp). Meshes are written here (ASCII, binary
little- and big-endian PLY; OBJ with its MTL); the session YAML and control scripts are the
repository's own. Seeds are kept small (libFuzzer
mutates small inputs much faster); the test FuzzSeeds.EverySeedIsAccepted checks that every
seed still parses with today's readers. Files of tests/fuzz/legacy/<target>/ (older format
versions the readers still load, kept from before a format change) are not copied here:
run_fuzz.sh gives that folder to the fuzzer as a second seed corpus.
"""
import pathlib
import os
import shutil
import struct
import subprocess
import sys
import tempfile

ROOT = pathlib.Path(__file__).resolve().parents[2]
CORPUS = ROOT / "tests" / "fuzz" / "corpus"
MAX_SEED_BYTES = 256 * 1024


def put(target, name, data):
    d = CORPUS / target
    d.mkdir(parents=True, exist_ok=True)
    (d / name).write_bytes(data if isinstance(data, bytes) else data.encode())


def smallest(files, count):
    files = sorted((f for f in files if f.stat().st_size <= MAX_SEED_BYTES),
                   key=lambda f: f.stat().st_size)
    return files[:count]


# A unit cube's corner tetrahedron split: 5 vertices, 4 triangles and a quad (fan-triangulated).
VERTS = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 0.5)]
NORMALS = [(0, 0, -1), (1, 0, 0), (0, 1, 0), (0, 0, 1), (0.6, 0.6, 0.5)]
COLOURS = [(255, 0, 0), (0, 255, 0), (0, 0, 255), (128, 128, 128), (10, 20, 30)]
UVS = [(0, 0), (1, 0), (0, 1), (0.5, 0.5), (1, 1)]
FACES = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3), (1, 4, 2, 3)]


def ply_header(fmt, texcoord):
    h = [f"ply", f"format {fmt} 1.0", "comment TextureFile skin.png" if texcoord else None,
         f"element vertex {len(VERTS)}", "property float x", "property float y",
         "property float z", "property float nx", "property float ny", "property float nz",
         "property uchar red", "property uchar green", "property uchar blue",
         "property float s", "property float t", f"element face {len(FACES)}",
         "property list uchar int vertex_indices",
         "property list uchar float texcoord" if texcoord else None, "end_header"]
    return "\n".join(x for x in h if x is not None) + "\n"


def ply_ascii():
    out = ply_header("ascii", False)
    for v, n, c, t in zip(VERTS, NORMALS, COLOURS, UVS):
        out += " ".join(map(str, (*v, *n, *c, *t))) + "\n"
    for f in FACES:
        out += f"{len(f)} " + " ".join(map(str, f)) + "\n"
    return out.encode()


def ply_binary(endian):
    fmt = "binary_little_endian" if endian == "<" else "binary_big_endian"
    out = ply_header(fmt, True).encode()
    for v, n, c, t in zip(VERTS, NORMALS, COLOURS, UVS):
        out += struct.pack(endian + "6f3B2f", *v, *n, *c, *t)
    for f in FACES:
        out += struct.pack(endian + "B" + "i" * len(f), len(f), *f)
        uv = [x for i in f for x in UVS[i]]
        out += struct.pack(endian + "B" + "f" * len(uv), len(uv), *uv)
    return out


def obj():
    lines = ["mtllib input.mtl", "o corner"]
    lines += [f"v {x} {y} {z} {r / 255:.3f} {g / 255:.3f} {b / 255:.3f}"
              for (x, y, z), (r, g, b) in zip(VERTS, COLOURS)]
    lines += [f"vt {u} {v}" for u, v in UVS] + [f"vt 0.25 0.75"]
    lines += [f"vn {x} {y} {z}" for x, y, z in NORMALS]
    # Every corner form with texture coordinates: absolute, relative (negative) and a quad.
    lines += ["usemtl skin", "f 1/1/1 3/3/3 2/2/2", "f 1/6/1 2/2/2 4/4/4",
              "f -5/-6/-5 -2/-3/-2 -3/-4/-3", "f 2/2/2 5/5/5 3/3/3 4/4/4"]
    mtl = ["newmtl skin", "Kd 1 1 1", "map_Kd skin.png"]
    return "\n".join(lines) + "\n--8<-- input.mtl\n" + "\n".join(mtl) + "\n"


def write_seeds(writer, scratch):
    env = dict(os.environ, TMPDIR=str(scratch))
    subprocess.run([writer, str(scratch / "seeds")], env=env, check=True)


def colmap(calibration):
    cams = (calibration / "cameras.txt").read_text()
    imgs = (calibration / "images.txt").read_text()
    rig = (calibration / "rig.json").read_text()
    put("colmap_model", "rig", cams + "--8<-- images.txt\n" + imgs + "--8<-- rig.json\n" + rig)
    put("colmap_model", "no_rig", cams + "--8<-- images.txt\n" + imgs)


def main():
    scratch = pathlib.Path(tempfile.mkdtemp(prefix="fourd_corpus_"))
    write_seeds(sys.argv[1], scratch)
    seeds = scratch / "seeds"
    for target in ["colmap_model", "ply", "obj", "bvh", "gltf", "session_yaml", "twarp",
                   "mspace", "asset", "control_script"]:
        shutil.rmtree(CORPUS / target, ignore_errors=True)
    colmap(seeds / "colmap")
    put("ply", "ascii.ply", ply_ascii())
    put("ply", "binary_le.ply", ply_binary("<"))
    put("ply", "binary_be.ply", ply_binary(">"))
    put("obj", "textured", obj())
    put("session_yaml", "tiny.yaml", (ROOT / "sample_capture/tiny/session.yaml").read_bytes())
    put("session_yaml", "default.yaml", (ROOT / "sample_capture/session.yaml").read_bytes())
    for f in sorted((ROOT / "sample_capture/play").glob("*.txt")):
        put("control_script", f.name, f.read_bytes())
    for target in ["bvh", "gltf", "twarp", "mspace", "asset"]:
        files = smallest((seeds / target).glob("*"), 2)
        if not files:
            sys.exit(f"make_corpus: no {target} seed of at most {MAX_SEED_BYTES} B")
        for f in files:
            put(target, f.name, f.read_bytes())
    shutil.rmtree(scratch)


if __name__ == "__main__":
    main()
