#!/usr/bin/env bash
# Whole-process speed of the main job (issue 12): machine-seconds compensated per wall-second of
# `gcpipe batch`, one process (the compensation is single-threaded), on LinuxCNC's
# planner_tests/trochoidal.ngc (when ../shared/data is there) and on a generated CAM-like program
# of about ten machine-minutes (`gcpipe synth --cam-segments`). A benchmark, not a test: it prints
# figures and never fails on them.
#   bash tests/bench/compensate_bench.sh [build/stages/cli/gcpipe] [segments]
set -euo pipefail
gcpipe="${1:-build/stages/cli/gcpipe}"
segments="${2:-8000}"
here="$(cd "$(dirname "$0")/../.." && pwd)"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT

measure() {  # name program
  /usr/bin/time -f "%e %U %M" -o "$work/time" "$gcpipe" batch "$2" -o "$work/out" --no-progress > "$work/log" 2>&1 || {
    echo "$1: gcpipe batch failed:"; tail -3 "$work/log"; return 0; }
  python3 - "$1" "$work" <<'PY'
import json, sys
name, work = sys.argv[1], sys.argv[2]
s = json.load(open(f"{work}/out/report.json"))["simulation"]
wall, user, rss = open(f"{work}/time").read().split()
machine = s["cycle_time_before_s"]
print(f"{name}: {machine:.1f} s of machine time (control) in {float(wall):.2f} s wall ({float(user):.2f} s user): "
      f"{machine / float(wall):.1f}x real time, peak RSS {int(rss) / 1024:.0f} MB; cutting max "
      f"{s['contour_error_before']['cutting']['max_mm'] * 1e3:.1f} -> {s['contour_error_after']['cutting']['max_mm'] * 1e3:.1f} um, "
      f"cycle planned {s['cycle_time_planned_s']:.1f} s -> compensated {s['cycle_time_after_s']:.1f} s")
PY
}

trochoidal="$here/../shared/data/gcode/linuxcnc/planner_tests/trochoidal.ngc"
if [ -f "$trochoidal" ]; then
  measure "planner_tests/trochoidal.ngc" "$trochoidal"
else
  echo "planner_tests/trochoidal.ngc: skipped, ../shared/data is not beside the checkout"
fi
"$gcpipe" synth --cam-segments "$segments" --seed 1 -o "$work/cam.nc"
measure "generated CAM-like program ($segments segments, seed 1)" "$work/cam.nc"
