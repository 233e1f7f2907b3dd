#!/usr/bin/env bash
# How reconstruction's time and memory grow with the studio: rigs of 4, 8 and 16 cameras at
# 640x480 and 1920x1080 (the same field of view). Per rig: synth renders two frames of a walk,
# segment runs, then one frame is reconstructed as one job (`--take walk --frames 1:1`, all
# cores) under /usr/bin/time; prints a markdown table (also OUT/summary.md) of wall seconds,
# CPU seconds and peak memory of that frame's job, with the frame's vertex count.
# Usage: bash scripts/studio_size_study.sh OUT   (needs a build: scripts/build.sh)
set -euo pipefail
if [[ $# -lt 1 || "$1" == -h || "$1" == --help ]]; then
  sed -n '2,7p' "$0" | sed 's/^# \{0,1\}//'
  exit 2
fi
out="$1"
repo="$(cd "$(dirname "$0")/.." && pwd)"
bin="$repo/build/bin"
[[ -x "$bin/fourd" ]] || { echo "error: $bin/fourd not found: run scripts/build.sh first" >&2; exit 3; }
mkdir -p "$out"
out="$(cd "$out" && pwd)"

summary="$out/summary.md"
{
  echo "| cameras | resolution | wall s | CPU s | peak memory MB | vertices |"
  echo "|---:|---|---:|---:|---:|---:|"
} > "$summary.tmp"
for res in "640 480 560" "1920 1080 1680"; do
  read -r w h f <<< "$res"
  for count in 4 8 16; do
    s="$out/c${count}_${w}x${h}"
    mkdir -p "$s"
    cat > "$s/session.yaml" <<YAML
# Written by scripts/studio_size_study.sh.
name: c${count}_${w}x${h}
fps: 12
motions:
  - {name: walk, takes: [walk], parameter: speed, cyclic: true}
stages:
  synth:
    seed: 2012
    rig: {count: $count, radius: 3.5, height: 1.6, width: $w, height_px: $h, focal_px: $f,
          k1: -0.02, k2: 0.004}
    studio: {samples_per_pixel: 2, noise_sigma: 2.0}
    takes:
      - {take: walk, kind: walk, frames: 2, speed: 1.3}
YAML
    echo "== $count cameras, ${w}x${h}" >&2
    [[ -d "$s/capture" ]] || "$bin/fourd-synth" "$s" > "$s/synth.log" 2>&1
    [[ -d "$s/segment" ]] || "$bin/fourd-segment" "$s" > "$s/segment.log" 2>&1
    rm -rf "$s/reconstruct"
    /usr/bin/time -f '%e %U %S %M' -o "$s/time.txt" \
      "$bin/fourd-reconstruct" "$s" --take walk --frames 1:1 > "$s/reconstruct.log" 2>&1
    read -r wall user sys rss < "$s/time.txt"
    vertices=$(python3 -c "import json; print(json.load(open('$s/reconstruct/walk/000001.json'))['vertices'])")
    python3 -c "print('| $count | ${w}x${h} | %.1f | %.1f | %.0f | $vertices |' % \
      ($wall, $user + $sys, $rss / 1024))" >> "$summary.tmp"
  done
done
mv "$summary.tmp" "$summary"
cat "$summary"
