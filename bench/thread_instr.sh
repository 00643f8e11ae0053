#!/bin/bash
# The serial work of a step, load-independently: valgrind (callgrind --separate-threads=yes)
# instruction counts of `consph run taylor-green --scheme S --layout lattice --nx NX --cfl 0.25
# --steps K --threads 2` (α = 0 for wcsph: bench/speed.sh's runs) at two step counts, differenced
# so that the set-up cancels; bench/thread_instr.py prints each thread's instructions per
# particle-step, the master's outside every parallel region, and the functions only it ran.
# OMP_WAIT_POLICY=passive: a waiting thread sleeps instead of counting its spins.
#
# usage: bench/thread_instr.sh [WORK]   (from the repository root, after make)
# environment: CONSPH (default build/consph), SCHEMES (default "wcsph tvf edac"), CASES
#   (nx:K1:K2, default "100:5:25 250:3:9"), THREADS (default 2).
# About 15 minutes on one core for the defaults.
set -eu
CONSPH=${CONSPH:-build/consph}
SCHEMES=${SCHEMES:-"wcsph tvf edac"}
CASES=${CASES:-"100:5:25 250:3:9"}
THREADS=${THREADS:-2}
WORK=${1:-${TMPDIR:-/tmp}/consph_thread_instr}
HERE=$(cd "$(dirname "$0")" && pwd)
command -v valgrind >/dev/null || { echo "thread_instr: needs valgrind" >&2; exit 2; }
for s in $SCHEMES; do
    al=""
    [ "$s" = wcsph ] && al="--alpha 0"
    for c in $CASES; do
        IFS=: read -r nx k1 k2 <<< "$c"
        for k in $k1 $k2; do
            o=$WORK/$s.$nx.$k
            rm -rf "$o"
            mkdir -p "$o"
            OMP_WAIT_POLICY=passive valgrind --tool=callgrind --separate-threads=yes \
                --callgrind-out-file="$o/cg.out" "$CONSPH" run taylor-green --scheme "$s" \
                --layout lattice --nx "$nx" --cfl 0.25 $al --steps "$k" --threads "$THREADS" \
                >"$o/log" 2>&1
        done
        echo "## $s, nx $nx, steps $k2 - $k1, $THREADS threads"
        /usr/bin/python3 "$HERE/thread_instr.py" "$WORK/$s.$nx.$k1" "$WORK/$s.$nx.$k2" "$k1" "$k2" \
            $((nx * nx))
        echo
    done
done
