#!/usr/bin/env bash
# The generated bash completion (docs/gen_cli_docs.sh completion) completes what gcpipe takes:
# a command, a command's option, and dds's subcommand.
#   bash tests/docs/completion_check.sh build/docs/gcpipe.bash
set -euo pipefail
# shellcheck disable=SC1090
source "${1:?the completion script}"
complete_words() {  # the completions of the command line "$@", the last word being completed
  COMP_WORDS=("$@"); COMP_CWORD=$(($# - 1)); COMPREPLY=()
  _gcpipe
  echo "${COMPREPLY[*]}"
}
check() {  # check EXPECTED WORDS...
  local want=$1; shift
  local got; got=$(complete_words "$@")
  if [ "$got" != "$want" ]; then echo "completing '$*': got '$got', expected '$want'" >&2; exit 1; fi
  echo "ok: '$*' -> '$got'"
}
check "batch" gcpipe bat
check "--no-simulate" gcpipe batch --no-s
check "--partition" gcpipe node --parti
check "--feed-rate" gcpipe stream --feed
check "clean" gcpipe dds c
