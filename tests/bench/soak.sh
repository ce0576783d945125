#!/usr/bin/env bash
# Issue 34 item 5's soak: PROGRAMS programs of mixed size, one after another, through ONE
# `gcpipe launch` pipeline (on_crash: restart), with a kill -9 of a random stage during a random
# KILL_PERCENT of them. Every program must either arrive byte-identical to `gcpipe batch` (both
# of its files: output.nc from the write node, compensated.nc from the compensate node, with
# batch's exit status) or fail loudly with the stage named; nothing may arrive wrong, and no sink
# may hang. A benchmark, not a test: it prints one line per program and the counts, and exits 1
# when a program arrived with other bytes than batch's, hung, or failed without naming a stage.
#
#   bash tests/bench/soak.sh [GCPIPE] [PROGRAMS] [KILL_PERCENT] [DOMAIN] [SEED] [SECONDS]
#
# SECONDS (default: none) ends the soak after the program running then, and says how many ran.
# The soak also ends when two feeds in a row find no reader of the program topic: the pipeline
# no longer matches new participants, and every later program would only wait out its timeouts.
#
# The pool: every samples/*.nc (0.3-3 KB; the G275 slots expand to 20,000 blocks) and two
# seeded synthetic programs of 0.3 and 2 MB (`gcpipe synth`; their simulation leaves the X
# travel, so batch writes no compensated.nc and the compensate node must fail as batch does).
# After a kill the next program waits until the launcher says the restarted stage is ready (a
# program fed while a stage is down is skipped by the stage as published before it started, and
# its sink then waits out its idle timeout: that is a stage missing, not the fault under test).
set -euo pipefail
gcpipe="$(realpath "${1:-build/stages/cli/gcpipe}")"
programs="${2:-200}"
kill_percent="${3:-20}"
domain="${4:-153}"
RANDOM="${5:-34}"
time_limit="${6:-0}"
root="$(cd "$(dirname "$0")/../.." && pwd)"
work="$(mktemp -d /tmp/gcpipe_soak.XXXXXX)"
nodes=(parse trochoid write force compensate)
declare -A stage_of_topic=([gcpipe_program]=feed [gcpipe_blocks]=parse [gcpipe_toolpath]=trochoid
                           [gcpipe_gcode]=write [gcpipe_planned]=force [gcpipe_compensated]=compensate)
launch_pid=""
cleanup() {
  [ -n "$launch_pid" ] && kill -INT "$launch_pid" 2>/dev/null && wait "$launch_pid" 2>/dev/null || true
  "$gcpipe" dds clean > /dev/null 2>&1 || true
}
trap cleanup EXIT

# ---- the pool and batch's files for each program ----
pool=("$root"/samples/*.nc)
"$gcpipe" synth --megabytes 0.3 --seed 5 -o "$work/synth_0.3mb.nc" > /dev/null
"$gcpipe" synth --megabytes 2 --seed 6 -o "$work/synth_2mb.nc" > /dev/null
pool+=("$work/synth_0.3mb.nc" "$work/synth_2mb.nc")
declare -A batch_status
for p in "${pool[@]}"; do
  name="$(basename "$p" .nc)"
  set +e
  "$gcpipe" batch "$p" -o "$work/batch/$name" --quiet 2> "$work/batch_$name.err"
  batch_status[$name]=$?
  set -e
done

# ---- one pipeline for the whole soak ----
cat > "$work/pipeline.yaml" <<EOF
pipeline:
  name: soak
  domain: $domain
  config: $root/pipeline_configs/default.yaml
  on_crash: restart
  max_restarts: 100
  timeout: 120
nodes: [$(IFS=,; echo "${nodes[*]}" | sed 's/,/, /g')]
EOF
"$gcpipe" launch "$work/pipeline.yaml" > "$work/launch.log" 2>&1 &
launch_pid=$!
for _ in $(seq 600); do grep -q "processes ready" "$work/launch.log" && break; sleep 0.1; done
grep -q "processes ready" "$work/launch.log" || { cat "$work/launch.log"; echo "soak: the pipeline never got ready"; exit 1; }

pid_of() { grep -o "  $1: started (pid [0-9]*" "$work/launch.log" | tail -n 1 | grep -o '[0-9]*$'; }
readies_of() { grep -c "  $1: ready after" "$work/launch.log" || true; }
wait_line() {  # FILE TEXT SECONDS
  for _ in $(seq $(( $3 * 20 ))); do grep -q "$2" "$1" 2>/dev/null && return 0; sleep 0.05; done
  return 1
}
# Exit status of PID, or 124 after killing it when it overran SECONDS.
wait_pid() {
  local pid=$1 limit=$2 t=0
  while kill -0 "$pid" 2>/dev/null; do
    sleep 0.1
    t=$((t + 1))
    if [ $t -ge $((limit * 10)) ]; then kill -9 "$pid" 2>/dev/null; wait "$pid" 2>/dev/null; return 124; fi
  done
  wait "$pid" 2>/dev/null
}
# The stage a failed sink's log names: the watchdog's "the X stage", or the topic of a writer
# that went away, or a stage's own failure passed on ("node X:").
named_stage() {
  local log="$1" s
  s="$(grep -o 'the [a-z]* stage (pid' "$log" | head -n 1 | awk '{print $2}')"
  if [ -z "$s" ]; then
    local topic
    topic="$(grep -o 'the writer of gcpipe_[a-z]*' "$log" | head -n 1 | awk '{print $4}')"
    [ -n "$topic" ] && s="${stage_of_topic[$topic]:-}"
  fi
  echo "$s"
}

declare -A count=([identical]=0 [failed_named]=0 [as_batch_failed]=0 [failed_unnamed]=0 [wrong_bytes]=0 [hung]=0)
kills=0 deaf=0 ran=0
start=$SECONDS
printf '%4s %-28s %-10s %-7s %s\n' "#" program killed result detail | tee "$work/soak.txt"
for i in $(seq 1 "$programs"); do
  p="${pool[$((RANDOM % ${#pool[@]}))]}"
  name="$(basename "$p" .nc)"
  id=$(( (RANDOM << 30) | (RANDOM << 15) | RANDOM | 1 ))
  run="$work/run$i"
  mkdir -p "$run"
  dds=(--domain "$domain" --idle-timeout 60 --timeout 60 --program-id "$id")
  "$gcpipe" sink -o "$run/output.nc" "${dds[@]}" > /dev/null 2> "$run/sink_gcode.err" &
  sink_g=$!
  "$gcpipe" sink --in gcpipe_compensated -o "$run/compensated.nc" "${dds[@]}" > /dev/null 2> "$run/sink_comp.err" &
  sink_c=$!
  wait_line "$run/sink_gcode.err" "ready" 30 || true
  wait_line "$run/sink_comp.err" "ready" 30 || true
  "$gcpipe" feed "$p" "${dds[@]}" > /dev/null 2> "$run/feed.err" &
  feed=$!
  victim="-"
  if [ $((RANDOM % 100)) -lt "$kill_percent" ]; then
    victim="${nodes[$((RANDOM % ${#nodes[@]}))]}"
    before=$(readies_of "$victim")
    sleep "$(awk -v r=$RANDOM 'BEGIN { printf "%.2f", 0.2 + 3.0 * r / 32768 }')"
    kill -9 "$(pid_of "$victim")" 2>/dev/null || victim="$victim(gone)"
    kills=$((kills + 1))
  fi
  set +e
  wait_pid $sink_g 150; st_g=$?
  wait_pid $sink_c 150; st_c=$?
  wait_pid $feed 150
  set -e
  expected=${batch_status[$name]}
  result="" detail=""
  for branch in gcode comp; do
    if [ $branch = gcode ]; then st=$st_g; out="$run/output.nc"; ref="$work/batch/$name/output.nc"; log="$run/sink_gcode.err"
    else st=$st_c; out="$run/compensated.nc"; ref="$work/batch/$name/compensated.nc"; log="$run/sink_comp.err"; fi
    if [ $st -eq 124 ]; then r=hung
    elif [ -f "$out" ]; then
      if [ -f "$ref" ] && cmp -s "$out" "$ref"; then r=identical; else r=wrong_bytes; fi
    elif [ ! -f "$ref" ]; then r=as_batch_failed  # batch wrote no such file either
    elif [ -n "$(named_stage "$log")" ]; then r=failed_named
    else r=failed_unnamed; fi
    # A gcode file identical to batch's must also exit as batch does (0, or 3: lines rejected).
    if [ $r = identical ] && [ $branch = gcode ] && [ $st -ne "$expected" ] && [ "$expected" -ne 1 ]; then r=wrong_bytes; fi
    count[$r]=$((count[$r] + 1))
    result+="$branch:$r "
    [ $r = failed_named ] && detail+="$branch named $(named_stage "$log"); "
    [ $r = failed_unnamed ] || [ $r = wrong_bytes ] || [ $r = hung ] && detail+="$branch: $(tail -n 1 "$log"); "
  done
  if grep -q "no reader of gcpipe_program within" "$run/feed.err"; then
    deaf=$((deaf + 1))
    detail+="feed: $(tail -n 1 "$run/feed.err"); "
  else
    deaf=0
  fi
  ran=$i
  printf '%4d %-28s %-10s %s %s\n' "$i" "$name" "$victim" "$result" "$detail" | tee -a "$work/soak.txt"
  if [ $deaf -ge 2 ]; then
    echo "soak: stopped after program $i: two feeds in a row matched no reader of gcpipe_program" | tee -a "$work/soak.txt"
    break
  fi
  if [ "$time_limit" -gt 0 ] && [ $((SECONDS - start)) -ge "$time_limit" ]; then
    echo "soak: stopped after program $i: the $time_limit s given are up" | tee -a "$work/soak.txt"
    break
  fi
  # The next program only once a killed stage is back (see the header).
  if [ "$victim" != "-" ] && [[ "$victim" != *gone* ]]; then
    for _ in $(seq 600); do [ "$(readies_of "$victim")" -gt "$before" ] && break; sleep 0.1; done
  fi
done

echo "soak: $ran programs ($((2 * ran)) files) of $programs asked, $kills kills -9, $((SECONDS - start)) s; files: identical to batch ${count[identical]}," \
     "failed as batch did ${count[as_batch_failed]}, failed loudly naming the stage ${count[failed_named]}," \
     "failed without naming it ${count[failed_unnamed]}, WRONG BYTES ${count[wrong_bytes]}, hung ${count[hung]}" \
  | tee -a "$work/soak.txt"
echo "soak: per-program lines and logs in $work"
[ "${count[wrong_bytes]}" -eq 0 ] && [ "${count[hung]}" -eq 0 ] && [ "${count[failed_unnamed]}" -eq 0 ]
