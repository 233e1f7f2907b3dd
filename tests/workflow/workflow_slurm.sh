#!/usr/bin/env bash
# The session's workflow run through Slurm: starts a one-node Slurm on this machine
# (slurm_node.sh, as root), measures the per-job overhead with empty jobs, runs every job of
# the workflow with the Slurm profile (`fourd workflow` writes it), checks the outputs equal
# those of the local `fourd run`, and stops the daemons it started.
# usage: workflow_slurm.sh <session.yaml recipe> <work dir> [reference session]
#   The reference is a finished `fourd run` of the recipe (workflow_local.sh leaves one in its
#   work dir as local/); without it this script makes one. FOURD_BIN: the executables' folder;
#   FOURD_FRAMES_PER_JOB: frames per job (default 6).
set -euo pipefail
recipe="$1"
work="$2"
reference="${3:-}"
bin="${FOURD_BIN:?FOURD_BIN must name the folder of the fourd executables}"
fpj="${FOURD_FRAMES_PER_JOB:-6}"
here="$(cd "$(dirname "$0")" && pwd)"
rm -rf "$work"
mkdir -p "$work"
work="$(cd "$work" && pwd)"

if [ -z "$reference" ] || [ ! -f "$reference/reports/metrics.json" ]; then
  echo "== reference: fourd run"
  reference="$work/local"
  mkdir -p "$reference"
  cp "$recipe" "$reference/session.yaml"
  "$bin/fourd" run "$reference"
fi
s="$work/slurm"
mkdir -p "$s"
cp -a "$reference/session.yaml" "$reference/capture" "$reference/calibration" "$s/"
[ -d "$reference/ground_truth" ] && cp -a "$reference/ground_truth" "$s/"

echo "== a one-node Slurm"
start=$SECONDS
trap 'bash "$here/slurm_node.sh" stop "$work/cluster"' EXIT
conf=$(bash "$here/slurm_node.sh" start "$work/cluster" | tail -n 1)
export SLURM_CONF="$conf"
sinfo
echo "started in $((SECONDS - start)) s"

echo "== per-job overhead: empty jobs, from sbatch to completion"
python3 - <<'PY'
import subprocess, time
times = []
for _ in range(5):
    t = time.time()
    subprocess.run(["sbatch", "--wait", "--quiet", "-o", "/dev/null", "--wrap", "true"], check=True)
    times.append(time.time() - t)
print("empty job round trips (s): " + ", ".join(f"{t:.2f}" for t in times) +
      f"; median {sorted(times)[len(times) // 2]:.2f}")
PY

echo "== the workflow through the Slurm profile"
"$bin/fourd" workflow "$s" --frames-per-job "$fpj"
start=$SECONDS
snakemake -s "$s/workflow/Snakefile" -d "$s" --profile "$s/workflow/profiles/slurm" --quiet
echo "snakemake --profile slurm: $((SECONDS - start)) s"
jobs=$(grep -c '^rule ' "$s/workflow/Snakefile")
slurm_logs=$(find "$s/logs/slurm" -name '*.log' | wc -l)
echo "Slurm ran $slurm_logs job(s) for the workflow's $((jobs - 1)) job rule(s)"
[ "$slurm_logs" -eq $((jobs - 1)) ] || { echo "FAILED: not every job went through Slurm"; exit 1; }
python3 "$here/compare_sessions.py" "$bin/fourd" "$reference" "$s"
echo "slurm ok"
