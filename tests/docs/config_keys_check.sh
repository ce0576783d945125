#!/usr/bin/env bash
# Every key a config reader accepts is documented in docs/config.md: the keys are taken from the
# reject_unknown({...}) lists in the code (the readers' own whitelists), so a key added there
# without a line in config.md fails this.
#   bash tests/docs/config_keys_check.sh SOURCE_DIR
set -euo pipefail
src="${1:?SOURCE_DIR}"
doc="$src/docs/config.md"
# The lists span lines: join each file, cut out every reject_unknown({...}), split on the quotes.
keys=$(find "$src/stages" -name '*.cpp' ! -path '*/common/config.cpp' -print0 |
  xargs -0 cat | tr '\n' ' ' | grep -o 'reject_unknown({[^}]*})' | grep -o '"[^"]*"' | tr -d '"' | sort -u)
[ -n "$keys" ] || { echo "no reject_unknown lists found under $src/stages" >&2; exit 1; }
missing=0
for k in $keys; do
  # Documented as `key` or as part of a dotted name (`pipeline.key`) or a list (`a_offset_y`, ...).
  if ! grep -qE "\`([a-z_0-9]+\.)?$k\`" "$doc"; then echo "docs/config.md does not name the key '$k'" >&2; missing=$((missing + 1)); fi
done
echo "$(echo "$keys" | wc -w) keys checked, $missing missing"
[ "$missing" -eq 0 ]
