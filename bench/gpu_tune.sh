#!/usr/bin/env bash
# Where the GPU step's time goes, and the launch shape of its pair passes (docs/gpu.md), in one
# run of under two minutes on a machine with an NVIDIA GPU:
#   1. per register cap (nvcc -maxrregcount, CMake's CONSPH_CUDA_MAXRREG; 0: none) one bench_gpu,
#      built here with --build-only into build-gpu-tune/bin/bench_gpu-<TAG><cap> (MPI off, the
#      static CUDA runtime, sm_90 only: the binaries need only the C, C++, OpenMP and zlib
#      runtimes and the driver), with the registers and spills ptxas reported for each kernel
#      beside it; builds of other code (another TAG: TAG=n after a change) join the same folder,
#      so that one run there compares them;
#   2. there, with --no-build: each variant's bench_gpu on each case (edac and wcsph, 2D Taylor-Green
#      nx 1000 and 3D Beltrami nx 100: 10^6 particles) with --blocks (the pair passes' threads
#      per block, CONSPH_GPU_BLOCK_PAIR) and --stages: per block size a fresh GPU solver, its
#      state after one step against the CPU's (bit for bit expected), the step time, then every
#      stage's time per step between CUDA events;
#   3. writes DIR/tune.md (the stage table at the defaults, the sweep, ptxas's registers) and
#      keeps the raw lines in DIR/results.txt.
#
#   bash bench/gpu_tune.sh --build-only              # here (nvcc, no GPU needed)
#   bash bench/gpu_tune.sh --no-build --out DIR      # there, build-gpu-tune/bin carried
#   bash build-gpu-tune/bin/gpu_tune.sh --no-build --out DIR   # the same from any checkout
#   bash bench/gpu_tune.sh --emulate --quick --out DIR   # a check of the script without a GPU
#
# Options: --out DIR (default build-gpu-tune/out), --quick (2D nx 60, 3D nx 14), --emulate (the
# host emulation instead of the GPU: blocks and caps then change nothing), --budget S (no process
# starts after S seconds, default 100; each under timeout), --no-build, --build-only.
# Environment: NVCC (the compiler), TAG (the build's name, default r), CUDA_FLAGS (more nvcc
# flags for the build, e.g. -DCONSPH_GPU_PAIRS=2), CAPS (default
# "0 128 96 80 64"), VARIANTS (what runs, in order; default every binary there, cap by cap in
# the order of CAPS: the budget drops the last first), BLOCKS (default "64,128"),
# CASES (scheme:dim:nx, default "edac:2:1000 edac:3:100 wcsph:2:1000 wcsph:3:100"), THREADS
# (the CPU's threads for set-up and the reference step; default nproc), LAYOUT (bench_gpu's
# --layout: lattice for l-ipst-c, whose packed start takes minutes at 10^6).
set -u
# the script runs from bench/ or as the copy the build puts beside the binaries (carried with
# gpu_args.sh)
here=$(cd "$(dirname "$0")" && pwd)
if compgen -G "$here/bench_gpu-*" >/dev/null; then root=$(cd "$here/../.." && pwd); else root=$(cd "$here/.." && pwd); fi
cd "$root" || exit 1
budget=100
. "$here/gpu_args.sh"
gpu_args bench/gpu_tune.sh "$@"
bdir=build-gpu-tune
bin=$bdir/bin
caps=${CAPS:-"0 128 96 80 64"}
blocks=${BLOCKS:-"64,128"}
tag=${TAG:-r}
threads=${THREADS:-$(nproc)}
start=$(date +%s)
say() { echo "[$(($(date +%s) - start)) s] $*"; }

# ---- 1. the build: one build folder, the CUDA objects recompiled per cap, one binary each ----
if [ $build = 1 ]; then
    nvcc=${NVCC:-$(command -v nvcc || { [ -x /usr/local/cuda/bin/nvcc ] && echo /usr/local/cuda/bin/nvcc; })}
    [ -n "$nvcc" ] || { echo "bench/gpu_tune.sh: no nvcc (set NVCC)" >&2; exit 1; }
    mkdir -p "$bin"
    for cap in $caps; do
        [ "$cap" = 0 ] && c="" || c=$cap
        v=$tag$cap
        say "build $v: register cap ${c:-none}"
        if ! { cmake -S . -B "$bdir" -DCMAKE_BUILD_TYPE=Release -DCONSPH_MPI=OFF -DCONSPH_CUDA=ON \
            -DCMAKE_CUDA_COMPILER="$nvcc" -DCMAKE_CUDA_ARCHITECTURES=90 \
            -DCMAKE_CUDA_FLAGS="-Xptxas -v ${CUDA_FLAGS:-}" -DCONSPH_CUDA_MAXRREG="$c" &&
            touch src/gpu/cuda.cu && cmake --build "$bdir" -j "$(nproc)" --target bench_gpu; } \
            >"$bin/build-$v.log" 2>&1; then
            tail -20 "$bin/build-$v.log"
            say "build failed: $bin/build-$v.log"
            exit 1
        fi
        cp "$bdir/bench/bench_gpu" "$bin/bench_gpu-$v"
        # ptxas's lines for cuda.cu's kernels: kernel registers spill-store-bytes
        awk '/Compiling entry function/ { k = $0; sub(/.*_cuda_cu_[0-9a-f]+[0-9]+/, "", k);
                 sub(/E8gpu_view.*/, "", k); name = k ~ /^k_/ ? k : "" }
             /spill stores/ { sp = $5 }
             /Used [0-9]+ registers/ && name != "" { print name, $5, sp; name = "" }' \
            "$bin/build-$v.log" | sort -u >"$bin/ptxas-$v.txt"
    done
    cp bench/gpu_tune.sh bench/gpu_args.sh "$bin/"
    echo "$(git rev-parse --short HEAD)$([ -n "$(git status --porcelain -uno)" ] && echo ' (with uncommitted changes)')" >"$bin/BUILT_FROM-$tag"
    du -sh "$bin"
    say "built $bin (carry it: bash bench/gpu_tune.sh --no-build --out DIR there)"
    [ $build_only = 1 ] && exit 0
fi

# ---- 2. the sweep ----
out=${out:-$bdir/out}
mkdir -p "$out/raw" || exit 1
out=$(cd "$out" && pwd)
: >"$out/results.txt"
if [ $quick = 1 ]; then
    cases=${CASES:-"edac:2:60 edac:3:14 wcsph:2:60 wcsph:3:14"}
else
    cases=${CASES:-"edac:2:1000 edac:3:100 wcsph:2:1000 wcsph:3:100"}
fi
# the variants: VARIANTS, or every binary there, cap by cap in the order of CAPS, then any other
if [ -n "${VARIANTS:-}" ]; then
    variants=$VARIANTS
else
    variants=""
    for cap in $caps; do
        for f in "$bin"/bench_gpu-*"$cap"; do
            v=${f##*/bench_gpu-}
            [ -x "$f" ] && [ "${v%$cap}" != "$v" ] && [[ "${v%$cap}" =~ ^[a-z]+$ ]] && variants="$variants $v"
        done
    done
    for f in "$bin"/bench_gpu-*; do
        v=${f##*/bench_gpu-}
        [ -x "$f" ] && [[ " $variants " != *" $v "* ]] && variants="$variants $v"
    done
fi
say "variants:$variants"
emu=()
[ $emulate = 1 ] && emu=(--emulate)
for v in $variants; do
    exe=$bin/bench_gpu-$v
    [ -x "$exe" ] || { say "no $exe: skipped (build with --build-only)"; continue; }
    vtag=${v%%[0-9]*}
    vcap=${v#$vtag}
    for c in $cases; do
        IFS=: read -r scheme dim nx <<<"$c"
        [ "$dim" = 2 ] && problem=taylor-green || problem=beltrami
        # GPU steps to a tenth of a second or so, the stages over half as many
        [ "$dim" = 2 ] && { g=20 k=10; } || { g=10 k=5; }
        [ $quick = 1 ] && { g=2 k=1; }
        elapsed=$(($(date +%s) - start))
        if [ $elapsed -ge "$budget" ]; then
            say "$v $scheme ${dim}D nx $nx: skipped (budget of $budget s spent)"
            echo "variant=$v tag=$vtag cap=$vcap scheme=$scheme dim=$dim nx=$nx skipped=budget" >>"$out/results.txt"
            continue
        fi
        left=$((budget - elapsed + 15))
        [ $left -gt 30 ] && left=30
        timeout "$left" "$exe" --scheme "$scheme" --problem "$problem" --nx "$nx" \
            --gpu-steps $g --stages $k --cpu-steps 0 --serial-steps 0 --blocks "$blocks" \
            --threads-max "$threads" --setup-threads "$threads" "${emu[@]}" ${LAYOUT:+--layout "$LAYOUT"} \
            >"$out/raw/${v}_${scheme}_${dim}d.txt" 2>"$out/raw/${v}_${scheme}_${dim}d.err"
        rc=$?
        sed "s/^/variant=$v tag=$vtag cap=$vcap /; s/\$/ nx=$nx rc=$rc/" \
            "$out/raw/${v}_${scheme}_${dim}d.txt" >>"$out/results.txt"
        say "$v $scheme ${dim}D nx $nx: exit $rc"
    done
done
cp "$bin"/ptxas-*.txt "$out/raw/" 2>/dev/null

# ---- 3. the report ----
gpu_name=$(nvidia-smi --query-gpu=name,driver_version --format=csv,noheader 2>/dev/null | head -1)
built=$(for f in "$bin"/BUILT_FROM-*; do [ -f "$f" ] && printf ' %s: consph %s;' "${f##*-}" "$(cat "$f")"; done)
{
    echo "# GPU step: stages and launch shape (bench/gpu_tune.sh)"
    echo
    echo "Run $(date -u '+%Y-%m-%d %H:%M UTC'), GPU: ${gpu_name:-none found}$([ $emulate = 1 ] && echo ', the host emulation (--emulate)')."
    echo "Variant = the code's tag (built from:$built) and the register cap (nvcc -maxrregcount,"
    echo "0: none); block: threads per block of the density and rate passes (CONSPH_GPU_BLOCK_PAIR;"
    echo "every other kernel 256). Times in ms per step; stages between CUDA events around each"
    echo "launch (wall: the same steps' wall time). Step 1: every particle array after one step"
    echo "against the CPU's (0 differing: bit for bit)."
    echo
    echo "## Stages without a cap, block 128, ms per step"
    echo
    awk '
    function v(k,   i, a) { for (i = 1; i <= NF; ++i) { split($i, a, "="); if (a[1] == k) return a[2] } return "" }
    v("cap") == 0 && v("block") == 128 && v("stage_steps") != "" {
        c = v("variant") " " v("scheme") " " v("dim") "D"; cols[++nc] = c
        for (i = 1; i <= NF; ++i) { split($i, a, "=")
            if (a[1] ~ /^stage_.*_ms$/) { s = a[1]; sub(/^stage_/, "", s); sub(/_ms$/, "", s)
                if (!(s in seen)) { seen[s] = 1; rows[++nr] = s } t[s, c] = a[2] } }
    }
    END {
        if (!nc) { print "(no run without a cap at block 128)"; exit }
        printf "| stage |"; for (j = 1; j <= nc; ++j) printf " %s |", cols[j]; print ""
        printf "|---|"; for (j = 1; j <= nc; ++j) printf "---|"; print ""
        for (i = 1; i <= nr; ++i) { printf "| %s |", rows[i]
            for (j = 1; j <= nc; ++j) printf " %s |", ((rows[i], cols[j]) in t) ? sprintf("%.4g", t[rows[i], cols[j]]) : "-"; print "" }
    }' "$out/results.txt"
    echo
    echo "## Sweep: variant x block size"
    echo
    echo "| case | variant | block | step ms | density ms | rates ms | rest ms | pairs/s | step 1 differing / values |"
    echo "|---|---|---|---|---|---|---|---|---|"
    awk '
    function v(k,   i, a) { for (i = 1; i <= NF; ++i) { split($i, a, "="); if (a[1] == k) return a[2] } return "" }
    {
        c = v("scheme") " " v("dim") "D"
        if (v("skipped") != "") { printf "| %s nx %s | %s | | skipped (%s) ||||||\n", c, v("nx"), v("variant"), v("skipped"); next }
        if (v("gpu_step_s") == "") { printf "| %s | %s | %s | failed (exit %s) ||||||\n", c, v("variant"), v("block"), v("rc"); next }
        d = v("stage_density_ms"); r = v("stage_rates_ms"); s = v("stage_sum_ms")
        printf "| %s | %s | %s | %.4g | %s | %s | %s | %.3g | %s / %s |\n", c, v("variant"), v("block"),
            1e3 * v("gpu_step_s"), d == "" ? "-" : sprintf("%.4g", d), r == "" ? "-" : sprintf("%.4g", r),
            s == "" ? "-" : sprintf("%.4g", s - d - r), v("gpu_pairs_per_s"), v("step1_differing"), v("step1_values")
        t = 1e3 * v("gpu_step_s")
        if (!(c in best) || t < best[c]) { best[c] = t; at[c] = v("variant") ", block " v("block") }
        if (first == "") first = v("variant")
        if (!(c in base) && v("variant") == first && v("block") == 128) { base[c] = t; bat[c] = v("variant") ", block 128" }
        if (!(c in seen)) { seen[c] = 1; order[++nc] = c }
    }
    END {
        if (nc) print "\nFastest step per case, against the first variant at block 128:\n"
        for (i = 1; i <= nc; ++i) { c = order[i]
            printf "- %s: %.4g ms at %s", c, best[c], at[c]
            if (c in base) printf " (%s: %.4g ms, x%.3g)", bat[c], base[c], base[c] / best[c]
            print "" }
    }' "$out/results.txt"
    echo
    echo "## ptxas: registers / spill-store bytes per thread of the pair kernels"
    echo
    echo "| kernel |$(for v in $variants; do printf ' %s |' "$v"; done)"
    echo "|---|$(for v in $variants; do printf -- '---|'; done)"
    for k in k_density k_density2 k_density3 k_wprep k_rates2 k_rates2g k_rates3 k_rates3g k_wrates2 k_wrates2g k_wrates3 k_wrates3g; do
        printf '| %s |' "$k"
        for v in $variants; do
            f=$bin/ptxas-$v.txt
            x=$([ -f "$f" ] && awk -v k="$k" '$1 == k { print $2 " / " $3 }' "$f")
            printf ' %s |' "${x:--}"
        done
        echo
    done
    echo
    echo "Raw: results.txt (bench_gpu's lines, variant= first), raw/*.err, raw/ptxas-*.txt."
} >"$out/tune.md"
say "wrote $out/tune.md"
cat "$out/tune.md"
grep -q "rc=[1-9]" "$out/results.txt" && exit 1
exit 0
