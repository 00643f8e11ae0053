#!/usr/bin/env bash
# The GPU solver on a machine with an NVIDIA GPU, in one run of a few minutes (docs/gpu.md):
#   1. builds consph with nvcc (CONSPH_CUDA, -fmad=false) in build-gpu/;
#   2. runs the GPU tests (ctest -L gpu: the emulation and the CUDA backend against the CPU
#      solver bit for bit, two GPU runs bit for bit, the CLI's --device gpu);
#   3. edac and l-ipst-c (SCHEMES) at 10^5, 10^6, 10^7 particles (2D Taylor-Green) and 10^6 (3D
#      Beltrami; l-ipst-c from the lattice, LIPSTC_LAYOUT, not its packed start) with
#      bench_gpu: µs per particle-step and pairs/s on the GPU, on all cores and on one core, GPU
#      memory per particle, the GPU's state after one step against the CPU's;
#   4. writes the tables to gpu.md (and the raw lines, logs) in the output folder, and (not with
#      --quick or --emulate) to bench/gpu.md.
# Without nvcc or a GPU it runs what it can (the CPU columns) and says what it skipped.
#
# Where the GPU machine cannot build (no cmake, no zlib headers), build here and carry build-gpu:
#   bash bench/gpu.sh --build-only        # here, with nvcc: build-gpu/ (no MPI, static CUDA runtime)
#   bash bench/gpu.sh --no-build --out "$OUT"   # there, build-gpu carried
# With neither flag the script builds, and falls back to a carried build-gpu when the build fails.
# A build writes build-gpu/COMMIT (the commit it was made from, "+changes" when the tree had
# uncommitted edits); carry it with the binaries, since the report names that commit.
#
# Usage: bash bench/gpu.sh [--out DIR] [--quick] [--emulate] [--budget SECONDS] [--no-build]
#                          [--build-only]
#   --out DIR     where gpu.md, results.txt and the logs go (default: build-gpu/gpu-out)
#   --quick       small sizes (a check of the script: 2D nx 40 and 60, 3D nx 12)
#   --emulate     the GPU columns from the host emulation (no GPU needed; slow: small sizes)
#   --budget S    no case starts after S seconds (default 330); each case runs under timeout
#   --no-build    use build-gpu/ as it is
#   --build-only  build build-gpu/ and stop
# Environment: NVCC (the compiler; "none": build without CUDA), CUDA_ARCHS (the GPU
# architectures, CMake's list; default: 90 with --build-only, for the lent H100/H200, else the
# project's 80;90), BUILD (default build-gpu),
# CASES (a list of dim:nx, default "2:316 2:1000 3:100 2:3162"), SCHEMES (default "edac l-ipst-c";
# the GPU runs edac, wcsph, 001-table9's schemes and the δ family; the pair columns count
# l-ipst-c's and the δ family's passes, not the other 001 schemes'), LIPSTC_LAYOUT (l-ipst-c's and
# the δ family's start: "lattice", the
# default, or "scheme": its packed start, which takes minutes to pack at 10^6 particles and
# more), THREADS (default: nproc).
set -u
cd "$(dirname "$0")/.."
root=$(pwd)
budget=330
. "$root/bench/gpu_args.sh"
gpu_args bench/gpu.sh "$@"
bdir=${BUILD:-build-gpu}
out=${out:-$bdir/gpu-out}
mkdir -p "$out/raw" || exit 1
out=$(cd "$out" && pwd)
threads=${THREADS:-$(nproc)}
start=$(date +%s)
log() { echo "[$(($(date +%s) - start)) s] $*" | tee -a "$out/run.log"; }
: >"$out/run.log"
: >"$out/results.txt"

# ---- 1. the build ----
nvcc=${NVCC:-$(command -v nvcc || { [ -x /usr/local/cuda/bin/nvcc ] && echo /usr/local/cuda/bin/nvcc; })}
[ -n "$nvcc" ] || nvcc=none
have_build() { [ -x "$bdir/consph" ] && [ -x "$bdir/bench/bench_gpu" ] && [ -x "$bdir/tests/test_gpu_cuda" ]; }
if [ $build = 1 ]; then
    if [ "$nvcc" = none ]; then
        log "build: no nvcc, building without CUDA"
        cuda=(-DCONSPH_CUDA=OFF)
    else
        log "build: $nvcc"
        cuda=(-DCONSPH_CUDA=ON -DCMAKE_CUDA_COMPILER="$nvcc")
        # a build carried to the lent machine (an H100 or H200) needs sm_90's code alone: about
        # a fifth smaller (consph 8.3 -> 6.5 MB), and the carry has a limit of 64 MiB
        archs=${CUDA_ARCHS:-}
        [ -z "$archs" ] && [ $build_only = 1 ] && archs=90
        [ -n "$archs" ] && cuda+=(-DCMAKE_CUDA_ARCHITECTURES="$archs")
    fi
    # no MPI: a build carried to another machine then needs only the C, OpenMP and zlib
    # runtimes and the GPU driver there
    if ! { cmake -S . -B "$bdir" -DCMAKE_BUILD_TYPE=Release -DCONSPH_MPI=OFF "${cuda[@]}" &&
        cmake --build "$bdir" -j "$threads" --target consph bench_gpu test_gpu_emul test_gpu_cuda; } \
        >"$out/build.log" 2>&1; then
        tail -20 "$out/build.log"
        if have_build && [ $build_only = 0 ]; then
            log "build failed ($out/build.log): using the build-gpu that is there (carried?)"
        else
            log "build failed: $out/build.log"
            exit 1
        fi
    else
        # the report names the commit the binaries were built from, which a carried build
        # keeps beside them, not the commit of the checkout the script later runs in
        { git -C "$root" rev-parse --short HEAD 2>/dev/null || echo '?'; } |
            tr -d '\n' >"$bdir/COMMIT"
        git -C "$root" diff --quiet HEAD 2>/dev/null || printf '+changes' >>"$bdir/COMMIT"
    fi
fi
if [ $build_only = 1 ]; then
    log "built $bdir (carry it: bash bench/gpu.sh --no-build there)"
    exit 0
fi
have_build || { log "no build in $bdir (consph, bench/bench_gpu, tests/test_gpu_cuda)"; exit 1; }
"$bdir/consph" run taylor-green --scheme edac --nx 8 --steps 1 --device gpu 2>&1 |
    grep -q "without GPU support" && cuda_built=no || cuda_built=yes
log "build done (CUDA: $cuda_built)"

# ---- 2. the GPU tests (ctest -L gpu's, run directly: a carried build's CTest files name the
# paths of the machine that built it) ----
ctest_rc=0
tests_line=""
: >"$out/ctest.log"
for t in "$bdir/tests/test_gpu_emul" "$bdir/tests/test_gpu_cuda" \
    "bash tests/cli_gpu.sh $bdir/consph $root"; do
    name=$(basename "${t%% *}")
    [ "$name" = bash ] && name=cli_gpu
    echo "== $name" >>"$out/ctest.log"
    OMP_NUM_THREADS=4 timeout 240 $t >>"$out/ctest.log" 2>&1
    rc=$?
    case $rc in
    0) r=passed ;;
    77) r=skipped ;;
    *) r="FAILED ($rc)"; ctest_rc=1 ;;
    esac
    tests_line="$tests_line $name $r;"
done
log "GPU tests:$tests_line"

# ---- 3. the cases ----
if [ $quick = 1 ]; then
    cases=${CASES:-"2:40 2:60 3:12"}
else
    cases=${CASES:-"2:316 2:1000 3:100 2:3162"}  # the largest last: the budget cuts it first
fi
emu=()
[ $emulate = 1 ] && emu=(--emulate)
# each size for every scheme before the next size: the budget cuts the largest first
for c in $cases; do
for scheme in ${SCHEMES:-edac l-ipst-c}; do
    dim=${c%%:*}
    nx=${c##*:}
    [ "$dim" = 2 ] && problem=taylor-green || problem=beltrami
    n=$((dim == 2 ? nx * nx : nx * nx * nx))
    # steps by size: the GPU's to a tenth of a second or more, the CPU's to a few seconds
    if [ $n -le 200000 ]; then g=50 k=5 s=2; elif [ $n -le 2000000 ]; then g=20 k=3 s=1; else g=10 k=1 s=1; fi
    [ $quick = 1 ] && { g=3 k=2 s=1; }
    elapsed=$(($(date +%s) - start))
    if [ $elapsed -ge "$budget" ]; then
        log "case $scheme $problem nx $nx: skipped (budget of $budget s spent)"
        echo "scheme=$scheme problem=$problem dim=$dim nx=$nx skipped=budget" >>"$out/results.txt"
        continue
    fi
    left=$((budget - elapsed + 60))
    layout=scheme
    # the δ family's packed start packs as long as l-ipst-c's: the lattice too
    case $scheme in l-ipst-c | delta-*) layout=${LIPSTC_LAYOUT:-lattice} ;; esac
    log "case $scheme $problem nx $nx ($n particles, $layout start): gpu $g steps, $threads threads $k, serial $s (timeout $left s)"
    line=$(timeout "$left" "$bdir/bench/bench_gpu" --scheme "$scheme" --problem "$problem" --nx "$nx" --gpu-steps $g \
        --cpu-steps $k --serial-steps $s --threads-max "$threads" --setup-threads "$threads" \
        --layout "$layout" "${emu[@]}" 2>"$out/raw/case_${scheme}_${dim}d_$nx.err")
    rc=$?
    echo "$line nx=$nx rc=$rc" >>"$out/results.txt"
    log "  exit $rc: $line"
done
done

# ---- 4. the report ----
gpu_name=$(nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv,noheader 2>/dev/null | head -1)
cpu_name=$(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //')
nvcc_ver=$([ "$nvcc" != none ] && "$nvcc" --version 2>/dev/null | tail -2 | head -1)
if [ -s "$bdir/COMMIT" ]; then
    commit="$(head -c 64 "$bdir/COMMIT" | tr -cd '0-9a-z+') (the build's)"
else
    commit="$(git -C "$root" rev-parse --short HEAD 2>/dev/null) (the checkout's; the build kept none)"
fi
{
    echo "# GPU solver (bench/gpu.sh)"
    echo
    echo "Run $(date -u '+%Y-%m-%d %H:%M UTC') on $(hostname), consph ${commit:-?}."
    echo
    echo '```'
    echo "GPU:   ${gpu_name:-none found}"
    echo "CPU:   $cpu_name, $(nproc) cores; all-core columns on $threads threads"
    echo "nvcc:  ${nvcc_ver:-none} (CUDA built: $cuda_built)"
    echo "tests (ctest -L gpu):$tests_line"
    [ $emulate = 1 ] && echo "GPU columns: the host emulation (--emulate), not a GPU"
    why=$(grep -m1 -o 'gpu_why="[^"]*"' "$out/results.txt" | cut -d'"' -f2)
    [ -n "$why" ] && echo "GPU columns: none, $why"
    echo '```'
    echo
    echo "Quintic kernel, h = 1.2 Δs; 2D: Taylor-Green, 3D: Beltrami. edac, wcsph: pec; a step is the"
    echo "re-sort, two half-steps of the integrator, the cell lists, the density and rate passes."
    echo "l-ipst-c: rk2 (two evaluations of the volumes, the kit's first pass and coupled_bc's"
    echo "Laplacian, then the rates) and IPST after step 1 and every 10 steps (to eq. 21 or ten"
    echo "shifts); it starts from the lattice (marked so), not its packed layout, which takes"
    echo "minutes to pack at these sizes: a speed measurement, the flow's accuracy aside."
    echo "pairs/particle: neighbours per particle and pass, i itself included; pairs/s: the pair"
    echo "evaluations of one step (every pass: edac two, wcsph one, l-ipst-c six, IPST's not"
    echo "counted though its time is) over its time."
    echo "GPU step time: steps to the copy back that ends them, less that copy. x serial / x all:"
    echo "the serial and all-core CPU step time over the GPU's. B/particle: the device memory the"
    echo "GPU state holds (two copies of every particle array, for the re-sort, plus the cell"
    echo "lists). Step 1: every particle array after one step, GPU against CPU."
    echo
    echo "| scheme | dim | N | pairs/particle | GPU µs/particle-step | GPU pairs/s | all-core µs/p-s | serial µs/p-s | x serial | x all | B/particle | step 1: differing / values | step 1: max rel |"
    echo "|---|---|---|---|---|---|---|---|---|---|---|---|---|"
    awk '
    function v(k,   i, a) { for (i = 1; i <= NF; ++i) { split($i, a, "="); if (a[1] == k) return a[2] } return "" }
    function f(x, fmt) { return x == "" ? "-" : sprintf(fmt, x) }
    {
        if (v("skipped") != "") { printf "| %s | %s | nx %s | skipped (%s) |||||||||| \n", v("scheme"), v("dim"), v("nx"), v("skipped"); next }
        g = v("gpu_us_per_particle_step"); c = v("cpu_us_per_particle_step"); s = v("serial_us_per_particle_step")
        xs = (g != "" && s != "" && g > 0) ? sprintf("%.3g", s / g) : "-"
        xa = (g != "" && c != "" && g > 0) ? sprintf("%.3g", c / g) : "-"
        d1 = v("step1_differing") == "" ? "-" : v("step1_differing") " / " v("step1_values")
        sc = v("scheme"); if (v("layout") == "lattice") sc = sc " (lattice)"
        printf "| %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s |\n", sc, v("dim"), v("n"),
            f(v("pairs_per_particle"), "%.1f"), f(g, "%.4g"), f(v("gpu_pairs_per_s"), "%.3g"),
            f(c, "%.4g"), f(s, "%.4g"), xs, xa, f(v("gpu_bytes_per_particle"), "%.0f"), d1,
            f(v("step1_maxrel"), "%.1e")
        if (v("rc") != 0) bad = bad " " v("scheme") " " v("dim") "D nx " v("nx") " (exit " v("rc") ")"
    }
    END { if (bad != "") print "\nFailed cases:" bad " (raw/*.err)" }' "$out/results.txt"
    echo
    echo "Raw: results.txt (bench_gpu's lines), run.log, build.log, ctest.log (the tests' output), raw/*.err."
} >"$out/gpu.md"
# bench/gpu.md holds a full run's tables on a GPU only (not --quick's, not the emulation's, not a
# run whose cases found no device: that would replace the record with empty GPU columns)
if [ $quick = 0 ] && [ $emulate = 0 ] && [ "$out" != "$root/bench" ]; then
    if grep -q 'backend="CUDA"' "$out/results.txt"; then
        cp "$out/gpu.md" "$root/bench/gpu.md"
    else
        log "no case ran on a GPU: bench/gpu.md left as it was"
    fi
fi
log "wrote $out/gpu.md"
cat "$out/gpu.md"
exit $ctest_rc
