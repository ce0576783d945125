#!/bin/bash
# Measures the pipeline across two "hosts": network namespaces joined by a veth pair (made here,
# removed on exit; needs root), feed + parse + trochoid on A, write + sink on B, with the shipped
# shop profile (pipeline_configs/dds_network_shop.xml) rewritten to the pair's addresses. Runs the
# same program plain and under DDS Security (identities from make_security.sh), and checks both
# outputs against `gcpipe batch`. Usage:
#   sudo stages/dds/measure_hosts.sh GCPIPE_EXE BLOCKS|PROGRAM.nc
# BLOCKS: a `gcpipe synth --blocks BLOCKS --seed 1` program; or an existing program file.
# Prints one line per run: blocks written, seconds from feed start to sink exit (discovery and
# the security handshakes included), the sink's streaming seconds, bytes sent from A to B.
set -euo pipefail
G=$(realpath "$1")
BLOCKS=$2
HERE=$(cd "$(dirname "$0")" && pwd)
W=$(mktemp -d /tmp/gcpipe_hosts.XXXXXX)
A=gcmeasA$$; B=gcmeasB$$
cleanup() { ip netns del "$A" 2>/dev/null || true; ip netns del "$B" 2>/dev/null || true; rm -rf "$W"; }
trap cleanup EXIT
ip netns add "$A"; ip netns add "$B"
ip link add "gcm$$a" type veth peer name "gcm$$b"
ip link set "gcm$$a" netns "$A"; ip link set "gcm$$b" netns "$B"
ip -n "$A" addr add 10.232.0.1/24 dev "gcm$$a"; ip -n "$B" addr add 10.232.0.2/24 dev "gcm$$b"
for ns in "$A" "$B"; do ip -n "$ns" link set lo up; done
ip -n "$A" link set "gcm$$a" up; ip -n "$B" link set "gcm$$b" up
sed -e 's/192\.0\.2\.11/10.232.0.1/g' -e 's/192\.0\.2\.12/10.232.0.2/g' \
  "$HERE/../../pipeline_configs/dds_network_shop.xml" > "$W/network.xml"
bash "$HERE/make_security.sh" "$W/ids" 17 > /dev/null
if [[ -f "$BLOCKS" ]]; then cp "$BLOCKS" "$W/in.nc"
else "$G" synth --blocks "$BLOCKS" --seed 1 -o "$W/in.nc" > /dev/null; fi
"$G" batch "$W/in.nc" -o "$W/batch" --quiet --no-simulate || true

# UDP datagrams a namespace dropped because a socket's receive buffer was full (/proc/net/snmp).
udp_receive_buffer_errors() {
  ip netns exec "$1" awk '/^Udp:/ { if (!h) { for (i = 1; i <= NF; i++) c[$i] = i; h = 1 } else print $c["RcvbufErrors"] }' /proc/net/snmp
}

run() {  # run LABEL NODE_IDENTITY_ARGS FEEDER_IDENTITY_ARGS
  local label=$1 node=$2 feeder=$3 dds="--network $W/network.xml --domain 17 --idle-timeout 120 --timeout 120"
  # 32 KB batches and chunks, one sample per UDP datagram, as the README's figures were taken
  # (the one-host default is 128 KB: stages/dds/README.md, "Batch size").
  local batch="--batch-bytes 32768"
  local tx0; tx0=$(ip netns exec "$A" cat "/sys/class/net/gcm$$a/statistics/tx_bytes")
  local drop0; drop0=$(udp_receive_buffer_errors "$B")
  rm -f "$W/sink.nc"
  ip netns exec "$B" "$G" sink -o "$W/sink.nc" $dds $node 2> "$W/sink.log" & local S=$!
  ip netns exec "$B" "$G" node write $dds $batch $node 2> "$W/write.log" & local WR=$!
  ip netns exec "$A" "$G" node trochoid $dds $batch $node 2> "$W/trochoid.log" & local T=$!
  ip netns exec "$A" "$G" node parse $dds $batch $node 2> "$W/parse.log" & local P=$!
  local t0; t0=$(date +%s.%N)
  ip netns exec "$A" "$G" feed "$W/in.nc" $dds --chunk-bytes 32768 $feeder 2> "$W/feed.log"
  wait $P $T $WR; wait $S || true
  local t1; t1=$(date +%s.%N)
  cmp -s "$W/sink.nc" "$W/batch/output.nc" || { echo "$label: OUTPUT DIFFERS"; tail -n 3 "$W"/*.log; exit 1; }
  local tx1; tx1=$(ip netns exec "$A" cat "/sys/class/net/gcm$$a/statistics/tx_bytes")
  local drops=$(( $(udp_receive_buffer_errors "$B") - drop0 ))
  local blocks; blocks=$(sed 's/.*"blocks_written":\([0-9]*\).*/\1/' "$W/batch/summary.json")
  local stream; stream=$(sed -n 's/.* \([0-9.]*\) s$/\1/p' "$W/sink.log")
  awk -v l="$label" -v b="$blocks" -v t0="$t0" -v t1="$t1" -v ts="$stream" -v tx=$((tx1 - tx0)) -v d="$drops" \
    'BEGIN { printf "%-8s blocks %d  pipeline %.3f s  streaming %.3f s (%.0f blocks/s)  A->B %.1f MB, datagrams dropped on B for a full receive buffer %d  identical\n", l, b, t1 - t0, ts, b / ts, tx / 1e6, d }'
}
run plain "" ""
run secured "--identity $W/ids/node" "--identity $W/ids/feeder"
