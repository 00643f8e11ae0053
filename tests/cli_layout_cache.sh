#!/usr/bin/env bash
# CLI tests of the cache of packed layouts: the default directory under $XDG_CACHE_HOME, a hit
# giving the file of a fresh generation, a damaged file detected and rewritten, concurrent
# writers leaving one valid file, --no-cache writing nothing, the options of every command that
# can pack (layout, approx, study, run), and the refusals.
# Usage: cli_layout_cache.sh <path-to-consph> <source-dir>
set -u
bin=$(cd "$(dirname "$1")" && pwd)/$(basename "$1")
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
export OMP_NUM_THREADS=1
. "$2/tests/lib_cli.sh"

export XDG_CACHE_HOME=$work/xdg
cache=$XDG_CACHE_HOME/consph
gen=(layout --kind packed --dim 2 --nx 10 --max-iter 300 --history-every 100)
files() { find "$1" -name 'layout-*.bin' 2>/dev/null | wc -l; }

# A miss writes one file in the default directory; a hit says so and gives the same CSV (all
# digits) and report; --no-cache gives it too, from a fresh packing, and writes nothing.
"$bin" "${gen[@]}" --out "$work/miss.csv" >"$work/o1" 2>"$work/e1" || bad "miss: exit $?"
[ "$(files "$cache")" = 1 ] && pass=$((pass + 1)) || bad "miss: $(files "$cache") files in $cache"
[ -s "$work/e1" ] && bad "miss: stderr $(cat "$work/e1")"
"$bin" "${gen[@]}" --out "$work/hit.csv" >"$work/o2" 2>"$work/e2" || bad "hit: exit $?"
grep -q "read from the layout cache" "$work/o2" && pass=$((pass + 1)) || bad "hit: $(cat "$work/o2")"
cmp -s "$work/miss.csv" "$work/hit.csv" && pass=$((pass + 1)) || bad "hit: another CSV"
diff <(grep -v '^packing:\|^wrote' "$work/o1") <(grep -v '^packing:\|^wrote' "$work/o2") >/dev/null &&
    pass=$((pass + 1)) || bad "hit: other statistics or history"
XDG_CACHE_HOME=$work/xdg-off "$bin" "${gen[@]}" --no-cache --out "$work/off.csv" >"$work/o3" 2>&1 ||
    bad "--no-cache: exit $?"
cmp -s "$work/miss.csv" "$work/off.csv" && pass=$((pass + 1)) || bad "--no-cache: another CSV"
[ -e "$work/xdg-off" ] && bad "--no-cache created $work/xdg-off" || pass=$((pass + 1))
# --cache DIR overrides the default; lattice-based cheap kinds are not cached.
"$bin" "${gen[@]}" --cache "$work/mine" >/dev/null 2>&1 && [ "$(files "$work/mine")" = 1 ] &&
    pass=$((pass + 1)) || bad "--cache DIR: $(files "$work/mine") files"
"$bin" layout --kind random --dim 2 --nx 10 --cache "$work/cheap" >/dev/null 2>&1
[ -e "$work/cheap" ] && bad "random was cached" || pass=$((pass + 1))
# Different parameters, different files.
"$bin" "${gen[@]}" --seed 2 >/dev/null 2>&1
"$bin" "${gen[@]}" --perturb 0.4 >/dev/null 2>&1
[ "$(files "$cache")" = 3 ] && pass=$((pass + 1)) || bad "seed/perturb: $(files "$cache") files, want 3"

# A flipped byte, then a truncation: one line on stderr, the same CSV, the file rewritten.
f=$("$bin" "${gen[@]}" --history-every 0 >/dev/null 2>&1; ls "$cache"/layout-*.bin | head -1)
for damage in flip truncate; do
    for g in "$cache"/layout-*.bin; do
        size=$(stat -c %s "$g")
        if [ $damage = flip ]; then
            printf '\x55' | dd of="$g" bs=1 seek=$((size / 2)) conv=notrunc status=none
        else
            truncate -s $((size - 5)) "$g"
        fi
    done
    "$bin" "${gen[@]}" --out "$work/$damage.csv" >"$work/o" 2>"$work/e" || bad "$damage: exit $?"
    [ "$(grep -c 'layout cache.*recomputing' "$work/e")" = 1 ] && pass=$((pass + 1)) ||
        bad "$damage: stderr '$(cat "$work/e")'"
    grep -q "read from the layout cache" "$work/o" && bad "$damage: trusted the damaged file"
    cmp -s "$work/miss.csv" "$work/$damage.csv" && pass=$((pass + 1)) || bad "$damage: another CSV"
    "$bin" "${gen[@]}" >"$work/o" 2>"$work/e"
    grep -q "read from the layout cache" "$work/o" && [ ! -s "$work/e" ] &&
        pass=$((pass + 1)) || bad "$damage: not rewritten: $(cat "$work/e")"
done
[ -n "$f" ] || bad "no cache file found"

# Two writers at once: one whole file, no temporary left, and it hits.
c2=$work/concurrent
"$bin" "${gen[@]}" --cache "$c2" >"$work/w1" 2>&1 &
p1=$!
"$bin" "${gen[@]}" --cache "$c2" >"$work/w2" 2>&1 &
p2=$!
wait $p1 || bad "writer 1: exit $?"
wait $p2 || bad "writer 2: exit $?"
[ "$(files "$c2")" = 1 ] && [ -z "$(find "$c2" -name '.layout-tmp*')" ] && pass=$((pass + 1)) ||
    bad "concurrent: $(ls -a "$c2")"
# ... and one of them packed: the other waited on the key's lock and read the file
[ "$(cat "$work/w1" "$work/w2" | grep -c 'read from the layout cache')" = 1 ] && pass=$((pass + 1)) ||
    bad "concurrent: not packed once: $(grep -h '^packing:' "$work/w1" "$work/w2")"
"$bin" "${gen[@]}" --cache "$c2" --out "$work/c.csv" >"$work/o" 2>"$work/e"
grep -q "read from the layout cache" "$work/o" && [ ! -s "$work/e" ] &&
    cmp -s "$work/miss.csv" "$work/c.csv" && pass=$((pass + 1)) || bad "concurrent: not a valid file"

# A directory that cannot be written: a warning, the layout all the same.
touch "$work/plain"
"$bin" "${gen[@]}" --cache "$work/plain/sub" --out "$work/w.csv" >"$work/o" 2>"$work/e" &&
    grep -q "warning: cannot write the layout cache" "$work/e" && cmp -s "$work/miss.csv" "$work/w.csv" &&
    pass=$((pass + 1)) || bad "unwritable: exit or message '$(cat "$work/e")'"

# Refusals: exit 2, the option named, nothing written.
failing 2 "option --cache: empty value" "$work/o" -- "$bin" "${gen[@]}" --cache "" &&
    pass=$((pass + 1))
failing 2 "--cache and --no-cache" "$work/o" -- "$bin" "${gen[@]}" --cache "$work/x" --no-cache &&
    pass=$((pass + 1))
[ -e "$work/x" ] && bad "refused run created $work/x"

# approx, run and study take the options; approx packs through the cache.
"$bin" approx --op function --layout packed --nx 8 --pack-iter 20 --cache "$work/ap" --format csv \
    >/dev/null 2>&1 && [ "$(files "$work/ap")" = 1 ] && pass=$((pass + 1)) ||
    bad "approx: $(files "$work/ap") files"
"$bin" approx --op function --layout packed --nx 8 --pack-iter 20 --no-cache --format csv \
    >/dev/null 2>&1 || bad "approx --no-cache: exit $?"
failing 2 "option --cache: empty value" "$work/o" -- "$bin" run taylor-green --scheme wcsph \
    --nx 8 --steps 1 --cache "" && pass=$((pass + 1))
failing 2 "--cache and --no-cache" "$work/o" -- "$bin" study 001-table3 --quick --cache "$work/s" \
    --no-cache && pass=$((pass + 1))
"$bin" run taylor-green --scheme wcsph --layout packed --nx 8 --steps 1 --cache "$work/run" \
    >/dev/null 2>&1 && [ "$(files "$work/run")" = 1 ] && pass=$((pass + 1)) ||
    bad "run: $(files "$work/run") files"

# A study without the cache packs its rows' layouts into a private directory of its own (under
# $TMPDIR, shared by its worker processes), removed at the end: the user's cache is not created
# and nothing is left behind; with the cache the same rows are the same numbers.
mkdir -p "$work/tmp"
cat >"$work/nc.study" <<'END'
study = nc
title = two packed series
[figure f]
kind = run
problem = taylor-green
nx = 8,10
steps = 2
[series A]
scheme = l-ipst-c
[series B]
scheme = tv-c
END
TMPDIR=$work/tmp XDG_CACHE_HOME=$work/xdg-nc "$bin" study "$work/nc.study" --no-cache --jobs 2 \
    --out "$work/nc-off" >"$work/o" 2>&1 || bad "study --no-cache: exit $?, $(cat "$work/o")"
[ -e "$work/xdg-nc" ] && bad "study --no-cache created $work/xdg-nc" || pass=$((pass + 1))
[ -z "$(ls -A "$work/tmp")" ] && pass=$((pass + 1)) || bad "study --no-cache left $(ls -A "$work/tmp")"
"$bin" study "$work/nc.study" --cache "$work/nc-cache" --out "$work/nc-on" >"$work/o" 2>&1 ||
    bad "study --cache: exit $?, $(cat "$work/o")"
cut -d, -f1-14,16- "$work/nc-off/nc/f.csv" >"$work/nc-off.csv"
cut -d, -f1-14,16- "$work/nc-on/nc/f.csv" >"$work/nc-on.csv"
cmp -s "$work/nc-off.csv" "$work/nc-on.csv" && pass=$((pass + 1)) ||
    bad "study --no-cache: other rows than with the cache"

summary cli_layout_cache
