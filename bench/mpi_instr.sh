#!/bin/bash
# What a rank does beyond its share of the serial work, load-independently: valgrind
# (cachegrind, --cache-sim=no) instruction counts of `consph run PROBLEM --scheme l-ipst-c
# --layout lattice --threads 1 --nx NX` serially and under `mpirun -np K` (one file per rank),
# at STEPS1 and STEPS2 steps, differenced so that the set-up and the last output cancel (with
# the default --log-every 10 and IPST every 10 steps, 10 more steps hold one sample and one IPST
# step, as a long run does); bench/mpi_instr.py sums the ranks and prints the instructions per
# particle-step by kind of work. Written to bench/mpi.md by hand (docs/mpi.md, costs).
#
# usage: bench/mpi_instr.sh [WORK]   (from the repository root, after make)
# environment: CONSPH (default build/consph), RANKS (default "1 2 4"), CASES (default
#   "beltrami:24 taylor-green:100"), STEPS1/STEPS2 (default 10/20), MPIRUN (default
#   "mpirun --oversubscribe --mca mpi_yield_when_idle 1": ranks waiting under valgrind on a
#   shared machine yield; their polling still counts, in the MPI row).
# About 15 minutes on 2 shared cores.
set -eu
CONSPH=${CONSPH:-build/consph}
RANKS=${RANKS:-"1 2 4"}
CASES=${CASES:-"beltrami:24 taylor-green:100"}
STEPS1=${STEPS1:-10}
STEPS2=${STEPS2:-20}
MPIRUN=${MPIRUN:-mpirun --oversubscribe --mca mpi_yield_when_idle 1}
WORK=${1:-${TMPDIR:-/tmp}/consph_mpi_instr}
HERE=$(cd "$(dirname "$0")" && pwd)
export OMP_NUM_THREADS=1 OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
command -v valgrind >/dev/null || { echo "mpi_instr: needs valgrind" >&2; exit 2; }
for c in $CASES; do
    prob=${c%%:*} nx=${c##*:}
    cols=""
    for k in $RANKS; do
        for st in $STEPS1 $STEPS2; do
            o=$WORK/$prob.k$k.s$st
            rm -rf "$o"
            mkdir -p "$o"
            vg="valgrind --tool=cachegrind --cache-sim=no --cachegrind-out-file=$o/cg.%p"
            run="$CONSPH run $prob --scheme l-ipst-c --layout lattice --threads 1 --nx $nx --steps $st --out $o/r"
            if [ "$k" = 1 ]; then
                $vg $run >"$o/out" 2>"$o/err"
            else
                $MPIRUN -np "$k" $vg $run >"$o/out" 2>"$o/err"
            fi
        done
        cols="$cols K$k=$WORK/$prob.k$k.s$STEPS1:$WORK/$prob.k$k.s$STEPS2"
    done
    n=$(awk -v nx="$nx" -v p="$prob" 'BEGIN { printf "%d", p == "beltrami" ? nx^3 : nx^2 }')
    echo "### $prob, l-ipst-c, nx $nx ($n particles): instructions per particle-step"
    echo
    /usr/bin/python3 "$HERE/mpi_instr.py" "$n" $((STEPS2 - STEPS1)) $cols
    echo
done
