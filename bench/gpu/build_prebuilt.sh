#!/usr/bin/env bash
# Builds bench/gpu/prebuilt/ on this (Debian 12) machine for run_probe.sh on a GPU machine that
# has nvcc but no offload compiler: the OpenMP offload probe (gcc-12-offload-nvptx), fallback
# builds of probe_cpu and probe.cu, and the shared objects they load, so that they run there
# either on its own C library (lib/gomp on LD_LIBRARY_PATH) or on ours (lib/glibc's loader).
# Needs: apt-get install -y gcc-12-offload-nvptx libgomp-plugin-nvptx1; nvcc optional.
set -euo pipefail
HERE=$(cd "$(dirname "$0")" && pwd)
PRE=$HERE/prebuilt
rm -rf "$PRE"
mkdir -p "$PRE/lib/gomp" "$PRE/lib/glibc"
cd "$HERE"
CFLAGS=(-std=c11 -O3 -fno-math-errno -fopenmp -Wall -Wextra -Werror -D_POSIX_C_SOURCE=199309L)
for v in fast off; do
    name=$([ $v = fast ] && echo fma || echo nofma)
    # -misa=sm_80: CUDA 13's ptxas, which nvptx-as calls to check the PTX, no longer knows
    # gcc 12's default sm_35; the driver compiles this PTX for the H100's sm_90 at load time.
    gcc "${CFLAGS[@]}" -ffp-contract=$v -foffload=nvptx-none \
        -foffload-options=nvptx-none="-misa=sm_80 -lm -ffp-contract=$v" -fcf-protection=none \
        -no-pie -o "$PRE/probe_omp_$name" probe_omp.c -lm
    # generic x86-64 has no FMA instruction: fma and nofma host builds compute alike here
    gcc "${CFLAGS[@]}" -ffp-contract=$v -o "$PRE/probe_cpu_$name" probe_cpu.c -lm
done
NVCC=${NVCC:-$(command -v nvcc || echo /usr/local/cuda/bin/nvcc)}
if [ -x "$NVCC" ]; then
    "$NVCC" --version | tail -2 > "$PRE/nvcc_version.txt"
    for fm in true false; do
        name=$([ $fm = true ] && echo fma || echo nofma)
        "$NVCC" -O3 -fmad=$fm -gencode arch=compute_90,code=sm_90 \
            -gencode arch=compute_90,code=compute_90 -o "$PRE/probe_cuda_$name" probe.cu
    done
else
    echo "no nvcc here: no prebuilt probe_cuda" >&2
fi
# what the binaries and the offload plugin load (libcuda.so.1 comes from the GPU machine's driver)
plugin=$(gcc -print-file-name=libgomp-plugin-nvptx.so.1)
[ -f "$plugin" ] || plugin=/usr/lib/x86_64-linux-gnu/libgomp-plugin-nvptx.so.1
cp -L "$(gcc -print-file-name=libgomp.so.1)" "$plugin" "$PRE/lib/gomp/"
for f in "$PRE"/probe_* "$plugin" "$PRE/lib/gomp/libgomp.so.1"; do ldd "$f" 2>/dev/null; done |
    awk '$3 ~ /^\// {print $3} $1 ~ /^\/.*ld-linux/ {print $1}' | sort -u |
    while read -r so; do
        case $(basename "$so") in libgomp*) ;; *) cp -L "$so" "$PRE/lib/glibc/" ;; esac
    done
# libcuda.so.1 of the driver needs these, which glibc 2.34+ keeps as stubs
for so in libdl.so.2 libpthread.so.0 librt.so.1; do
    cp -L "/lib/x86_64-linux-gnu/$so" "$PRE/lib/glibc/"
done
ldd --version | head -1 > "$PRE/glibc_version.txt"
gcc --version | head -1 > "$PRE/gcc_version.txt"
du -sh "$PRE"
ls -la "$PRE" "$PRE/lib/gomp" "$PRE/lib/glibc"
