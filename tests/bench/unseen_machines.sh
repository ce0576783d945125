#!/usr/bin/env bash
# The measured-data loop on machines gcpipe has not seen (issue 29 items 4 and 5): the whole set
# of seeded machines from the second simulator (tests/unseen_machine), each calibrated from one
# trace of the circle, the trochoidal slot or the five-axis move, scored (effect named within
# 15 %, clean machines silent, effects outside the catalogue left unidentified), and the loop
# closed on the first `loop` of them (compensated with the declared config and with the calibrated
# drives, both run on the machine). The CI runs the first 5 machines and 1 loop; this runs them
# all. A benchmark, not a test: it prints the table and the counts and never fails on them.
#   bash tests/bench/unseen_machines.sh [build] [machines] [loop] [parts]
# `parts` > 1 runs the machines in that many processes side by side (machines are independent
# and seeded, so the counts are the same as in one process) and adds up their counts.
set -uo pipefail
build="${1:-build}"
machines="${2:-36}"
loop="${3:-6}"
parts="${4:-1}"
echo "== $(date -u +%FT%TZ) $(lscpu | sed -n 's/^Model name: *//p') $(nproc) cores, $parts process(es)"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
per=$(( (machines + parts - 1) / parts ))
for ((p = 0; p < parts; ++p)); do
  first=$(( p * per ))
  count=$(( machines - first < per ? machines - first : per ))
  (( count > 0 )) || break
  GCPIPE_UNSEEN_FIRST="$first" GCPIPE_UNSEEN_MACHINES="$count" "$build/tests/calibrate_unseen_test" \
    --gtest_filter='*EffectsAreNamed*' > "$tmp/part$p.log" 2>&1 &
done
wait
for f in "$tmp"/part*.log; do
  grep -E '^machine|^  [XYC]: named|^  effect|^  clean|^  outside|^unseen machines' "$f"
done
# The counts of every part, added up (each part prints "a/b" pairs and the false names).
grep -h '^unseen machines' "$tmp"/part*.log | awk -F'[:;/]' '
  { m += $2; ef += $4; e += $5; cs += $7; c += $8; os += $10; o += $11; fn += $13 }
  END { printf "all %d machines: effects found within 15 %%: %d/%d; clean machines with nothing named: %d/%d; outside-catalogue effects left unidentified: %d/%d; effects named where the machine has none: %d\n", m, ef, e, cs, c, os, o, fn }'
if (( loop > 0 )); then
  GCPIPE_UNSEEN_LOOP="$loop" "$build/tests/calibrate_unseen_test" --gtest_filter='*Compensation*' | grep -E '^closed loop'
fi
echo "== done $(date -u +%FT%TZ)"
exit 0
