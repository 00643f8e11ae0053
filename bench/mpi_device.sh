#!/bin/bash
# consph over 1-16 MPI ranks on a lent machine without OpenMPI: runs bench/mpi.sh's solver
# section (and a quick study over ranks) with the OpenMPI run-time and the MPI build of consph
# that bench/mpi_carry.sh packed into a folder (CARRY), and writes to OUTDIR (6 files):
#   mpi.md      bench/mpi.md's tables (weak scaling of the 3D Beltrami flow with L-IPST-C,
#               strong scaling, bytes per particle-step, comm fraction, halo/owned)
#   hello.txt   the 2-rank start and the set-up (MPI version, paths, launcher options)
#   progress.log  bench/mpi.sh's per-case lines (kept if the whole is stopped)
#   diag.txt    on a failed start: ldd of the binaries, OPAL paths, components, environment
#   machine.txt CPU, memory, /dev/shm;   times.txt  wall seconds of each part
#
# usage: bash CARRY/scripts/bench/mpi_device.sh [OUTDIR]   (from anywhere; OUTDIR default
#   ./mpi-device-out). Environment: CARRY (default: the folder this script was packed into,
#   else ./mpi-carry), RANKS (default "2 4 8 16"; 1 is always run), BUDGET (seconds for the
#   whole, default 175), WEAK_PER_RANK (default 100000, the issue's size; 10^5 x 16 ranks needs
#   about 45 GB with the solver cut at its set-up), STRONG_NX (default 48: the issue's 200^3
#   needs about 150 GB), STEPS1/STEPS2 (default 1/3), STUDY (default 003-kernels, "" for none),
#   SYSTEM_MPI=1 (use this machine's OpenMPI instead: for the test here), BEFORE (default
#   CARRY/bin/consph-before when packed: an earlier build measured with this one on the largest
#   rank count at BEFORE_PER_RANK particles per rank, default 20000, before the tables).
# CASE=strong200 runs instead (after the 2-rank start) only the strong scaling of the issue's
#   200^3 (bench/mpi_strong.sh: 16, 8 then 4 ranks, 1 and 2 steps each, within BUDGET_BIG
#   seconds, default 500: one 10-minute device call with the machine's start; BIG_NX and
#   BIG_RANKS change the size and the rank counts) into OUTDIR/mpi.md.
# Exit 0 with the tables written; 2 when 2 ranks cannot start (diag.txt says why).
set -u
T0=$(date +%s)
HERE=$(cd "$(dirname "$0")" && pwd)
OUTDIR=${1:-mpi-device-out}
mkdir -p "$OUTDIR"
OUTDIR=$(cd "$OUTDIR" && pwd)
if [ -z "${CARRY:-}" ]; then
    if [ -x "$HERE/../../bin/consph" ]; then CARRY=$HERE/../..; else CARRY=$(pwd)/mpi-carry; fi
fi
CARRY=$(cd "$CARRY" && pwd) || { echo "mpi_device: no carried folder $CARRY" >&2; exit 2; }
SCRIPTS=$CARRY/scripts/bench
[ -f "$SCRIPTS/mpi.sh" ] || SCRIPTS=$HERE
RANKS=${RANKS:-"2 4 8 16"}
BUDGET=${BUDGET:-175}
cnx=${CEILING_NX:-46}
csteps=${CEILING_STEPS:-2}
[[ "$cnx" =~ ^[1-9][0-9]*$ && "$csteps" =~ ^[1-9][0-9]*$ ]] ||
    { echo "mpi_device: CEILING_NX and CEILING_STEPS must be whole numbers > 0" >&2; exit 2; }
STUDY=${STUDY-003-kernels}
KMAX=1
for k in $RANKS; do KMAX=$k; done

export OMP_NUM_THREADS=1 OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
# One node, shared memory only: no network transport is tried.
export OMPI_MCA_btl=self,vader OMPI_MCA_pml=ob1 OMPI_MCA_btl_vader_single_copy_mechanism=none
# mpirun's PMIx takes its component folder from its build, not from PMIX_PREFIX or
# PMIX_MCA_mca_base_component_path: on a machine with another PMIx there (the lent one), it
# tries that one's compression component and warns. Its load errors follow OpenMPI's setting;
# the diagnostics below turn them on again.
export OMPI_MCA_mca_base_component_show_load_errors=0 PMIX_MCA_pcompress_base_silence_warning=1
if [ "${SYSTEM_MPI:-0}" != 1 ]; then
    P=$CARRY/usr
    LIB=$P/lib/x86_64-linux-gnu
    export OPAL_PREFIX=$P
    export PMIX_PREFIX=$LIB/pmix2 PMIX_INSTALL_PREFIX=$LIB/pmix2
    export OMPI_MCA_mca_base_component_path=$LIB/openmpi/lib/openmpi3
    export PMIX_MCA_mca_base_component_path=$LIB/pmix2/lib/pmix
    # hwloc's plugins (PCI, GL, OpenCL) are not carried: the CPU topology needs none
    export HWLOC_PLUGINS_PATH=$CARRY/no-hwloc-plugins
    export LD_LIBRARY_PATH=$LIB${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}
    export PATH=$P/bin:$PATH
fi
CONSPH=${CONSPH:-$CARRY/bin/consph}
BENCH_PAR=${BENCH_PAR:-$CARRY/bin/bench_par}
# A small /dev/shm (containers: 64 MB) cannot hold 16 ranks' shared-memory segments
shm_kb=$(df -Pk /dev/shm 2>/dev/null | awk 'NR == 2 { print $4 }')
[ "${shm_kb:-0}" -ge 1048576 ] || export OMPI_MCA_btl_vader_backing_directory=/tmp

{
    echo "date: $(date -u '+%Y-%m-%d %H:%M:%S UTC')"
    echo "cores online $(getconf _NPROCESSORS_ONLN), nproc --all $(nproc --all); $(grep -m1 'model name' /proc/cpuinfo)"
    lscpu 2>/dev/null | grep -E '^(CPU\(s\)|Thread|Core|Socket|NUMA node\(s\))'
    grep -E '^(MemTotal|MemAvailable)' /proc/meminfo
    echo "/dev/shm free kB: ${shm_kb:-?}; load: $(cat /proc/loadavg)"
    ldd --version | head -n 1
} >"$OUTDIR/machine.txt" 2>&1

diag() {
    {
        echo "== $1"
        echo "CARRY=$CARRY OPAL_PREFIX=${OPAL_PREFIX:-} PMIX_PREFIX=${PMIX_PREFIX:-}"
        echo "LD_LIBRARY_PATH=${LD_LIBRARY_PATH:-}"
        env | grep -E '^(OMPI|OPAL|PMIX|HWLOC)' | sort
        echo "== which mpirun: $(command -v mpirun)"
        echo "== ldd consph"; ldd "$CONSPH" 2>&1
        echo "== ldd mpirun"; ldd "$(command -v mpirun)" 2>&1
        echo "== ompi_info --path all"; timeout 20 ompi_info --path all 2>&1
        echo "== components"; ls "${OMPI_MCA_mca_base_component_path:-/nonexistent}" 2>&1 | tr '\n' ' '
        echo
        echo "== 2 ranks, verbose"
        timeout 30 mpirun $BIND -np 2 --mca plm_base_verbose 5 --mca btl_base_verbose 30 \
            --mca pml_base_verbose 10 --mca mca_base_component_show_load_errors 1 \
            "$CONSPH" --version 2>&1 | tail -n 80
        echo "== 2 ranks of hostname"; timeout 20 mpirun -np 2 hostname 2>&1 | tail -n 20
    } >>"$OUTDIR/diag.txt" 2>&1
    cat "$OUTDIR/machine.txt" "$OUTDIR/diag.txt" >&2
}

# hello: 2 ranks first (a broken set-up shows within seconds), then the launcher options that
# start KMAX ranks one per core (fall back to hardware threads, then to no binding).
BIND="--bind-to core"
{
    echo "mpirun: $(command -v mpirun); $(mpirun --version 2>&1 | head -n 1)"
    echo "consph: $CONSPH"
    echo "libmpi loaded by consph: $(LD_DEBUG=libs "$CONSPH" --version 2>&1 | sed -n 's/.*calling init: \(.*libmpi.*\)/\1/p' | head -n 1)"
} | tee "$OUTDIR/hello.txt"
hello=$(timeout 20 mpirun $BIND -np 2 "$CONSPH" --version 2>&1)
echo "$hello" | tee -a "$OUTDIR/hello.txt"
if ! echo "$hello" | grep -qx 'MPI ranks 2'; then
    echo "mpi_device: 2 ranks did not start" | tee -a "$OUTDIR/hello.txt" >&2
    diag "2-rank start failed"
    exit 2
fi
if [ "${SYSTEM_MPI:-0}" != 1 ]; then
    timeout 20 ompi_info --path all 2>&1 | grep -E 'Prefix|Libdir|Pkglibdir|Datadir' | tee -a "$OUTDIR/hello.txt"
fi
MPIRUN=
for opts in "--bind-to core --map-by core" "--use-hwthread-cpus --bind-to hwthread" "--oversubscribe --bind-to none"; do
    if timeout 20 mpirun $opts -np "$KMAX" "$CONSPH" --version 2>&1 | grep -qx "MPI ranks $KMAX"; then
        MPIRUN="mpirun $opts"
        break
    fi
done
if [ -z "$MPIRUN" ]; then
    echo "mpi_device: $KMAX ranks did not start with any binding" | tee -a "$OUTDIR/hello.txt" >&2
    diag "$KMAX-rank start failed"
    exit 2
fi
echo "launcher for $KMAX ranks: $MPIRUN ($(($(date +%s) - T0)) s so far)" | tee -a "$OUTDIR/hello.txt"
echo "hello $(($(date +%s) - T0))" >"$OUTDIR/times.txt"

WORK=${WORK:-${TMPDIR:-/tmp}/consph_mpi_device}
: >"$OUTDIR/progress.log"
STEPS1=${STEPS1:-1} STEPS2=${STEPS2:-3}

if [ "${CASE:-}" = strong200 ]; then
    t=$(date +%s)
    MPIRUN="$MPIRUN" CONSPH="$CONSPH" OUT="$OUTDIR/mpi.md" WORK="$WORK" NX="${BIG_NX:-200}" \
        RANKS="${BIG_RANKS:-16 8 4}" DEADLINE=$((T0 + ${BUDGET_BIG:-500})) \
        bash "$SCRIPTS/mpi_strong.sh" 2>&1 | tee -a "$OUTDIR/progress.log"
    echo "strong200 $(($(date +%s) - t))" >>"$OUTDIR/times.txt"
    echo "total $(($(date +%s) - T0))" >>"$OUTDIR/times.txt"
    cat "$OUTDIR/times.txt"
    exit 0
fi

# The earlier build, if packed, on KMAX ranks first (so that the solver tables below cannot
# leave it no time), and this build on the same case; their rows are appended after the tables.
# The size is BEFORE_PER_RANK particles per rank (default 20000): an earlier build that makes
# the whole solver on every rank before the cut needs about 12.8 kB per particle on every
# rank, which 10^5 per rank on 16 ranks (315 GB) does not fit.
BEFORE=${BEFORE:-$CARRY/bin/consph-before}
nxb=$(awk -v k="$KMAX" -v n="${BEFORE_PER_RANK:-20000}" 'BEGIN { printf "%d", (k * n)^(1 / 3) + 0.5 }')
: >"$WORK.before.md"
if [ -x "$BEFORE" ]; then
    t=$(date +%s)
    rows=
    for build in before after; do
        bin=$BEFORE
        [ $build = before ] || bin=$CONSPH
        row=
        for st in $STEPS1 $STEPS2; do
            rm -rf "$WORK.b"
            if timeout 40 $MPIRUN -np "$KMAX" "$bin" run beltrami --scheme l-ipst-c \
                --layout lattice --threads 1 --nx "$nxb" --steps "$st" --out "$WORK.b" \
                >"$WORK.b.out" 2>"$WORK.b.err"; then
                row="$row $(sed -n 's/^\([0-9.]*\) s, .*/\1/p' "$WORK.b.out") $(sed -n 's/^consph run: MPI [0-9]* ranks: \([0-9]*\) bytes sent.* \([0-9.]*\) s in MPI calls per rank.*/\1 \2/p' "$WORK.b.err")"
            else
                row="$row FAIL"
                echo "$build build: $(tail -n 3 "$WORK.b.err")" >>"$OUTDIR/progress.log"
            fi
        done
        rm -rf "$WORK.b"
        echo "$build build weak $KMAX ranks nx $nxb:$row" | tee -a "$OUTDIR/progress.log"
        case $row in
        *FAIL*) ;;
        *)
            rows="$rows$(echo "$row" | awk -v b=$build -v k="$KMAX" -v nx="$nxb" -v d="$((STEPS2 - STEPS1))" '{
                t = ($4 - $1) / d; by = ($5 - $2) / d / nx^3; c = ($6 - $3) / d
                printf "| %s | %d | %d | %.4g | %.0f | %.4g | %.2f |\n", b, k, nx, t, by, c, c / t }')
"
            ;;
        esac
    done
    if [ -n "$rows" ]; then
        {
            echo
            echo "### The earlier build (consph-before) and this one on $KMAX ranks, nx $nxb"
            echo
            echo "Same command, steps and differencing as the weak rows above, at ${BEFORE_PER_RANK:-20000} particles"
            echo "per rank; before: the build packed as bin/consph-before (bench/mpi_carry.sh with"
            echo "BEFORE=...): $(cat "$BEFORE.txt" 2>/dev/null || echo an earlier commit); after: bin/consph."
            echo
            echo "| build | ranks | nx | s/step | bytes/particle-step | MPI s/step | comm fraction |"
            echo "|---|---|---|---|---|---|---|"
            printf '%s' "$rows"
        } >"$WORK.before.md"
    fi
    echo "before $(($(date +%s) - t))" >>"$OUTDIR/times.txt"
fi

# The machine's own ceiling on weak scaling, before the solver's: K independent serial runs of
# the 1-rank weak case at once, one per CPU (taskset 0..K-1), and two on CPUs 0 and KMAX/2. A
# rank can at best run as fast as one of these: where the CPUs share cores (hardware threads a
# VM shows as cores) or memory bandwidth, t(1) / t(K) falls below 1 with no communication at
# all. CEILING_NX (default 46: 10^5 particles), CEILING_STEPS (default 2); CEILING=0: skip.
: >"$WORK.ceiling.md"
if [ "${CEILING:-1}" != 0 ] && command -v taskset >/dev/null; then
    t=$(date +%s)
    # batch CPUS (comma-separated): "K CPUS s n", s the mean of the runs' own steps' seconds
    batch() {
        local c pids=() k=0
        for c in ${1//,/ }; do
            taskset -c "$c" "$CONSPH" run beltrami --scheme l-ipst-c --layout lattice --threads 1 \
                --nx "$cnx" --steps "$csteps" >"$WORK.c$k.out" 2>&1 &
            pids+=($!)
            k=$((k + 1))
        done
        wait "${pids[@]}"
        for ((j = 0; j < k; j++)); do sed -n 's/^\([0-9.]*\) s, .*/\1/p' "$WORK.c$j.out"; done |
            awk -v k="$k" -v c="$1" '{ s += $1; n++ } END { if (n) printf "%d %s %.4f %d\n", k, c, s / n, n }'
        rm -f "$WORK".c*.out
    }
    {
        batch 0
        for k in $RANKS; do
            [ $(($(date +%s) - T0)) -lt $((BUDGET / 3)) ] || break
            batch "$(seq -s, 0 $((k - 1)))"
        done
        [ "$KMAX" -ge 4 ] && batch "0,$((KMAX / 2))"
    } >"$WORK.ceiling.txt"
    cat "$WORK.ceiling.txt" >>"$OUTDIR/progress.log"
    {
        echo
        echo "### The machine's ceiling: K independent serial runs at once"
        echo
        echo "\`taskset -c CPU consph run beltrami --scheme l-ipst-c --layout lattice --threads 1 --nx $cnx"
        echo "--steps $csteps\` started K times at once, one per CPU (no MPI); s = the mean of the runs' own"
        echo "steps' seconds (set-up excluded); ceiling = s(1) / s(K): the weak-scaling efficiency no"
        echo "decomposition can pass on this machine at this size per CPU. runs: how many reported."
        echo
        echo "| K | CPUs | s | ceiling | runs |"
        echo "|---|---|---|---|---|"
        # the ceiling against the lone run on CPU 0 (none where that run reported nothing)
        awk 'NR == 1 && $1 == 1 { s1 = $3 }
             { printf "| %d | %s | %.3f | %s | %d |\n", $1, $2, $3, s1 ? sprintf("%.2f", s1 / $3) : "-", $4 }' \
            "$WORK.ceiling.txt"
    } >"$WORK.ceiling.md"
    echo "ceiling $(($(date +%s) - t))" >>"$OUTDIR/times.txt"
fi

# The solver: weak scaling, then strong; each run under CASE_TIMEOUT and none past BUDGET - 8 s,
# no case started after BUDGET - 25 s, cases too big for the memory skipped.
t=$(date +%s)
DEADLINE=$((T0 + BUDGET - 25)) HARD_END=$((T0 + BUDGET - 8)) MPIRUN="$MPIRUN" CONSPH="$CONSPH" BENCH_PAR="$BENCH_PAR" \
    OUT="$OUTDIR/mpi.md" RANKS="$RANKS" SECTIONS=solver SOLVER_CASES=3d MACHINE_NOTE="${MACHINE_NOTE:-bench/mpi_device.sh, one rank per core, the OpenMPI run-time carried}" \
    WEAK_PER_RANK=${WEAK_PER_RANK:-100000} STRONG_NX=${STRONG_NX:-48} STEPS1=$STEPS1 \
    STEPS2=$STEPS2 CASE_TIMEOUT=${CASE_TIMEOUT:-40} WORK="$WORK" \
    bash "$SCRIPTS/mpi.sh" 2>&1 | tee -a "$OUTDIR/progress.log"
echo "solver $(($(date +%s) - t))" >>"$OUTDIR/times.txt"
[ -f "$OUTDIR/mpi.md" ] && cat "$WORK.ceiling.md" "$WORK.before.md" >>"$OUTDIR/mpi.md"

# A quick study over ranks, if time is left (its table is appended to mpi.md)
left=$((T0 + BUDGET - $(date +%s)))
if [ -n "$STUDY" ] && [ "$left" -gt 12 ]; then
    t=$(date +%s)
    MPIRUN="$MPIRUN" CONSPH="$CONSPH" OUT="$WORK.study.md" RANKS="$RANKS" SECTIONS=studies \
        STUDIES="$STUDY" HARD_END=$((T0 + BUDGET)) WORK="$WORK" \
        bash "$SCRIPTS/mpi.sh" 2>&1 | tee -a "$OUTDIR/progress.log"
    [ -f "$WORK.study.md" ] && sed -n '/^## Studies/,/^Load average after/p' "$WORK.study.md" |
        grep -v '^Load average' >>"$OUTDIR/mpi.md"
    echo "study $(($(date +%s) - t))" >>"$OUTDIR/times.txt"
fi
echo "total $(($(date +%s) - T0))" >>"$OUTDIR/times.txt"
cat "$OUTDIR/times.txt"
[ -f "$OUTDIR/mpi.md" ] && cat "$OUTDIR/mpi.md"
