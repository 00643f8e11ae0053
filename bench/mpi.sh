#!/bin/sh
# consph over MPI ranks as a benchmark (docs/mpi.md); writes bench/mpi.md.
# 1. Studies over ranks: each study of STUDIES (--quick) serially and under
#    `mpirun -np K` for every K of RANKS, one OpenMP thread per rank: wall time, CPU time of all
#    ranks, rows per second, speed-up and efficiency against the serial run, and whether every
#    output equals the serial one (wall-time columns masked, as tests/cli_mpi.sh).
# 2. The solver's weak and strong scaling (solver_scaling below): measured once `consph run` runs
#    decomposed over ranks; until then the section says it is pending.
#
# usage: bench/mpi.sh        (from the repository root, after make)
# environment: CONSPH (default build/consph), OUT (default bench/mpi.md), RANKS (default "2";
#   on a 16-core machine "2 4 8 16"), STUDIES (default "003-kernels 001-table9": 45 short rows,
#   and 21 solver rows of about 75 CPU seconds in all), WORK (scratch directory), and for the
#   solver: WEAK_PER_RANK (particles per rank, default 100000), STRONG_NX (default 200),
#   STEPS1/STEPS2 (default 2/12).
# Exit 2 when the binary has no MPI or mpirun cannot start 2 ranks.
set -eu

CONSPH=${CONSPH:-build/consph}
OUT=${OUT:-bench/mpi.md}
RANKS=${RANKS:-2}
STUDIES=${STUDIES:-"003-kernels 001-table9"}
WORK=${WORK:-${TMPDIR:-/tmp}/consph_mpi_bench}
WEAK_PER_RANK=${WEAK_PER_RANK:-100000}
STRONG_NX=${STRONG_NX:-200}
STEPS1=${STEPS1:-2}
STEPS2=${STEPS2:-12}
HERE=$(cd "$(dirname "$0")" && pwd)
export OMP_NUM_THREADS=1 OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1

[ -x "$CONSPH" ] || { echo "mpi: $CONSPH not built (run make)" >&2; exit 2; }
"$CONSPH" --version | grep -qx 'MPI ranks 1' || { echo "mpi: $CONSPH built without MPI" >&2; exit 2; }
mpirun --oversubscribe -np 2 "$CONSPH" --version 2>&1 | grep -qx 'MPI ranks 2' ||
    { echo "mpi: mpirun cannot start 2 ranks of $CONSPH" >&2; exit 2; }
rm -rf "$WORK"
mkdir -p "$WORK"
# masked(): a study output with its wall-time columns blanked
. "$HERE/../tests/lib_cli.sh"

# timed K CMD...: runs CMD (under mpirun -np K when K > 1), prints "wall cpu" in seconds.
timed() {
    np=$1
    shift
    if [ "$np" = 1 ]; then
        /usr/bin/time -f "%e %U %S" -o "$WORK/time" "$@" >"$WORK/out" 2>"$WORK/err"
    else
        /usr/bin/time -f "%e %U %S" -o "$WORK/time" mpirun --oversubscribe -np "$np" "$@" \
            >"$WORK/out" 2>"$WORK/err"
    fi
    awk '{ printf "%s %.2f\n", $1, $2 + $3 }' "$WORK/time"
}

same_dirs() {
    [ "$(ls -A "$1")" = "$(ls -A "$2")" ] || return 1
    for f in "$1"/*; do
        masked "$f" >"$WORK/a"
        masked "$2/${f##*/}" >"$WORK/b"
        cmp -s "$WORK/a" "$WORK/b" || return 1
    done
}

TMPMD=$(mktemp "$WORK/mpi.md.XXXXXX")
trap 'rm -f "$TMPMD"' EXIT
{
    echo "# consph over MPI ranks"
    echo
    echo "Written by \`bench/mpi.sh\` on $(date -u '+%Y-%m-%d %H:%M UTC'), $(getconf _NPROCESSORS_ONLN) cores,"
    echo "$(mpirun --version | head -n 1), one OpenMP thread per rank; load average before:"
    echo "$(cut -d' ' -f1-3 /proc/loadavg). Wall times on a machine shared with other work are noisy;"
    echo "the CPU column (user + system of every rank and of mpirun) shows the overhead of the ranks."
    echo
    echo "## Studies over ranks"
    echo
    echo "\`mpirun -np K consph study NAME --quick\`: the rows dealt round-robin over the ranks,"
    echo "rank 0 writing the reports from the kept rows (docs/mpi.md). Speed-up: serial wall /"
    echo "wall on K ranks; efficiency: speed-up / K. Same: every output file equals the serial"
    echo "run's, wall-time columns masked."
    echo
    echo "Fixed costs do not shrink with K: starting mpirun and MPI (about 0.5 s here), and rank 0's"
    echo "report pass (reading the rows back, the CSV, markdown and gnuplot files), serial as in a"
    echo "serial study. A quick study of 1-2 CPU seconds measures them; a study whose rows take"
    echo "seconds each (001-table9) measures the spread of the rows."
    echo
    echo "| study | rows | ranks | wall s | CPU s | rows/s | speed-up | efficiency | same |"
    echo "|---|---|---|---|---|---|---|---|---|"
} >"$TMPMD"

for s in $STUDIES; do
    set -- $(timed 1 "$CONSPH" study "$s" --quick --out "$WORK/s1")
    wall1=$1
    rows=$(grep -c '^study: row .* done' "$WORK/err" || true)
    echo "$s serial: $wall1 s" >&2
    echo "| $s | $rows | serial | $1 | $2 | $(awk -v r="$rows" -v w="$1" 'BEGIN { printf "%.2f", r / w }') | 1 | 1 | |" >>"$TMPMD"
    for k in $RANKS; do
        set -- $(timed "$k" "$CONSPH" study "$s" --quick --out "$WORK/s$k")
        same=no
        same_dirs "$WORK/s1/$s" "$WORK/s$k/$s" && same=yes
        echo "$s $k ranks: $1 s, same $same" >&2
        awk -v s="$s" -v r="$rows" -v k="$k" -v w="$1" -v c="$2" -v w1="$wall1" -v same="$same" \
            'BEGIN { printf "| %s | %d | %d | %s | %s | %.2f | %.2f | %.2f | %s |\n", s, r, k, w, c, r / w, w1 / w, w1 / w / k, same }' >>"$TMPMD"
    done
    rm -rf "$WORK"/s[0-9]*
done

# ---- the solver's scaling: filled in by the decomposition's entry point ----
# solver_scaling RUN...: RUN is the command that runs the 3D Beltrami flow with L-IPST-C (its
# --nx, --steps and --out are appended). Weak scaling: WEAK_PER_RANK particles per rank,
# nx = round((K * WEAK_PER_RANK)^(1/3)), efficiency t_step(1) / t_step(K) · (N_K / (K N_1)) (the
# nx rounding corrected); strong scaling: nx = STRONG_NX on every K, efficiency
# t_step(1) / (K t_step(K)). t_step: (time of STEPS2 steps - time of STEPS1 steps) / (STEPS2 -
# STEPS1), so that set-up and output do not count. Bytes communicated per particle-step and the
# fraction of step time in communication come from the run's summary.json (keys comm_bytes and
# comm_seconds, when the decomposition writes them). While `consph run` refuses K > 1 ranks
# (exit 2), the section says so and measures nothing.
solver_scaling() {
    echo
    echo "## The solver over ranks: weak and strong scaling"
    echo
    if mpirun --oversubscribe -np 2 "$@" --nx 8 --steps 1 --out "$WORK/probe" >/dev/null 2>"$WORK/err"; then :; else
        echo "Pending: \`mpirun -np 2 $(echo "$*" | sed "s|$CONSPH|consph|")\` exits $? (\`consph run\` is not"
        echo "decomposed over ranks yet: \"$(grep -o 'consph run does not decompose[^;]*' "$WORK/err" | head -n 1)\")."
        echo "Once it is, this section holds: weak scaling on the 3D Beltrami flow with L-IPST-C at"
        echo "$WEAK_PER_RANK particles per rank (target: efficiency >= 80 % from 1 to 16 ranks), strong"
        echo "scaling at ${STRONG_NX}³, time per step from $STEPS1 and $STEPS2 steps, and bytes"
        echo "communicated per particle-step with the fraction of step time in communication."
        return 0
    fi
    echo "Time per step from $STEPS1 and $STEPS2 steps (set-up and output excluded)."
    echo
    echo "| scaling | ranks | nx | particles | s/step | efficiency | bytes/particle-step | comm fraction |"
    echo "|---|---|---|---|---|---|---|---|"
    for mode in weak strong; do
        t1=
        n1=
        for k in 1 $RANKS; do
            if [ $mode = weak ]; then
                nx=$(awk -v k="$k" -v n="$WEAK_PER_RANK" 'BEGIN { printf "%d", (k * n)^(1 / 3) + 0.5 }')
            else
                nx=$STRONG_NX
            fi
            a=$(timed "$k" "$@" --nx "$nx" --steps "$STEPS1" --out "$WORK/r1" | cut -d' ' -f1)
            b=$(timed "$k" "$@" --nx "$nx" --steps "$STEPS2" --out "$WORK/r2" | cut -d' ' -f1)
            step=$(awk -v a="$a" -v b="$b" -v s1="$STEPS1" -v s2="$STEPS2" 'BEGIN { printf "%.4g", (b - a) / (s2 - s1) }')
            n=$((nx * nx * nx))
            [ -z "$t1" ] && t1=$step n1=$n
            if [ $mode = weak ]; then
                eff=$(awk -v t1="$t1" -v t="$step" -v k="$k" -v n="$n" -v n1="$n1" 'BEGIN { printf "%.2f", t1 / t * n / (k * n1) }')
            else
                eff=$(awk -v t1="$t1" -v t="$step" -v k="$k" 'BEGIN { printf "%.2f", t1 / (k * t) }')
            fi
            cb=$(grep -o '"comm_bytes": *[0-9.eE+-]*' "$WORK/r2/summary.json" 2>/dev/null | sed 's/.*: *//' || true)
            cs=$(grep -o '"comm_seconds": *[0-9.eE+-]*' "$WORK/r2/summary.json" 2>/dev/null | sed 's/.*: *//' || true)
            bps=--
            frac=--
            [ -n "$cb" ] && bps=$(awk -v c="$cb" -v n="$n" -v s="$STEPS2" 'BEGIN { printf "%.1f", c / (n * s) }')
            [ -n "$cs" ] && frac=$(awk -v c="$cs" -v t="$b" 'BEGIN { printf "%.2f", c / t }')
            echo "| $mode | $k | $nx | $n | $step | $eff | $bps | $frac |"
            rm -rf "$WORK/r1" "$WORK/r2"
        done
    done
}
solver_scaling "$CONSPH" run beltrami --scheme l-ipst-c >>"$TMPMD"

echo >>"$TMPMD"
echo "Load average after: $(cut -d' ' -f1-3 /proc/loadavg)." >>"$TMPMD"
cp "$TMPMD" "$OUT"
rm -f "$TMPMD"
trap - EXIT
echo "wrote $OUT" >&2
