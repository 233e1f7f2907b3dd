#!/usr/bin/env bash
# End-to-end: the tiny sample through every built stage with the `fourd` driver, then checks
# (1) the metrics the stages promise are present and within range, (2) a second run skips
# every stage, (3) the synthetic studio is deterministic (same seed, same bytes).
# usage: tiny_sample.sh <recipe dir> <work dir>   (FOURD_BIN: folder of the executables)
set -euo pipefail
recipe="$1"
work="$2"
bin="${FOURD_BIN:?FOURD_BIN must name the folder of the fourd executables}"
rm -rf "$work"
mkdir -p "$work"
cp "$recipe/session.yaml" "$work/session.yaml"

echo "== first run"
"$bin/fourd" run "$work"
test -f "$work/reports/metrics.json" || { echo "no reports/metrics.json"; exit 1; }

echo "== metrics"
python3 - "$work/reports/metrics.json" <<'PY'
import json, sys
m = json.load(open(sys.argv[1]))
flat = {}
def walk(d, p=""):
    if isinstance(d, dict):
        for k, v in d.items(): walk(v, f"{p}.{k}" if p else k)
    else:
        flat[p] = d
walk(m)
for k in sorted(flat): print(f"  {k} = {flat[k]}")
def need(key, lo=None, hi=None):
    assert key in flat, f"metric {key} missing"
    v = flat[key]
    assert lo is None or v >= lo, f"{key} = {v} < {lo}"
    assert hi is None or v <= hi, f"{key} = {v} > {hi}"
need("synth.takes", 4, 4)
need("synth.cameras", 4, 4)
need("synth.frames", 96, 96)
need("synth.silhouette_vertex_consistency", 0.99, 1.0)
print("metrics ok")
PY

echo "== second run skips unchanged stages"
out=$("$bin/fourd" run "$work" 2>&1)
echo "$out"
if echo "$out" | grep -qE "running|ran "; then
  if ! echo "$out" | grep -q "skipped"; then echo "second run did not skip"; exit 1; fi
fi
echo "$out" | grep -q "synth" || true

echo "== determinism: same seed, same bytes"
mkdir -p "$work/again"
cp "$work/session.yaml" "$work/again/session.yaml"
"$bin/fourd" run "$work/again" --only synth
( cd "$work" && find capture ground_truth calibration -type f ! -name '.*' | sort | xargs sha256sum ) > "$work/a.sha"
( cd "$work/again" && find capture ground_truth calibration -type f ! -name '.*' | sort | xargs sha256sum ) > "$work/b.sha"
diff -q "$work/a.sha" "$work/b.sha"
echo "e2e ok"
