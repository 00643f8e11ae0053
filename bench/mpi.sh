#!/bin/bash
# consph over MPI ranks as a benchmark (docs/mpi.md); writes bench/mpi.md.
# 1. Studies over ranks: each study of STUDIES (--quick) serially and under
#    `mpirun -np K` for every K of RANKS, one OpenMP thread per rank: wall time, CPU time of all
#    ranks, rows per second, speed-up and efficiency against the serial run, and whether every
#    output equals the serial one (wall-time columns masked, as tests/cli_mpi.sh).
# 2. The solver over ranks (solver_scaling): weak scaling of `consph run` on the 3D Beltrami flow
#    and the 2D Taylor-Green vortex with L-IPST-C, strong scaling at the largest K's size, the
#    bytes per particle-step and the fraction of the step time in MPI calls (the run's
#    "consph run: MPI" line on stderr), and the extrapolation to 16 ranks.
# 3. The serial overhead of the MPI hooks (serial_overhead): this build against BASE, the serial
#    binary before them, on the same serial runs.
#
# usage: bench/mpi.sh        (from the repository root, after make)
# environment: CONSPH (default build/consph), OUT (default bench/mpi.md), SECTIONS (default
#   "studies solver serial"), RANKS (default "2"; on a 16-core machine "2 4 8 16"), STUDIES
#   (default "003-kernels 001-table9": 45 short rows, and 21 solver rows of about 75 CPU seconds
#   in all), WORK (scratch directory), REPEAT (tries of each timing, minimum kept; default 1),
#   for the solver WEAK_PER_RANK (3D particles per rank, default 100000), WEAK_PER_RANK_2D
#   (default 40000), STEPS1/STEPS2 (default 2/12), BENCH_PAR (default build/bench/bench_par,
#   for halo/owned), BANDWIDTH (bytes/s per rank in the extrapolation; default measured by
#   `bench_par --bandwidth` with the largest K of RANKS exchanging 4 MiB in pairs, else 5e9),
#   BASE (serial binary before the MPI merge; the section is left out without) and NOMPI (this
#   tree built with -DCONSPH_MPI=OFF, an optional column of that section).
#   For a machine of its own (bench/mpi_device.sh): MPIRUN (the launcher and its options,
#   default "mpirun --oversubscribe"), SOLVER_CASES (default "3d 2d"), STRONG_NX / STRONG_NX_2D
#   (the strong-scaling size; default the largest K's weak size), CASE_TIMEOUT (seconds per
#   run, 0 = none), DEADLINE (epoch seconds: later cases are skipped), MEM_KB (memory the
#   ranks may use; a case whose ranks would need more, scaled from the serial run's peak (the
#   solver cut at its set-up: docs/mpi.md), is skipped; default 80 % of MemAvailable)
#   HARD_END (epoch seconds: no run goes past it, a run cut there counts as failed)
#   and MACHINE_NOTE (a few words on the machine for the last paragraph).
# Exit 2 when the binary has no MPI or mpirun cannot start 2 ranks.
set -eu

CONSPH=${CONSPH:-build/consph}
OUT=${OUT:-bench/mpi.md}
RANKS=${RANKS:-2}
STUDIES=${STUDIES:-"003-kernels 001-table9"}
WORK=${WORK:-${TMPDIR:-/tmp}/consph_mpi_bench}
WEAK_PER_RANK=${WEAK_PER_RANK:-100000}
WEAK_PER_RANK_2D=${WEAK_PER_RANK_2D:-40000}
SECTIONS=${SECTIONS:-"studies solver serial"}
REPEAT=${REPEAT:-1}
BENCH_PAR=${BENCH_PAR:-build/bench/bench_par}
BANDWIDTH=${BANDWIDTH:-}
BANDWIDTH_HOW="assumed bandwidth,"
NOMPI=${NOMPI:-}
BASE=${BASE:-}
STEPS1=${STEPS1:-2}
STEPS2=${STEPS2:-12}
MPIRUN=${MPIRUN:-mpirun --oversubscribe}
SOLVER_CASES=${SOLVER_CASES:-"3d 2d"}
STRONG_NX=${STRONG_NX:-}
STRONG_NX_2D=${STRONG_NX_2D:-}
CASE_TIMEOUT=${CASE_TIMEOUT:-0}
DEADLINE=${DEADLINE:-0}
HARD_END=${HARD_END:-0}
MEM_KB=${MEM_KB:-$(awk '/^MemAvailable:/ { printf "%d", $2 * 0.8 }' /proc/meminfo)}
HERE=$(cd "$(dirname "$0")" && pwd)
export OMP_NUM_THREADS=1 OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1

[ -x "$CONSPH" ] || { echo "mpi: $CONSPH not built (run make)" >&2; exit 2; }
"$CONSPH" --version | grep -qx 'MPI ranks 1' || { echo "mpi: $CONSPH built without MPI" >&2; exit 2; }
$MPIRUN -np 2 "$CONSPH" --version 2>&1 | grep -qx 'MPI ranks 2' ||
    { echo "mpi: mpirun cannot start 2 ranks of $CONSPH" >&2; exit 2; }
rm -rf "$WORK"
mkdir -p "$WORK"
# masked(): a study output with its wall-time columns blanked
. "$HERE/../tests/lib_cli.sh"

# limit: the seconds a run may take (0: no limit), CASE_TIMEOUT or what is left before HARD_END.
limit() {
    lim=$CASE_TIMEOUT
    if [ "$HARD_END" -gt 0 ]; then
        left=$((HARD_END - $(date +%s)))
        [ "$left" -gt 1 ] || left=1
        { [ "$lim" = 0 ] || [ "$left" -lt "$lim" ]; } && lim=$left
    fi
    echo "$lim"
}

# timed K CMD...: runs CMD (under mpirun -np K when K > 1), prints "wall cpu" in seconds.
timed() {
    np=$1
    shift
    if [ "$np" = 1 ]; then
        /usr/bin/time -f "%e %U %S" -o "$WORK/time" timeout "$(limit)" "$@" >"$WORK/out" 2>"$WORK/err" || true
    else
        /usr/bin/time -f "%e %U %S" -o "$WORK/time" timeout "$(limit)" $MPIRUN -np "$np" "$@" \
            >"$WORK/out" 2>"$WORK/err" || true
    fi
    tail -n 1 "$WORK/time" | awk '{ printf "%s %.2f\n", $1, $2 + $3 }'
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
} >"$TMPMD"
case " $SECTIONS " in *" studies "*) ;; *) STUDIES= ;; esac
[ -z "$STUDIES" ] || {
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
} >>"$TMPMD"

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

# ---- the solver over ranks ----
# run_once K NX STEPS RUN...: one run of RUN (its --nx, --steps and --out appended) on K ranks;
# prints "T B C U": the steps' wall time (stdout's "X s, ..." line: set-up excluded), the bytes
# every rank sent and the mean seconds per rank in MPI calls (the "consph run: MPI" line of
# stderr, apps/cmd_run.c; 0 0 serially), the CPU seconds of every rank (and mpirun), and the
# peak resident kB (serially: the run's). A run that fails or passes CASE_TIMEOUT prints FAIL.
run_once() {
    np=$1 nx=$2 steps=$3
    shift 3
    launch=
    [ "$np" = 1 ] || launch="$MPIRUN -np $np"
    if ! /usr/bin/time -f "%U %S %M" -o "$WORK/time" timeout "$(limit)" $launch "$@" \
        --nx "$nx" --steps "$steps" --out "$WORK/r" >"$WORK/out" 2>"$WORK/err"; then
        echo "mpi: $* --nx $nx --steps $steps on $np ranks failed or timed out: $(grep -v '^Command' "$WORK/err" | head -n 3)" >&2
        rm -rf "$WORK/r"
        echo FAIL
        return 0
    fi
    rm -rf "$WORK/r"
    t=$(sed -n 's/^\([0-9.]*\) s, .*/\1/p' "$WORK/out")
    b=$(sed -n 's/^consph run: MPI [0-9]* ranks: \([0-9]*\) bytes sent.*/\1/p' "$WORK/err")
    c=$(sed -n 's/.* \([0-9.]*\) s in MPI calls per rank.*/\1/p' "$WORK/err")
    u=$(tail -n 1 "$WORK/time" | awk '{ print $1 + $2 }')
    echo "$t ${b:-0} ${c:-0} $u $(tail -n 1 "$WORK/time" | awk '{ print $3 }')"
}

# measure K NX RUN...: time per step and communication per step from STEPS1 and STEPS2 steps,
# the minimum of REPEAT tries of each; prints "s/step bytes/step comm-s/step cpu-s/step" and
# the peak resident kB of the longer run, or FAIL.
measure() {
    np=$1 nx=$2
    shift 2
    best1= best2=
    r=0
    while [ $r -lt "$REPEAT" ]; do
        l1=$(run_once "$np" "$nx" "$STEPS1" "$@")
        [ "$l1" != FAIL ] || { echo FAIL; return 0; }
        l2=$(run_once "$np" "$nx" "$STEPS2" "$@")
        [ "$l2" != FAIL ] || { echo FAIL; return 0; }
        best1=$(printf '%s\n%s\n' "$l1" "$best1" | grep . | sort -g | head -n 1)
        best2=$(printf '%s\n%s\n' "$l2" "$best2" | grep . | sort -g | head -n 1)
        r=$((r + 1))
    done
    echo "$best1 $best2" | awk -v s1="$STEPS1" -v s2="$STEPS2" \
        '{ d = s2 - s1; printf "%.4g %.6g %.4g %.4g %d\n", ($6 - $1) / d, ($7 - $2) / d, ($8 - $3) / d, ($9 - $4) / d, $10 }'
}

# halo K NX PROBLEM SCHEME: halo / owned particles, mean over ranks (bench_par, one step), then
# the cut's geometry: the search's cells along each axis, the halo's width in cells and the
# pieces along each axis (each comma separated, the three ";" separated), then the most
# particles a rank owns over the mean ("--" where bench_par is missing or did not say).
halo() {
    [ -x "$BENCH_PAR" ] || { echo "-- -- --"; return; }
    timeout "$(limit)" $MPIRUN -np "$1" "$BENCH_PAR" "$3" "$4" "$2" 1 2>/dev/null | awk '
        /^  rank [0-9]*: owns / { o = $4 + 0; own += o; if (o > omax) omax = o; no++ }
        /\(halo [0-9.]* of owned\)/ { sub(/.*\(halo /, ""); sub(/ of owned.*/, ""); s += $1; n++ }
        /^  boxes / { kb = $2; gsub(/x/, ",", kb)
                      sub(/.* of cells /, ""); sub(/, halo width /, " "); sub(/ cells$/, "")
                      m = split($1, c, "x"); g = c[1]; for (a = 2; a <= m; a++) g = g "," c[a]
                      w = $2; for (a = 3; a <= NF; a++) w = w "," $a; geo = g ";" w ";" kb }
        END { printf "%s %s %s\n", n ? sprintf("%.2f", s / n) : "--", geo != "" ? geo : "--",
                     (no && own > 0) ? sprintf("%.3f", omax * no / own) : "--" }'
}

# solver_case DIM PER_RANK STRONG_NX PROBLEM SCHEME: weak scaling at PER_RANK particles per rank
# (nx = round((K PER_RANK)^(1/DIM))), and strong scaling at STRONG_NX (empty: the largest K's
# nx); where the largest K's boxes are uneven (whole cell layers), that K again at the nearest
# nx whose cells its cut divides evenly ("weak, cells even"); then the extrapolation of the halo and the communication to 16 ranks from the largest K
# measured, when that is below 16: the cut that consph would choose at 16 ranks (par_solver.c
# choose_boxes: the fewest halo cells per rank) on the 16-rank size's cells, its halo/owned
# scaled by what the largest K measured against its own cells' count.
solver_case() {
    dim=$1 per=$2 snx=$3 prob=$4 scheme=$5
    set -- "$CONSPH" run "$prob" --scheme "$scheme" --layout lattice --threads 1
    echo
    echo "### $prob, $scheme, ${dim}D: weak scaling at $per particles per rank"
    echo
    echo "| scaling | ranks | nx | particles | s/step | efficiency | CPU s/step | bytes/particle-step | comm fraction | halo/owned | most owned / mean |"
    echo "|---|---|---|---|---|---|---|---|---|---|---|"
    : >"$WORK/cache"
    kmax=1
    for k in 1 $RANKS; do kmax=$k; done
    nxs=$(awk -v k="$kmax" -v n="$per" -v d="$dim" 'BEGIN { printf "%d", (k * n)^(1 / d) + 0.5 }')
    [ -z "$snx" ] || nxs=$snx
    kb_per=
    for mode in weak strong; do
        t1= n1=
        for k in 1 $RANKS; do
            if [ $mode = weak ]; then
                nx=$(awk -v k="$k" -v n="$per" -v d="$dim" 'BEGIN { printf "%d", (k * n)^(1 / d) + 0.5 }')
            else
                nx=$nxs
            fi
            m=$(sed -n "s/^$k $nx //p" "$WORK/cache")
            n=$(awk -v nx="$nx" -v d="$dim" 'BEGIN { printf "%d", nx^d }')
            if [ -z "$m" ]; then
                # the ranks together hold about 1.6 times the serial peak (a rank's pair cache
                # is its owned particles', its halo's fields, the migration's buffers: 15 kB
                # per owned particle measured in 3D against 11.7 serially); each makes only its
                # share of the set-up (about 2 kB per particle held at the first cut's peak)
                need=$(awk -v n="$n" -v b="$kb_per" 'BEGIN { if (b != "") printf "%d", 1.6 * n * b + 2 * n * 2; else print 0 }')
                if [ "$DEADLINE" -gt 0 ] && [ "$(date +%s)" -ge "$DEADLINE" ]; then
                    m="SKIP time budget spent"
                elif [ "$need" -gt "$MEM_KB" ]; then
                    m="SKIP needs about $((need / 1048576)) GiB (all ranks)"
                else
                    m=$(measure "$k" "$nx" "$@")
                    [ "$m" = FAIL ] || echo "$k $nx $m" >>"$WORK/cache"
                fi
            fi
            echo "$prob $mode $k ranks nx $nx: $m" >&2
            case $m in
            FAIL | SKIP*)
                echo "| $mode | $k | $nx | $n | ${m#SKIP } | | | | | | |"
                [ -n "$t1" ] || t1=0 n1=$n
                continue
                ;;
            esac
            step=${m%% *}
            [ "$k" = 1 ] && kb_per=$(echo "$m" | awk -v n="$n" '{ printf "%.6f", $5 / n }')
            [ -z "$t1" ] && t1=$step n1=$n
            if [ $mode = weak ]; then
                eff=$(awk -v t1="$t1" -v t="$step" -v k="$k" -v n="$n" -v n1="$n1" 'BEGIN { if (t1 > 0) printf "%.2f", t1 / t * n / (k * n1); else print "--" }')
            else
                eff=$(awk -v t1="$t1" -v t="$step" -v k="$k" 'BEGIN { if (t1 > 0) printf "%.2f", t1 / (k * t); else print "--" }')
            fi
            h=-- geo=-- imb=--
            [ "$k" -gt 1 ] && read -r h geo imb <<EOF
$(halo "$k" "$nx" "$prob" "$scheme")
EOF
            echo "$m" | awk -v mode=$mode -v k="$k" -v nx="$nx" -v n="$n" -v eff="$eff" -v h="$h" -v imb="$imb" \
                '{ printf "| %s | %d | %d | %d | %s | %s | %s | %.0f | %.2f | %s | %s |\n", mode, k, nx, n, $1, eff, $4, $2 / n, $3 / $1, h, imb }'
            echo "$mode $k $nx $n $m $h $geo $imb" >>"$WORK/rows"
        done
    done
    # the largest K's weak row again at the nearest resolution whose cells its cut divides
    # evenly, where the row's boxes were uneven: what the cut's whole cell layers cost there
    last=$(awk -v k="$kmax" '$1 == "weak" && $2 == k' "$WORK/rows" | tail -n 1)
    first=$(awk '$1 == "weak" && $2 == 1' "$WORK/rows" | tail -n 1)
    if [ "$kmax" -gt 1 ] && [ -n "$last" ] && [ -n "$first" ]; then
        read -r _ _ nxk _ _ _ _ _ _ _ geok imbk <<EOF
$last
EOF
        # candidates nearest first, each cut by bench_par (its cells, its pieces) until one
        # divides evenly along every axis
        nxe=0
        if awk -v imb="$imbk" -v geo="$geok" 'BEGIN { exit !(imb != "--" && imb + 0 >= 1.01 && split(geo, g, ";") >= 3) }'; then
            for dn in 1 -1 2 -2 3 -3 4 -4; do
                cand=$((nxk - dn))
                read -r _ geoc _ <<EOF
$(halo "$kmax" "$cand" "$prob" "$scheme")
EOF
                if awk -v geo="$geoc" 'BEGIN { if (split(geo, g, ";") < 3) exit 1
                        d = split(g[1], nc, ","); split(g[3], kq, ",")
                        for (a = 1; a <= d; a++) if (nc[a] % kq[a]) exit 1
                        exit 0 }'; then
                    nxe=$cand
                    break
                fi
            done
        fi
        if [ "$nxe" -gt 0 ]; then
            n=$(awk -v nx="$nxe" -v d="$dim" 'BEGIN { printf "%d", nx^d }')
            if [ "$DEADLINE" -gt 0 ] && [ "$(date +%s)" -ge "$DEADLINE" ]; then
                m=FAIL
            else
                m=$(measure "$kmax" "$nxe" "$@")
            fi
            echo "$prob weak (cells even) $kmax ranks nx $nxe: $m" >&2
            if [ "$m" != FAIL ]; then
                read -r h geo imb <<EOF
$(halo "$kmax" "$nxe" "$prob" "$scheme")
EOF
                eff=$(awk -v f="$first" -v t="${m%% *}" -v k="$kmax" -v n="$n" 'BEGIN { split(f, a, " "); printf "%.2f", a[5] / t * n / (k * a[4]) }')
                echo "$m" | awk -v k="$kmax" -v nx="$nxe" -v n="$n" -v eff="$eff" -v h="$h" -v imb="$imb" \
                    '{ printf "| weak, cells even | %d | %d | %d | %s | %s | %s | %.0f | %.2f | %s | %s |\n", k, nx, n, $1, eff, $4, $2 / n, $3 / $1, h, imb }'
            fi
        fi
    fi
    # extrapolation: the weak row of the largest K
    awk -v dim="$dim" -v per="$per" -v bw="$BANDWIDTH" -v bwhow="$BANDWIDTH_HOW" '
        # halo cells per owned cell of the best cut of K ranks over cells nc[] with halo width
        # w[]: par_solver.c choose_boxes (a tie goes to the slabs, pieces along the later axes);
        # heavy: its heaviest box over the mean, where the density is uniform (an axis of nc
        # cell layers cut into k pieces of whole layers: the heaviest holds ceil(nc / k))
        function best_cut(K, nc, w, d,    k0, k1, k2, a, own, ext, o, e, best, kk, fits, hv) {
            best = -1
            for (k2 = (d > 2 ? K : 1); k2 >= 1; k2--) {
                if (K % k2) continue
                for (k1 = K / k2; k1 >= 1; k1--) {
                    if ((K / k2) % k1) continue
                    kk[0] = K / k2 / k1; kk[1] = k1; kk[2] = k2
                    own = 1; ext = 1; fits = (d > 1 || k1 == 1)
                    for (a = 0; a < d; a++) {
                        if (kk[a] > nc[a]) fits = 0
                        o = nc[a] / kk[a]
                        e = kk[a] > 1 ? o + 2 * w[a] : o
                        if (e > nc[a]) e = nc[a]
                        own *= o; ext *= e
                    }
                    hv = 1
                    for (a = 0; a < d; a++)
                        if (kk[a] > 0) hv *= (int(nc[a] / kk[a]) + (nc[a] % kk[a] > 0)) / (nc[a] / kk[a])
                    if (fits && (best < 0 || ext - own < best)) {
                        best = ext - own; ratio = (ext - own) / own; heavy = hv
                        cut = kk[0]; for (a = 1; a < d; a++) cut = cut "x" kk[a]
                    }
                }
                if (d < 2) break
            }
            return best < 0 ? -1 : ratio
        }
        $1 == "weak" && $2 == 1 { t1 = $5 }
        $1 == "weak" && $2 >= kmax { kmax = $2; nx = $3; n = $4; t = $5; b = $6 / $4; c = $7; h = $10; geo = $11 }
        END {
            if (kmax < 2 || kmax >= 16 || h == "--" || h + 0 == 0 || geo == "--" || geo == "") exit
            nx16 = int((16 * per)^(1 / dim) + 0.5)
            split(geo, gw, ";"); split(gw[1], cs, ","); split(gw[2], ws, ",")
            for (a = 0; a < dim; a++) { ncm[a] = cs[a + 1] + 0; w[a] = ws[a + 1] + 0 }
            # the cut at kmax on its own cells, then at 16 on the cells of nx16 (the cells scale
            # with the resolution: a fixed number of spacings per cell); the measured halo/owned
            # over the geometric one at kmax carries the particles per halo cell over to 16
            gm = best_cut(kmax, ncm, w, dim); cutm = cut
            for (a = 0; a < dim; a++) nc16[a] = int(ncm[a] * nx16 / nx + 0.5)
            g16 = best_cut(16, nc16, w, dim); cut16 = cut; heavy16 = heavy
            if (gm <= 0 || g16 < 0) exit
            h16 = h * g16 / gm
            b16 = b * h16 / h
            kappa = c * kmax / (b * n)     # MPI seconds per byte a rank sends, kmax-rank run
            c16 = kappa * b16 * per
            comp = t1                      # the pair work of PER_RANK owned particles
            printf "\nAt 16 ranks (extrapolated, not measured): nx %d, the cut consph chooses there", nx16
            printf " (boxes %s of %d cells per axis, halo %d cells wide; %s at %d ranks on %d cells)", cut16, nc16[0], w[0], cutm, kmax, ncm[0]
            printf " holds halo/owned about %.2f (%.2f measured at %d ranks), about %.0f bytes per particle-step;", h16, h, kmax, b16
            printf " at the %d-rank cost per byte (%.2g s/MB, waiting on this shared machine included)", kmax, kappa * 1e6
            printf " communication would take %.3g s of a step whose pair work takes %.3g s:", c16, comp
            printf " weak-scaling efficiency about %.2f.", comp / (comp + c16)
            # the nearest resolution whose cells (scaled as above) every cut axis shares evenly
            nkq = split(cut16, kq, "x"); nx16e = 0
            for (dn = 0; dn <= 20 && !nx16e; dn++)
                for (sg = -1; sg <= 1 && !nx16e; sg += 2) {
                    even = 1
                    for (a = 0; a < dim; a++)
                        if (int(ncm[a] * (nx16 + sg * dn) / nx + 0.5) % kq[a + 1]) even = 0
                    if (even) nx16e = nx16 + sg * dn
                }
            if (heavy16 > 1.0005) {
                printf " The heaviest box holds %.3f times the mean (whole cell layers:", heavy16
                printf " %d cells in %s pieces), and every rank waits for it: about %.2f", nc16[dim - 1], cut16, comp / (comp * heavy16 + c16)
                printf " with both."
                if (nx16e) printf " At nx %d, whose cells the pieces share evenly, the first figure holds.", nx16e
            }
            cb = b16 * per / bw
            printf " At the %s %.2g GB/s per rank (shared memory in one node; latency, packing and", bwhow, bw / 1e9
            printf " waiting left out) the %.0f MB a rank sends per step take %.3g s: efficiency", b16 * per / 1e6, cb
            printf " about %.2f, if the halo work (refresh, search over the halo) costs nothing.\n", comp / (comp + cb)
        }' "$WORK/rows"
    rm -f "$WORK/rows"
}

solver_scaling() {
    if [ -z "$BANDWIDTH" ]; then
        # the largest K of RANKS in pairs (at least 2), 4 MiB each way: the halo refresh's
        # messages at 10^5 particles per rank are of that order (some 100 MB a step per rank
        # over several refreshes and neighbours); shared memory here slows from a few MiB on
        kb=2
        for k in $RANKS; do [ "$k" -gt "$kb" ] && kb=$k; done
        BANDWIDTH=$(timeout 60 $MPIRUN -np "$kb" "$BENCH_PAR" --bandwidth 4194304 2>/dev/null |
            sed -n 's/.*: \([0-9.e+]*\) bytes\/s per rank$/\1/p')
        if [ -n "$BANDWIDTH" ]; then
            BANDWIDTH_HOW="bandwidth measured by bench_par --bandwidth 4194304 ($kb ranks in pairs),"
        else
            BANDWIDTH=5e9
        fi
    fi
    echo
    echo "## The solver over ranks: weak and strong scaling"
    echo
    echo "\`[mpirun -np K] consph run PROBLEM --scheme S --layout lattice --threads 1 --nx NX\`;"
    echo "time per step = (steps' time of $STEPS2 steps - of $STEPS1) / $((STEPS2 - STEPS1)), the"
    echo "steps' time being the run's own (stdout: set-up excluded), minimum of $REPEAT tries."
    echo "Communication: the \"consph run: MPI\" line on stderr (bytes sent by every rank, mean"
    echo "seconds per rank in MPI calls, consph_par_solver_comm), differenced the same way; comm"
    echo "fraction = MPI seconds per step / s per step. halo/owned: bench/bench_par, mean over ranks."
    echo "Weak efficiency: t(1) / t(K) · N_K / (K N_1) (nx rounding corrected); strong: the largest"
    echo "K's size on every K, t(1) / (K t(K)). With ranks > cores, or cores shared with other"
    echo "work, a rank waits for a descheduled one inside MPI: comm fractions are upper bounds."
    case " $SOLVER_CASES " in *" 3d "*) solver_case 3 "$WEAK_PER_RANK" "$STRONG_NX" beltrami l-ipst-c ;; esac
    case " $SOLVER_CASES " in *" 2d "*) solver_case 2 "$WEAK_PER_RANK_2D" "$STRONG_NX_2D" taylor-green l-ipst-c ;; esac
    echo
    echo "### What the halo means for the targets"
    echo
    echo "Before every pass every rank refreshes the columns of its halo that the pass reads at its"
    echo "neighbours (consph_sys_next_reads: the kit's, IPST's, wcsph's, tvf's, edac's and the δ-SPH passes"
    echo "declare them; the others read every column) and that changed since the last refresh (only"
    echo "the positions at a search rebuild), and the halo is a fixed number of cell"
    echo "layers (the search's reach plus one) on each side of a rank's box along every cut axis,"
    echo "whatever its thickness. The cut is K = k0 k1 k2 boxes of cells chosen for the fewest halo"
    echo "cells (slabs where they win, at 2-3 ranks), so the halo grows more slowly with K than a"
    echo "slab's; the extrapolation above takes the cut consph would choose at 16 ranks. What a rank adds to the"
    echo "serial work, by kind, is measured in instructions by bench/mpi_instr.sh."
    echo "Boxes are whole cell layers: where an axis' cells do not divide into its pieces, the"
    echo "heaviest box holds ceil(nc/k) layers against nc/k on average (65 cells in 4 pieces: 17"
    echo "against 16.25), and every rank waits for it at every pass. The column \"most owned / mean\""
    echo "measures it; the 16-rank paragraphs take it in from the cut's geometry."
    echo "Measured here: ranks 1 $RANKS on $(getconf _NPROCESSORS_ONLN) cores${MACHINE_NOTE:+ ($MACHINE_NOTE)}."
}

# serial_overhead: main's serial binary against BASE (the serial binary before the MPI hooks),
# same runs, --threads 1: instructions (perf where it can count them, else valgrind's
# cachegrind without cache simulation: every instruction of the process, loader included) and
# the minimum user time of REPEAT tries.
icount() {
    if perf stat -x, -e instructions:u true 2>&1 | grep -q '^[0-9]'; then
        perf stat -x, -e instructions:u "$@" 2>&1 >/dev/null | grep instructions | cut -d, -f1
    elif command -v valgrind >/dev/null; then
        valgrind --tool=cachegrind --cache-sim=no --cachegrind-out-file=/dev/null "$@" 2>&1 >/dev/null |
            sed -n 's/.*I *refs: *//p' | tr -d ,
    else
        echo --
    fi
    rm -rf "$WORK/o"
}
serial_overhead() {
    how=valgrind
    perf stat -x, -e instructions:u true 2>&1 | grep -q '^[0-9]' && how=perf
    bins="$BASE ${NOMPI:-} $CONSPH"
    echo
    echo "## Serial overhead of the MPI hooks"
    echo
    echo "\`consph run taylor-green --scheme S --nx 100 --steps 40 --threads 1 --layout lattice\`"
    echo "(10 000 particles, set-up and output included) and \`consph --version\` (start-up only),"
    echo "serial (no mpirun). Before: the binary before the MPI merge (other merges since change"
    echo "it too); no MPI: this tree built with \`-DCONSPH_MPI=OFF\` (the hooks' serial stubs); now:"
    echo "this build, with MPI. Instructions: $how (user space, the whole process, loader included);"
    echo "user seconds: minimum of $REPEAT tries, the binaries alternating."
    echo
    echo "| command | instructions before | no MPI | now | now - no MPI | user s before / no MPI / now |"
    echo "|---|---|---|---|---|---|"
    for sch in --version wcsph l-ipst-c; do
        if [ "$sch" = --version ]; then
            set -- --version
        else
            set -- run taylor-green --scheme "$sch" --nx 100 --steps 40 --threads 1 --layout lattice --out "$WORK/o"
        fi
        : >"$WORK/user"
        r=0
        while [ $r -lt "$REPEAT" ]; do
            j=0
            for bin in $bins; do
                /usr/bin/time -f %U -o "$WORK/time" "$bin" "$@" >/dev/null 2>&1 || true
                rm -rf "$WORK/o"
                echo "$j $(tail -n 1 "$WORK/time")" >>"$WORK/user"
                j=$((j + 1))
            done
            r=$((r + 1))
        done
        users=$(awk '!($1 in m) || $2 < m[$1] { m[$1] = $2 } END { for (j = 0; j in m; j++) printf "%s%s", j ? " / " : "", m[j] }' "$WORK/user")
        ib=$(icount "$BASE" "$@")
        inm=--
        [ -n "$NOMPI" ] && inm=$(icount "$NOMPI" "$@")
        in=$(icount "$CONSPH" "$@")
        [ -n "$NOMPI" ] || users="$users (no MPI build not given)"
        echo "serial $sch: $ib $inm $in $users" >&2
        awk -v s="$sch" -v ib="$ib" -v inm="$inm" -v in_="$in" -v u="$users" 'BEGIN {
            ch = (inm != "--" && inm > 0) ? sprintf("%+d (%+.3f %%)", in_ - inm, 100 * (in_ - inm) / inm) : "--"
            printf "| %s | %s | %s | %s | %s | %s |\n", s, ib, inm, in_, ch, u }'
    done
}

case " $SECTIONS " in *" solver "*) solver_scaling >>"$TMPMD" ;; esac
case " $SECTIONS " in *" serial "*) [ -z "$BASE" ] || serial_overhead >>"$TMPMD" ;; esac

echo >>"$TMPMD"
echo "Load average after: $(cut -d' ' -f1-3 /proc/loadavg)." >>"$TMPMD"
cp "$TMPMD" "$OUT"
rm -f "$TMPMD"
trap - EXIT
echo "wrote $OUT" >&2
