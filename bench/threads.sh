#!/bin/sh
# Thread scaling of the solver on the machine it runs on: µs per particle-step of each scheme
# at each thread count, from the wall time of C2 steps minus that of C1 steps over (C2 - C1) N
# (set-up cancels), the fastest of REPEAT runs; speed-up and parallel efficiency against one
# thread of the same binary in the same run. Writes markdown to stdout.
#   bench/threads.sh                      (from the repository root, after make)
# environment: CONSPH (default build/consph), SCHEMES (default "wcsph edac l-ipst-c"), NX
#   (default 400), THREADS (default "1 2 4 8 16", capped at the machine's cores), C1/C2 (step
#   counts, default 5/25), REPEAT (default 2), LAYOUT (default lattice: packing would dominate
#   set-up and is not what is timed), WORK (scratch directory).
set -eu
CONSPH=${CONSPH:-build/consph}
SCHEMES=${SCHEMES:-"wcsph edac l-ipst-c"}
NX=${NX:-400}
THREADS=${THREADS:-"1 2 4 8 16"}
C1=${C1:-5}
C2=${C2:-25}
REPEAT=${REPEAT:-2}
LAYOUT=${LAYOUT:-lattice}
WORK=${WORK:-$(mktemp -d)}
HERE=$(cd "$(dirname "$0")" && pwd)
. "$HERE/timing.sh"
[ -x "$CONSPH" ] || { echo "threads.sh: $CONSPH not built (run make)" >&2; exit 2; }
cores=$(nproc)
# the fastest wall seconds of REPEAT runs (awk, not bc: lent machines may lack bc)
fastest() {
    best=""
    r=0
    while [ "$r" -lt "$REPEAT" ]; do
        t0=$(date +%s.%N)
        "$@" || return 1
        t=$(awk -v a="$t0" -v b="$(date +%s.%N)" 'BEGIN { printf "%.6f", b - a }')
        best=$(awk -v a="$best" -v t="$t" 'BEGIN { print (a == "" || t < a) ? t : a }')
        r=$((r + 1))
    done
    echo "$best"
}
run() { # scheme threads steps
    "$CONSPH" run taylor-green --scheme "$1" --layout "$LAYOUT" --nx "$NX" --steps "$3" \
        --threads "$2" --no-cache --overwrite --out "$WORK/run" > /dev/null
}
n=$(awk -v nx="$NX" 'BEGIN { print nx * nx }')
echo "# Thread scaling: taylor-green, $LAYOUT, nx $NX ($n particles), steps $C1 vs $C2"
echo
echo "$cores cores ($(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //')), load $(cut -d' ' -f1-3 /proc/loadavg)."
echo
echo "| scheme | threads | µs per particle-step | speed-up | efficiency |"
echo "|---|---|---|---|---|"
for s in $SCHEMES; do
    one=""
    for t in $THREADS; do
        [ "$t" -le "$cores" ] || continue
        a=$(fastest run "$s" "$t" "$C1") || { echo "| $s | $t | failed | - | - |"; continue; }
        b=$(fastest run "$s" "$t" "$C2") || { echo "| $s | $t | failed | - | - |"; continue; }
        us=$(awk -v a="$a" -v b="$b" -v n="$n" -v k=$((C2 - C1)) 'BEGIN { printf "%.4g", (b - a) / (k * n) * 1e6 }')
        [ -n "$one" ] || one=$us
        sp=$(ratio "$one" "$us")
        eff=$(awk -v s="$sp" -v t="$t" 'BEGIN { if (s == "-") print "-"; else printf "%.0f %%", 100 * s / t }')
        echo "| $s | $t | $us | $sp | $eff |"
    done
done
