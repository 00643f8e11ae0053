#!/usr/bin/env bash
# CLI tests of `consph layout`: every kind writes .csv and .vtu with the documented content; bad
# input gives exit status 2, one line on stderr naming the option, and no output file.
# Usage: cli_layout.sh <path-to-consph> <source-dir>
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

# --- every kind, both formats ------------------------------------------------------------
for kind in lattice random quasi-random packed packed-polished; do
    extra=()
    [ "$kind" = packed ] && extra=(--max-iter 300 --history-every 100)
    [ "$kind" = packed-polished ] && extra=(--max-iter 300 --tol 1e-2 --history-every 100)
    for ext in csv vtu; do
        out="$work/$kind.$ext"
        if ! "$bin" layout --kind "$kind" --dim 2 --nx 8 "${extra[@]}" --out "$out" \
            >"$work/stdout" 2>"$work/stderr"; then
            bad "$kind .$ext: exit status $? ($(cat "$work/stderr"))"
            continue
        fi
        [ -s "$work/stderr" ] && bad "$kind .$ext: unexpected stderr: $(cat "$work/stderr")"
        grep -q "particles 64" "$work/stdout" || bad "$kind .$ext: count not printed"
        grep -q "min spacing" "$work/stdout" || bad "$kind .$ext: min spacing not printed"
        grep -q "max|rho/rho0-1|" "$work/stdout" || bad "$kind .$ext: density spread not printed"
        [ -f "$out" ] || { bad "$kind .$ext: no file written"; continue; }
        if [ "$ext" = csv ]; then
            [ "$(head -n 1 "$out")" = "# consph particles" ] || bad "$kind csv: first line"
            grep -q '^# dim 2$' "$out" || bad "$kind csv: no '# dim 2' line"
            grep -q '^# periodic 1 1$' "$out" || bad "$kind csv: no '# periodic 1 1' line"
            header=$(grep -v '^#' "$out" | head -n 1)
            [ "$header" = "x,y,volume" ] || bad "$kind csv: header '$header' is not x,y,volume"
            rows=$(grep -v '^#' "$out" | tail -n +2 | wc -l)
            [ "$rows" -eq 64 ] || bad "$kind csv: $rows data rows, expected 64"
            # volume = 1/64 on every row; coordinates inside [0, 1).
            awk -F, '!/^#/ && NR > 1 && $1 != "x" {
                    if ($3 != 0.015625 || $1 < 0 || $1 >= 1 || $2 < 0 || $2 >= 1) bad++ }
                 END { exit bad > 0 }' "$out" || bad "$kind csv: a row has a wrong volume or lies outside the box"
        else
            grep -q 'NumberOfPoints="64"' "$out" || bad "$kind vtu: NumberOfPoints"
            grep -q 'Name="volume"' "$out" || bad "$kind vtu: no volume array"
            tail -n 1 "$out" | grep -q '</VTKFile>' || bad "$kind vtu: not closed"
        fi
    done
done

# The packed kind prints its iteration count and spread history.
"$bin" layout --kind packed --dim 2 --nx 8 --max-iter 200 --history-every 50 >"$work/stdout" 2>&1 ||
    bad "packed without --out failed"
grep -q '^packing: ' "$work/stdout" || bad "packed: no packing line"
[ "$(grep -cE '^ +(0|50|100|150|200) +[0-9.e+-]+$' "$work/stdout")" -ge 5 ] ||
    bad "packed: spread history missing: $(cat "$work/stdout")"

# The report never contradicts itself: a run that stops on --max-iter (0 included) does not say
# the tolerance was met, and one whose tolerance was met is not called "NOT converged".
for args in "packed --max-iter 0" "packed --max-iter 1" "packed --max-iter 0 --perturb 0" \
    "packed --move-tol 1e-2" "packed --walls 3 --max-iter 1" "packed-polished --max-iter 0" "packed-polished --max-iter 1" \
    "packed-polished --max-iter 0 --perturb 0" "packed-polished --max-iter 300 --tol 1e-2"; do
    # shellcheck disable=SC2086
    "$bin" layout --kind $args --dim 2 --nx 8 --history-every 0 >"$work/stdout" 2>&1 ||
        bad "packed $args failed: $(cat "$work/stdout")"
    if grep -q "NOT converged" "$work/stdout"; then
        ! grep -q "tolerance was met" "$work/stdout" || bad "packed $args: says both NOT converged and tolerance met"
    else
        grep -q "converged" "$work/stdout" || bad "packed $args: no convergence verdict"
        ! grep -q -- "--max-iter was reached" "$work/stdout" || bad "packed $args: converged yet --max-iter reached"
    fi
done
"$bin" layout --kind packed --dim 2 --nx 8 --max-iter 0 >"$work/stdout" 2>&1
grep -q "^packing: 0 iterations" "$work/stdout" && grep -q "no packing step" "$work/stdout" ||
    bad "packed --max-iter 0: not reported as no packing step: $(cat "$work/stdout")"
# packed stops by [51]'s rule, after a test (every 50 steps: 50k + 1 steps), and says so.
"$bin" layout --kind packed --dim 2 --nx 8 --history-every 0 >"$work/stdout" 2>&1 ||
    bad "packed default failed: $(cat "$work/stdout")"
grep -qE '^packing: [0-9]*[05]1 iterations .*move-tol 1.0e-02, converged\)' "$work/stdout" ||
    bad "packed: no stop by the rule: $(cat "$work/stdout")"

# 3D CSV header.
"$bin" layout --kind lattice --dim 3 --nx 3 --out "$work/l3.csv" >/dev/null 2>&1 || bad "3D lattice"
[ "$(grep -v '^#' "$work/l3.csv" | head -n 1)" = "x,y,z,volume" ] || bad "3D csv header"

# Help documents every option.
"$bin" layout --help >"$work/help" 2>&1 || bad "--help exit status"
for opt in --kind --dim --nx --periodic --seed --eps --kernel --hdx --perturb --tol --max-iter \
    --history-every --out; do
    grep -q -- "$opt" "$work/help" || bad "--help does not mention $opt"
done

# --- interrupted writes ----------------------------------------------------------------
# A signal that stops a large write leaves neither the temporary file nor the output, and the
# process still ends as killed by that signal (status 128 + signal number).
interrupt_write() { # interrupt_write SIGNAL STATUS
    local sig=$1 want=$2 dir="$work/sig-$1" pid status n try
    for try in 1 2 3; do
        rm -rf "$dir" && mkdir "$dir"
        # Job control, so that the background job does not start with SIGINT ignored.
        set -m
        "$bin" layout --kind lattice --dim 2 --nx 1500 --out "$dir/big.csv" >/dev/null 2>&1 &
        pid=$!
        set +m
        # Wait until the temporary file has data in it, then signal at once.
        for n in $(seq 6000); do
            [ -n "$(find "$dir" -name 'big.csv.tmp.*' -size +0 2>/dev/null)" ] && break
            kill -0 "$pid" 2>/dev/null || break
            sleep 0.01
        done
        kill -s "$sig" "$pid" 2>/dev/null
        wait "$pid"
        status=$?
        # Finished before the signal arrived: inconclusive, try again.
        [ "$status" -eq 0 ] && [ -f "$dir/big.csv" ] && continue
        [ "$status" -eq "$want" ] || bad "SIG$sig during a write: exit status $status, expected $want"
        [ -z "$(ls -A "$dir")" ] || bad "SIG$sig during a write left: $(ls -A "$dir")"
        return
    done
    bad "SIG$sig: the write finished before the signal every time"
}
interrupt_write INT 130
interrupt_write TERM 143

# --- bad input: status 2, one line naming the option, nothing written ----------------------
expect_usage_error() {
    local option=$1
    shift
    local dir
    dir=$(mktemp -d "$work/err.XXXXXX")
    (cd "$dir" && "$bin" layout "$@" >"$work/stdout" 2>"$work/stderr")
    local status=$?
    [ "$status" -eq 2 ] || bad "'$*': exit status $status, expected 2"
    local lines
    lines=$(wc -l <"$work/stderr")
    [ "$lines" -eq 1 ] || bad "'$*': $lines lines on stderr, expected 1: $(cat "$work/stderr")"
    grep -q -- "$option" "$work/stderr" || bad "'$*': stderr does not name $option: $(cat "$work/stderr")"
    [ -z "$(ls -A "$dir")" ] || bad "'$*': files were written: $(ls -A "$dir")"
}

expect_usage_error --kind --kind hexagonal --dim 2 --nx 8 --out p.vtu
expect_usage_error --nx --kind lattice --dim 2 --nx 12x --out p.vtu
expect_usage_error --dim --kind lattice --dim 4 --nx 8 --out p.vtu
expect_usage_error --bogus --kind lattice --dim 2 --nx 8 --bogus 3 --out p.vtu
expect_usage_error --out --kind lattice --dim 2 --nx 8 --out /nonexistent/dir/p.vtu
expect_usage_error --out --kind lattice --dim 2 --nx 8 --out p.txt
expect_usage_error --nx --kind lattice --dim 2 --out p.vtu
expect_usage_error --eps --kind lattice --dim 2 --nx 8 --eps 0.2 --out p.vtu
expect_usage_error --eps --kind random --dim 2 --nx 8 --eps 3 --out p.vtu
expect_usage_error --tol --kind random --dim 2 --nx 8 --tol 1e-3 --out p.vtu
expect_usage_error --periodic --kind packed --dim 2 --nx 8 --periodic no --out p.vtu
expect_usage_error --periodic --kind packed-polished --dim 2 --nx 8 --periodic no --out p.vtu
expect_usage_error --tol --kind packed --dim 2 --nx 8 --tol 1e-3 --out p.vtu
expect_usage_error --move-tol --kind packed-polished --dim 2 --nx 8 --move-tol 1e-3 --out p.vtu
expect_usage_error --walls --kind packed-polished --dim 2 --nx 8 --walls 3 --out p.vtu
expect_usage_error --walls --kind packed --dim 2 --nx 8 --walls 9 --out p.vtu
expect_usage_error --walls --kind packed --dim 2 --nx 8 --walls 1 --out p.vtu
expect_usage_error --walls --in p.csv --walls 3
expect_usage_error --periodic --kind lattice --dim 2 --nx 8 --periodic maybe --out p.vtu
expect_usage_error --kernel --kind packed --dim 2 --nx 8 --kernel nonsense --out p.vtu
expect_usage_error --kernel --kind packed --dim 2 --nx 8 --kernel m4 --hdx 1 --out p.vtu
expect_usage_error --nx --kind lattice --dim 3 --nx 5000 --out p.vtu

# One particle without periodic images has no spacing: n/a, not inf and -nan.
printf 'x,y\n0.5,0.5\n' >"$work/one.csv"
"$bin" layout --in "$work/one.csv" --box 0:1,0:1 >"$work/one.out" 2>&1 || bad "one particle: exit $?"
# the temporary directory's random name may hold "NaN" or "inf": look past the paths
sed "s#$work##g" "$work/one.out" | grep -qiw 'nan\|-nan\|inf\|-inf' && bad "one particle: $(cat "$work/one.out")"
grep -q '^min spacing n/a' "$work/one.out" || bad "one particle: no n/a: $(cat "$work/one.out")"
grep -q '^nearest-neighbour distance / Δs: n/a' "$work/one.out" || bad "one particle nn: $(cat "$work/one.out")"
"$bin" layout --in "$work/one.csv" --box 0:1,0:1 --periodic yes | grep -q '^min spacing 1 ' || bad "one periodic particle"
printf 'x,y\n1e-161,1e-161\n2e-161,2e-161\n' >"$work/tiny.csv"
"$bin" layout --in "$work/tiny.csv" --box 0:1e-160,0:1e-160 >"$work/o" 2>"$work/e"; rc=$?
[ $rc = 2 ] && grep -q 'allowed: spacing in' "$work/e" || bad "tiny box: exit $rc $(cat "$work/e")"

exit $fail
