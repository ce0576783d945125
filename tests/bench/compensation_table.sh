#!/usr/bin/env bash
# The compensation table of README.md and docs/benchmarks.md ("The look-ahead control"): gcpipe batch
# on the real programs of ../shared/data and eight generated CAM-like programs, one row each with the
# before / feed-forward / after figures from report.json, the cycle ratio, wall time and peak RSS.
#   bash tests/bench/compensation_table.sh [CONFIG] [OUTDIR]     (from the checkout, gcpipe built)
set -euo pipefail
cd "$(dirname "$0")/../.."
cfg=${1:-pipeline_configs/default.yaml}
out=${2:-out/compensation_table}
g=build/stages/cli/gcpipe
d=../shared/data/gcode/linuxcnc
mkdir -p "$out/synth"
progs="samples/trochoid_slot_f3000.nc $d/planner_tests/trochoidal.ngc $d/planner_tests/arcspiral.ngc"
progs="$progs $d/xyzac_trt/boat-xyzac.ngc $d/xyzac_trt/impeller-7bl-xyzac.ngc $d/xyzac_trt/xyzac_switchkins_test_1.ngc"
for s in 1 2 3 4 5 6 7 8; do
  "$g" synth --cam-segments 400 --seed "$s" -o "$out/synth/cam$s.nc"
  progs="$progs $out/synth/cam$s.nc"
done
for p in $progs; do
  [ -f "$p" ] || { echo "| $p | (absent) |"; continue; }
  n=$(basename "$p"); n=${n%.*}
  /usr/bin/time -f "%e s %M KB" -o "$out/$n.time" "$g" batch "$p" -o "$out/$n" --config "$cfg" --quiet > "$out/$n.log" 2>&1 || true
  python3 - "$out/$n" "$n" <<'PY'
import json, sys
d, n = sys.argv[1], sys.argv[2]
try:
    j = json.load(open(d + "/report.json"))["simulation"]
    b, f, a = (j[k]["max_mm"] * 1e3 for k in ("contour_error_before", "contour_error_feedforward", "contour_error_after"))
except (OSError, KeyError) as e:
    print(f"| {n} | no figures ({e}) |"); sys.exit()
cb, ca = j["cycle_time_before_s"], j["cycle_time_after_s"]
lim = j.get("reduction_limited_by", "")
if "axis " in lim: lim = lim[lim.index("axis "):]
elif lim.startswith("no limit"): lim = "no limit broken; the learning stopped gaining"
t = open(d + ".time").read().split()
print(f"| {n} | {b:.2f} | {f:.2f} ({j['feedforward_acceleration_over_limit']:.2f}×) | {a:.2f} | {b/a:.1f}× | {f/a:.2f}× "
      f"| {cb:.2f} / {ca:.2f} s = {ca/cb:.3f} | {lim} | {float(t[0]):.1f} s | {float(t[2]) / 1024:.0f} MB |")
PY
done
