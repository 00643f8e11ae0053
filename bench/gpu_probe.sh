#!/usr/bin/env bash
# Two questions about the GPU's per-step time that bench/gpu.sh's sizes leave open, in about a
# minute on a machine with an NVIDIA GPU (docs/gpu.md, "Measuring"):
#   1. the floor at the small resolutions of 001-table9 (nx 50-250: 2 500-62 500 particles),
#      where a step took 0.5-1.3 ms for a few thousand particles: bench_gpu --stages, each
#      stage's time per step between CUDA events, for edac, e-c and l-ipst-c;
#   2. what a log sample costs at 250 000 particles: `consph run --device gpu` of 100 steps
#      with and without log samples (--log-every 10 and 100000), with --exact both and
#      incompressible (the weakly-compressible reference at every particle, or not), and with
#      --error eq26 (no output times of the authors' measure), each with the parts of its samples'
#      time (CONSPH_SAMPLE_SECONDS=1: copy back, search, checks, diagnostics, authors' measure,
#      the reference's steps, evaluation and rest), and for three of them again with the samples
#      in line (CONSPH_SAMPLE_OVERLAP=0) instead of on a host thread beside the steps (the
#      default on a GPU, src/solver/sampler.c; its line says how long the steps waited for them).
#   3. rows side by side: 001-table9's figure at nx 50-250 (the floor's rows: table 9's seven
#      schemes, the lattice, 100 steps each) as one study run with --jobs 1, 2, 4 and 8 (the
#      rows on threads sharing the GPU, docs/studies.md), the wall time of each.
# Writes OUT/probe.txt: bench_gpu's lines (stage_<name>_ms=, stage_wall_ms=), the runs' lines and
# the studies' wall times.
# Usage: bash bench/gpu_probe.sh OUT [BUILD]   (BUILD: default build-gpu; carried builds work)
set -u
cd "$(dirname "$0")/.." || exit 1
out=${1:?usage: bash bench/gpu_probe.sh OUT [BUILD]}
bdir=${2:-build-gpu}
mkdir -p "$out" || exit 1
f=$out/probe.txt
: >"$f"
b=$bdir/bench/bench_gpu
c=$bdir/consph
for k in edac:50 edac:100 e-c:50 e-c:250 l-ipst-c:50 l-ipst-c:100 l-ipst-c:250; do
    s=${k%%:*} nx=${k##*:}
    echo "== stages $s nx $nx" >>"$f"
    timeout 30 "$b" --scheme "$s" --problem taylor-green --nx "$nx" --gpu-steps 200 --stages 100 \
        --cpu-steps 0 --serial-steps 0 --layout lattice >>"$f" 2>&1
done
for k in "l-ipst-c both 10 authors" "l-ipst-c both 10 authors 0" "l-ipst-c both 100000 authors" \
    "l-ipst-c incompressible 10 authors" "l-ipst-c both 10 eq26" "l-ipst-c both 10 eq26 0" \
    "l-ipst-c incompressible 10 eq26" "l-ipst-c incompressible 100000 eq26" "edac both 10 eq26" \
    "edac both 10 eq26 0" "edac incompressible 100000 eq26"; do
    set -- $k
    ov=${5:-}
    r=$(CONSPH_SAMPLE_OVERLAP=$ov CONSPH_SAMPLE_SECONDS=1 timeout 40 "$c" run taylor-green --scheme "$1" --nx 500 --c0 80 \
        --layout lattice --exact "$2" --error "$4" --steps 100 --log-every "$3" --device gpu 2>&1 |
        grep -E 'per particle-step|^consph: [0-9]+ log samples' | tr '\n' ' ')
    echo "run $1 --exact $2 --log-every $3 --error $4${ov:+ CONSPH_SAMPLE_OVERLAP=$ov} (nx 500, 100 steps): ${r:-failed}" >>"$f"
done
# 3. the small rows on 1, 2, 4 and 8 threads
sd=$(mktemp -d)
sed -e 's/^tf = 0.5$/steps = 100/' -e 's/^nx = .*/nx = 50,100,200,250/' -e '/^quick\./d' \
    -e 's/^\[figure table9\]$/[figure table9]\nlayout = lattice/' studies/001-table9.study \
    >"$sd/001-table9.study"
for j in 1 2 4 8; do
    t0=$(date +%s.%N)
    XDG_CACHE_HOME=$sd/cache timeout 60 "$c" study "$sd/001-table9.study" --device gpu --jobs "$j" \
        --out "$sd/o$j" >/dev/null 2>"$sd/e$j"
    rc=$?
    t1=$(date +%s.%N)
    echo "study nx 50-250, 7 schemes, 100 steps, --jobs $j: exit $rc, $(awk -v a="$t0" -v b="$t1" \
        'BEGIN { printf "%.2f", b - a }') s wall$([ $rc != 0 ] && echo ": $(tail -1 "$sd/e$j")")" >>"$f"
done
rm -rf "$sd"
cat "$f"
