#!/usr/bin/env bash
# Crash safety: kills each stage with SIGKILL at random points of its run and checks that
#  (1) right after the kill, every stage output file is either absent or identical to the
#      uninterrupted run's (results byte for byte; the run's own times aside, see manifest) (a stage never leaves a partial file under its real name; temp files
#      of the atomic writers, .<name>.tmp<pid>-<n>, are allowed and listed);
#  (2) rerunning the driver completes the stage, and a further `fourd run` has nothing to do;
#  (3) the session ends identical to the uninterrupted run (SHA-256 of every output file).
# The driver (`fourd run --only STAGE --force`, which also runs the stage's oracle variant) and
# the stage run in their own process group; the whole group is killed, as a power cut would.
#
# usage: kill_rerun.sh REFERENCE WORK KILLS_PER_STAGE [SEED] [STAGE...]
#   REFERENCE  a session the whole pipeline ran through, uninterrupted (e.g. the e2e test's);
#              it is not modified
#   WORK       scratch folder (replaced)
#   FOURD_BIN  folder of the fourd executables
# Kill times are uniform in [2 %, 98 %] of the stage's duration: at first REFERENCE's completion
# record's times KILL_TIME_SCALE (default 0.6, as REFERENCE usually ran beside other tests and
# took longer than a run here); SEED (default 1) makes them repeatable. A run that finishes
# before its kill time is not counted: the duration is taken from that run instead and the
# kill drawn again, so every stage gets KILLS real kills (each redraw costs a whole run).
# Prints one line per kill and a summary.
set -euo pipefail
ref="$(cd "$1" && pwd)"
work="$2"
kills="$3"
seed="${4:-1}"
shift $(( $# < 4 ? $# : 4 ))
bin="${FOURD_BIN:?FOURD_BIN must name the folder of the fourd executables}"
stages=("$@")
if [ ${#stages[@]} -eq 0 ]; then
  stages=(synth segment reconstruct align timewarp motionspace texture graph validate)
fi

# The stage outputs the manifest covers: every folder a stage writes (docs/design.md "The
# session folder"), without the logs and the e2e test's own extra folders, hashed by
# `fourd digest`: results byte for byte, run records (times, CPU, logs; see driver.h
# is_run_measurement) left out, the completion
# records too. Temp files of the atomic writers (.<name>.tmp<pid>-<n>) and hidden scratch
# folders (.<name>.tmp/: reconstruct's COLMAP workspace, the staging folders of the stages that
# replace their output folder whole) are listed under their own names.
manifest() {
  local folders=()
  for d in "$1"/*/; do
    d=$(basename "$d")
    case "$d" in logs | play_* | again) ;; *) folders+=("$d") ;; esac
  done
  "$bin/fourd" digest "$1" "${folders[@]}"
}

# The stage's run time in a session's completion records: its own and its oracle variant's
# (in <folder>_oracle).
stage_seconds() {
  python3 -c "
import json, os, sys
print(sum(json.load(open(f))['seconds'] for f in sys.argv[1:] if os.path.exists(f)))" \
    "$1/$out/.fourd_stage.json" "$1/${out}_oracle/.fourd_stage.json"
}

rm -rf "$work"
mkdir -p "$work"
manifest "$ref" > "$work/reference.sha"
echo "reference: $(wc -l < "$work/reference.sha") files"
session="$work/session"
cp -a "$ref" "$session"
RANDOM=$seed
failures=0
total_kills=0
start_all=$SECONDS
for stage in "${stages[@]}"; do
  # The completion record lives in the stage's first output folder; its oracle variant's in
  # <folder>_oracle. The stage's run time is the sum of both.
  case "$stage" in synth) out=capture ;; validate) out=reports ;; *) out="$stage" ;; esac
  [ -f "$ref/$out/.fourd_stage.json" ] || { echo "$stage: not in the reference session, skipped"; continue; }
  seconds=$(python3 -c "import sys; print(float(sys.argv[1]) * float(sys.argv[2]))" \
            "$(stage_seconds "$ref")" "${KILL_TIME_SCALE:-0.6}")
  stage_start=$SECONDS
  for ((k = 1; k <= kills; ++k)); do
    total_kills=$((total_kills + 1))
    for ((attempt = 1; ; ++attempt)); do
      # Uniform in [2 %, 98 %] of the stage's duration (RANDOM: 0..32767).
      at=$(python3 -c "import sys; print(f'{float(sys.argv[1]) * (0.02 + 0.96 * int(sys.argv[2]) / 32767):.2f}')" \
           "$seconds" "$RANDOM")
      setsid "$bin/fourd" run "$session" --only "$stage" --force > "$work/killed.log" 2>&1 &
      pid=$!
      sleep "$at"
      if kill -0 "$pid" 2> /dev/null; then
        kill -KILL -- "-$pid" 2> /dev/null || true
        wait "$pid" 2> /dev/null || true
        state="killed at ${at}s"
        break
      fi
      wait "$pid" 2> /dev/null || true
      state="finished before ${at}s"
      [ "$attempt" -lt 5 ] || break
      # The driver's own time for the whole run (it says "ran N stage(s) ... in S s").
      seconds=$(sed -n 's/.*ran [0-9]* stage(s).* in \([0-9.]*\) s$/\1/p' "$work/killed.log" | tail -1)
      [ -n "$seconds" ] || seconds=$(stage_seconds "$session")
      echo "     $stage kill $k: the run finished before ${at}s (it took ${seconds}s here); drawn again"
    done
    # (1) no partial file under a real name.
    manifest "$session" > "$work/after_kill.sha"
    temps=$(grep -vxFf "$work/reference.sha" "$work/after_kill.sha" \
            | grep -cE '(^|[ /])\.[^/]*\.tmp([0-9]+-[0-9]+)?[^/]*(/|$)' || true)
    bad=$(grep -vE '(^|[ /])\.[^/]*\.tmp([0-9]+-[0-9]+)?[^/]*(/|$)' "$work/after_kill.sha" \
          | grep -vxFf "$work/reference.sha" || true)
    ok=1
    if [ -n "$bad" ]; then
      echo "FAIL $stage kill $k ($state): files differ from the uninterrupted run right after the kill:"
      echo "$bad" | head -5
      ok=0
    fi
    # (2) the driver completes the stage; (3) then nothing is left to do and outputs match.
    if ! "$bin/fourd" run "$session" --only "$stage" > "$work/rerun.log" 2>&1; then
      echo "FAIL $stage kill $k ($state): the rerun failed:"; tail -5 "$work/rerun.log"; ok=0
    fi
    out=$("$bin/fourd" run "$session" 2>&1 || true)
    if ! grep -q "ran 0 stage(s)" <<< "$out"; then
      echo "FAIL $stage kill $k ($state): after the rerun the driver still ran stages:"
      echo "$out" | tail -5
      ok=0
    fi
    manifest "$session" > "$work/after_rerun.sha"
    if ! diff -q "$work/reference.sha" "$work/after_rerun.sha" > /dev/null; then
      echo "FAIL $stage kill $k ($state): the session differs from the uninterrupted run:"
      diff "$work/reference.sha" "$work/after_rerun.sha" | head -8 || true
      # What differs in the JSON files (run measurements aside: those never count). diff exits
      # 1 on a difference: the pipeline must not end the script (pipefail), the next kill runs.
      { diff "$work/reference.sha" "$work/after_rerun.sha" || true; } | sed -n 's/^> [0-9a-f]*  \(.*\.json\)$/\1/p' \
        | head -3 | while read -r f; do
          python3 - "$ref/$f" "$session/$f" <<'PY' || true
import json, sys
def flat(d, p=""):
    if isinstance(d, dict):
        return {k2: v for k, x in d.items() for k2, v in flat(x, f"{p}{k}.").items()}
    if isinstance(d, list):
        return {k2: v for i, x in enumerate(d) for k2, v in flat(x, f"{p}{i}.").items()}
    return {p.rstrip("."): d}
a, b = (flat(json.load(open(f))) for f in sys.argv[1:3])
timing = ("second", "cpu_s", "_us", "cost_ratio", "branch_jobs")
diffs = [k for k in sorted(set(a) | set(b))
         if a.get(k) != b.get(k) and not any(t in k for t in timing)]
for k in diffs[:10]:
    print(f"  {sys.argv[2]}: {k}: {a.get(k)!r} -> {b.get(k)!r}")
PY
        done || true
      ok=0
      # Start the next kill from the reference again.
      rm -rf "$session"
      cp -a "$ref" "$session"
    fi
    if [ $ok = 1 ]; then
      echo "ok   $stage kill $k: $state (of ${seconds}s), $temps temp file(s) left by the kill, rerun identical"
    else
      failures=$((failures + 1))
    fi
  done
  echo "== $stage: $kills kill(s) in $((SECONDS - stage_start)) s"
done
echo "kill_rerun: $total_kills kill(s), $failures failure(s), $((SECONDS - start_all)) s"
[ "$failures" -eq 0 ]
