#!/usr/bin/env bash
# The GPU probe (bench/gpu/README.md): builds probe.cu with the machine's nvcc and probe_cpu.c
# with its gcc, runs them and the prebuilt OpenMP offload probe (bench/gpu/prebuilt/, made by
# build_prebuilt.sh) at N = 1e5, 1e6, 1e7 (2D) and 1e6 (3D), compares their results bitwise,
# and writes OUTDIR/gpu_probe.md with the raw logs in OUTDIR/raw/. Every part runs under
# `timeout`; a part that fails is reported and skipped. Without nvcc or a GPU it runs the CPU
# parts only.
#   usage: bash bench/gpu/run_probe.sh OUTDIR
# Environment: NVCC (path, or "none" to skip CUDA), PROBE_BUDGET_S (default 240: parts that
# would start later are skipped; none runs past it + 60 s), PROBE_SIZES (default "2:316 2:1000 2:3162 3:100", dim:nx),
# PROBE_CMP (default "2:1000 3:100", the sizes compared bitwise), PROBE_THREADS (default nproc).
set -u
if [ $# -lt 1 ]; then
    echo "usage: bash bench/gpu/run_probe.sh OUTDIR" >&2
    exit 2
fi
HERE=$(cd "$(dirname "$0")" && pwd)
PRE=$HERE/prebuilt
mkdir -p "$1/raw" || exit 2
OUT=$(cd "$1" && pwd)
RAW=$OUT/raw
WORK=$(mktemp -d "${TMPDIR:-/tmp}/gpu_probe.XXXXXX") || exit 2
trap 'rm -rf "$WORK"' EXIT
exec > >(tee -a "$OUT/run.log") 2>&1
START=$(date +%s)
BUDGET=${PROBE_BUDGET_S:-240}
HARD=$((BUDGET + 60)) # no part runs past this many seconds
SIZES=${PROBE_SIZES:-"2:316 2:1000 2:3162 3:100"}
CMPS=${PROBE_CMP:-"2:1000 3:100"}
NT=${PROBE_THREADS:-$(nproc 2>/dev/null || echo 1)}
RES=$OUT/results.txt
CMP=$OUT/compare.txt
STATUS=$OUT/status.txt
: > "$RES"
: > "$CMP"
: > "$STATUS"

elapsed() { echo $(($(date +%s) - START)); }
note() { echo "[$(elapsed)s] $*"; }
status() { echo "$*" >> "$STATUS"; note "$*"; }

# part NAME TIMEOUT CMD...: runs CMD under timeout into raw/NAME.log; copies its RESULT lines,
# tagged, into results.txt; returns CMD's status (124: timed out, 125: skipped, out of budget).
part() {
    local name=$1 lim=$2 rc t0
    shift 2
    if [ "$(elapsed)" -ge "$BUDGET" ] || [ $((HARD - $(elapsed))) -lt 10 ]; then
        status "SKIP $name (budget of ${BUDGET}s spent)"
        return 125
    fi
    [ "$lim" -gt $((HARD - $(elapsed))) ] && lim=$((HARD - $(elapsed)))
    t0=$(date +%s)
    timeout -k 5 "$lim" "$@" > "$RAW/$name.log" 2>&1
    rc=$?
    grep '^RESULT' "$RAW/$name.log" | sed "s/^RESULT/RESULT tag=$name/" >> "$RES"
    if [ $rc -eq 0 ]; then
        note "ok   $name ($(($(date +%s) - t0))s)"
    else
        status "FAIL $name rc=$rc$([ $rc -eq 124 ] && echo ' (timeout)') ($(($(date +%s) - t0))s): $(tail -n 3 "$RAW/$name.log" | tr '\n' ' ' | cut -c1-300)"
    fi
    return $rc
}

# compare LABEL A B: the bitwise comparison of two dumps, into compare.txt.
compare() {
    local label=$1 a=$2 b=$3 line
    if [ ! -s "$a" ] || [ ! -s "$b" ]; then
        echo "COMPARE label=$label missing=$([ -s "$a" ] || echo "$(basename "$a")")$([ -s "$b" ] || echo ",$(basename "$b")")" >> "$CMP"
        return
    fi
    line=$(timeout 60 "${CPU_REF[@]}" compare "$a" "$b" 2>&1 | grep '^COMPARE ' | tail -1)
    echo "COMPARE label=$label ${line#COMPARE }" >> "$CMP"
    note "compare $label: ${line#COMPARE }"
}

echo "# GPU probe, $(date -u '+%Y-%m-%d %H:%M:%S UTC')"
note "host $(uname -n) $(uname -r), $(nproc) cores, $NT threads for the CPU runs"
{
    echo "== uname"; uname -a
    echo "== cpu"; (lscpu 2>/dev/null | grep -E 'Model name|^CPU\(s\)|Thread|Socket|MHz') || head -20 /proc/cpuinfo
    echo "== glibc"; ldd --version 2>&1 | head -1
    echo "== gcc"; gcc --version 2>&1 | head -1
    echo "== memory"; free -g 2>&1 | head -2
    echo "== nvidia-smi"
    timeout 15 nvidia-smi --query-gpu=name,driver_version,memory.total,clocks.max.sm,compute_cap --format=csv 2>&1
    timeout 15 nvidia-smi 2>&1
    echo "== libcuda"; (ldconfig -p 2>/dev/null | grep -E 'libcuda\.so') || echo "not in ldconfig"
} > "$RAW/environment.log" 2>&1
cat "$RAW/environment.log"

# ---- the driver's libcuda.so.1, for the offload plugin and the prebuilt CUDA probe
CUDALIB=""
for dir in $(ldconfig -p 2>/dev/null | awk '/libcuda\.so\.1 /{print $NF}' | xargs -r -n1 dirname) \
    /usr/lib/x86_64-linux-gnu /usr/lib64 /usr/local/nvidia/lib64 /usr/local/nvidia/lib \
    /usr/lib/wsl/lib /usr/local/cuda/compat; do
    if [ -e "$dir/libcuda.so.1" ]; then
        CUDALIB=$dir
        break
    fi
done
note "libcuda.so.1: ${CUDALIB:-not found}"

# ---- builds
FLAGS=(-std=c11 -O3 -fno-math-errno -fopenmp -Wall -Wextra -D_POSIX_C_SOURCE=199309L)
CPU_FMA=() CPU_NOFMA=() CPU_REF=()
for v in fast off; do
    name=$([ $v = fast ] && echo fma || echo nofma)
    ok=0
    for arch in -march=native ""; do
        if part "build_cpu_${name}${arch:+_native}" 120 gcc "${FLAGS[@]}" $arch -ffp-contract=$v \
            -o "$WORK/probe_cpu_$name" "$HERE/probe_cpu.c" -lm; then
            ok=1
            status "BUILD cpu_$name: gcc $arch -ffp-contract=$v"
            break
        fi
    done
    if [ $ok = 1 ]; then
        cmd=("$WORK/probe_cpu_$name")
    elif [ -x "$PRE/probe_cpu_$name" ]; then
        cmd=("$PRE/lib/glibc/ld-linux-x86-64.so.2" --library-path "$PRE/lib/gomp:$PRE/lib/glibc"
            "$PRE/probe_cpu_$name")
        status "BUILD cpu_$name: prebuilt (generic x86-64, no FMA instructions)"
    else
        cmd=()
        status "BUILD cpu_$name: none"
    fi
    if [ $v = fast ]; then CPU_FMA=("${cmd[@]}"); else CPU_NOFMA=("${cmd[@]}"); fi
done
CPU_REF=("${CPU_FMA[@]}")
[ ${#CPU_REF[@]} -eq 0 ] && CPU_REF=("${CPU_NOFMA[@]}")

NVCC=${NVCC:-}
if [ -z "$NVCC" ]; then
    NVCC=$(command -v nvcc 2>/dev/null)
    [ -z "$NVCC" ] && for f in /usr/local/cuda/bin/nvcc /usr/local/cuda-*/bin/nvcc /opt/cuda/bin/nvcc; do
        [ -x "$f" ] && NVCC=$f && break
    done
fi
CUDA_FMA=() CUDA_NOFMA=()
if [ -n "$NVCC" ] && [ "$NVCC" != none ] && [ -x "$NVCC" ]; then
    "$NVCC" --version > "$RAW/nvcc_version.log" 2>&1
    note "nvcc: $NVCC, $(tail -n 2 "$RAW/nvcc_version.log" | tr '\n' ' ')"
    for fm in true false; do
        name=$([ $fm = true ] && echo fma || echo nofma)
        for arch in "-arch=native" "-arch=sm_90" \
            "-gencode=arch=compute_90,code=sm_90 -gencode=arch=compute_90,code=compute_90" \
            "-arch=sm_90 -allow-unsupported-compiler" "-arch=sm_80"; do
            tag=$(echo "$arch" | tr -c 'A-Za-z0-9_\n' '_' | cut -c1-30)
            part "build_cuda_${name}_$tag" 180 "$NVCC" -O3 -fmad=$fm $arch \
                -o "$WORK/probe_cuda_$name" "$HERE/probe.cu" || continue
            # a build that runs: the smoke test finds a missing kernel image or driver
            if part "smoke_cuda_${name}_$tag" 60 "$WORK/probe_cuda_$name" --nx 40 --reps 1; then
                [ $fm = true ] && CUDA_FMA=("$WORK/probe_cuda_$name") || CUDA_NOFMA=("$WORK/probe_cuda_$name")
                status "BUILD cuda_$name: nvcc -O3 -fmad=$fm $arch"
                break
            fi
            # no device at all: the other architectures fail the same way
            grep -q 'no CUDA device' "$RAW/smoke_cuda_${name}_$tag.log" && break
        done
    done
else
    status "BUILD cuda: no nvcc found (NVCC=${NVCC:-unset})"
fi
for name in fma nofma; do
    var=CUDA_${name^^}[@]
    [ -n "${!var:-}" ] && continue
    [ -x "$PRE/probe_cuda_$name" ] || continue
    cmd=("$PRE/lib/glibc/ld-linux-x86-64.so.2" --library-path "$PRE/lib/glibc${CUDALIB:+:$CUDALIB}"
        "$PRE/probe_cuda_$name")
    if part "smoke_cuda_${name}_prebuilt" 60 "${cmd[@]}" --nx 40 --reps 1; then
        [ $name = fma ] && CUDA_FMA=("${cmd[@]}") || CUDA_NOFMA=("${cmd[@]}")
        status "BUILD cuda_$name: prebuilt ($(tr '\n' ' ' < "$PRE/nvcc_version.txt"))"
    fi
done
[ ${#CUDA_FMA[@]} -eq 0 ] && status "NO cuda_fma build runs: GPU CUDA parts skipped"

# The offload probe: on this machine's C library first, then on the carried one.
OMP_FMA=() OMP_NOFMA=()
for name in fma nofma; do
    bin=$PRE/probe_omp_$name
    if [ ! -x "$bin" ]; then
        status "NO prebuilt $bin (run bench/gpu/build_prebuilt.sh where gcc-12-offload-nvptx is)"
        continue
    fi
    for mode in system carried; do
        if [ $mode = system ]; then
            cmd=(env "LD_LIBRARY_PATH=$PRE/lib/gomp${CUDALIB:+:$CUDALIB}${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}" "$bin")
        else
            cmd=("$PRE/lib/glibc/ld-linux-x86-64.so.2" --library-path
                "$PRE/lib/gomp:$PRE/lib/glibc${CUDALIB:+:$CUDALIB}" "$bin")
        fi
        part "smoke_omp_${name}_$mode" 90 env OMP_TARGET_OFFLOAD=MANDATORY "${cmd[@]}" --nx 40 --reps 1
        if grep -q 'target_ran_on=device' "$RAW/smoke_omp_${name}_$mode.log"; then
            [ $name = fma ] && OMP_FMA=("${cmd[@]}") || OMP_NOFMA=("${cmd[@]}")
            status "BUILD omp_$name: prebuilt gcc-12 offload, $mode C library"
            break
        fi
        note "omp_$name ($mode libc) did not reach the device: $(grep -E 'OFFLOAD|error|rror' "$RAW/smoke_omp_${name}_$mode.log" | head -3 | tr '\n' ' ')"
    done
    if [ $name = fma ] && [ ${#OMP_FMA[@]} -eq 0 ]; then
        status "NO offload to the GPU (omp_fma); GOMP_DEBUG=1 log in raw/omp_debug.log"
        GOMP_DEBUG=1 LD_DEBUG=libs OMP_TARGET_OFFLOAD=MANDATORY timeout 60 "${cmd[@]}" --nx 20 \
            --reps 1 2>&1 | grep -vE 'trying file|search path|^ *[0-9]+: *$' | tail -n 200 \
            > "$RAW/omp_debug.log"
        grep -iE 'libcuda|plugin|error|cannot|GOMP|OFFLOAD' "$RAW/omp_debug.log" | tail -n 15
    fi
done

# ---- measurements: CUDA first (cheap), the compared sizes, all threads, serial, then offload
# (the least predictable) last
reps_gpu() { case $2 in 316) echo 5 ;; 3162) echo 2 ;; *) echo 3 ;; esac; }
reps_omp() { case $2 in 316) echo 3 ;; 3162) echo 1 ;; *) echo 2 ;; esac; }
dumpfor() { # NAME DIM NX: the dump option when DIM:NX is a compared size
    case " $CMPS " in *" $2:$3 "*) echo "--dump $WORK/$1.bin" ;; esac
}
for s in $SIZES; do
    d=${s%%:*} nx=${s##*:}
    if [ ${#CUDA_FMA[@]} -gt 0 ]; then
        part "cuda_fma_${d}d_$nx" 90 "${CUDA_FMA[@]}" --dim "$d" --nx "$nx" --reps "$(reps_gpu "$d" "$nx")" \
            $(dumpfor "cuda_fma_${d}d_$nx" "$d" "$nx")
    fi
done
for s in $CMPS; do
    d=${s%%:*} nx=${s##*:}
    [ ${#CUDA_FMA[@]} -gt 0 ] && part "cuda_fma_again_${d}d_$nx" 90 "${CUDA_FMA[@]}" --dim "$d" \
        --nx "$nx" --reps 1 --dump "$WORK/cuda_fma_again_${d}d_$nx.bin"
    [ ${#CUDA_NOFMA[@]} -gt 0 ] && part "cuda_nofma_${d}d_$nx" 90 "${CUDA_NOFMA[@]}" --dim "$d" \
        --nx "$nx" --reps 2 --dump "$WORK/cuda_nofma_${d}d_$nx.bin"
    [ ${#CPU_NOFMA[@]} -gt 0 ] && part "cpu_nofma_t${NT}_${d}d_$nx" 120 "${CPU_NOFMA[@]}" --dim "$d" \
        --nx "$nx" --reps 1 --threads "$NT" --dump "$WORK/cpu_nofma_t${NT}_${d}d_$nx.bin"
done
for s in $SIZES; do
    d=${s%%:*} nx=${s##*:}
    [ ${#CPU_FMA[@]} -gt 0 ] && part "cpu_fma_t${NT}_${d}d_$nx" 120 "${CPU_FMA[@]}" --dim "$d" --nx "$nx" \
        --reps 2 --threads "$NT" $(dumpfor "cpu_fma_t${NT}_${d}d_$nx" "$d" "$nx")
done
for s in $SIZES; do
    d=${s%%:*} nx=${s##*:}
    [ ${#CPU_FMA[@]} -gt 0 ] && part "cpu_fma_t1_${d}d_$nx" 150 "${CPU_FMA[@]}" --dim "$d" --nx "$nx" \
        --reps 1 --threads 1 $(dumpfor "cpu_fma_t1_${d}d_$nx" "$d" "$nx")
done
for s in $SIZES; do
    d=${s%%:*} nx=${s##*:}
    [ ${#OMP_FMA[@]} -gt 0 ] && part "omp_fma_${d}d_$nx" 60 "${OMP_FMA[@]}" --dim "$d" --nx "$nx" \
        --reps "$(reps_omp "$d" "$nx")" $(dumpfor "omp_fma_${d}d_$nx" "$d" "$nx")
done
for s in $CMPS; do
    d=${s%%:*} nx=${s##*:}
    [ ${#OMP_FMA[@]} -gt 0 ] && part "omp_fma_again_${d}d_$nx" 90 "${OMP_FMA[@]}" --dim "$d" \
        --nx "$nx" --reps 1 --dump "$WORK/omp_fma_again_${d}d_$nx.bin"
    [ ${#OMP_NOFMA[@]} -gt 0 ] && part "omp_nofma_${d}d_$nx" 90 "${OMP_NOFMA[@]}" --dim "$d" \
        --nx "$nx" --reps 1 --dump "$WORK/omp_nofma_${d}d_$nx.bin"
done

# ---- comparisons
if [ ${#CPU_REF[@]} -gt 0 ]; then
    for s in $CMPS; do
        d=${s%%:*} nx=${s##*:} z=${s%%:*}d_${s##*:}
        compare "cuda_run1_vs_run2_$z" "$WORK/cuda_fma_$z.bin" "$WORK/cuda_fma_again_$z.bin"
        compare "cuda_fma_vs_cpu_fma_$z" "$WORK/cuda_fma_$z.bin" "$WORK/cpu_fma_t${NT}_$z.bin"
        compare "cuda_nofma_vs_cpu_nofma_$z" "$WORK/cuda_nofma_$z.bin" "$WORK/cpu_nofma_t${NT}_$z.bin"
        compare "cuda_fma_vs_cuda_nofma_$z" "$WORK/cuda_fma_$z.bin" "$WORK/cuda_nofma_$z.bin"
        compare "omp_run1_vs_run2_$z" "$WORK/omp_fma_$z.bin" "$WORK/omp_fma_again_$z.bin"
        compare "omp_fma_vs_cpu_fma_$z" "$WORK/omp_fma_$z.bin" "$WORK/cpu_fma_t${NT}_$z.bin"
        compare "omp_nofma_vs_cpu_nofma_$z" "$WORK/omp_nofma_$z.bin" "$WORK/cpu_nofma_t${NT}_$z.bin"
        compare "cpu_t1_vs_t${NT}_$z" "$WORK/cpu_fma_t1_$z.bin" "$WORK/cpu_fma_t${NT}_$z.bin"
        compare "cpu_fma_vs_cpu_nofma_$z" "$WORK/cpu_fma_t${NT}_$z.bin" "$WORK/cpu_nofma_t${NT}_$z.bin"
    done
fi
grep -h '^CELLORDER FAIL' "$RAW"/*.log > /dev/null 2>&1 && status "CELLORDER FAIL in: $(grep -l '^CELLORDER FAIL' "$RAW"/*.log | xargs -n1 basename | tr '\n' ' ')"

# ---- the report
bash "$HERE/report.sh" "$OUT" "$NT" > "$OUT/gpu_probe.md"
note "wrote $OUT/gpu_probe.md ($(elapsed)s in all)"
cat "$OUT/gpu_probe.md"
exec >&- 2>&-
sleep 1 # let tee finish run.log
exit 0
