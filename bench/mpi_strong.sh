#!/bin/bash
# Strong scaling of one large 3D run over MPI ranks: the issue's 200^3 Beltrami flow with
# L-IPST-C (8.0e6 particles) on a lent 16-core machine, called by bench/mpi_device.sh with
# CASE=strong200 (one 10-minute device call). Each rank makes only its share of the set-up
# (docs/mpi.md, "Costs and limits"); the pair cache follows its default budget (half the
# memory over the ranks: at 200^3 it is refused on 4-16 ranks of 128 GB, so every K runs
# without it, the same path).
#
# Per K, largest first (RANKS, default "16 8 4"): two runs of STEPS1 and STEPS2 steps (default
# 1 and 2); s/step = (steps' time of STEPS2 - of STEPS1) / (STEPS2 - STEPS1), the steps' time
# being the run's own (stdout: set-up excluded); set-up s = wall - steps' time of the shorter
# run; bytes/particle-step and the comm fraction from the "consph run: MPI" line, differenced
# the same way; the peak resident MB of rank 0 (the gathers for the diagnostics) and the
# largest of the others (/usr/bin/time per rank). Strong efficiency: t(K0) K0 / (K t(K)), K0 the
# smallest K measured. A run past the time left before DEADLINE (epoch seconds) is stopped
# and its row says so; no K starts with less than MIN_LEFT seconds (default 60) left.
#
# Environment: CONSPH, MPIRUN (default "mpirun --oversubscribe"), NX (200), RANKS, STEPS1,
# STEPS2, DEADLINE (default now + 540), OUT (markdown, default mpi_strong.md), WORK.
set -u
CONSPH=${CONSPH:-build/consph}
MPIRUN=${MPIRUN:-mpirun --oversubscribe}
NX=${NX:-200}
RANKS=${RANKS:-"16 8 4"}
STEPS1=${STEPS1:-1}
STEPS2=${STEPS2:-2}
DEADLINE=${DEADLINE:-$(($(date +%s) + 540))}
MIN_LEFT=${MIN_LEFT:-60}
OUT=${OUT:-mpi_strong.md}
WORK=${WORK:-${TMPDIR:-/tmp}/consph_mpi_strong}
export OMP_NUM_THREADS=1
mkdir -p "$WORK"
N=$((NX * NX * NX))

# one_run K STEPS: "steps_s wall_s bytes mpi_s rss0_MB rssmax_MB" or "FAIL why"
one_run() {
    k=$1 steps=$2
    left=$((DEADLINE - $(date +%s)))
    [ "$left" -gt 5 ] || { echo "FAIL no time left"; return; }
    rm -f "$WORK"/rss.*
    t0=$(date +%s.%N)
    # shellcheck disable=SC2016
    if ! timeout "$left" $MPIRUN -np "$k" sh -c '/usr/bin/time -f %M -o "$0.${OMPI_COMM_WORLD_RANK:-0}" "$@"' \
        "$WORK/rss" "$CONSPH" run beltrami --scheme l-ipst-c --layout lattice --threads 1 --nx "$NX" \
        --steps "$steps" >"$WORK/out" 2>"$WORK/err"; then
        echo "FAIL $(grep -v '^Command' "$WORK/err" | head -n 2 | tr '\n' ' ')"
        return
    fi
    wall=$(echo "$(date +%s.%N) $t0" | awk '{ printf "%.1f", $1 - $2 }')
    t=$(sed -n 's/^\([0-9.]*\) s, .*/\1/p' "$WORK/out")
    b=$(sed -n 's/^consph run: MPI [0-9]* ranks: \([0-9]*\) bytes sent.*/\1/p' "$WORK/err")
    c=$(sed -n 's/.* \([0-9.]*\) s in MPI calls per rank.*/\1/p' "$WORK/err")
    r0=$(tail -n 1 "$WORK/rss.0" 2>/dev/null)
    rmax=$(for f in "$WORK"/rss.*; do [ "$f" = "$WORK/rss.0" ] || tail -n 1 "$f"; done | sort -n | tail -n 1)
    echo "${t:-0} $wall ${b:-0} ${c:-0} $(( ${r0:-0} / 1024 )) $(( ${rmax:-0} / 1024 ))"
}

rows=
: >"$WORK/steps"
k0= t0s=
for k in $RANKS; do
    if [ $((DEADLINE - $(date +%s))) -lt "$MIN_LEFT" ]; then
        rows="$rows| $k | skipped: time budget spent | | | | | | |"$'\n'
        echo "strong $NX^3: $k ranks skipped (time)" >&2
        continue
    fi
    a=$(one_run "$k" "$STEPS1")
    case $a in FAIL*) rows="$rows| $k | ${a#FAIL } | | | | | | |"$'\n'; echo "strong $NX^3 $k ranks: $a" >&2; continue ;; esac
    b=$(one_run "$k" "$STEPS2")
    case $b in FAIL*) rows="$rows| $k | ${b#FAIL } (the $STEPS1-step run: $a) | | | | | | |"$'\n'; echo "strong $NX^3 $k ranks: $b" >&2; continue ;; esac
    echo "strong $NX^3 $k ranks: $STEPS1 steps: $a; $STEPS2 steps: $b" >&2
    set -- $a $b
    step=$(awk -v a="$1" -v b="$7" -v d=$((STEPS2 - STEPS1)) 'BEGIN { printf "%.3f", (b - a) / d }')
    setup=$(awk -v w="$2" -v t="$1" 'BEGIN { printf "%.1f", w - t }')
    bps=$(awk -v a="$3" -v b="$9" -v d=$((STEPS2 - STEPS1)) -v n="$N" 'BEGIN { printf "%.0f", (b - a) / d / n }')
    frac=$(awk -v a="$4" -v b="${10}" -v s="$step" -v d=$((STEPS2 - STEPS1)) 'BEGIN { if (s > 0) printf "%.2f", (b - a) / d / s; else print "--" }')
    r0=$(( $5 > ${11} ? $5 : ${11} )) rmax=$(( $6 > ${12} ? $6 : ${12} ))
    # the smallest K measured so far is the reference (RANKS runs from the largest)
    k0=$k t0s=$step
    rows="$rows| $k | $step | EFF_$k | $setup | $bps | $frac | $r0 | $rmax |"$'\n'
    echo "$k $step" >>"$WORK/steps"
done
{
    echo
    echo "### Strong scaling of ${NX}^3 ($N particles), beltrami, l-ipst-c, 3D"
    echo
    echo "\`mpirun -np K consph run beltrami --scheme l-ipst-c --layout lattice --threads 1 --nx $NX"
    echo "--steps S\` (S = $STEPS1, $STEPS2; no --out), bench/mpi_strong.sh, $(date -u '+%Y-%m-%d %H:%M UTC')."
    echo "Efficiency relative to the smallest K measured ($k0 ranks): t($k0) $k0 / (K t(K))."
    echo
    echo "| ranks | s/step | strong efficiency | set-up s | bytes/particle-step | comm fraction | peak MB rank 0 | peak MB other ranks (max) |"
    echo "|---|---|---|---|---|---|---|---|"
    printf '%s' "$rows" | while IFS= read -r line; do
        for kk in $RANKS; do
            e=$(awk -v k0="$k0" -v t0="$t0s" -v k="$kk" -v f="$WORK/steps" 'BEGIN { while ((getline l < f) > 0) { split(l, a, " "); if (a[1] == k) t = a[2] } if (t > 0 && t0 > 0) printf "%.2f", t0 * k0 / (k * t); else print "--" }')
            line=${line//EFF_$kk /$e }
        done
        echo "$line"
    done
} >>"$OUT"
rm -f "$WORK/steps" "$WORK"/rss.*
cat "$OUT"
