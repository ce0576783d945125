#!/usr/bin/env bash
# Issue 11's speed benchmark: end-to-end wall time of `gcpipe stream` against `gcpipe batch
# --no-simulate` on a generated 20 MB program, runs alternating within this one benchmark run,
# and the median ratio; then the DDS latency of every hop (reception minus source timestamp of
# each sample: p50, p99, max), as the nodes and the sink print it. A benchmark, not a test: it
# prints figures and fails only when the two outputs differ. Last, one paced run (the feed sends
# RATE bytes/s, below the pipeline's capacity) gives the hop latencies of the transport without
# the queues a throughput-bound run builds.
#
#   bash tests/bench/stream_bench.sh [GCPIPE] [MEGABYTES] [RUNS] [NODES] [DOMAIN] [RATE]
#
# NODES: the streamed stages, comma-separated (default parse,trochoid,write: the stages that make
# output.nc; batch --no-simulate runs those and the IK beside them). A `+` groups stages into one
# process, as a pipeline file's `groups:` does: parse+trochoid+write.
set -euo pipefail
gcpipe="$(realpath "${1:-build/stages/cli/gcpipe}")"
megabytes="${2:-20}"
runs="${3:-5}"
nodes="${4:-parse,trochoid,write}"
domain="${5:-231}"
rate="${6:-5000000}"
root="$(cd "$(dirname "$0")/../.." && pwd)"
work="$(mktemp -d /tmp/gcpipe_stream_bench.XXXXXX)"
trap 'rm -rf "$work"' EXIT

"$gcpipe" synth --megabytes "$megabytes" --seed 1 -o "$work/in.nc" > /dev/null
node_list="$(tr '+' ',' <<< "$nodes")"
{
  echo "pipeline:"
  echo "  name: stream_bench"
  echo "  domain: $domain"
  echo "  config: $root/pipeline_configs/default.yaml"
  echo "  on_crash: stop"
  echo "  timeout: 120"
  echo "nodes: [$node_list]"
  groups=()
  for g in ${nodes//,/ }; do [[ "$g" == *+* ]] && groups+=("$g"); done
  if [ ${#groups[@]} -gt 0 ]; then echo "groups: [$(IFS=,; echo "${groups[*]}")]"; fi
} > "$work/pipeline.yaml"

echo "program: $(stat -c %s "$work/in.nc") bytes, $(wc -l < "$work/in.nc") lines; streamed: $nodes;" \
     "$(nproc) cores, load average $(cut -d' ' -f1-3 /proc/loadavg)"
ratios=()
for run in $(seq "$runs"); do
  t0=$(date +%s.%N)
  "$gcpipe" batch "$work/in.nc" -o "$work/batch" --no-simulate --quiet || true
  t1=$(date +%s.%N)
  "$gcpipe" stream "$work/in.nc" -o "$work/stream" --pipeline "$work/pipeline.yaml" -v > "$work/stream.log" 2>&1 || true
  t2=$(date +%s.%N)
  if ! cmp -s "$work/batch/output.nc" "$work/stream/output.nc"; then
    echo "run $run: output.nc DIFFERS between batch and stream"; tail -30 "$work/stream.log"; exit 1
  fi
  ratio=$(awk -v a="$t0" -v b="$t1" -v c="$t2" 'BEGIN { printf "%.3f", (c - b) / (b - a) }')
  ratios+=("$ratio")
  awk -v r="$run" -v a="$t0" -v b="$t1" -v c="$t2" -v q="$ratio" \
    'BEGIN { printf "run %d: batch --no-simulate %.3f s, stream %.3f s: %.2fx (output.nc identical)\n", r, b - a, c - b, q }'
  grep -o "hop latency from .*" "$work/stream.log" | sed "s/^/  run $run: /" > "$work/hops.$run"
done
median=$(printf '%s\n' "${ratios[@]}" | sort -g | awk '{ v[NR] = $1 } END { print (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2 }')
echo "median stream / batch: ${median}x over $runs alternating runs (target <= 1.3x)"
echo "hop latencies (one line per reader and run; target p99 < 1 ms):"
cat "$work"/hops.*
"$gcpipe" stream "$work/in.nc" -o "$work/paced" --pipeline "$work/pipeline.yaml" --feed-rate "$rate" -v \
  > "$work/paced.log" 2>&1 || { echo "the paced run failed"; tail -30 "$work/paced.log"; exit 1; }
cmp -s "$work/batch/output.nc" "$work/paced/output.nc" || { echo "paced run: output.nc DIFFERS"; exit 1; }
echo "paced run (the feed sends $rate bytes/s; output.nc identical), hop latencies:"
grep -o "hop latency from .*" "$work/paced.log" | sed "s/^/  /"
