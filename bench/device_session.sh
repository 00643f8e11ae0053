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
#       1. bench/gpu.sh: the GPU tests and the µs-per-particle-step table (GPU_SHARE, default 40 %);
#       2. bench/gpu_study.sh: 001-table9's schemes on the GPU, extrapolated (STUDY_SHARE, 20 %);
#       3. bench/gpu_probe.sh: the stages at 001-table9's small resolutions and what a log
#          sample costs at 250 000 particles, with and without the samples beside the steps,
#          and the small rows on 1-8 threads (about two minutes, PROBE_LIMIT s, default 150);
#       4. bench/mpi_device.sh: the machine's ceiling, then 1-16 ranks, weak scaling at 10^5 per
#          rank (the rest; each case up to MPI_CASE_TIMEOUT s, default 120: the 16-rank case's
#          set-up of 1.6·10^6 particles did not fit 40);
#       and leaves in OUTDIR 8 files: gpu.md, gpu_study.md, probe.txt, mpi.md, session.log, and
#       gpu.tar.gz, gpu_study.tar.gz, mpi.tar.gz (every log of each part).
#       PARTS (default "gpu study probe mpi") runs some of them: a session's 15 device minutes
#       hold two calls, e.g. PARTS="gpu study probe" BUDGET=400, then PARTS=mpi BUDGET=300 (the
#       whole weak series to 16 ranks at 10^5 per rank takes about 4 minutes).
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
    strip build-gpu-carry/consph build-gpu-carry/bench/bench_gpu build-gpu-carry/tests/* 2>/dev/null
    bash bench/mpi_carry.sh mpi-carry || exit 1
    echo "device_session: prepared build-gpu-carry ($(du -sh build-gpu-carry | cut -f1)) and" \
        "mpi-carry ($(du -sh mpi-carry | cut -f1)); on the device run (carry both):"
    echo "  bash bench/device_session.sh --run \"\$OUT\""
    ;;
--run)
    [ $# -ge 2 ] || { echo "bench/device_session.sh: --run needs an output folder" >&2; exit 2; }
    out=$2
    parts=" ${PARTS:-gpu study probe mpi} "
    for p in $parts; do
        case $p in gpu | study | probe | mpi) ;;
        *) echo "bench/device_session.sh: PARTS has '$p' (allowed: gpu study probe mpi)" >&2; exit 2 ;;
        esac
    done
    for v in PROBE_LIMIT MPI_CASE_TIMEOUT GPU_SHARE STUDY_SHARE; do
        [[ "${!v:-1}" =~ ^[0-9]+$ ]] || { echo "bench/device_session.sh: $v must be a whole number" >&2; exit 2; }
    done
    budget=${BUDGET:-540}
    [[ "$budget" =~ ^[0-9]+$ ]] || { echo "bench/device_session.sh: BUDGET must be seconds" >&2; exit 2; }
    mkdir -p "$out" && out=$(cd "$out" && pwd) || exit 2
    gpu_share=${GPU_SHARE:-40}
    study_share=${STUDY_SHARE:-20}
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
        # a part left out leaves its share to the others
        [[ $parts == *" gpu "* ]] || gpu_share=0
        [[ $parts == *" study "* ]] || study_share=0
        if [ $gpu_share -gt 0 ]; then
            b=$((budget * gpu_share / 100))
            log "1. bench/gpu.sh, budget $b s"
            part gpu $((b + 120)) env BUILD=build-gpu-carry bash bench/gpu.sh --no-build \
                --budget "$b" --out "$work/gpu"
        fi
        if [ $study_share -gt 0 ]; then
            b=$(($(left) * study_share * 100 / (100 - gpu_share) / 100))
            log "2. bench/gpu_study.sh, budget $b s"
            part gpu_study $((b + 120)) env BUILD=build-gpu-carry bash bench/gpu_study.sh \
                --no-build --budget "$b" --out "$work/gpu_study"
        fi
        if [[ $parts == *" probe "* ]]; then
            log "3. bench/gpu_probe.sh"
            timeout "${PROBE_LIMIT:-150}" bash bench/gpu_probe.sh "$out" build-gpu-carry >/dev/null 2>&1
            log "   exit $?"
        fi
    else
        log "1-3. skipped: no build-gpu-carry (bash bench/device_session.sh --prep here, then carry it)"
    fi
    if [[ $parts != *" mpi "* ]]; then
        :
    elif [ -x mpi-carry/bin/consph ]; then
        b=$(($(left) - 20))
        if [ $b -gt 60 ]; then
            log "4. bench/mpi_device.sh, budget $b s"
            part mpi $((b + 60)) env BUDGET="$b" CASE_TIMEOUT="${MPI_CASE_TIMEOUT:-120}" STUDY= \
                bash mpi-carry/scripts/bench/mpi_device.sh "$work/mpi"
        else
            log "4. skipped: $b s left"
        fi
    else
        log "4. skipped: no mpi-carry (bash bench/device_session.sh --prep here, then carry it)"
    fi
    rm -rf "$work"
    log "done"
    ;;
*)
    echo "usage: bash bench/device_session.sh --prep | --run OUTDIR" >&2
    exit 2
    ;;
esac
