#!/usr/bin/env bash
# consph study: the pack_walls key packs an approximation study's particles inside frozen
# lattice layers (consph layout --walls) and gives the same particles as consph layout; it is
# refused (exit 2, naming the key and what is allowed) off the packed layout, as a fraction and
# out of range, and below the kernel's reach (the library's check, at run time: exit 2 as well).
# Usage: cli_study_walls.sh <path-to-consph> <source-dir>
set -u
bin=$1
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
export XDG_CACHE_HOME=$work/cache
fail=0
bad() { echo "FAIL: $*"; fail=1; }
study() { # walls layout extra-line
    cat > "$work/w.study" <<EOS
study = w
title = walls
paper = none
note = self-test

[figure grad]
title = Gradient on walled packed particles
op = grad
form = asym
corr = bc
kernel = quintic
layout = $2
pack_walls = $1
pack_iter = 300
nx = 12,16
EOS
}
refused() { # walls layout what-the-message-must-say
    study "$1" "$2"
    "$bin" study "$work/w.study" --out "$work/o" > "$work/out" 2> "$work/err"
    rc=$?
    [ "$rc" = 2 ] && grep -q "$3" "$work/err" || bad "walls $1 layout $2: rc $rc, $(cat "$work/err")"
    [ ! -e "$work/o/w" ] || bad "walls $1 layout $2: left $work/o/w"
    rm -rf "$work/o"
}
refused 3 lattice "pack_walls"
refused 2.5 packed "pack_walls"
refused 9 packed "pack_walls"
refused 1 packed "walls"
study 3 packed
"$bin" study "$work/w.study" --out "$work/o" > "$work/out" 2> "$work/err" ||
    bad "walls 3: rc $?, $(cat "$work/err")"
[ -s "$work/o/w/README.md" ] || bad "walls 3: no report"
# the study's nx 16 particles are those of consph layout --walls 3 (the cache holds both under
# one key: a second generation through the layout command reads the study's entry)
"$bin" layout --kind packed --dim 2 --nx 16 --walls 3 --max-iter 300 > "$work/lay" 2>&1 ||
    bad "layout --walls 3: $(cat "$work/lay")"
grep -q "read from the layout cache" "$work/lay" || bad "layout --walls 3 did not hit the study's cache entry: $(cat "$work/lay")"
[ "$fail" = 0 ] && echo "cli_study_walls: ok"
exit "$fail"
