#!/usr/bin/env bash
# The docs test (issue 33 item 6): every recipe in README.md and docs/*.md runs as written.
#
#   bash tests/docs/run_doc_recipes.sh SOURCE_DIR GCPIPE_DIR
#
# A recipe is a fenced block opened by ```sh run (GitHub still shows it as sh). Other ```sh blocks
# are synopses with placeholders (IN.nc, OUTDIR), commands that never end (launch, monitor) or take
# minutes (train-ik), and are not run; among them the README's first two commands, which install
# packages and build: .ci/run runs exactly those, so CI runs them before it runs this test.
# docs/commands_extra.md is skipped: its recipes are run where the generator copies them, in
# docs/commands.md.
#
# Each page's recipes run in order, with `bash -euo pipefail`, in a fresh folder of its own that
# sees the checkout's samples/, pipeline_configs/, stages/ and docs/ (as a user in the checkout
# does), with GCPIPE_DIR first on PATH and GCPIPE_DDS_DOMAIN set to a domain no other test uses, so
# a streaming recipe cannot meet another test's pipeline. A recipe that fails, or takes longer than
# GCPIPE_RECIPE_TIMEOUT seconds (default 120), fails the test, named by page and line.
set -uo pipefail
src="$(cd "${1:?SOURCE_DIR}" && pwd)"
gcpipe_dir="$(cd "${2:?GCPIPE_DIR}" && pwd)"
timeout_s="${GCPIPE_RECIPE_TIMEOUT:-120}"
export PATH="$gcpipe_dir:$PATH"
export GCPIPE_DDS_DOMAIN="${GCPIPE_DOCS_DDS_DOMAIN:-171}"
[ -x "$gcpipe_dir/gcpipe" ] || { echo "no executable $gcpipe_dir/gcpipe" >&2; exit 1; }

scratch="$(mktemp -d "${TMPDIR:-/tmp}/gcpipe_doc_recipes.XXXXXX")"
trap 'rm -rf "$scratch"' EXIT

ran=0 failed=0 readme_ran=0
for page in "$src/README.md" "$src"/docs/*.md; do
  rel="${page#"$src"/}"
  [ "$rel" = docs/commands_extra.md ] && continue
  work="$scratch/$(echo "$rel" | tr '/.' '__')"
  mkdir -p "$work/recipes"
  for d in samples pipeline_configs stages docs; do ln -s "$src/$d" "$work/$d"; done
  # One file per recipe, named by the line of its opening fence.
  awk -v dir="$work/recipes" '
    /^```sh run[[:space:]]*$/ { on = 1; start = NR; f = sprintf("%s/%06d.sh", dir, NR); next }
    on && /^```/ { on = 0; close(f); next }
    on { print > f }' "$page"
  for recipe in "$work"/recipes/*.sh; do
    [ -e "$recipe" ] || continue
    line=$((10#$(basename "$recipe" .sh)))
    ran=$((ran + 1))
    [ "$rel" = README.md ] && readme_ran=$((readme_ran + 1))
    start=$(date +%s%N)
    if (cd "$work" && timeout --kill-after=10 "$timeout_s" bash -euo pipefail "$recipe") >"$recipe.log" 2>&1; then
      echo "ok    $rel:$line ($(( ($(date +%s%N) - start) / 1000000 )) ms)"
    else
      rc=$?
      failed=$((failed + 1))
      echo "FAIL  $rel:$line: exit status $rc$([ $rc -eq 124 ] && echo " (timed out after $timeout_s s)")"
      sed 's/^/    | /' "$recipe"
      echo "    output:"
      tail -n 30 "$recipe.log" | sed 's/^/    > /'
    fi
  done
done

echo "$ran recipes run, $failed failed"
# A convention that matched nothing would pass with nothing tested.
if [ "$readme_ran" -eq 0 ]; then echo "no \`\`\`sh run recipe found in README.md" >&2; exit 1; fi
[ "$failed" -eq 0 ]
