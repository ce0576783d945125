#!/bin/bash
# Measures the streaming pipeline end to end: feed -> node parse -> node trochoid -> node write
# -> sink, five processes on one host, against `gcpipe batch` on the same program, and checks the
# output is byte-identical. Usage:
#   stages/dds/measure_pipeline.sh GCPIPE_EXE BLOCKS|PROGRAM.nc [BATCH_BYTES] [DOMAIN]
# BLOCKS: a `gcpipe synth --blocks BLOCKS --seed 1` program; or an existing program file.
# Batch mode runs the same stages (parse, trochoid, write: --no-simulate).
# Prints one line: blocks written, batch size, batch-mode seconds, pipeline seconds (feed start to
# sink exit, including discovery), the sink's streaming seconds (first chunk to end marker),
# blocks/s for both pipeline figures and pipeline/batch; then each hop's DDS latency (reception
# minus source timestamp of every sample: p50, p99, max).
set -euo pipefail
G=$1
BLOCKS=$2
BATCH=${3:-32768}
export GCPIPE_DDS_DOMAIN=${4:-90}
W=$(mktemp -d /tmp/gcpipe_measure.XXXXXX)
trap 'rm -rf "$W"' EXIT
if [[ -f "$BLOCKS" ]]; then cp "$BLOCKS" "$W/in.nc"
else "$G" synth --blocks "$BLOCKS" --seed 1 -o "$W/in.nc" > /dev/null; fi
t0=$(date +%s.%N)
"$G" batch "$W/in.nc" -o "$W/batch" --quiet --no-simulate || true
t1=$(date +%s.%N)
"$G" sink -o "$W/sink.nc" --idle-timeout 120 2> "$W/sink.log" & S=$!
"$G" node write --batch-bytes "$BATCH" --idle-timeout 120 2> "$W/write.log" & WR=$!
"$G" node trochoid --batch-bytes "$BATCH" --idle-timeout 120 2> "$W/trochoid.log" & T=$!
"$G" node parse --batch-bytes "$BATCH" --idle-timeout 120 2> "$W/parse.log" & P=$!
t2=$(date +%s.%N)
"$G" feed "$W/in.nc" --chunk-bytes "$BATCH" 2> "$W/feed.log"
wait $P $T $WR
wait $S || true
t3=$(date +%s.%N)
cmp -s "$W/sink.nc" "$W/batch/output.nc" || { echo "OUTPUT DIFFERS"; cat "$W"/*.log; exit 1; }
emitted=$(sed 's/.*"blocks_written":\([0-9]*\).*/\1/' "$W/batch/summary.json")
stream=$(sed -n 's/.* \([0-9.]*\) s$/\1/p' "$W/sink.log")
awk -v b="$emitted" -v bb="$BATCH" -v t0="$t0" -v t1="$t1" -v t2="$t2" -v t3="$t3" \
    -v ts="$stream" 'BEGIN { tb = t1 - t0; tp = t3 - t2; printf "blocks %d  batch %d B  batch-mode %.3f s  pipeline %.3f s (%.0f blocks/s, %.2fx batch)  streaming %.3f s (%.0f blocks/s)  identical\n", b, bb, tb, tp, b / tp, tp / tb, ts, b / ts }'
grep -h "hop latency" "$W/parse.log" "$W/trochoid.log" "$W/write.log" "$W/sink.log" | sed 's/^/  /'
