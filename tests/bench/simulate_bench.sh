#!/usr/bin/env bash
# Whole-process speed of `gcpipe simulate` with the trace written, as a user runs it: 200 s of
# full circles (R 10 mm, F3000) on the default config, three runs, machine seconds per wall
# second of each. A benchmark, not a test: it prints figures and never fails on them.
#   bash tests/bench/simulate_bench.sh [build/stages/cli/gcpipe]
set -euo pipefail
gcpipe="${1:-build/stages/cli/gcpipe}"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
{
  echo "%"
  echo "O0200 (200 s of circles at F3000: the simulate benchmark)"
  echo "G17 G21 G90 G94 G54"
  echo "G0 X10 Y0 Z5"
  echo "G1 Z0 F3000"
  for _ in $(seq 160); do echo "G3 X10 Y0 I-10 J0 F3000"; done
  echo "G0 Z5"
  echo "M30"
  echo "%"
} > "$work/circles.nc"
for run in 1 2 3; do
  start=$(date +%s.%N)
  "$gcpipe" simulate "$work/circles.nc" -o "$work/trace.csv" --no-progress 2> "$work/err"
  end=$(date +%s.%N)
  machine=$(sed -n 's/.*ticks (\([0-9.]*\) s at.*/\1/p' "$work/err")
  awk -v r="$run" -v m="$machine" -v s="$start" -v e="$end" -v b="$(stat -c %s "$work/trace.csv")" \
    'BEGIN { w = e - s; printf "run %d: %.1f s of machine time in %.3f s wall: %.0fx real time (trace %.1f MB)\n", r, m, w, m / w, b / 1e6 }'
done
