#!/usr/bin/env bash
# `consph run ... --device gpu`: the refusals (exit 2) name what is wrong: a scheme not ported
# (naming those that are), an option of heat, a build without GPU support or a machine without a
# device. A checkpoint between two log samples (--checkpoint-every) equals the CPU's. The GPU path of the CLI on the host emulation
# (CONSPH_GPU_BACKEND=emulation), and on the GPU where one is found: the run's log, snapshots,
# final checkpoint and summary equal the CPU run's byte for byte (edac, wcsph and tvf, 2D and 3D;
# l-ipst-c, l-pst-c, e-c, l-rr-c; delta-plus-sph, delta-plus-sph-d; --error authors, whose run
# copies back at its output times only; the log samples on a host thread beside the steps).
# Usage: bash cli_gpu.sh PATH-TO-CONSPH SOURCE-DIR
set -u
consph=$1
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
. "$2/tests/lib_cli.sh"

run() { "$consph" run taylor-green --nx 16 --steps 3 --threads 1 "$@"; }
failing 2 "kdk, tvf's" "$work/o" -- run --scheme tvf --integrator pec --device gpu && pass=$((pass + 1))
failing 2 "rk2, that of 001's schemes and the δ-SPH family" "$work/o" -- run --scheme delta-plus-sph \
    --integrator ssprk3 --device gpu && pass=$((pass + 1))
failing 2 "allowed: cpu,gpu" "$work/o" -- run --scheme edac --device tpu && pass=$((pass + 1))
failing 2 "--skin" "$work/o" -- run --scheme edac --device gpu --skin 0.1 && pass=$((pass + 1))
failing 2 "--device" "$work/o" -- "$consph" run heat --nx 10 --steps 2 --device gpu &&
    pass=$((pass + 1))
# --checkpoint-every: a checkpoint between the samples holds every array of its step. The run
# leaves the weakly-compressible range at step 43 (exit 3, the same step on both: --log-every 1
# checks every step), so the checkpoint of step 40 is the one left. The two checkpoints differ in
# their run ids and timing alone: each continued to step 42 on the CPU, and the GPU's on the GPU
# too, writes the same log and snapshot byte for byte
for d in cpu gpu; do
    CONSPH_GPU_BACKEND=emulation "$consph" run taylor-green --scheme wcsph --nx 16 --c0 3 --cfl 1 \
        --steps 60 --log-every 1 --checkpoint-every 10 --threads 1 --device $d \
        --out "$work/ck-$d" >/dev/null 2>"$work/ck-$d.err"
    rc=$?
    [ $rc -eq 3 ] && grep -q "diverged at step 43" "$work/ck-$d.err" ||
        bad "checkpoint-every on the $d: exit $rc, $(tail -n 1 "$work/ck-$d.err")"
done
for c in cpu:cpu gpu:cpu gpu:gpu; do
    CONSPH_GPU_BACKEND=emulation "$consph" run --restart "$work/ck-${c%:*}/checkpoint.ckpt" \
        --steps 42 --device "${c#*:}" --out "$work/re-${c%:*}-${c#*:}" >/dev/null 2>&1 ||
        bad "the restart of the ${c%:*}'s checkpoint on the ${c#*:}"
done
for c in gpu-cpu gpu-gpu; do
    for f in log.csv snap_000042.vtu; do
        cmp -s "$work/re-cpu-cpu/$f" "$work/re-$c/$f" ||
            bad "--checkpoint-every: $f of the restart $c differs from the CPU's"
    done
done
[ -e "$work/re-cpu-cpu/snap_000042.vtu" ] && pass=$((pass + 1))
# the CPU is the default and --device cpu changes nothing
run --scheme edac --out "$work/a" >/dev/null && run --scheme edac --device cpu --out "$work/b" >/dev/null ||
    bad "edac on the CPU"
cmp -s "$work/a/log.csv" "$work/b/log.csv" && pass=$((pass + 1)) || bad "--device cpu changed the log"

# the CPU's and the GPU's files of one run: log, snapshots (the GPU copies its state back for
# them and the log samples only), summary but its timing (the pairs too: the GPU counts them on
# the device); BACKEND: the environment's
# CONSPH_GPU_BACKEND ("" the CUDA device, "emulation" the host emulation)
same_files() {
    local backend=$1 case=$2 d
    for d in cpu gpu; do
        # shellcheck disable=SC2086
        CONSPH_GPU_BACKEND=$backend "$consph" run $case --device $d \
            --out "$work/$d" --overwrite --format json >"$work/$d.json" || bad "$case on the $d"
    done
    local n=0 f
    for f in "$work"/cpu/log.csv "$work"/cpu/snap_*.vtu "$work"/cpu/checkpoint.ckpt; do
        [ -e "$f" ] || continue
        n=$((n + 1))
        cmp -s "$f" "$work/gpu/${f##*/}" || bad "${backend:-cuda}: $case: ${f##*/} differs"
    done
    [ $n -ge 3 ] || bad "${backend:-cuda}: $case: only $n files compared"
    diff <(grep -v '"seconds"' "$work/cpu.json") <(grep -v '"seconds"' "$work/gpu.json") >/dev/null ||
        bad "${backend:-cuda}: $case: the summaries differ"
    pass=$((pass + 1))
}
# the host emulation behind the CLI: everywhere
same_files emulation "taylor-green --scheme edac --nx 24 --steps 12 --log-every 5 --snapshot-every 4"
same_files emulation "beltrami --scheme edac --nx 8 --steps 6 --log-every 4"
same_files emulation "taylor-green --scheme wcsph --nx 24 --steps 8 --log-every 3 --snapshot-every 5"
# tvf: kick-drift-kick, 2D and 3D
same_files emulation "taylor-green --scheme tvf --nx 24 --steps 12 --log-every 5 --snapshot-every 4"
same_files emulation "beltrami --scheme tvf --nx 8 --steps 6 --log-every 4"
# L-IPST-C: IPST after steps 1 and 11
same_files emulation "taylor-green --scheme l-ipst-c --nx 16 --steps 13 --log-every 4 --snapshot-every 6"
same_files emulation "taylor-green --scheme l-pst-c --nx 12 --steps 5 --log-every 2 --snapshot-every 3"
same_files emulation "taylor-green --scheme e-c --nx 12 --steps 5 --log-every 2 --snapshot-every 3"
same_files emulation "taylor-green --scheme l-rr-c --nx 12 --steps 4 --log-every 2 --snapshot-every 3"
# the δ-SPH family: δ+-SPH (Sun's shifting velocity) in 2D, δ+-SPH-D in 3D
same_files emulation "taylor-green --scheme delta-plus-sph --nx 12 --steps 5 --log-every 2 --snapshot-every 3"
same_files emulation "beltrami --scheme delta-plus-sph-d --nx 6 --steps 3 --log-every 2 --snapshot-every 2"
# 001's authors' measure: its output times are sampled from the same states, by --steps (6, 12,
# 18, 24, 30) and by --tf (steps cut to land on them); the GPU copies back after those steps, the
# log samples (10, 20) and the last step only: 7 copies in 30 steps, not 30
same_files emulation "taylor-green --scheme edac --nx 12 --steps 30 --log-every 10 --error authors --error-times 6"
copies=$(CONSPH_GPU_BACKEND=emulation CONSPH_GPU_COUNT_COPIES=1 "$consph" run taylor-green \
    --scheme edac --nx 12 --steps 30 --log-every 10 --error authors --error-times 6 --device gpu \
    2>&1 >/dev/null | sed -n 's/^GPU: \([0-9]*\) copies back.*/\1/p')
[ "$copies" = 7 ] && pass=$((pass + 1)) || bad "error authors: ${copies:-no count of} copies back, not 7"
# the hook CONSPH_SAMPLE_SECONDS: the log samples counted (t = 0, 10, 20, 30) and each part timed
line=$(CONSPH_GPU_BACKEND=emulation CONSPH_SAMPLE_SECONDS=1 "$consph" run taylor-green \
    --scheme edac --nx 12 --steps 30 --log-every 10 --error authors --error-times 6 --exact both \
    --device gpu 2>&1 >/dev/null | grep '^consph: [0-9]* log samples')
n='[0-9]+\.[0-9]+ s'
if [[ "$line" =~ ^consph:\ 4\ log\ samples\;\ all\ samples:\ copy\ back\ $n,\ search\ $n,\ checks\ $n,\ diagnostics\ $n,\ authors\'\ measure\ $n,\ reference\ steps\ $n,\ reference\ evaluation\ $n,\ reference\ rest\ $n$ ]]; then
    pass=$((pass + 1))
else
    bad "CONSPH_SAMPLE_SECONDS: '${line:-no line}'"
fi
same_files emulation "taylor-green --scheme l-ipst-c --nx 12 --tf 0.02 --log-every 50 --error authors --error-times 4"
# the log samples on a host thread beside the device's steps (src/solver/sampler.c: a GPU's
# default, the emulation's with CONSPH_SAMPLE_OVERLAP=1): the CPU's files still, with samples
# between snapshots, output times of the authors' measure and the reference's sums
export CONSPH_SAMPLE_OVERLAP=1
same_files emulation "taylor-green --scheme l-ipst-c --nx 16 --steps 13 --log-every 2 --snapshot-every 6 --exact both --error authors --error-times 4"
same_files emulation "taylor-green --scheme edac --nx 24 --tf 0.03 --log-every 3 --snapshot-every 5 --exact both --threads 2"
same_files emulation "beltrami --scheme tvf --nx 8 --steps 7 --log-every 2 --snapshot-every 4"
# ... and they ran there: steps 10, 20 and 30 (t = 0 is the set-up's, in line)
line=$(CONSPH_GPU_BACKEND=emulation CONSPH_SAMPLE_SECONDS=1 "$consph" run taylor-green \
    --scheme edac --nx 12 --steps 30 --log-every 10 --error authors --error-times 6 --exact both \
    --device gpu 2>&1 >/dev/null | grep 'beside the steps')
if [[ "$line" =~ ^consph:\ 3\ log\ samples\ beside\ the\ steps\;\ waited\ for\ them\ $n$ ]]; then
    pass=$((pass + 1))
else
    bad "CONSPH_SAMPLE_OVERLAP=1: '${line:-no line}'"
fi
export CONSPH_SAMPLE_OVERLAP=0
line=$(CONSPH_GPU_BACKEND=emulation CONSPH_SAMPLE_SECONDS=1 "$consph" run taylor-green \
    --scheme edac --nx 12 --steps 30 --log-every 10 --device gpu 2>&1 >/dev/null | grep -c 'beside')
[ "$line" = 0 ] && pass=$((pass + 1)) || bad "CONSPH_SAMPLE_OVERLAP=0 still overlapped"
unset CONSPH_SAMPLE_OVERLAP

run --scheme edac --device gpu >"$work/o" 2>"$work/err"
rc=$?
if [ $rc = 2 ]; then
    # no GPU here: the message says which of the two is missing
    if grep -qE "without GPU support|no CUDA device" "$work/err"; then
        pass=$((pass + 1))
    else
        bad "no GPU: $(cat "$work/err")"
    fi
elif [ $rc = 0 ]; then
    for scheme in edac wcsph tvf l-ipst-c delta-plus-sph; do
        same_files "" "taylor-green --scheme $scheme --nx 64 --steps 20 --snapshot-every 7"
        same_files "" "beltrami --scheme $scheme --nx 12 --steps 10"
    done
else
    bad "edac --device gpu: exit $rc: $(cat "$work/err")"
fi
summary cli_gpu
