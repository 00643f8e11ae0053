#!/usr/bin/env bash
# The shared library's dynamic symbol table is its API: every exported symbol starts with
# consph_ and is declared in include/consph/*.h (internals such as ops_run or consph_rd_* stay
# hidden), and every function the headers declare is exported.
# Usage: symbols.sh <path-to-libconsph.so> <source-dir>
set -u
lib=$1 src=$2
cc=${CC:-cc}
command -v nm >/dev/null || { echo "symbols: nm not found, skipped"; exit 77; }
command -v "$cc" >/dev/null || { echo "symbols: no C compiler for the headers, skipped"; exit 77; }
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
fail=0

# Declared: identifiers called like functions in the preprocessed headers (comments gone), less
# the static inline ones, which have no symbol.
names() { grep -oE "$1" | grep -oE 'consph_[A-Za-z0-9_]+' | sort -u; }
for h in "$src"/include/consph/*.h; do
    "$cc" -E -P -I"$src/include" "$h" || { echo "FAIL: cannot preprocess $h"; exit 1; }
done | tr '\n' ' ' >"$work/headers"
names '\bconsph_[A-Za-z0-9_]+[[:space:]]*\(' <"$work/headers" >"$work/called"
names '\bstatic[^;{}()]*\bconsph_[A-Za-z0-9_]+[[:space:]]*\(' <"$work/headers" >"$work/static"
comm -23 "$work/called" "$work/static" >"$work/declared"
# Exported: defined dynamic symbols (nm -D prints "ADDRESS TYPE NAME").
nm -D --defined-only "$lib" | awk 'NF >= 3 { print $3 }' | sed 's/@.*//' | sort -u >"$work/exported"
[ -s "$work/declared" ] || { echo "FAIL: no declarations found in $src/include/consph"; exit 1; }
[ -s "$work/exported" ] || { echo "FAIL: $lib exports nothing"; exit 1; }

bad_prefix=$(grep -v '^consph_' "$work/exported")
[ -z "$bad_prefix" ] || { echo "FAIL: exported without the consph_ prefix:" $bad_prefix; fail=1; }
undeclared=$(comm -23 "$work/exported" "$work/declared" | grep '^consph_')
[ -z "$undeclared" ] || { echo "FAIL: exported but not in include/consph/:" $undeclared; fail=1; }
missing=$(comm -13 "$work/exported" "$work/declared")
[ -z "$missing" ] || { echo "FAIL: declared in include/consph/ but not exported:" $missing; fail=1; }

echo "symbols: $(wc -l <"$work/exported") exported, $(wc -l <"$work/declared") declared"
exit $fail
