#!/usr/bin/env bash
# bench/speed.sh's plumbing, never its timings: the PASS/MISS rule of bench/timing.sh, a QUICK=1
# run against a stub "PySPH" (called as the comparison calls PySPH's example, --openmp for 2
# threads), the report's sections and one row per target and per scheme of the binary, exit 77
# and a report still written without PySPH, and no report at all when the binary is missing.
# Usage: bash cli_bench_speed.sh PATH-TO-CONSPH SOURCE-DIR
set -u
consph=$1
src=$2
fail=0
bad() { echo "FAIL: $*"; fail=1; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

# the verdict rule: ≥ and ≤ inclusive, n/a for a failed or noise-negative measurement
v() { sh -c ". '$src/bench/timing.sh'; verdict \"\$@\"" verdict "$@"; }
check_v() { # expected value op target
    got=$(v "$2" "$3" "$4")
    [ "$got" = "$1" ] || bad "verdict $2 $3 $4: $got, expected $1"
}
check_v PASS 12.5 ge 10
check_v PASS 10 ge 10
check_v MISS 9.99 ge 10
check_v PASS 0.4 le 0.4
check_v MISS 0.41 le 0.4
check_v PASS 3.5e-1 le 0.4
check_v n/a - ge 10
check_v n/a -0.3 le 0.4
check_v n/a 0 ge 10
check_v n/a "not run" le 20
r=$(sh -c ". '$src/bench/timing.sh'; ratio 3 1.5; ratio 3 -; ratio 3 0; ratio -1 2")
[ "$r" = "$(printf '2.000\n-\n-\n-')" ] || bad "ratio: $r"

# a stub PySPH: answers the three questions the script asks python, and runs "its example" by
# logging the arguments; sleeps in proportion to the steps so the step difference is positive
mkdir -p "$tmp/stub"
cat > "$tmp/stub/python" << EOF
#!/bin/sh
if [ "\$1" = -c ]; then
    case "\$2" in
    *taylor_green*) echo "$tmp/stub/taylor_green.py" ;;
    *__version__*) echo 1.0b1-stub ;;
    esac
    exit 0
fi
echo "\$*" >> "$tmp/stub.log"
k=\$(echo "\$*" | sed -n 's/.*--max-steps \([0-9]*\).*/\1/p')
sleep "\$(echo "\$k * 0.05" | bc -l)"
EOF
chmod +x "$tmp/stub/python"
touch "$tmp/stub/taylor_green.py"

cd "$src" || exit 1
QUICK=1 SCHEMES="wcsph edac" CONSPH=$consph PYTHON=$tmp/stub/python OUT=$tmp/speed.md \
    WORK=$tmp/work sh bench/speed.sh > "$tmp/out" 2>&1
rc=$?
[ "$rc" = 0 ] || bad "QUICK=1 with the stub: exit $rc: $(tail -n 5 "$tmp/out")"
md=$tmp/speed.md
[ -f "$md" ] || bad "no report"
[ "$(stat -c %a "$md")" = 644 ] || bad "the report's mode is $(stat -c %a "$md"), not 644"
[ -z "$(ls "$tmp" | grep 'speed.md.')" ] || bad "a temporary report was left behind"
for h in "## Targets" "## consph against PySPH" "## consph 2 threads against 1" "## L-IPST-C, serial" \
    "## Pairs per second per core" "## Studies"; do
    grep -q "^$h" "$md" || bad "no section '$h'"
done
grep -q "^- machine: $(nproc) cores" "$md" || bad "no machine line"
grep -q "load average .* at the start, .* at the end" "$md" || bad "no load averages"
grep -q "^- PySPH: 1.0b1-stub" "$md" || bad "PySPH's version not reported"
grep -q "^- consph: .*commit " "$md" || bad "no commit line"
# the targets table: one row per target, each with a verdict
targets=$(sed -n '/^## Targets/,/^## /p' "$md" | grep '^| ' | grep -v '^| target |')
for t in "10× PySPH per particle-step, wcsph, nx 8, serial" "10× PySPH per particle-step, edac, nx 8, serial" \
    "1.8× 1 thread, wcsph, nx 8" "1.8× 1 thread, edac, nx 8" "L-IPST-C ≤ 0.4 µs" "001-table9 estimate" \
    "001-table3"; do
    echo "$targets" | grep -qF "$t" || bad "no target row '$t'"
done
echo "$targets" | grep -vqE '\| (PASS|MISS|n/a|-) \|$' &&
    bad "a target without PASS/MISS/n/a: $(echo "$targets" | grep -vE '\| (PASS|MISS|n/a|-) \|$')"
grep -q "001-table3.*not run (FULL=1)" "$md" || bad "001-table3 ran without FULL=1"
grep -q "001-table9 --quick.*not run (QUICK=1)" "$md" || bad "001-table9 --quick ran with QUICK=1"
# the stub ran as PySPH's example: serial and --openmp, every scheme, K1 and K2 steps
for s in wcsph edac; do
    grep -q -- "--scheme $s --nx 8 .*--max-steps 3 --disable-output -d" "$tmp/stub.log" ||
        bad "PySPH $s serial not run"
    grep -q -- "--scheme $s --nx 8 .*--max-steps 1 --disable-output --openmp" "$tmp/stub.log" ||
        bad "PySPH $s --openmp not run"
done
# a row per scheme of the binary in the pairs table, each a number
schemes=$("$consph" run taylor-green --scheme ' ' --nx 8 2>&1 | sed -n 's/.*(allowed: \([a-z0-9,+-]*\)).*/\1/p' |
    tr , ' ')
[ -n "$schemes" ] || bad "no scheme list from $consph"
# (a rate whose seconds' difference came out zero or negative is '-': at nx 8 on loaded cores, as
# under `ctest -j` beside other work, that happens; every scheme has its row, and most a number)
numbers=0
for s in $schemes; do
    grep -qE "^\| $s \| ([0-9.e+]+|-) \| ([0-9.e+]+|-) \|$" "$md" ||
        bad "pairs per second of $s: $(grep "^| $s |" "$md")"
    grep -qE "^\| $s \| [0-9.e+]+ \| [0-9.e+]+ \|$" "$md" && numbers=$((numbers + 1))
done
[ $((2 * numbers)) -gt "$(echo $schemes | wc -w)" ] ||
    bad "pairs per second: $numbers of the schemes have numbers"


# without PySPH: exit 77, every other part still measured and reported
QUICK=1 SCHEMES=wcsph PAIR_SCHEMES=wcsph CONSPH=$consph PYTHON=/bin/false OUT=$tmp/nopy.md \
    WORK=$tmp/work sh bench/speed.sh > "$tmp/out" 2>&1
rc=$?
[ "$rc" = 77 ] || bad "without PySPH: exit $rc, expected 77"
grep -q "n/a (no PySPH)" "$tmp/nopy.md" || bad "without PySPH: no 'n/a (no PySPH)'"
grep -qE "^\| wcsph \| 8 \| 1 \| - \| " "$tmp/nopy.md" || bad "without PySPH: the consph row is missing"
grep -q "L-IPST-C ≤ 0.4" "$tmp/nopy.md" || bad "without PySPH: L-IPST-C not measured"

# no binary: exit 2 and no report
CONSPH=$tmp/none OUT=$tmp/none.md sh bench/speed.sh > "$tmp/out" 2>&1
rc=$?
[ "$rc" = 2 ] || bad "missing binary: exit $rc, expected 2"
[ ! -e "$tmp/none.md" ] || bad "missing binary: a report was written"

exit $fail
