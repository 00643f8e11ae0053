#!/usr/bin/env bash
# `consph run ... --device gpu`: the refusals (exit 2) name what is wrong: a scheme not ported
# (naming those that are), --checkpoint-every, an option of heat, a build without GPU support or
# a machine without a device. Where a GPU is found, the GPU run's summary, log and final
# snapshot equal the CPU run's byte for byte (edac, 2D and 3D).
# Usage: bash cli_gpu.sh PATH-TO-CONSPH SOURCE-DIR
set -u
consph=$1
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
. "$2/tests/lib_cli.sh"

run() { "$consph" run taylor-green --nx 16 --steps 3 --threads 1 "$@"; }
failing 2 "allowed: edac" "$work/o" -- run --scheme wcsph --device gpu && pass=$((pass + 1))
failing 2 "allowed: cpu,gpu" "$work/o" -- run --scheme edac --device tpu && pass=$((pass + 1))
failing 2 "--checkpoint-every" "$work/o" -- run --scheme edac --device gpu --out "$work/ck" \
    --checkpoint-every 2 && pass=$((pass + 1))
failing 2 "--skin" "$work/o" -- run --scheme edac --device gpu --skin 0.1 && pass=$((pass + 1))
failing 2 "--device" "$work/o" -- "$consph" run heat --nx 10 --steps 2 --device gpu &&
    pass=$((pass + 1))
# the CPU is the default and --device cpu changes nothing
run --scheme edac --out "$work/a" >/dev/null && run --scheme edac --device cpu --out "$work/b" >/dev/null ||
    bad "edac on the CPU"
cmp -s "$work/a/log.csv" "$work/b/log.csv" && pass=$((pass + 1)) || bad "--device cpu changed the log"

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
    for case in "taylor-green --nx 64 --steps 20" "beltrami --nx 12 --steps 10"; do
        for d in cpu gpu; do
            # shellcheck disable=SC2086
            "$consph" run $case --scheme edac --device $d --out "$work/$d" --overwrite \
                --format json >"$work/$d.json" || bad "$case on the $d"
        done
        for f in log.csv snap_000000.vtu; do
            cmp -s "$work/cpu/$f" "$work/gpu/$f" && pass=$((pass + 1)) || bad "$case: $f differs"
        done
        last=$(ls "$work/cpu" | grep '^snap_' | sort | tail -1)
        cmp -s "$work/cpu/$last" "$work/gpu/$last" && pass=$((pass + 1)) ||
            bad "$case: $last differs between the CPU and the GPU"
        # the summaries differ only in the timing
        diff <(grep -v '"seconds"\|"pairs"' "$work/cpu.json") \
            <(grep -v '"seconds"\|"pairs"' "$work/gpu.json") >/dev/null && pass=$((pass + 1)) ||
            bad "$case: the summaries differ"
    done
else
    bad "edac --device gpu: exit $rc: $(cat "$work/err")"
fi
summary cli_gpu
