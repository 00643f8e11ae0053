#!/usr/bin/env bash
# consph under mpirun (docs/mpi.md). A study on 2 and 3 ranks writes the files a serial study
# writes (every file byte for byte, the wall-time columns masked; the same hidden rows kept); a
# study with fewer rows than ranks leaves ranks idle; a study stopped on 2 ranks resumes on 3 to
# the serial report; a row that fails on rank 1 ends every rank with the serial exit status and
# message, printed once, and so does a rank that stops before the study starts; `consph run` on
# 2 and 3 ranks writes the serial run's files, also sampling every step (l-rr-c and heat
# refused, exit 2, once); the other commands run on rank 0 alone (layout: the serial
# file and output, once). A serial run never initialises MPI.
# In a build without MPI: a launch on 2 ranks is refused (exit 2). Skips (77) without mpirun or
# where mpirun cannot start 2 ranks.
# Usage: cli_mpi.sh <path-to-consph> <source-dir>
set -u
bin=$1 src=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
. "$(dirname "${BASH_SOURCE[0]}")/lib_cli.sh"

if "$bin" --version | grep -qx 'MPI not built in'; then
    # Without MPI, a launch on 2 ranks (as mpirun's environment says) is refused, not run twice.
    failing 2 "launched by an MPI launcher on 2 ranks, but this consph was built without MPI" \
        /dev/null -- env OMPI_COMM_WORLD_SIZE=2 OMPI_COMM_WORLD_RANK=1 "$bin" layout --kind lattice \
        --dim 2 --nx 4 --out "$work/l.csv" && [ ! -e "$work/l.csv" ] && pass=$((pass + 1))
    env PMI_SIZE=1 "$bin" --version >/dev/null && pass=$((pass + 1)) || bad "PMI_SIZE=1: refused"
    summary cli_mpi
    exit
fi
command -v mpirun >/dev/null || { echo "skipped: no mpirun"; exit 77; }
# mpirun refuses root without these; one process per rank on however few cores there are.
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_rmaps_base_oversubscribe=1
mpi() {
    local np=$1
    shift
    timeout 120 mpirun --oversubscribe -np "$np" "$@"
}
# mpirun's own lines about a rank's non-zero exit, which are not consph's
ours() { grep -v -e '^---' -e '^Primary job' -e '^a non-zero exit' -e '^mpirun detected' \
    -e '^the job to be' -e '^ *Process name' -e '^ *Exit code' -e '^$' "$1"; }
mpi 2 "$bin" --version >"$work/v" 2>&1 && [ "$(grep -c '^MPI ranks 2$' "$work/v")" = 1 ] ||
    { echo "skipped: mpirun cannot start 2 ranks here: $(head -3 "$work/v")"; exit 77; }
pass=$((pass + 1))

study=$src/tests/data/resume.study
"$bin" study "$study" --quick --out "$work/s1" >/dev/null 2>"$work/err" ||
    { bad "serial study: $(cat "$work/err")"; summary cli_mpi; exit; }
for np in 2 3; do
    mpi $np "$bin" study "$study" --quick --out "$work/s$np" >"$work/out" 2>"$work/err" ||
        { bad "$np ranks: exit $?: $(cat "$work/err")"; continue; }
    same_study "$work/s1/resume" "$work/s$np/resume" "$np ranks" && pass=$((pass + 1))
    # rank 0 alone writes stdout: one title line, one "done" line
    [ "$(grep -c '^study resume:' "$work/out")" = 1 ] && [ "$(grep -c '^done in' "$work/out")" = 1 ] &&
        pass=$((pass + 1)) || bad "$np ranks: stdout not rank 0's alone: $(cat "$work/out")"
done

# Fewer rows than ranks: one approx row and one m0 figure on 3 ranks.
two=$src/tests/data/two.study
"$bin" study "$two" --quick --out "$work/t1" >/dev/null 2>&1 &&
    mpi 3 "$bin" study "$two" --quick --out "$work/t3" >/dev/null 2>"$work/err" &&
    same_study "$work/t1/two" "$work/t3/two" "2 rows on 3 ranks" && pass=$((pass + 1)) ||
    bad "2 rows on 3 ranks: $(cat "$work/err")"

# Stopped on 2 ranks (each rank stops after its first row), resumed on 3.
CONSPH_TEST_STOP_AFTER_ROWS=1 mpi 2 "$bin" study "$study" --quick --out "$work/k" >/dev/null \
    2>"$work/err"
rc=$?
if [ $rc != 130 ]; then
    bad "stop on 2 ranks: exit $rc, want 130: $(cat "$work/err")"
elif ! grep -q '^\*\*Partial results\*\*: stopped by SIGINT after 2 of 12 rows' "$work/k/resume/README.md"; then
    bad "stop on 2 ranks: README.md: $(head -3 "$work/k/resume/README.md")"
elif [ "$(ours "$work/err" | grep -c 'resume with')" != 1 ]; then
    bad "stop on 2 ranks: the resume command not printed once: $(cat "$work/err")"
elif ! mpi 3 "$bin" study "$study" --quick --out "$work/k" --resume >/dev/null 2>"$work/err"; then
    bad "resume on 3 ranks: $(cat "$work/err")"
else
    same_study "$work/s1/resume" "$work/k/resume" "stopped on 2 ranks, resumed on 3" && pass=$((pass + 1))
fi

# A row that fails on rank 1 (its row file cannot be written: a directory holds the name).
cat >"$work/g.study" <<'STUDY'
study = g
[figure g]
op = grad
nx = 8,10
STUDY
for np in 1 2; do
    mkdir -p "$work/f$np/g/.g.s0.r1.row/x"
    run=mpi
    [ $np = 1 ] && run=
    $run ${run:+$np} "$bin" study "$work/g.study" --quick --out "$work/f$np" >/dev/null 2>"$work/e$np"
    echo $? >"$work/rc$np"
done
msg="'$work/f2/g/.g.s0.r1.row' is a directory"
if [ "$(cat "$work/rc1")" = 0 ] || [ "$(cat "$work/rc2")" != "$(cat "$work/rc1")" ]; then
    bad "a row failing on rank 1: exit $(cat "$work/rc2"), serial $(cat "$work/rc1")"
elif [ "$(ours "$work/e2" | grep -cF "consph study: $msg")" != 1 ]; then
    bad "a row failing on rank 1: message not printed once: $(cat "$work/e2")"
else
    pass=$((pass + 1))
fi

# A rank that stops before the study starts (the study is found on rank 0 only): every rank
# ends, exit 2, nothing written, rank 0 names the rank.
mkdir -p "$work/dA" "$work/dB"
sed 's/^study = g$/study = onlyhere/' "$work/g.study" >"$work/dA/onlyhere.study"
timeout 120 mpirun --oversubscribe -np 1 env CONSPH_STUDIES="$work/dA" "$bin" study onlyhere --quick \
    --out "$work/div" : -np 1 env CONSPH_STUDIES="$work/dB" "$bin" study onlyhere --quick \
    --out "$work/div" >/dev/null 2>"$work/err"
rc=$?
[ $rc = 2 ] && grep -q '^consph study: rank 1 of 2 stopped before the study started' "$work/err" &&
    [ ! -e "$work/div" ] && pass=$((pass + 1)) ||
    bad "study found on rank 0 only: exit $rc: $(ours "$work/err")"

# consph run decomposes the solver: 2 and 3 ranks write the serial run's files bit for bit
# (summary.json's timings aside), and its table once; a checkpoint of 3 ranks restarts on 2.
runargs=(run taylor-green --scheme edac --layout lattice --nx 24 --steps 6 --snapshot-every 3
    --checkpoint-every 3)
"$bin" "${runargs[@]}" --out "$work/r1" >"$work/ro1" 2>"$work/err" || bad "serial run: $(cat "$work/err")"
for np in 2 3; do
    mpi $np "$bin" "${runargs[@]}" --out "$work/r$np" >"$work/ro$np" 2>"$work/err" ||
        { bad "run on $np ranks: exit $?: $(ours "$work/err")"; continue; }
    # rank 0 alone reports the communication of every rank, on stderr
    [ "$(grep -c "^consph run: MPI $np ranks: [1-9][0-9]* bytes sent" "$work/err")" = 1 ] &&
        pass=$((pass + 1)) || bad "run on $np ranks: no communication line once: $(ours "$work/err")"
    same_run "$work/r1" "$work/r$np" "run on $np ranks" &&
        cmp -s <(grep -v ' s, ' "$work/ro1") <(grep -v ' s, ' "$work/ro$np") && pass=$((pass + 1)) ||
        bad "run on $np ranks: stdout $(diff <(grep -v ' s, ' "$work/ro1") <(grep -v ' s, ' "$work/ro$np") | head -4)"
done
# Sampled at every step, snapshots at the first and last only (a sample gathers only what the
# diagnostics read): the serial log, summary and snapshots; a scheme with a per-particle mass.
# Without files (the run's end then gathers no field): the serial table on 3 ranks.
runargs=(run taylor-green --scheme delta-plus-sph --layout random --nx 24 --steps 5 --log-every 1)
"$bin" "${runargs[@]}" --snapshot-every 0 --out "$work/l1" >"$work/lo1" 2>"$work/err" ||
    bad "serial run: $(cat "$work/err")"
mpi 2 "$bin" "${runargs[@]}" --snapshot-every 0 --out "$work/l2" >/dev/null 2>"$work/err" &&
    same_run "$work/l1" "$work/l2" "sampled every step on 2 ranks" && pass=$((pass + 1)) ||
    bad "sampled every step on 2 ranks: $(ours "$work/err")"
mpi 3 "$bin" "${runargs[@]}" >"$work/lo3" 2>"$work/err" &&
    cmp -s <(grep -v ' s, ' "$work/lo1") <(grep -v ' s, ' "$work/lo3") && pass=$((pass + 1)) ||
    bad "without files on 3 ranks: $(diff "$work/lo1" "$work/lo3" | head -4) $(ours "$work/err")"
cp -r "$work/r3" "$work/rr"
mpi 2 "$bin" run --restart "$work/rr/checkpoint.ckpt" --out "$work/rr" >/dev/null 2>"$work/err" &&
    same_run "$work/r1" "$work/rr" "restart of 3 ranks' checkpoint on 2" && pass=$((pass + 1)) ||
    bad "restart on 2 ranks: $(ours "$work/err")"
# A restart to another end with other snapshot times (step 3 to 8, every 4): the snapshot of the
# former end (step 6) is removed, as the serial restart removes it.
cp -r "$work/r1" "$work/xs" && cp -r "$work/r1" "$work/xm"
"$bin" run --restart "$work/xs/checkpoint.ckpt" --steps 8 --snapshot-every 4 --out "$work/xs" \
    >/dev/null 2>"$work/err" || bad "serial restart to step 8: $(cat "$work/err")"
[ ! -e "$work/xs/snap_000006.vtu" ] || bad "serial restart to step 8 kept the former end's snapshot"
mpi 2 "$bin" run --restart "$work/xm/checkpoint.ckpt" --steps 8 --snapshot-every 4 --out "$work/xm" \
    >/dev/null 2>"$work/err" &&
    same_run "$work/xs" "$work/xm" "restart to step 8 on 2 ranks" && pass=$((pass + 1)) ||
    bad "restart to step 8 on 2 ranks: $(ours "$work/err")"
# Given particles (a random layout's file): each rank's set-up takes its share of them, the run
# is the serial one.
"$bin" layout --kind random --dim 2 --nx 24 --out "$work/given.csv" >/dev/null 2>"$work/err" ||
    bad "layout for --particles: $(cat "$work/err")"
"$bin" run taylor-green --scheme edac --particles "$work/given.csv" --steps 3 --out "$work/g1" \
    >/dev/null 2>"$work/err" || bad "serial run of given particles: $(cat "$work/err")"
mpi 3 "$bin" run taylor-green --scheme edac --particles "$work/given.csv" --steps 3 \
    --out "$work/g3" >/dev/null 2>"$work/err" && same_run "$work/g1" "$work/g3" \
    "given particles on 3 ranks" && pass=$((pass + 1)) ||
    bad "given particles on 3 ranks: $(ours "$work/err")"
# Rank 0 alone reads the file and hands each rank its share: ranks 1 and 2 given a file that
# does not exist still run the serial run.
timeout 120 mpirun --oversubscribe -np 1 "$bin" run taylor-green --scheme edac --particles \
    "$work/given.csv" --steps 3 --out "$work/g0" : -np 2 "$bin" run taylor-green --scheme edac \
    --particles "$work/nowhere.csv" --steps 3 --out "$work/g0" >/dev/null 2>"$work/err" &&
    same_run "$work/g1" "$work/g0" "given particles read by rank 0 only" && pass=$((pass + 1)) ||
    bad "given particles read by rank 0 only: $(ours "$work/err")"
# A bad file: the reader's message once, exit 2, nothing written.
head -c 300 "$work/given.csv" >"$work/short.csv"
failing 2 "short.csv:11: short row" /dev/null -- \
    mpi 3 "$bin" run taylor-green --scheme edac --particles "$work/short.csv" --steps 3 \
    --out "$work/gbad" && [ "$(ours "$work/err" | grep -c 'short row')" = 1 ] &&
    [ ! -e "$work/gbad" ] && pass=$((pass + 1)) || bad "bad particle file on 3 ranks: $(ours "$work/err")"
# What the decomposition cannot serve: exit 2, once, nothing written.
failing 2 "l-rr-c" /dev/null -- \
    mpi 2 "$bin" run taylor-green --scheme l-rr-c --layout lattice --nx 8 --steps 2 --out "$work/rrc" &&
    [ "$(ours "$work/err" | grep -c 'l-rr-c')" = 1 ] && [ -z "$(ls -A "$work/rrc" 2>/dev/null)" ] &&
    pass=$((pass + 1)) || bad "l-rr-c on 2 ranks: $(ours "$work/err")"
failing 2 "problem heat is not decomposed" /dev/null -- mpi 2 "$bin" run heat --nx 9 --steps 2 &&
    pass=$((pass + 1))
# A bad option: exit 2, its message once.
failing 2 "unknown value 'nope'" /dev/null -- mpi 2 "$bin" layout --kind nope &&
    [ "$(ours "$work/err" | grep -c "unknown value 'nope'")" = 1 ] && pass=$((pass + 1))
# The other commands: rank 0 runs them, the serial output once.
"$bin" layout --kind lattice --dim 2 --nx 6 --out "$work/l1.csv" >"$work/o1" &&
    mpi 3 "$bin" layout --kind lattice --dim 2 --nx 6 --out "$work/l3.csv" >"$work/o3" &&
    cmp -s "$work/l1.csv" "$work/l3.csv" && cmp -s <(sed 's/l1.csv/lX/' "$work/o1") <(sed 's/l3.csv/lX/' "$work/o3") &&
    pass=$((pass + 1)) || bad "layout on 3 ranks: $(diff "$work/o1" "$work/o3" | head -4)"

# A serial run does not initialise MPI: no OpenMPI session directory appears for it.
tmpdir=$work/ompi-tmp
mkdir -p "$tmpdir"
TMPDIR=$tmpdir "$bin" study "$work/g.study" --quick --out "$work/serial" >/dev/null 2>&1 &&
    [ -z "$(ls -A "$tmpdir")" ] && pass=$((pass + 1)) ||
    bad "a serial study left OpenMPI files in TMPDIR: $(ls -A "$tmpdir")"
summary cli_mpi
