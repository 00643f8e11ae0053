#!/usr/bin/env bash
# Everything a lent GPU machine (one NVIDIA GPU, 16 cores, no build tools assumed) should
# measure, prepared here in one step and run there in one call, because a machine is lent for
# minutes and its start takes some of them:
#   bash bench/device_session.sh --prep
#       here: builds build-gpu/ with nvcc (bench/gpu.sh --build-only), keeps what the GPU runs
#       need in build-gpu-carry/ (consph, bench_gpu, test_gpu_emul, test_gpu_cuda, COMMIT: about
#       25 MB), and packs OpenMPI with an MPI build into mpi-carry/ (bench/mpi_carry.sh, about
#       14 MB); prints the device command and what it must carry.
#   bash bench/device_session.sh --run OUTDIR      (there, carrying build-gpu-carry and mpi-carry)
#       in order, each part with its share of BUDGET seconds (default 540), what is left going on:
#       1. bench/gpu.sh: the GPU tests and the µs-per-particle-step table (GPU_SHARE, default 45 %);
#       2. bench/gpu_study.sh: 001-table9's schemes on the GPU, extrapolated (STUDY_SHARE, 25 %);
#       3. bench/mpi_device.sh: 1-16 ranks, weak scaling at 10^5 per rank (the rest);
#       and leaves in OUTDIR at most 8 files: gpu.md, gpu_study.md, mpi.md, session.log, and
#       gpu.tar.gz, gpu_study.tar.gz, mpi.tar.gz (every log of each part).
# A part whose carried folder is missing is skipped and said so in session.log.
set -u
cd "$(dirname "$0")/.."
mode=${1:-}
case "$mode" in
--prep)
    BUILD=build-gpu bash bench/gpu.sh --build-only || exit 1
    rm -rf build-gpu-carry
    mkdir -p build-gpu-carry/bench build-gpu-carry/tests || exit 1
    cp build-gpu/consph build-gpu/COMMIT build-gpu-carry/ &&
        cp build-gpu/bench/bench_gpu build-gpu-carry/bench/ &&
        cp build-gpu/tests/test_gpu_emul build-gpu/tests/test_gpu_cuda build-gpu-carry/tests/ ||
        exit 1
    bash bench/mpi_carry.sh mpi-carry || exit 1
    echo "device_session: prepared build-gpu-carry ($(du -sh build-gpu-carry | cut -f1)) and" \
        "mpi-carry ($(du -sh mpi-carry | cut -f1)); on the device run (carry both):"
    echo "  bash bench/device_session.sh --run \"\$OUT\""
    ;;
--run)
    [ $# -ge 2 ] || { echo "bench/device_session.sh: --run needs an output folder" >&2; exit 2; }
    out=$2
    mkdir -p "$out" && out=$(cd "$out" && pwd) || exit 2
    budget=${BUDGET:-540}
    [[ "$budget" =~ ^[0-9]+$ ]] || { echo "bench/device_session.sh: BUDGET must be seconds" >&2; exit 2; }
    gpu_share=${GPU_SHARE:-45}
    study_share=${STUDY_SHARE:-25}
    start=$(date +%s)
    work=$(mktemp -d)
    log() { echo "[$(($(date +%s) - start)) s] $*" | tee -a "$out/session.log"; }
    : >"$out/session.log"
    log "device: $(nvidia-smi --query-gpu=name --format=csv,noheader 2>/dev/null | head -1), $(nproc) cores"
    left() { echo $((budget - ($(date +%s) - start))); }
    # part NAME LIMIT CMD...: CMD writes into $work/NAME under a time limit; its log joins that
    # folder, its report NAME.md is copied out and the folder packed as NAME.tar.gz
    part() {
        local name=$1 limit=$2
        shift 2
        timeout "$limit" "$@" >"$work/$name.log" 2>&1
        log "   exit $?"
        mkdir -p "$work/$name"
        mv "$work/$name.log" "$work/$name/"
        cp "$work/$name/$name.md" "$out/" 2>/dev/null
        tar -C "$work" -czf "$out/$name.tar.gz" "$name" 2>/dev/null
    }
    if [ -x build-gpu-carry/consph ]; then
        b=$((budget * gpu_share / 100))
        log "1. bench/gpu.sh, budget $b s"
        part gpu $((b + 120)) env BUILD=build-gpu-carry bash bench/gpu.sh --no-build \
            --budget "$b" --out "$work/gpu"
        b=$(($(left) * study_share * 100 / (100 - gpu_share) / 100))
        log "2. bench/gpu_study.sh, budget $b s"
        part gpu_study $((b + 120)) env BUILD=build-gpu-carry bash bench/gpu_study.sh \
            --no-build --budget "$b" --out "$work/gpu_study"
    else
        log "1-2. skipped: no build-gpu-carry (bash bench/device_session.sh --prep here, then carry it)"
    fi
    if [ -x mpi-carry/bin/consph ]; then
        b=$(($(left) - 20))
        if [ $b -gt 60 ]; then
            log "3. bench/mpi_device.sh, budget $b s"
            part mpi $((b + 60)) env BUDGET="$b" bash mpi-carry/scripts/bench/mpi_device.sh \
                "$work/mpi"
        else
            log "3. skipped: $b s left"
        fi
    else
        log "3. skipped: no mpi-carry (bash bench/device_session.sh --prep here, then carry it)"
    fi
    rm -rf "$work"
    log "done"
    ;;
*)
    echo "usage: bash bench/device_session.sh --prep | --run OUTDIR" >&2
    exit 2
    ;;
esac
