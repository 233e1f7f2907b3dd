#!/usr/bin/env python3
"""Compares what two runs of the same session produced: every result file of the stage folders,
as `fourd digest` hashes them (results byte for byte; run records such as times, CPU, job
split and logs left out, see pipeline/driver/driver.h is_run_measurement). The inputs
(capture/, calibration/, ground_truth/), logs and the workflow's own folders are not compared.
Exit 1 on any difference.

usage: compare_sessions.py FOURD SESSION_A SESSION_B   (FOURD: the fourd executable)
"""
import os
import subprocess
import sys

SKIP_DIRS = {"workflow", ".snakemake", "logs", "capture", "ground_truth", "calibration"}


def digests(fourd, root, folders):
    out = subprocess.run([fourd, "digest", root, *folders], check=True, capture_output=True,
                         text=True).stdout
    return {path: digest for digest, path in (line.split("  ", 1) for line in out.splitlines())}


def main():
    fourd, a, b = sys.argv[1:4]
    folders = sorted({d for root in (a, b) for d in os.listdir(root)
                      if os.path.isdir(os.path.join(root, d)) and d not in SKIP_DIRS})
    # A folder only one run wrote is a difference too: hash it in both (absent: no lines).
    da = digests(fourd, a, [f for f in folders if os.path.isdir(os.path.join(a, f))])
    db = digests(fourd, b, [f for f in folders if os.path.isdir(os.path.join(b, f))])
    bad = 0
    for rel in sorted(set(da) | set(db)):
        if da.get(rel) != db.get(rel):
            bad += 1
            if bad <= 10:
                state = "only in A" if rel not in db else "only in B" if rel not in da else "differs"
                print(f"  {rel}: {state}")
    meshes = sum(1 for r in da if r.endswith(".ply"))
    print(f"files compared: {len(da)} ({meshes} meshes) in {', '.join(folders)}; "
          f"differing: {bad}")
    if bad or meshes == 0 or "reports/metrics.json" not in da:
        print("sessions differ")
        return 1
    print("sessions identical")
    return 0


if __name__ == "__main__":
    sys.exit(main())
