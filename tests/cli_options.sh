#!/usr/bin/env bash
# The shared option parsers of apps/cli.c as every command sees them: a list with an empty item,
# a box with an empty axis, or a periodic axis the particles do not have is rejected with exit
# status 2 and one line naming the option and what is allowed; the good forms still work.
# Usage: cli_options.sh <path-to-consph> <source-dir>
set -u
bin=$(cd "$(dirname "$1")" && pwd)/$(basename "$1")
fail=0
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
export OMP_NUM_THREADS=1
bad() {
    echo "FAIL: $*" >&2
    fail=1
}

# usage_error OPTION ALLOWED COMMAND ARGS...: exit 2, one line naming OPTION and matching ALLOWED
# (a grep pattern for what is allowed).
usage_error() {
    local option=$1 allowed=$2
    shift 2
    (cd "$work/run" && "$bin" "$@" >"$work/stdout" 2>"$work/stderr")
    local status=$?
    [ "$status" -eq 2 ] || bad "'$*': exit status $status, expected 2"
    [ "$(wc -l <"$work/stderr")" -eq 1 ] || bad "'$*': stderr is not one line: $(cat "$work/stderr")"
    grep -q -- "option $option" "$work/stderr" || bad "'$*': does not name $option: $(cat "$work/stderr")"
    grep -q -- "$allowed" "$work/stderr" || bad "'$*': does not say '$allowed' is allowed: $(cat "$work/stderr")"
    [ ! -s "$work/stdout" ] || bad "'$*': printed results: $(head -3 "$work/stdout")"
    [ -z "$(ls -A "$work/run")" ] || bad "'$*': wrote $(ls -A "$work/run")"
}
ok() {
    "$bin" "$@" >"$work/stdout" 2>"$work/stderr" || bad "'$*': exit status $?: $(cat "$work/stderr")"
}
mkdir "$work/run"
"$bin" layout --kind lattice --dim 2 --nx 10 --out "$work/p.csv" >/dev/null || bad "layout p.csv"

# Integer lists: every empty item is an error, not only a trailing one.
for nx in "10,,20" "10," ",10" "," "10,20,,"; do
    usage_error --nx "allowed: .*integer 2..100000" approx --op grad --nx "$nx" --format csv
done
usage_error --nx "allowed: .*integer 2..100000" approx --op grad --nx "$(printf '0%.0s' $(seq 200))10" --format csv
ok approx --op grad --nx 10,20 --format csv
[ "$(grep -c '^[12]0,' "$work/stdout")" = 2 ] || bad "--nx 10,20: not two rows: $(cat "$work/stdout")"

# Periodic axes past the dimension: layouts (--dim) and particle files (their own dimension).
usage_error --periodic "allowed: .*among xy$" approx --op grad --nx 10 --dim 2 --periodic z --format csv
usage_error --periodic "allowed: .*among xy$" approx --op grad --nx 10 --dim 2 --periodic xz --format csv
usage_error --periodic "allowed: .*among x$" approx --op grad --nx 10 --dim 1 --periodic y --format csv
usage_error --periodic "allowed: .*among xy$" approx --op grad --particles "$work/p.csv" --periodic z --format csv
usage_error --periodic "allowed: .*among xy$" study 001-table3 --quick --particles "$work/p.csv" --periodic z --out "$work/run/s"
for p in "x,,y" ",x" "x," "xx" "w"; do
    usage_error --periodic "allowed: yes, no" approx --op grad --nx 10 --periodic "$p" --format csv
done
ok approx --op grad --nx 10 --dim 3 --periodic z --format csv
ok approx --op grad --nx 10 --dim 2 --periodic x,y --format csv
ok approx --op grad --nx 10 --dim 2 --periodic yes --format csv

# Boxes and file lists with an empty item.
usage_error --box "allowed: x0:x1" approx --op grad --particles "$work/p.csv" --box 0:1,,0:1 --format csv
usage_error --box "allowed: x0:x1" approx --op grad --particles "$work/p.csv" --box ,0:1,0:1 --format csv
usage_error --particles "comma-separated list of files" approx --op grad --particles "$work/p.csv,,$work/p.csv" --format csv
usage_error --particles "comma-separated list of files" study 001-table3 --quick --particles "$work/p.csv,,$work/p.csv" --out "$work/run/s"
ok approx --op grad --particles "$work/p.csv" --box 0:1,0:1 --format csv

[ $fail = 0 ] && echo "cli_options: passed" || echo "cli_options: FAILED"
exit $fail
