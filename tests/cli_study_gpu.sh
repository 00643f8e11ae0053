#!/usr/bin/env bash
# consph study --device cpu|gpu|auto (docs/studies.md, docs/gpu.md), on the host emulation behind
# --device gpu (CONSPH_GPU_BACKEND=emulation) and on the GPU where one is found: a study of edac
# and wcsph rows under --device gpu writes the CPU study's files (every file, the wall-time
# columns and the line that says which device ran the rows masked; the pairs are the CPU's);
# --device gpu on a study with a series the GPU does not run (edac under rk2) exits 2 naming it and
# writes nothing; --device auto runs it mixed and writes the CPU's report, its device line
# naming the rows of each device; without a GPU, gpu exits 2 with the reason and auto runs on the
# CPU, said once; the study file's key `device` and the option that overrides it; bad values,
# --jobs J with a GPU: J threads whose rows share it, the same report.
# Usage: cli_study_gpu.sh <path-to-consph> <source-dir>
set -u
bin=$1 src=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
. "$(dirname "${BASH_SOURCE[0]}")/lib_cli.sh"

study=$src/tests/data/gpu.study
# a series the GPU does not run: every scheme runs there, so edac under an integrator it does not
# (the host emulation refuses it as CUDA does)
CONSPH_GPU_BACKEND=emulation "$bin" run taylor-green --scheme edac --integrator rk2 --nx 8 \
    --steps 1 --device gpu >/dev/null 2>"$work/err"
[ $? = 2 ] && grep -q "integrator 'rk2' does not run edac on the GPU" "$work/err" &&
    pass=$((pass + 1)) || bad "edac under rk2 on the GPU: $(cat "$work/err")"
# the study with a series of it
{ cat "$study"; printf '\n[figure tgv2]\ntitle = Taylor-Green, edac under rk2 too\nkind = run\n'
  printf 'problem = taylor-green\nnx = 16,20\nsteps = 3\n\n[series EDAC]\nscheme = edac\n\n'
  printf '[series OTHER]\nscheme = edac\nintegrator = rk2\n'; } | sed 's/^study = gpu$/study = mixed/' \
    >"$work/mixed.study"

# norm FILE: masked (lib_cli.sh), without the device line and its blank line
norm() {
    masked "$1" | awk '
        skip && $0 == "" { skip = 0; next }
        /^Device: / { skip = 1; next }
        { skip = 0 }
        { print }'
}
# same_report A B WHAT: the same files, equal once normed
same_report() {
    local f ok=0
    [ "$(ls -A "$1")" = "$(ls -A "$2")" ] ||
        { bad "$3: files $(ls -A "$2" | tr '\n' ' ') want $(ls -A "$1" | tr '\n' ' ')"; return 1; }
    for f in "$1"/*; do
        cmp -s <(norm "$f") <(norm "$2/${f##*/}") ||
            { bad "$3: ${f##*/} differs: $(diff <(norm "$f") <(norm "$2/${f##*/}") | head -4)"; ok=1; }
    done
    return $ok
}
# device_line DIR FIGURE: the line saying which device ran its rows
device_line() { grep '^Device: ' "$1/$2.md"; }

"$bin" study "$study" --quick --out "$work/cpu" >/dev/null 2>"$work/err" ||
    { bad "CPU study: $(cat "$work/err")"; summary cli_study_gpu; exit; }
"$bin" study "$work/mixed.study" --quick --out "$work/cpu" >/dev/null 2>"$work/err" ||
    { bad "CPU mixed study: $(cat "$work/err")"; summary cli_study_gpu; exit; }
# without --device the report says nothing of devices
grep -q '^Device' "$work/cpu/gpu/tgv.md" "$work/cpu/gpu/README.md" &&
    bad "a study without --device names a device" || pass=$((pass + 1))

failing 2 "allowed: cpu,gpu,auto" "$work/o" -- "$bin" study "$study" --quick --device tpu \
    --out "$work/x" && pass=$((pass + 1))
mkdir "$work/badkey"
sed 's/^paper = none$/paper = none\ndevice = tpu/' "$study" >"$work/badkey/gpu.study"
failing 2 "'device': unknown value 'tpu'" "$work/o" -- "$bin" study "$work/badkey/gpu.study" --quick \
    --out "$work/x" &&
    pass=$((pass + 1))
[ -e "$work/x" ] && bad "a refused study wrote $work/x" || pass=$((pass + 1))
# one GPU for the ranks of mpirun: refused where this consph has MPI and mpirun starts 2 ranks
if ! "$bin" --version | grep -qx 'MPI not built in' && command -v mpirun >/dev/null; then
    export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
    timeout 120 mpirun --oversubscribe -np 2 "$bin" study "$study" --quick --device auto \
        --out "$work/x" >"$work/o" 2>&1
    rc=$?
    if grep -q "launched on 2 MPI ranks" "$work/o"; then
        [ $rc = 2 ] && [ ! -e "$work/x" ] && pass=$((pass + 1)) || bad "mpirun -np 2: exit $rc"
    elif ! grep -q "^MPI ranks 2$" <(timeout 60 mpirun --oversubscribe -np 2 "$bin" --version 2>&1); then
        echo "mpirun cannot start 2 ranks here: not checked"
    else
        bad "mpirun -np 2 --device auto: exit $rc: $(head -5 "$work/o")"
    fi
fi
# --device cpu runs as the default does, and says so
"$bin" study "$study" --quick --device cpu --out "$work/dcpu" >/dev/null 2>"$work/err" ||
    bad "--device cpu: $(cat "$work/err")"
same_report "$work/cpu/gpu" "$work/dcpu/gpu" "--device cpu" && pass=$((pass + 1))
[ "$(device_line "$work/dcpu/gpu" tgv)" = "Device: the CPU ran every row." ] &&
    pass=$((pass + 1)) || bad "--device cpu: $(device_line "$work/dcpu/gpu" tgv)"

# gpu_runs BACKEND: the GPU's studies against the CPU's (BACKEND: "" the CUDA device, or
# "emulation")
gpu_runs() {
    local be=$1 w=$work/${1:-cuda}
    # on 2 cores, where the default --jobs is 2 workers: one GPU makes it one process
    OMP_NUM_THREADS=2 CONSPH_GPU_BACKEND=$be "$bin" study "$study" --quick --device gpu --out "$w/gpu" \
        >"$w.out" 2>"$work/err" || { bad "${be:-cuda}: --device gpu: $(cat "$work/err")"; return; }
    same_report "$work/cpu/gpu" "$w/gpu/gpu" "${be:-cuda}: --device gpu" && pass=$((pass + 1))
    [ "$(device_line "$w/gpu/gpu" tgv)" = "Device: the GPU ran every row." ] &&
        pass=$((pass + 1)) || bad "${be:-cuda}: --device gpu: $(device_line "$w/gpu/gpu" tgv)"
    # the operator figure has no device
    grep -q '^Device' "$w/gpu/gpu/grad.md" && bad "${be:-cuda}: grad names a device" ||
        pass=$((pass + 1))
    # --jobs 3: the rows on three threads sharing the GPU (study_run_threads), the same report
    OMP_NUM_THREADS=2 CONSPH_GPU_BACKEND=$be "$bin" study "$study" --quick --device gpu --jobs 3 \
        --out "$w/gpu3" >"$w.out3" 2>"$work/err" ||
        { bad "${be:-cuda}: --device gpu --jobs 3: $(cat "$work/err")"; return; }
    same_report "$work/cpu/gpu" "$w/gpu3/gpu" "${be:-cuda}: --device gpu --jobs 3" &&
        pass=$((pass + 1))
    grep -q "row .* done" "$work/err" && pass=$((pass + 1)) ||
        bad "${be:-cuda}: --jobs 3: no line per row on stderr: $(head -3 "$work/err")"
    # a stop request on the threads (the test hook raises SIGINT once, after a row): the partial
    # report and the resume command; the resume finishes the CPU's report
    CONSPH_TEST_STOP_AFTER_ROWS=1 CONSPH_GPU_BACKEND=$be "$bin" study "$study" --quick --device gpu \
        --jobs 2 --out "$w/stop" >/dev/null 2>"$work/err"
    local rc=$?
    [ $rc = 130 ] && [ -f "$w/stop/gpu/README.md" ] && grep -q -- "--resume" "$work/err" &&
        pass=$((pass + 1)) || bad "${be:-cuda}: --jobs 2 stopped: exit $rc: $(cat "$work/err")"
    CONSPH_GPU_BACKEND=$be "$bin" study "$study" --quick --device gpu --jobs 2 --out "$w/stop" \
        --resume >/dev/null 2>"$work/err" || bad "${be:-cuda}: --jobs 2 --resume: $(cat "$work/err")"
    same_report "$work/cpu/gpu" "$w/stop/gpu" "${be:-cuda}: --jobs 2 stopped and resumed" &&
        pass=$((pass + 1))
    failing 2 "series 'OTHER' (nx 16, 20): integrator 'rk2' does not run edac on the GPU" "$w.o" -- \
        env CONSPH_GPU_BACKEND="$be" "$bin" study "$work/mixed.study" --quick --device gpu \
        --out "$w/refused" && pass=$((pass + 1))
    [ -e "$w/refused" ] && bad "${be:-cuda}: the refused study wrote $w/refused" ||
        pass=$((pass + 1))
    CONSPH_GPU_BACKEND=$be "$bin" study "$work/mixed.study" --quick --device auto --out "$w/auto" \
        >/dev/null 2>"$work/err" || { bad "${be:-cuda}: --device auto: $(cat "$work/err")"; return; }
    same_report "$work/cpu/mixed" "$w/auto/mixed" "${be:-cuda}: --device auto" && pass=$((pass + 1))
    local want="Device: the GPU ran EDAC (nx 16, 20); the CPU ran OTHER (nx 16, 20). T_r and the"
    want="$want seconds compare wall times of both."
    [ "$(device_line "$w/auto/mixed" tgv2)" = "$want" ] && pass=$((pass + 1)) ||
        bad "${be:-cuda}: --device auto: $(device_line "$w/auto/mixed" tgv2)"
    # ... and on two threads, the CPU's rows and the GPU's side by side
    CONSPH_GPU_BACKEND=$be "$bin" study "$work/mixed.study" --quick --device auto --jobs 2 \
        --out "$w/auto2" >/dev/null 2>"$work/err" ||
        { bad "${be:-cuda}: --device auto --jobs 2: $(cat "$work/err")"; return; }
    same_report "$work/cpu/mixed" "$w/auto2/mixed" "${be:-cuda}: --device auto --jobs 2" &&
        pass=$((pass + 1))
    [ "$(device_line "$w/auto2/mixed" tgv2)" = "$want" ] && pass=$((pass + 1)) ||
        bad "${be:-cuda}: --device auto --jobs 2: $(device_line "$w/auto2/mixed" tgv2)"
    # the study file's key, and the option that wins over it
    mkdir -p "$w.key"
    sed 's/^paper = none$/paper = none\ndevice = gpu/' "$study" >"$w.key/gpu.study"
    CONSPH_GPU_BACKEND=$be "$bin" study "$w.key/gpu.study" --quick --out "$w/key" >/dev/null \
        2>"$work/err" || bad "${be:-cuda}: device = gpu: $(cat "$work/err")"
    [ "$(device_line "$w/key/gpu" tgv)" = "Device: the GPU ran every row." ] &&
        pass=$((pass + 1)) || bad "${be:-cuda}: key device = gpu: $(device_line "$w/key/gpu" tgv)"
    CONSPH_GPU_BACKEND=$be "$bin" study "$w.key/gpu.study" --quick --device cpu --out "$w/key" \
        >/dev/null 2>"$work/err" || bad "${be:-cuda}: --device cpu over the key: $(cat "$work/err")"
    [ "$(device_line "$w/key/gpu" tgv)" = "Device: the CPU ran every row." ] &&
        pass=$((pass + 1)) || bad "${be:-cuda}: --device cpu over the key: $(device_line "$w/key/gpu" tgv)"
}
mkdir -p "$work/emulation" "$work/cuda"
gpu_runs emulation

# the machine's own: no GPU (CI) or one
"$bin" study "$study" --quick --device gpu --out "$work/real" >/dev/null 2>"$work/err"
rc=$?
if [ $rc = 2 ]; then
    grep -qE "without GPU support|no CUDA device" "$work/err" && pass=$((pass + 1)) ||
        bad "no GPU: $(cat "$work/err")"
    [ -e "$work/real" ] && bad "no GPU: --device gpu wrote $work/real" || pass=$((pass + 1))
    "$bin" study "$work/mixed.study" --quick --device auto --out "$work/auto" >/dev/null \
        2>"$work/err" || bad "no GPU: --device auto: $(cat "$work/err")"
    [ "$(grep -c 'every row runs on the CPU' "$work/err")" = 1 ] && pass=$((pass + 1)) ||
        bad "no GPU: --device auto: stderr $(cat "$work/err")"
    same_report "$work/cpu/mixed" "$work/auto/mixed" "no GPU: --device auto" && pass=$((pass + 1))
    [ "$(device_line "$work/auto/mixed" tgv2)" = "Device: the CPU ran every row." ] &&
        pass=$((pass + 1)) || bad "no GPU: --device auto: $(device_line "$work/auto/mixed" tgv2)"
elif [ $rc = 0 ]; then
    gpu_runs ""
else
    bad "--device gpu: exit $rc: $(cat "$work/err")"
fi
summary cli_study_gpu
