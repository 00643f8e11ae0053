#!/usr/bin/env bash
# A convergence study on one GPU against the same study on every core (docs/gpu.md, "Studies"),
# in about two minutes on the lent machine (one GPU, 16 cores):
#   0. runs tests/cli_study_gpu.sh (on the GPU too where there is one: a study's report under
#      --device gpu and auto equals the CPU's);
#   1. finds the schemes the GPU runs (a one-step `consph run --device gpu` of each scheme of
#      001-table9, and edac);
#   2. writes a study of 001-table9's figure (Taylor-Green, c_o = 80, h/Δs 1.2, Δt from the
#      finest h, IPST's schedule, error = authors, exact = both, the paper's resolutions
#      50..500) with one series per table-9 scheme the GPU runs and edac, each run STEPS steps
#      (a fraction of t_f = 0.5, which takes about 56 250) on the lattice (layout = lattice: a
#      packed layout is made on the host, the same for both devices, cached between the
#      Lagrangian schemes; its cost is estimated apart, below);
#   3. runs it with --device gpu, once more on the GPU with a third of the steps (a row's time
#      is then split into a cost per step, log samples included, and a cost per row: set-up,
#      the first and last samples, the two output times of error = authors), both again with
#      --jobs JOBS (the rows on threads sharing the GPU), then with --device cpu on THREADS
#      threads when the budget allows;
#   4. extrapolates each to the full 001-table9 (six resolutions, seven schemes, t = 0.5):
#      per scheme and resolution, on the GPU the cost per step times ceil(0.5/Δt) steps plus 25
#      times the cost per row (the full row's 50 output times priced as 25 times the 2 here: an
#      upper bound, since the set-up is counted 25 times too); on the CPU, whose fixed costs are
#      a trifle beside its steps, the wall time per step of the long run times the steps; a
#      table-9 scheme the GPU does not run yet is priced as the reference series (l-ipst-c when
#      the GPU runs it, else edac standing for EWCSPH) times its T_r relative to it from 001
#      Table 9 (E-C 1.19, EWCSPH 1.00, L-IPST-C 1.53, L-PST-C 2.02, L-RR-C 1.41, PE-IPST-C 1.65,
#      TV-C 1.88; edac taken as 1.00); plus the set-up measured here (wall time less the steps'),
#      scaled to 42 rows, plus the packings by consph's own model (the difference of two
#      `consph study --estimate` of the table with and without packed layouts);
#   5. writes gpu_study.md (and the study outputs, logs) in the output folder.
#
# Build where the GPU machine cannot (as bench/gpu.sh; both use build-gpu/):
#   bash bench/gpu_study.sh --build-only                # here, with nvcc
#   bash bench/gpu_study.sh --no-build --out "$OUT"     # there, build-gpu carried
#
# Usage: bash bench/gpu_study.sh [--out DIR] [--steps K] [--budget S] [--quick] [--emulate]
#                                [--no-build] [--build-only]
#   --out DIR     where gpu_study.md and the studies go (default: build-gpu/gpu-study-out)
#   --steps K     steps of every row (default 150; the short GPU run takes K/3, at least 10)
#   --budget S    no study starts after S seconds; each runs under timeout (default 140)
#   --quick       nx 20, 30, 40 and 5 steps (a check of the script)
#   --emulate     the GPU's rows on the host emulation (CONSPH_GPU_BACKEND=emulation; slow: use
#                 with --quick)
# Environment: BUILD (default build-gpu), THREADS (the CPU study's threads, default nproc), JOBS
#   (default 4: the GPU's two runs again with --jobs JOBS, the rows on that many threads sharing
#   the GPU, and the whole study's wall time extrapolated for both; 1: not run).
set -u
cd "$(dirname "$0")/.." || exit 1
out=""
steps=150
budget=140
quick=0
emulate=0
build=auto
while [ $# -gt 0 ]; do
    case "$1" in
    --out | --steps | --budget)
        [ $# -ge 2 ] || { echo "bench/gpu_study.sh: $1 needs a value" >&2; exit 2; }
        case "$1" in
        --out) out=$2 ;;
        --steps | --budget)
            [[ "$2" =~ ^[1-9][0-9]*$ ]] ||
                { echo "bench/gpu_study.sh: $1 needs a whole number > 0, not '$2'" >&2; exit 2; }
            [ "$1" = --steps ] && steps=$2 || budget=$2
            ;;
        esac
        shift 2
        ;;
    --quick) quick=1; shift ;;
    --emulate) emulate=1; shift ;;
    --no-build) build=no; shift ;;
    --build-only) build=only; shift ;;
    *)
        echo "bench/gpu_study.sh: unknown argument '$1' (allowed: --out DIR, --steps K," \
            "--budget S, --quick, --emulate, --no-build, --build-only)" >&2
        exit 2
        ;;
    esac
done
bdir=${BUILD:-build-gpu}
if [ $build = only ] || { [ $build = auto ] && [ ! -x "$bdir/consph" ]; }; then
    BUILD=$bdir bash bench/gpu.sh --build-only || exit 1
    [ $build = only ] && exit 0
fi
consph=$bdir/consph
[ -x "$consph" ] || { echo "bench/gpu_study.sh: no $consph (build it: --build-only)" >&2; exit 1; }
consph=$(cd "$(dirname "$consph")" && pwd)/consph
out=${out:-$bdir/gpu-study-out}
mkdir -p "$out" || exit 1
out=$(cd "$out" && pwd)
threads=${THREADS:-$(nproc)}
jobs=${JOBS:-4}
case $jobs in '' | *[!0-9]*) echo "bench/gpu_study.sh: JOBS=$jobs: a whole number" >&2; exit 2 ;; esac
start=$(date +%s)
elapsed() { echo $(($(date +%s) - start)); }
log() { echo "[$(elapsed) s] $*" | tee -a "$out/run.log"; }
: >"$out/run.log"
nx=50,100,200,250,400,500
[ $quick = 1 ] && { nx=20,30,40; steps=5; }
gpu_env=()
[ $emulate = 1 ] && gpu_env=(CONSPH_GPU_BACKEND=emulation)
# the layout cache of this run alone: the packing estimate must not find layouts made elsewhere
export XDG_CACHE_HOME=$out/cache

# ---- 0. the study test on this machine's GPU: the GPU's report equals the CPU's ----
timeout 60 bash tests/cli_study_gpu.sh "$consph" "$(pwd)" >"$out/cli_study_gpu.log" 2>&1
test_rc=$?
test_line="tests/cli_study_gpu.sh: $(tail -1 "$out/cli_study_gpu.log") (exit $test_rc)"
log "$test_line"

# ---- 1. the schemes the GPU runs ----
table9="e-c ewcsph l-ipst-c l-pst-c l-rr-c pe-ipst-c tv-c"
on_gpu=""
for s in $table9 edac; do
    env ${gpu_env[@]+"${gpu_env[@]}"} "$consph" run taylor-green --scheme "$s" --nx 8 --steps 1 --device gpu \
        >/dev/null 2>"$out/probe.err" && on_gpu="$on_gpu $s"
done
if [ -z "$on_gpu" ]; then
    log "no scheme runs on the GPU here: $(tail -1 "$out/probe.err")"
    exit 1
fi
log "the GPU runs:$on_gpu (table 9: $table9); $threads threads for the CPU study"

# ---- 2. the study ----
sdir=$out/study
mkdir -p "$sdir"
write_study() { # write_study FILE ERROR STEPS
    {
        echo "study = gpustudy"
        echo "title = 001-table9's runs, $3 steps each, on the GPU's schemes (bench/gpu_study.sh)"
        echo "paper = none"
        echo "note = A timing of 001-table9's figure: its keys, $3 steps per row, the lattice."
        echo
        echo "[figure table9]"
        echo "title = Taylor-Green, c_o = 80, $3 steps"
        echo "kind = run"
        echo "problem = taylor-green"
        echo "hdx = 1.2"
        echo "c0 = 80"
        echo "nx = $nx"
        echo "steps = $3"
        echo "dt_rule = finest"
        echo "ipst_h_dt = 0.0024"
        echo "layout = lattice"
        echo "error = $2"
        [ "$2" = authors ] && echo "error_times = 2"
        echo "exact = both"
        for s in $on_gpu; do printf '\n[series %s]\nscheme = %s\n' "$s" "$s"; done
    } >"$1"
}
short=$((steps / 3))
[ $short -lt 10 ] && short=10
[ $quick = 1 ] && short=2
write_study "$sdir/gpustudy.study" authors "$steps"

# study DEVICE DIR [ENV...]: wall seconds into $DIR.wall, or "" when it failed or ran out of time
study() {
    local device=$1 dir=$2 left
    shift 2
    left=$((budget - $(elapsed)))
    if [ $left -lt 10 ]; then
        log "$device: skipped (budget of $budget s spent)"
        return 1
    fi
    local t0 t1
    t0=$(date +%s.%N)
    env "$@" timeout "$left" "$consph" study "$sdir/gpustudy.study" --device "$device" \
        ${sjobs[@]+"${sjobs[@]}"} --out "$dir" >"$dir.log" 2>&1
    local rc=$?
    t1=$(date +%s.%N)
    if [ $rc != 0 ]; then
        log "$device: exit $rc ($([ $rc = 124 ] && echo "past the budget" || tail -2 "$dir.log" | tr '\n' ' '))"
        return 1
    fi
    awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.2f\n", b - a }' >"$dir.wall"
    log "$device${sjobs[*]+ ${sjobs[*]}}: $(cat "$dir.wall") s ($dir/gpustudy/table9.md)"
}
sjobs=()
study gpu "$out/gpu" ${gpu_env[@]+"${gpu_env[@]}"}
write_study "$sdir/gpustudy.study" authors "$short"
study gpu "$out/gpu-short" ${gpu_env[@]+"${gpu_env[@]}"}
# the same two with the rows on JOBS threads sharing the GPU (--jobs: each row's steps on its
# thread's own stream)
if [ "$jobs" -gt 1 ]; then
    sjobs=(--jobs "$jobs")
    study gpu "$out/gpuj-short" ${gpu_env[@]+"${gpu_env[@]}"}
    write_study "$sdir/gpustudy.study" authors "$steps"
    study gpu "$out/gpuj" ${gpu_env[@]+"${gpu_env[@]}"}
    sjobs=()
fi
write_study "$sdir/gpustudy.study" authors "$steps"
study cpu "$out/cpu" OMP_NUM_THREADS="$threads"

# ---- 3. the packing the table's Lagrangian schemes start from, by consph's model ----
# `consph study --estimate` adds the packings (its model of their iterations, timed here) to the
# steps' cost: with one step per row the steps are a trifle, and the same study with every
# series on the lattice leaves that trifle alone
packing=""
if [ $quick = 0 ] && [ $(($(elapsed) + 20)) -lt "$budget" ]; then
    est() { OMP_NUM_THREADS=$threads timeout 20 "$consph" study "$1" --estimate 2>/dev/null |
        sed -n 's/^estimated run time: \([0-9.e+]*\) s.*/\1/p'; }
    mkdir -p "$out/est/packed" "$out/est/lattice"
    sed 's/^tf = 0.5$/steps = 1/' studies/001-table9.study >"$out/est/packed/001-table9.study"
    awk '/^\[series/ { print; print "layout = lattice"; next } { print }' \
        "$out/est/packed/001-table9.study" >"$out/est/lattice/001-table9.study"
    with=$(est "$out/est/packed/001-table9.study")
    without=$(est "$out/est/lattice/001-table9.study")
    if [ -n "$with" ] && [ -n "$without" ]; then
        packing=$(awk -v a="$with" -v b="$without" 'BEGIN { printf "%.0f", a - b }')
        log "the packings of 001-table9 by consph's model on $threads threads: $packing s"
    fi
fi

# ---- 4. the extrapolation ----
# rows DIR: "scheme nx n steps dt seconds" of the study's CSV
rows() {
    awk -F, 'NR == 1 { for (i = 1; i <= NF; i++) c[$i] = i; next }
        { print $c["scheme"], $c["nx"], $c["n"], $c["steps"], $c["dt"], $c["seconds"] }' \
        "$1/gpustudy/table9.csv"
}
# per_row DIR [SHORT]: "scheme nx n per_step_s per_row_s dt" per row: with SHORT (the same
# study at fewer steps), the slope and intercept of the two runs' seconds against steps; without,
# the seconds over the steps and no per-row cost
per_row() {
    { [ $# -ge 2 ] && [ -f "$2.wall" ] && rows "$2" | sed 's/^/S /'; rows "$1" | sed 's/^/L /'; } |
        awk '$1 == "S" { k = $2 ":" $3; s1[k] = $5; t1[k] = $7; next }
             { k = $2 ":" $3
               if ((k in s1) && $5 > s1[k]) {
                   per = ($7 - t1[k]) / ($5 - s1[k]); fixed = t1[k] - s1[k] * per
                   if (fixed < 0) fixed = 0
               } else { per = $7 / $5; fixed = 0 }
               printf "%s %s %s %.9g %.9g %s\n", $2, $3, $4, per, fixed, $6 }'
}
# extrapolate DIR [SHORT]: per scheme the full table's seconds, then the total (see the header)
extrapolate() {
    local dir=$1
    [ -f "$dir.wall" ] || { echo "none"; return; }
    per_row "$@" | awk -v wall="$(cat "$dir.wall")" -v stepsec="$(rows "$dir" | awk '{ s += $6 } END { print s }')" \
        -v table9="$table9" -v pack="${packing:-0}" '
        BEGIN { split("e-c 1.19 ewcsph 1.00 l-ipst-c 1.53 l-pst-c 2.02 l-rr-c 1.41 pe-ipst-c 1.65 tv-c 1.88 edac 1.00", t, " ")
                for (i = 1; i < 18; i += 2) tr[t[i]] = t[i + 1] }
        { full = int(0.5 / $6 + 0.999999)
          f[$1] += $4 * full + 25 * $5; fx[$1] += 25 * $5; nrows++; steps_full = full }
        END {
            ref = ("l-ipst-c" in f) ? "l-ipst-c" : "edac"
            n = split(table9, s, " ")
            for (i = 1; i <= n; i++) {
                v = (s[i] in f) ? f[s[i]] : f[ref] * tr[s[i]] / tr[ref]
                w = (s[i] in f) ? fx[s[i]] : fx[ref] * tr[s[i]] / tr[ref]
                total += v; fixed += w
                how = how sprintf("%s%s %.0f s%s", i > 1 ? ", " : "", s[i], v, (s[i] in f) ? "" : " (T_r)")
            }
            setup = (wall - stepsec) / nrows * 42
            printf "%.0f|%.0f|%.0f|%.0f|%d|%s|%s\n", total + setup + pack, setup, total - fixed, fixed, steps_full, how, ref
        }'
}
md=$out/gpu_study.md
{
    echo "# A study on one GPU against $threads cores (bench/gpu_study.sh)"
    echo
    echo "$(date -u '+%Y-%m-%d %H:%M UTC'); $(nvidia-smi --query-gpu=name --format=csv,noheader 2>/dev/null | head -1)"
    echo "$([ $emulate = 1 ] && echo '(GPU rows on the host emulation: not a GPU measurement) ')$([ $quick = 1 ] && echo '(--quick: a check of the script, not the paper'"'"'s resolutions) ')CPU: $(nproc) cores, $threads threads."
    echo
    echo "$test_line"
    echo
    echo "The study: 001-table9's figure (its keys; \`layout = lattice\`), series:$on_gpu, nx $nx,"
    echo "$steps steps per row. Wall time of the whole \`consph study\` (set-up, steps, reports):"
    echo
    echo "| run | wall s | Σ step s | full 001-table9 extrapolated: total s (h) | of it set-up s | steps s | rows' own costs s |"
    echo "|---|---|---|---|---|---|---|"
    for d in gpu cpu; do
        [ -f "$out/$d.wall" ] || { echo "| $d | not run | | | | | |"; continue; }
        sd=()
        [ $d = gpu ] && sd=("$out/gpu-short")
        IFS='|' read -r tot setup stp fixed nsteps how ref <<<"$(extrapolate "$out/$d" "${sd[@]}")"
        sum=$(rows "$out/$d" | awk '{ s += $6 } END { printf "%.2f", s }')
        echo "| $d | $(cat "$out/$d.wall") | $sum | $tot ($(awk -v t="$tot" 'BEGIN { printf "%.2f", t / 3600 }')) | $setup | $stp | $fixed |"
        echo "$d: $how (reference $ref; $nsteps steps per row)" >>"$out/how.txt"
    done
    [ -f "$out/gpu-short.wall" ] && echo "
The GPU's short run ($short steps per row): $(cat "$out/gpu-short.wall") s."
    if [ -f "$out/gpuj.wall" ] && [ -f "$out/gpuj-short.wall" ] && [ -f "$out/gpu-short.wall" ]; then
        full=$(rows "$out/gpu" | awk 'NR == 1 { printf "%d", int(0.5 / $5 + 0.999999) }')
        whole() { awk -v l="$(cat "$1.wall")" -v s="$(cat "$2.wall")" -v L="$steps" -v S="$short" \
            -v F="$full" 'BEGIN { b = (l - s) / (L - S); printf "%.0f", l + (F - L) * b }'; }
        w1=$(whole "$out/gpu" "$out/gpu-short")
        wj=$(whole "$out/gpuj" "$out/gpuj-short")
        echo
        echo "Rows on $jobs threads sharing the GPU (\`--jobs $jobs\`, each row's steps on its thread's own"
        echo "stream): wall time of this study at $steps and $short steps per row, one thread"
        echo "$(cat "$out/gpu.wall") and $(cat "$out/gpu-short.wall") s, $jobs threads $(cat "$out/gpuj.wall") and"
        echo "$(cat "$out/gpuj-short.wall") s. The whole study (every row here) extrapolated to the full"
        echo "$full steps per row as wall(K) + ($full − K) × (wall(K) − wall(K/3)) / (K − K/3): one thread"
        echo "$w1 s ($(awk -v t="$w1" 'BEGIN { printf "%.2f", t / 3600 }') h), $jobs threads $wj s ($(awk -v t="$wj" 'BEGIN { printf "%.2f", t / 3600 }') h): ×$(awk -v a="$w1" -v b="$wj" 'BEGIN { if (b > 0) printf "%.2f", a / b; else printf "-" }')."
        echo "(Its rows include edac's; the 50 output times of the full rows and the packing are not"
        echo "in it; the per-scheme table above is the one-thread run's.)"
    fi
    echo
    echo "Per scheme, the full table's seconds (\"T_r\": priced from the reference series):"
    echo
    sed 's/^/- /' "$out/how.txt" 2>/dev/null
    echo
    echo "Per row: the GPU's cost per step (ms; log samples included) and per row (ms: set-up, the"
    echo "first and last samples, two output times), from its $steps- and $short-step runs; the"
    echo "wall time per step of its $steps-step run; the CPU's wall time per step:"
    echo
    echo "| scheme | nx | N | GPU ms/step | GPU ms/row | GPU ms/step ($steps-step run) | CPU ms/step | CPU/GPU |"
    echo "|---|---|---|---|---|---|---|---|"
    : >"$out/r.gpu"
    : >"$out/r.cpu"
    [ -f "$out/gpu.wall" ] && per_row "$out/gpu" "$out/gpu-short" |
        awk '{ printf "%s:%s %s %.4f %.3f\n", $1, $2, $3, 1000 * $4, 1000 * $5 }' >"$out/r.gpu"
    [ -f "$out/cpu.wall" ] && per_row "$out/cpu" | awk '{ printf "%s:%s %s %.4f\n", $1, $2, $3, 1000 * $4 }' >"$out/r.cpu"
    [ -f "$out/gpu.wall" ] && per_row "$out/gpu" | awk '{ printf "%s:%s %.4f\n", $1, $2, 1000 * $4 }' >"$out/r.mean"
    awk 'FILENAME ~ /r.cpu$/ { c[$1] = $3; next } FILENAME ~ /r.mean$/ { m[$1] = $2; next }
         { k[++n] = $1; N[$1] = $2; g[$1] = $3; r[$1] = $4 }
         END { for (i = 1; i <= n; i++) { split(k[i], a, ":"); x = k[i]
               printf "| %s | %s | %s | %.3f | %.1f | %s | %s | %s |\n", a[1], a[2], N[x], g[x], r[x],
                   (x in m) ? sprintf("%.3f", m[x]) : "",
                   (x in c) ? sprintf("%.3f", c[x]) : "", (x in c) ? sprintf("%.1f", c[x] / g[x]) : "" } }' \
        "$out/r.cpu" "$out/r.mean" "$out/r.gpu"
    echo
    echo "Method: per scheme and nx, on the GPU (seconds per step) × ceil(0.5/Δt) + 25 × (seconds per"
    echo "row) (Δt from the finest h, as the table runs; the full row's 50 output times priced as 25"
    echo "times this row's two, set-up included: an upper bound), on the CPU (seconds / steps) ×"
    echo "ceil(0.5/Δt); a table-9 scheme the GPU does not run is priced as the reference times"
    echo "its 001 Table 9 T_r over the reference's (edac counted as EWCSPH, 1.00); set-up = (wall −"
    echo "Σ step s)/rows × 42 rows; packing: ${packing:-not estimated} s by consph's model on the CPU"
    echo "(\`consph study --estimate\` of the table at one step per row, less the same with every series"
    echo "on the lattice; the packed layouts are made on the host for either device, once per nx, kept"
    echo "in the layout cache for the other schemes). A GPU row copies the particles back at every log"
    echo "sample (every log_every = 10 steps: the host's diagnostics, eq. 26's sum and, with exact ="
    echo "both, the weakly-compressible reference at every particle) and at the output times of"
    echo "error = authors (docs/gpu.md)."
} >"$md"
cat "$md"
log "done: $md"
