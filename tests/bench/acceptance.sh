#!/usr/bin/env bash
# Acceptance of real programs (issue 32 item 4): every program under DIR goes through
# `gcpipe parse` with a shipped config, and through LinuxCNC's rs274 where it reads the dialect.
#
#   bash tests/bench/acceptance.sh DIR [OUT]        (gcpipe from build/stages/cli or PATH)
#
# DIR holds in-scope programs only (3- and 5-axis milling; no lathe, plasma, laser), collected
# outside the project. Per program:
#   - the config: LinuxCNC's (pipeline_configs/linuxcnc_xyzac_trt.yaml) for .ngc files, the
#     default (Fanuc dialect, pipeline_configs/default.yaml) for every other extension;
#   - "whole": every line accepted with that config and its machine file's tool table;
#   - "own tools": accepted once the program's own tools are in the table, as a shop's table
#     (--tool-table) would have them: the only errors were tools the machine file does not list,
#     and a table naming each tool of the program (T, H, D words; diameter 6 mm, length 100 mm)
#     clears them;
#   - "rejected": the first error that remains, whose class (the message with its numbers,
#     words and quotes blanked) is counted over all programs;
#   - rs274 (.ngc only, when installed): whether LinuxCNC's interpreter reads it without error
#     (`rs274 -n 0 -g -t TABLE`, the same generated table), so that a rejection both share is
#     told from one only gcpipe makes.
# Writes OUT/programs.tsv (one row a program) and OUT/summary.txt (totals, classes), prints the
# summary. OUT defaults to ./acceptance_out.
set -u
DIR=${1:?usage: acceptance.sh DIR [OUT]}
OUT=${2:-acceptance_out}
HERE=$(cd "$(dirname "$0")/../.." && pwd)
GCPIPE=${GCPIPE:-$HERE/build/stages/cli/gcpipe}
[ -x "$GCPIPE" ] || GCPIPE=$(command -v gcpipe) || { echo "gcpipe not found: build it or set GCPIPE" >&2; exit 2; }
RS274=$(command -v rs274 || true)
mkdir -p "$OUT/tables" "$OUT/logs"

config_for() {  # the shipped config for a program, by its extension
  case "${1,,}" in
    *.ngc) echo "$HERE/pipeline_configs/linuxcnc_xyzac_trt.yaml" ;;
    *) echo "$HERE/pipeline_configs/default.yaml" ;;
  esac
}

# A LinuxCNC tool table naming every tool number the program uses: T, and H (G43) and D (G41/G42)
# words, which name tools too (words outside comments; a G41.1 D diameter adds a harmless entry).
tool_table_for() {
  local prog=$1 table=$2
  sed -e 's/([^)]*)//g' -e 's/;.*$//' "$prog" | grep -oiE '(^|[^A-Z#<_])[THD] *[0-9]+' | grep -oE '[0-9]+' | sort -un |
    awk '$1 > 0 {printf "T%d P%d Z100 D6 ;\n", $1, $1}' >"$table"  # T0 is no tool
  [ -s "$table" ] || echo "T1 P1 Z100 D6 ;" >"$table"
}

# The first error's class: numbers, quoted words and single words like 'X12' blanked.
error_class() {
  sed -E -e 's/^[^:]*:[0-9]+:[0-9]+: error: //' -e "s/'[^']*'/'_'/g" -e 's/[A-Z#][-+0-9.]+/_/g' \
         -e 's/-?[0-9]+(\.[0-9]+)?/N/g' -e 's/ +/ /g' | cut -c1-110
}

first_error() { grep -m1 ': error: ' "$1" || true; }

# gcpipe parse: "whole", "own tools" or "rejected"; sets REASON to the first error left.
judge_gcpipe() {
  local prog=$1 key=$2 cfg
  cfg=$(config_for "$prog")
  timeout 300 "$GCPIPE" parse "$prog" --config "$cfg" --no-progress -o /dev/null 2>"$OUT/logs/$key.err"
  local st=$?
  REASON=$(first_error "$OUT/logs/$key.err")
  if [ $st -eq 0 ]; then echo whole; return; fi
  [ $st -eq 124 ] && { REASON="timeout (300 s)"; echo rejected; return; }
  [ $st -ne 3 ] && [ -z "$REASON" ] && REASON=$(tail -n1 "$OUT/logs/$key.err")
  if grep ': error: ' "$OUT/logs/$key.err" | grep -vq 'is not in the machine config.s tool table'; then
    echo rejected
    return
  fi
  tool_table_for "$prog" "$OUT/tables/$key.tbl"
  timeout 300 "$GCPIPE" parse "$prog" --config "$cfg" --tool-table "$OUT/tables/$key.tbl" --no-progress -o /dev/null \
    2>"$OUT/logs/$key.tools.err"
  if [ $? -eq 0 ]; then echo "own tools"; return; fi
  REASON=$(first_error "$OUT/logs/$key.tools.err")
  echo rejected
}

# rs274 on .ngc programs: "reads" (no error), "errors" (its first message), "no output" (three
# runs without a canonical call), or "-" (not run).
judge_rs274() {
  local prog=$1 key=$2
  case "${prog,,}" in *.ngc) ;; *) echo "-"; return ;; esac
  [ -n "$RS274" ] || { echo "-"; return; }
  [ -s "$OUT/tables/$key.tbl" ] || tool_table_for "$prog" "$OUT/tables/$key.tbl"
  # -n 0 reads on after an error; M2 appended: rs274 repeats its complaint about a missing end.
  { cat "$prog"; echo; echo M2; } >"$OUT/logs/$key.rs274.ngc"
  # Another rs274 running at the same time (another checkout's tests) can leave a run with no
  # output at all, which would read as "no error": such a run is tried again, then said.
  local try
  for try in 1 2 3; do
    (cd "$(dirname "$prog")" && timeout 120 "$RS274" -n 0 -g -t "$OUT/tables/$key.tbl" "$OUT/logs/$key.rs274.ngc") \
      >"$OUT/logs/$key.rs274.out" 2>"$OUT/logs/$key.rs274.err"
    grep -q 'N[.0-9]* *[A-Z_]*(' "$OUT/logs/$key.rs274.out" && break
  done
  grep -q 'N[.0-9]* *[A-Z_]*(' "$OUT/logs/$key.rs274.out" || { echo "no output"; return; }
  local msg
  msg=$(grep -v -e '^executing$' -e '^ *$' "$OUT/logs/$key.rs274.err" | head -n1)
  if [ -z "$msg" ]; then echo reads; else echo "errors: $msg"; fi
}

printf 'program\tgcpipe\tfirst error\trs274\n' >"$OUT/programs.tsv"
n=0
while IFS= read -r prog; do
  n=$((n + 1))
  key=$(printf '%04d' $n)
  verdict=$(judge_gcpipe "$prog" "$key")
  reason=""
  [ "$verdict" = rejected ] && reason=$(first_error "$OUT/logs/$key.err")
  [ "$verdict" = rejected ] && [ -s "$OUT/logs/$key.tools.err" ] && reason=$(first_error "$OUT/logs/$key.tools.err")
  [ "$verdict" = rejected ] && [ -z "$reason" ] && [ -s "$OUT/logs/$key.tools.err" ] && reason=$(tail -n1 "$OUT/logs/$key.tools.err")
  [ "$verdict" = rejected ] && [ -z "$reason" ] && reason=$(tail -n1 "$OUT/logs/$key.err")
  rs=$(judge_rs274 "$prog" "$key")
  printf '%s\t%s\t%s\t%s\n' "${prog#"$DIR"/}" "$verdict" "$reason" "$rs" >>"$OUT/programs.tsv"
done < <(find "$DIR" -type f \( -iname '*.ngc' -o -iname '*.nc' -o -iname '*.gcode' -o -iname '*.tap' -o -iname '*.gc' \) | sort)

{
  total=$(($(wc -l <"$OUT/programs.tsv") - 1))
  whole=$(awk -F'\t' 'NR > 1 && $2 == "whole"' "$OUT/programs.tsv" | wc -l)
  tools=$(awk -F'\t' 'NR > 1 && $2 == "own tools"' "$OUT/programs.tsv" | wc -l)
  rejected=$((total - whole - tools))
  pct() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.0f %%", b ? 100 * a / b : 0 }'; }
  echo "gcpipe: $GCPIPE"
  echo "programs: $total (from $DIR)"
  echo "accepted whole with the shipped configs: $whole ($(pct "$whole" "$total"))"
  echo "accepted with the program's own tool table: $tools more ($(pct $((whole + tools)) "$total") in all)"
  echo "rejected: $rejected"
  ngc=$(awk -F'\t' 'NR > 1 && $4 != "-"' "$OUT/programs.tsv" | wc -l)
  reads=$(awk -F'\t' 'NR > 1 && $4 == "reads"' "$OUT/programs.tsv" | wc -l)
  both=$(awk -F'\t' 'NR > 1 && $4 == "reads" && $2 != "rejected"' "$OUT/programs.tsv" | wc -l)
  only_ours=$(awk -F'\t' 'NR > 1 && $4 == "reads" && $2 == "rejected"' "$OUT/programs.tsv" | wc -l)
  echo "rs274 ran on $ngc .ngc programs: reads $reads without error; of those gcpipe accepts $both, rejects $only_ours"
  echo
  echo "first error left, by class (count, class, first program):"
  awk -F'\t' 'NR > 1 && $2 == "rejected" { print $1 "\t" $3 }' "$OUT/programs.tsv" |
    while IFS=$'\t' read -r p r; do printf '%s\t%s\n' "$(printf '%s' "$r" | error_class)" "$p"; done |
    awk -F'\t' '{ c[$1]++; if (!($1 in f)) f[$1] = $2 } END { for (k in c) printf "%4d  %s  [%s]\n", c[k], k, f[k] }' |
    sort -rn
} | tee "$OUT/summary.txt"
