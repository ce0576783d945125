#!/usr/bin/env bash
# Whole-process speed of the main job (issue 12): machine-seconds compensated per wall-second of
# `gcpipe batch`, one process (the compensation is single-threaded), on LinuxCNC's
# planner_tests/trochoidal.ngc (when ../shared/data is there) and on a generated CAM-like program
# (`gcpipe synth --cam-segments`, 8000 segments: 261.7 s as the control runs it, 566.6 s planned
# and compensated). Each program runs `runs` times, alternating, and the median and the range are
# printed: on the 2-core VM the same binary's wall time drifts by up to 20 % from minute to minute.
# A benchmark, not a test: it prints figures and never fails on them.
#   bash tests/bench/compensate_bench.sh [build/stages/cli/gcpipe] [segments] [runs]
set -euo pipefail
gcpipe="${1:-build/stages/cli/gcpipe}"
segments="${2:-8000}"
runs="${3:-5}"
here="$(cd "$(dirname "$0")/../.." && pwd)"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT

run_once() {  # name program -> appends "wall user rss" to $work/<name>.runs
  /usr/bin/time -f "%e %U %M" -o "$work/time" "$gcpipe" batch "$2" -o "$work/out_$1" --no-progress > "$work/log" 2>&1 || {
    echo "$1: gcpipe batch failed:"; tail -3 "$work/log"; return 1; }
  cat "$work/time" >> "$work/$1.runs"
}

summary() {  # name label
  python3 - "$1" "$2" "$work" <<'PY'
import json, statistics, sys
key, label, work = sys.argv[1], sys.argv[2], sys.argv[3]
s = json.load(open(f"{work}/out_{key}/report.json"))["simulation"]
rows = [tuple(float(x) for x in line.split()) for line in open(f"{work}/{key}.runs")]
walls = sorted(r[0] for r in rows)
machine = s["cycle_time_before_s"]
med = statistics.median(walls)
print(f"{label}: {machine:.1f} s of machine time (control), {len(walls)} runs: median {med:.2f} s wall "
      f"(range {walls[0]:.2f}-{walls[-1]:.2f}): {machine / med:.1f}x real time (range {machine / walls[-1]:.1f}-"
      f"{machine / walls[0]:.1f}x), peak RSS {max(r[2] for r in rows) / 1024:.0f} MB; cutting max "
      f"{s['contour_error_before']['cutting']['max_mm'] * 1e3:.1f} -> {s['contour_error_after']['cutting']['max_mm'] * 1e3:.1f} um, "
      f"cycle planned {s['cycle_time_planned_s']:.1f} s -> compensated {s['cycle_time_after_s']:.1f} s "
      f"({s['cycle_time_after_s'] / med:.1f}x its compensated cycle)")
PY
}

trochoidal="$here/../shared/data/gcode/linuxcnc/planner_tests/trochoidal.ngc"
"$gcpipe" synth --cam-segments "$segments" --seed 1 -o "$work/cam.nc"
have_trochoidal=0
[ -f "$trochoidal" ] && have_trochoidal=1
for _ in $(seq "$runs"); do
  if [ "$have_trochoidal" = 1 ]; then run_once trochoidal "$trochoidal"; fi
  run_once cam "$work/cam.nc"
done
if [ "$have_trochoidal" = 1 ]; then
  summary trochoidal "planner_tests/trochoidal.ngc"
else
  echo "planner_tests/trochoidal.ngc: skipped, ../shared/data is not beside the checkout"
fi
summary cam "generated CAM-like program ($segments segments, seed 1)"
