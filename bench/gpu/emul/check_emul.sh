#!/usr/bin/env bash
# Runs probe.cu's kernels and launches serially on the host (cuda_emul.h; no GPU, no nvcc) and
# compares its dumps with probe_cpu's: they must be bitwise equal (no FMA on either side).
#   usage: bash bench/gpu/emul/check_emul.sh [WORKDIR]
set -euo pipefail
HERE=$(cd "$(dirname "$0")" && pwd)
W=${1:-$(mktemp -d)}
mkdir -p "$W"
sed -E -e 's|#include <cuda_runtime.h>|#include "cuda_emul.h"|' \
    -e 's/([A-Za-z_0-9]+)<<<([^,]+), ([^>]+)>>>\(/EMUL_LAUNCH(\1, \2, \3, /' \
    "$HERE/../probe.cu" > "$W/probe_emul.cc"
g++ -std=c++14 -O2 -ffp-contract=off -Wall -Wextra -Werror -Wno-unused-function \
    -I"$HERE" -I"$HERE/.." -o "$W/probe_emul" "$W/probe_emul.cc"
gcc -std=c11 -O2 -ffp-contract=off -fno-math-errno -fopenmp -D_POSIX_C_SOURCE=199309L \
    -o "$W/probe_cpu" "$HERE/../probe_cpu.c" -lm
fail=0
for s in 2:37 2:120 3:15 3:24; do
    d=${s%%:*} nx=${s##*:}
    "$W/probe_emul" --dim "$d" --nx "$nx" --reps 1 --dump "$W/e.bin" | grep -E 'CELLORDER'
    "$W/probe_cpu" --dim "$d" --nx "$nx" --reps 1 --dump "$W/c.bin" > /dev/null
    line=$("$W/probe_cpu" compare "$W/e.bin" "$W/c.bin" | tail -1)
    echo "dim $d nx $nx: $line"
    case $line in *"ndiff_a=0 "*"ndiff_b=0 "*) ;; *) fail=1 ;; esac
done
[ $fail = 0 ] && echo "emulated CUDA probe equals probe_cpu bitwise" || echo "MISMATCH"
exit $fail
