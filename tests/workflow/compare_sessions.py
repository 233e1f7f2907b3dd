#!/usr/bin/env python3
"""Compares what two runs of the same session produced: every mesh (*.ply) and silhouette
(segment*/ *.png) byte for byte, the asset files, and reports/metrics.json with the timing
metrics left out (wall-clock times differ from run to run). Exit 1 on any difference.

usage: compare_sessions.py SESSION_A SESSION_B
"""
import hashlib
import json
import os
import re
import sys

SKIP_DIRS = {"workflow", ".snakemake", "logs", "capture", "ground_truth", "calibration"}
# Metrics that measure time (seconds per frame, wall time, CPU seconds of a transition search,
# a cost ratio of two timings) rather than results.
TIMING = re.compile(r"(^|[._])(wall_)?seconds|_seconds_|seconds_per_frame|_cpu_s$|cost_ratio")


def digests(root):
    out = {}
    for d, dirs, files in os.walk(root):
        rel_dir = os.path.relpath(d, root)
        top = rel_dir.split(os.sep)[0]
        if top in SKIP_DIRS:
            dirs[:] = []
            continue
        for f in files:
            path = os.path.join(d, f)
            rel = os.path.relpath(path, root)
            is_mesh = f.endswith(".ply")
            is_silhouette = f.endswith(".png") and top.startswith("segment")
            is_asset = top.startswith("asset")
            if f.startswith(".") or not (is_mesh or is_silhouette or is_asset):
                continue
            with open(path, "rb") as fh:
                out[rel] = hashlib.sha256(fh.read()).hexdigest()
    return out


def flat_metrics(root):
    with open(os.path.join(root, "reports", "metrics.json")) as fh:
        m = json.load(fh)
    flat = {}

    def walk(node, prefix):
        if isinstance(node, dict):
            for k, v in node.items():
                walk(v, f"{prefix}.{k}" if prefix else k)
        else:
            flat[prefix] = node

    walk(m, "")
    return {k: v for k, v in flat.items() if not TIMING.search(k)}, len(flat)


def main():
    a, b = sys.argv[1], sys.argv[2]
    da, db = digests(a), digests(b)
    bad = 0
    for rel in sorted(set(da) | set(db)):
        if da.get(rel) != db.get(rel):
            bad += 1
            if bad <= 10:
                state = "only in A" if rel not in db else "only in B" if rel not in da else "differs"
                print(f"  {rel}: {state}")
    meshes = sum(1 for r in da if r.endswith(".ply"))
    print(f"files compared: {len(da)} ({meshes} meshes), differing: {bad}")
    ma, na = flat_metrics(a)
    mb, _ = flat_metrics(b)
    mdiff = [k for k in sorted(set(ma) | set(mb)) if ma.get(k) != mb.get(k)]
    for k in mdiff[:10]:
        print(f"  metric {k}: {ma.get(k)} vs {mb.get(k)}")
    print(f"metrics compared: {len(ma)} of {na} (timing left out), differing: {len(mdiff)}")
    if bad or mdiff or meshes == 0:
        print("sessions differ")
        return 1
    print("sessions identical")
    return 0


if __name__ == "__main__":
    sys.exit(main())
