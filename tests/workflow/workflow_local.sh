#!/usr/bin/env bash
# The same session processed by `fourd run` and by Snakemake (the workflow `fourd workflow`
# writes, `snakemake --cores 2`) gives identical meshes, silhouettes, asset and metrics; the
# stages refuse bad frame ranges and missing upstream outputs before any work; a reconstruct
# job killed mid-frame leaves only whole files and a rerun redoes just its chunk; a frame that
# fails reconstruction is reported by the workflow with its job's log.
# usage: workflow_local.sh <session.yaml recipe> <work dir>
#   (FOURD_BIN: folder of the executables; FOURD_FRAMES_PER_JOB: frames per job, default 6)
# Leaves <work dir>/local (the `fourd run` result) for the Slurm test to compare against.
set -euo pipefail
recipe="$1"
work="$2"
bin="${FOURD_BIN:?FOURD_BIN must name the folder of the fourd executables}"
fpj="${FOURD_FRAMES_PER_JOB:-6}"
here="$(cd "$(dirname "$0")" && pwd)"
rm -rf "$work"
mkdir -p "$work/base"
cp "$recipe" "$work/base/session.yaml"

echo "== synth (shared by both runs)"
"$bin/fourd" run "$work/base" --only synth
cp -a "$work/base" "$work/local"
cp -a "$work/base" "$work/snakemake"
s="$work/snakemake"
smk=(snakemake -s "$s/workflow/Snakefile" -d "$s" --show-failed-logs)

echo "== fourd run"
start=$SECONDS
"$bin/fourd" run "$work/local"
echo "fourd run: $((SECONDS - start)) s"

echo "== fourd workflow + snakemake --cores 2, one reconstruct job killed mid-frame"
"$bin/fourd" workflow "$s" --frames-per-job "$fpj"
start=$SECONDS
"${smk[@]}" --cores 2 --keep-going --quiet > "$work/first_run.log" 2>&1 &
runner=$!
pid=""
for _ in $(seq 6000); do
  # The first reconstruct job's stage process, once it has written one of its frames' meshes
  # (so it is killed in the middle of another); killed by its pid alone.
  line=$(pgrep -a -f -- "^[^ ]*/fourd-reconstruct \. --take " | head -n 1 || true)
  if [ -n "$line" ]; then
    take=$(echo "$line" | sed 's/.* --take \([^ ]*\) .*/\1/')
    frames=$(echo "$line" | sed 's/.* --frames \([0-9]*\):\([0-9]*\) .*/\1-\2/')
    done_frames=0
    for ((f = ${frames%%-*}; f <= ${frames##*-}; ++f)); do
      [ -f "$s/reconstruct/$take/$(printf '%06d' "$f").ply" ] && done_frames=$((done_frames + 1))
    done
    if [ "$done_frames" -ge 1 ]; then
      pid=${line%% *}
      break
    fi
  fi
  kill -0 "$runner" 2>/dev/null || break
  sleep 0.2
done
[ -n "$pid" ] || { echo "FAILED: no reconstruct job was seen running"; cat "$work/first_run.log"; exit 1; }
kill -9 "$pid"
rc=0
wait "$runner" || rc=$?
[ "$rc" != 0 ] || { echo "FAILED: snakemake did not notice the killed job"; exit 1; }
rule="reconstruct_$(echo "$take" | sed 's/[^A-Za-z0-9]/_/g')_${frames/-/_}"
echo "  killed $rule (pid $pid) mid-frame; the other jobs went on; snakemake exited $rc"
python3 - "$s/reconstruct" <<'PY'
import json, os, sys
# Every mesh and record present is whole: a binary PLY's size matches its header, a record
# parses. (A killed writer leaves at most its hidden temporary file, which nothing reads.)
bad = 0
width = {"char": 1, "uchar": 1, "int8": 1, "uint8": 1, "short": 2, "ushort": 2, "int16": 2,
         "uint16": 2, "int": 4, "uint": 4, "int32": 4, "uint32": 4, "float": 4, "float32": 4,
         "double": 8, "float64": 8}
for d, _, files in os.walk(sys.argv[1]):
    for f in files:
        p = os.path.join(d, f)
        if f.startswith("."):
            continue
        data = open(p, "rb").read()
        if f.endswith(".json"):
            try:
                json.loads(data)
            except ValueError:
                print(f"half-written record {p}"); bad += 1
        elif f.endswith(".ply"):
            end = data.find(b"end_header\n")
            header = data[:end].decode("ascii", "replace").split("\n")
            if end < 0 or not header[1].startswith("format binary_little_endian"):
                print(f"unreadable mesh {p}"); bad += 1
                continue
            counts = {l.split()[1]: int(l.split()[2]) for l in header if l.startswith("element")}
            need, element = 0, None
            for l in header:
                w = l.split()
                if w and w[0] == "element":
                    element = w[1]
                elif w and w[0] == "property" and w[1] == "list":  # triangles
                    need += counts[element] * (width[w[2]] + 3 * width[w[3]])
                elif w and w[0] == "property":
                    need += counts[element] * width[w[1]]
            if len(data) - end - len(b"end_header\n") != need:
                print(f"half-written mesh {p}"); bad += 1
sys.exit(1 if bad else 0)
PY
echo "  every mesh and record left is whole"
"${smk[@]}" --cores 1 -n --quiet > "$work/rerun_plan.log" 2>&1
reconstruct_jobs=$(grep -o '^reconstruct_[A-Za-z_0-9]*' "$work/rerun_plan.log" | sort -u)
echo "  rerun plan: $(echo $reconstruct_jobs)"
[ "$reconstruct_jobs" = "$(printf '%s\n' "$rule" reconstruct_finish | sort -u)" ] || {
  echo "FAILED: the rerun would redo more (or less) than the killed chunk"; cat "$work/rerun_plan.log"; exit 1; }
"${smk[@]}" --cores 2 --quiet
echo "snakemake --cores 2 (first run with the kill, then the rerun): $((SECONDS - start)) s"
python3 "$here/compare_sessions.py" "$bin/fourd" "$work/local" "$s"

# expect CODE TEXT COMMAND...: the command exits with CODE and says TEXT, and no stage output
# changed (the error came before any work).
expect() {
  local code="$1" text="$2"
  shift 2
  local before after rc=0
  before=$(cd "$s" && find segment reconstruct -type f ! -name '.*' | sort | xargs -r sha256sum | sha256sum)
  "$@" > "$work/expect.log" 2>&1 || rc=$?
  after=$(cd "$s" && find segment reconstruct -type f ! -name '.*' | sort | xargs -r sha256sum | sha256sum)
  if [ "$rc" != "$code" ] || ! grep -q -- "$text" "$work/expect.log" || [ "$before" != "$after" ]; then
    echo "FAILED: $* exited $rc (expected $code), outputs changed: $([ "$before" = "$after" ] && echo no || echo yes)"
    cat "$work/expect.log"
    exit 1
  fi
  echo "  ok ($rc): $(grep -m1 -- "$text" "$work/expect.log" | sed 's/^.*\] //')"
}

echo "== bad input is refused before any work"
expect 4 "has frames 0:10" "$bin/fourd-reconstruct" "$s" --take walk_slow --frames 6:24
expect 4 "has frames 0:10" "$bin/fourd-segment" "$s" --take walk_slow --frames 20:
expect 2 "overlap" "$bin/fourd-segment" "$s" --take walk_slow --frames 0:5,3:8
expect 2 "empty or negative" "$bin/fourd-reconstruct" "$s" --take walk_slow --frames 5:2
expect 4 "take 'run' is not in the capture" "$bin/fourd-reconstruct" "$s" --take run --frames 0:1
mv "$s/segment/walk_fast/cam03/000004.png" "$work/held.png"
expect 4 "segment/walk_fast/cam03/000004.png is missing" \
  "$bin/fourd-reconstruct" "$s" --take walk_fast --frames 0:5
expect 4 "000004.png is missing" "$bin/fourd-segment" "$s" --finish
mv "$work/held.png" "$s/segment/walk_fast/cam03/000004.png"

echo "== a frame that fails reconstruction is reported with its job's log"
oiiotool --create 320x240 1 -d uint8 -o "$work/black.png"
for cam in "$s"/segment/walk_slow/*/; do cp "$work/black.png" "$cam/000002.png"; done
out=$("${smk[@]}" --cores 2 --until reconstruct_finish 2>&1) || { echo "$out"; exit 1; }
echo "$out" | grep "fourd: reconstruct: take walk_slow frame 2 failed" || {
  echo "FAILED: the failed frame was not reported"; echo "$out"; exit 1; }
grep -q "log: logs/reconstruct.walk_slow.0-" <<< "$out" || { echo "FAILED: no log named"; exit 1; }
# A job whose every frame fails fails the workflow, which prints the stage's log.
for f in "$s"/segment/walk_slow/*/0000*.png; do cp "$work/black.png" "$f"; done
rc=0
out=$("${smk[@]}" --cores 2 --until reconstruct_finish 2>&1) || rc=$?
[ "$rc" != 0 ] || { echo "FAILED: a job without any reconstructable frame passed"; exit 1; }
grep -q "no frame could be reconstructed" <<< "$out" || {
  echo "FAILED: the stage's log was not shown"; echo "$out"; exit 1; }
echo "  a job with no reconstructable frame fails the workflow; its log is shown"
echo "workflow ok"
