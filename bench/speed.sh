#!/bin/sh
# The speed targets as a benchmark: every ratio measured in this one run, against the other code
# or configuration on this machine, never a figure from elsewhere. Writes bench/speed.md with a
# PASS/MISS for each target:
# - consph per particle-step >= 10x faster than PySPH 1.0b1 for wcsph, tvf and edac at nx 100 and
#   250 serial (2 threads reported), and consph 2 threads >= 1.8x 1 thread at nx 250;
# - L-IPST-C <= 0.4 µs per particle-step serial at nx 250 (on the lattice; from its default packed
#   start too when the binary has a layout cache);
# - pairs per second per core of every scheme the binary has (summary.json's pairs / seconds,
#   differenced between PAIR_C1 and PAIR_C2 steps);
# - `consph study 001-table9 --quick` <= 20 s, the full 001-table9 estimate <= 12 hours, the full
#   001-table3 <= 10 minutes with an empty cache (only with FULL=1).
# Time per particle-step as bench/pysph_compare.sh (bench/timing.sh): K2 steps minus K1 steps,
# the fastest of REPEAT runs each; `study 001-table9 --quick` the fastest of REPEAT runs, each
# from an empty cache, and the smallest of REPEAT estimates of the full one (the full 001-table3
# runs once).
#
# usage: bench/speed.sh        (from the repository root, after make; `make bench` runs it)
# environment: CONSPH (default build/consph), OUT (default bench/speed.md), NXS (default
#   "100 250"), SCHEMES (compared with PySPH, default "wcsph tvf edac"), THREADS (default "1 2"),
#   REPEAT (default 3), PAIR_NX (pairs per second, default 100), PAIR_SCHEMES (default: all of
#   the binary's), IPST_NX (L-IPST-C, default 250), FULL=1 (also the full 001-table3),
#   QUICK=1 (a smoke test's tiny sizes, one repeat, no 001-table9 --quick), PYTHON (default
#   /usr/bin/python3), WORK (scratch directory), PROFILE=1 (append bench/profile.sh's top symbols
#   for each scheme that misses a target).
# Exit 77 when PySPH is not installed: its columns say so and everything else is still measured.
set -eu

HERE=$(cd "$(dirname "$0")" && pwd)
QUICK=${QUICK:-0}
FULL=${FULL:-0}
PROFILE=${PROFILE:-0}
PYTHON=${PYTHON:-/usr/bin/python3}
CONSPH=${CONSPH:-build/consph}
OUT=${OUT:-bench/speed.md}
SCHEMES=${SCHEMES:-"wcsph tvf edac"}
THREADS=${THREADS:-"1 2"}
if [ "$QUICK" = 1 ]; then
    NXS=${NXS:-8} REPEAT=${REPEAT:-1} PAIR_NX=${PAIR_NX:-8} IPST_NX=${IPST_NX:-10}
    PAIR_C1=1 PAIR_C2=11 IPST_C1=1 IPST_C2=11
else
    NXS=${NXS:-"100 250"} REPEAT=${REPEAT:-3} PAIR_NX=${PAIR_NX:-100} IPST_NX=${IPST_NX:-250}
    # IPST every 10 steps (the scheme's default): a difference of 40 steps holds 4 of them
    PAIR_C1=20 PAIR_C2=120 IPST_C1=5 IPST_C2=45
fi
WORK=${WORK:-${TMPDIR:-/tmp}/consph_speed}
# the thread speed-up target applies at the largest resolution measured (nx 250 by default)
SPEEDUP_NX=$(echo $NXS | tr ' ' '\n' | sort -n | tail -n 1)

[ -x "$CONSPH" ] || { echo "speed: $CONSPH not built (run make)" >&2; exit 2; }
mkdir -p "$WORK"
. "$HERE/timing.sh"
TMPMD=$(mktemp "$OUT.XXXXXX")
trap 'rm -f "$TMPMD"' EXIT

have_pysph=1
"$PYTHON" -c "import pysph, numpy" 2> /dev/null || have_pysph=0
TG="" PYVER="not installed (apt-get install -y python3-pysph)"
if [ "$have_pysph" = 1 ]; then
    TG=$("$PYTHON" -c "import os, pysph.examples.taylor_green as t; print(os.path.abspath(t.__file__))")
    PYVER="$("$PYTHON" -c "import pysph; print(pysph.__version__)")"
    deb=$(dpkg-query -W -f '${Version}' python3-pysph 2> /dev/null || true)
    [ -n "$deb" ] && PYVER="$PYVER (Debian python3-pysph $deb)"
fi
# every scheme of the binary: --scheme's allowed names in `run --help`, else the refusal of an
# unknown scheme, which lists them
all_schemes=$("$CONSPH" run --help 2>&1 | sed -n 's/^ *--scheme S .*(\([a-z0-9,+-]*\); default .*/\1/p')
[ -n "$all_schemes" ] || all_schemes=$("$CONSPH" run taylor-green --scheme ' ' --nx 8 2>&1 |
    sed -n 's/.*(allowed: \([a-z0-9,+-]*\)).*/\1/p' || true)
all_schemes=$(echo "$all_schemes" | tr , ' ')
PAIR_SCHEMES=${PAIR_SCHEMES:-$all_schemes}
# a layout cache: the packed start is then measured too, from a warm cache of this run's own
have_cache=0
"$CONSPH" run --help 2>&1 | grep -q -- '--cache' && have_cache=1
commit=unknown
bindir=$(cd "$(dirname "$CONSPH")" && pwd)
if git -C "$bindir" rev-parse HEAD > /dev/null 2>&1; then
    commit=$(git -C "$bindir" rev-parse HEAD)
    [ -z "$(git -C "$bindir" status --porcelain --untracked-files=no 2> /dev/null)" ] ||
        commit="$commit (with uncommitted changes)"
fi
load0=$(cut -d' ' -f1-3 /proc/loadavg)
model=$(sed -n 's/^model name[[:space:]]*: //p' /proc/cpuinfo | head -n 1)
started=$(date -u '+%Y-%m-%d %H:%M UTC')

as_factor() { if [ "$1" = - ]; then echo -; else echo "$1×"; fi; }
us() { awk -v s="$1" 'BEGIN { if (s == "-" || s + 0 <= 0) print "-"; else printf "%.3f", s * 1e6 }'; }
# the summary of the targets, one row each: target, measured, result
targets=$WORK/targets.md
: > "$targets"
target() { echo "| $1 | $2 | $3 |" >> "$targets"; }
# the thread speed-up's rows, listed after all the PySPH ratios
targets_threads=$WORK/targets-threads.md
: > "$targets_threads"
missed="" # schemes that missed a target, for PROFILE=1

# ---- consph against PySPH, and consph's 2 threads against 1 ----
rival=$WORK/rival.md
speedup=$WORK/speedup.md
: > "$rival"
: > "$speedup"
for nx in $NXS; do
    set -- $(step_counts "$nx")
    k1=$1 k2=$2 c1=$3 c2=$4
    n=$((nx * nx))
    for s in $SCHEMES; do
        cs1=-
        for th in $THREADS; do
            py=- cs=-
            if c=$(fastest run_consph_rival "$s" "$nx" "$th" "$c1") &&
                d=$(fastest run_consph_rival "$s" "$nx" "$th" "$c2"); then
                cs=$(per_particle_step "$c" "$d" "$c1" "$c2" "$n")
            fi
            if [ "$have_pysph" = 1 ]; then
                run_pysph "$s" "$nx" "$th" "$k1" || true # compiles this configuration once
                if a=$(fastest run_pysph "$s" "$nx" "$th" "$k1") &&
                    b=$(fastest run_pysph "$s" "$nx" "$th" "$k2"); then
                    py=$(per_particle_step "$a" "$b" "$k1" "$k2" "$n")
                fi
            fi
            x=$(ratio "$py" "$cs")
            if [ "$have_pysph" = 0 ]; then
                v="n/a (no PySPH)"
                [ "$th" = 1 ] && target "consph ≥ 10× PySPH per particle-step, $s, nx $nx, serial" "-" "$v"
            elif [ "$th" = 1 ]; then
                v=$(verdict "$x" ge 10)
                target "consph ≥ 10× PySPH per particle-step, $s, nx $nx, serial" "$(as_factor "$x")" "$v"
                [ "$v" = MISS ] && missed="$missed $s"
            else
                v="(reported)"
            fi
            echo "| $s | $nx | $th | $(us "$py") | $(us "$cs") | $x | $v |" >> "$rival"
            [ "$th" = 1 ] && cs1=$cs
            if [ "$th" = 2 ]; then
                x2=$(ratio "$cs1" "$cs")
                v2="(reported)"
                if [ "$nx" = "$SPEEDUP_NX" ]; then
                    v2=$(verdict "$x2" ge 1.8)
                    echo "| consph 2 threads ≥ 1.8× 1 thread, $s, nx $nx | $(as_factor "$x2") | $v2 |" >> "$targets_threads"
                fi
                echo "| $s | $nx | $(us "$cs1") | $(us "$cs") | $x2 | $v2 |" >> "$speedup"
            fi
        done
    done
done

cat "$targets_threads" >> "$targets"

# ---- L-IPST-C per particle-step, serial ----
ipst=$WORK/ipst.md
: > "$ipst"
n=$((IPST_NX * IPST_NX))
run_ipst() { # K [options]
    k=$1
    shift
    "$CONSPH" run taylor-green --scheme l-ipst-c --nx "$IPST_NX" --steps "$k" --threads 1 "$@" > /dev/null
}
ipst_row() { # start, options...
    start=$1
    shift
    cs=-
    if c=$(fastest run_ipst "$IPST_C1" "$@") && d=$(fastest run_ipst "$IPST_C2" "$@"); then
        cs=$(per_particle_step "$c" "$d" "$IPST_C1" "$IPST_C2" "$n")
    fi
    v=$(verdict "$(us "$cs")" le 0.4)
    echo "| $start | $IPST_NX | $(us "$cs") | $v |" >> "$ipst"
    target "L-IPST-C ≤ 0.4 µs per particle-step, serial, nx $IPST_NX, $start" "$(us "$cs" | sed "s/[0-9]$/& µs/")" "$v"
    [ "$v" = MISS ] && missed="$missed l-ipst-c"
    return 0
}
ipst_row "lattice (--layout lattice)" --layout lattice
if [ "$have_cache" = 1 ]; then
    cache=$WORK/layout-cache
    rm -rf "$cache"
    # fills the cache: the timed runs read the packed particles from it
    run_ipst 1 --cache "$cache" || true
    ipst_row "packed (the default), from a warm --cache" --cache "$cache"
else
    echo "| packed (the default) | $IPST_NX | not run: no layout cache in this binary (packing each run) | - |" >> "$ipst"
fi

# ---- pairs per second per core, every scheme ----
# Differenced as the times per particle-step are: (pairs of C2 steps - of C1) / (seconds of C2 -
# of C1) / threads, so that the first steps' costs (first touches, the threads' start) cancel;
# over 20 steps alone wcsph's 2 threads came out at half of 1 thread's rate per core.
pairs=$WORK/pairs.md
: > "$pairs"
# pairs_of STEPS THREADS: "pairs seconds" of one run's summary.json, or nothing
pairs_of() {
    rm -rf "$WORK/pairs-run"
    "$CONSPH" run taylor-green --scheme "$s" --nx "$PAIR_NX" --layout lattice --steps "$1" \
        --threads "$2" --out "$WORK/pairs-run" > /dev/null 2>&1 &&
        awk -F '[:,]' '/"pairs"/ { p = $2 } /"seconds"/ { t = $2 }
            END { if (p > 0 && t > 0) print p, t }' "$WORK/pairs-run/summary.json"
}
for s in $PAIR_SCHEMES; do
    for th in $THREADS; do
        best=-
        r=0
        while [ "$r" -lt "$REPEAT" ]; do
            a=$(pairs_of "$PAIR_C1" "$th" || true)
            b=$(pairs_of "$PAIR_C2" "$th" || true)
            if [ -n "$a" ] && [ -n "$b" ]; then
                rate=$(echo "$a $b" | awk -v th="$th" '{
                    if ($4 > $2 && $3 > $1) printf "%.6e", ($3 - $1) / ($4 - $2) / th; else print "-" }')
                best=$(awk -v a="$best" -v b="$rate" 'BEGIN {
                    if (b == "-") print a; else if (a == "-" || b + 0 > a + 0) print b; else print a }')
            fi
            r=$((r + 1))
        done
        echo "$s $th $best" >> "$pairs"
    done
done

# ---- studies ----
studies=$WORK/studies.md
: > "$studies"
wall() { # seconds of the command "$@", or - when it fails
    t0=$(now)
    if "$@" > "$WORK/study.log" 2>&1; then echo "$(now) - $t0" | bc -l; else echo -; fi
}
secs() { awk -v s="$1" 'BEGIN { if (s == "-") print "-"; else printf "%.1f", s }'; }
# the smaller of two times, either of which may be - (a failed run)
least() { awk -v a="$1" -v b="$2" 'BEGIN {
    if (b == "-") print a; else if (a == "-" || b + 0 < a + 0) print b; else print a }'; }
if [ "$QUICK" = 1 ]; then
    echo "| \`study 001-table9 --quick\` | ≤ 20 s | not run (QUICK=1) | - |" >> "$studies"
else
    # the fastest of REPEAT runs, each from an empty cache (then each again from the warm one),
    # as every timing here: load from elsewhere only adds time
    wq=- ww=-
    r=0
    while [ "$r" -lt "$REPEAT" ]; do
        rm -rf "$WORK/cache-q" "$WORK/study-q"
        w=$(wall env XDG_CACHE_HOME="$WORK/cache-q" "$CONSPH" study 001-table9 --quick --out "$WORK/study-q")
        wq=$(least "$wq" "$w")
        if [ "$have_cache" = 1 ]; then
            rm -rf "$WORK/study-q"
            w=$(wall env XDG_CACHE_HOME="$WORK/cache-q" "$CONSPH" study 001-table9 --quick --out "$WORK/study-q")
            ww=$(least "$ww" "$w")
        fi
        r=$((r + 1))
    done
    v=$(verdict "$wq" le 20)
    echo "| \`study 001-table9 --quick\`, empty cache (fastest of $REPEAT) | ≤ 20 s | $(secs "$wq") s | $v |" >> "$studies"
    target "\`study 001-table9 --quick\` ≤ 20 s ($(nproc) cores, empty cache)" "$(secs "$wq") s" "$v"
    if [ "$have_cache" = 1 ]; then
        echo "| \`study 001-table9 --quick\`, the same again (warm cache, fastest of $REPEAT) | (reported) | $(secs "$ww") s | - |" >> "$studies"
    fi
fi
# the smallest of REPEAT estimates: each calibrates on small runs of well under a second, whose
# speed drifts with the machine's (34-57 h for the same binary in consecutive calls here)
est=-
r=0
while [ "$r" -lt "$REPEAT" ]; do
    e=$("$CONSPH" study 001-table9 --estimate 2>&1 | sed -n 's/.*estimated run time: \([0-9.e+]*\) s.*/\1/p' | head -n 1)
    [ -n "$e" ] && est=$(least "$est" "$e")
    r=$((r + 1))
done
v=$(verdict "$est" le 43200)
esth=$(awk -v s="$est" 'BEGIN { if (s == "-") print "-"; else printf "%.1f h (%.1f days)", s / 3600, s / 86400 }')
echo "| \`study 001-table9 --estimate\` (the full study, smallest of $REPEAT) | ≤ 12 h | $esth | $v |" >> "$studies"
target "full 001-table9 estimate ≤ 12 h" "$esth" "$v"
if [ "$FULL" = 1 ]; then
    rm -rf "$WORK/cache-full" "$WORK/study-full"
    w=$(wall env XDG_CACHE_HOME="$WORK/cache-full" "$CONSPH" study 001-table3 --out "$WORK/study-full")
    v=$(verdict "$w" le 600)
    echo "| \`study 001-table3\` (full), empty cache | ≤ 600 s | $(secs "$w") s | $v |" >> "$studies"
    target "full 001-table3 ≤ 10 min, empty cache" "$(secs "$w") s" "$v"
else
    echo "| \`study 001-table3\` (full), empty cache | ≤ 600 s | not run (FULL=1) | - |" >> "$studies"
    target "full 001-table3 ≤ 10 min, empty cache" "not run (FULL=1)" "-"
fi
load1=$(cut -d' ' -f1-3 /proc/loadavg)

# ---- the report ----
{
    echo "# consph speed against its targets"
    echo
    echo "Written by \`bench/speed.sh\` ($started to $(date -u '+%H:%M UTC')); every ratio below"
    echo "was measured in this run, on this machine."
    echo
    echo "- machine: $(nproc) cores, $model; load average $load0 at the start, $load1 at the end"
    echo "- consph: \`$CONSPH\`, commit $commit"
    echo "- PySPH: $PYVER"
    echo "- method: time per particle-step = (wall time of C2 steps - wall time of C1 steps) / ((C2 -"
    echo "  C1) N), each the fastest of REPEAT = $REPEAT runs (\`bench/timing.sh\`), so start-up, set-up,"
    echo "  packing and PySPH's compilation cancel; load from elsewhere only adds time."
    [ "$QUICK" = 1 ] && echo "- QUICK=1: a smoke test's tiny sizes; the figures mean nothing."
    echo
    echo "## Targets"
    echo
    echo "| target | measured | result |"
    echo "|---|---|---|"
    cat "$targets"
    echo
    echo "## consph against PySPH 1.0b1, Taylor-Green"
    echo
    echo "PySPH's example and consph with the same set-up (lattice, Re 100, c_o 10, quintic, h/Δs 1.2,"
    echo "Δt = 0.25 h/(c_o + U), α = 0 for wcsph; each scheme's default integrator, one evaluation per"
    echo "step). PySPH 2 threads is \`--openmp\` with OMP_NUM_THREADS=2, consph \`--threads T\`. µs per"
    echo "particle-step (wall time); target: PySPH / consph ≥ 10 serial."
    echo
    echo "| scheme | nx | threads | PySPH µs | consph µs | PySPH / consph | result |"
    echo "|---|---|---|---|---|---|---|"
    cat "$rival"
    echo
    echo "## consph 2 threads against 1"
    echo
    echo "From the table above; target ≥ 1.8 at nx $SPEEDUP_NX."
    echo
    echo "| scheme | nx | 1 thread µs | 2 threads µs | speed-up | result |"
    echo "|---|---|---|---|---|---|"
    cat "$speedup"
    echo
    echo "## L-IPST-C, serial"
    echo
    echo "Its own defaults (001: RK2, IPST every 10 steps); steps $IPST_C1 and $IPST_C2, so the"
    echo "difference holds $(( (IPST_C2 - IPST_C1) / 10 )) IPST correction(s). Target ≤ 0.4 µs per particle-step."
    echo
    echo "| start | nx | µs per particle-step | result |"
    echo "|---|---|---|---|"
    cat "$ipst"
    echo
    echo "## Pairs per second per core"
    echo
    echo "\`consph run taylor-green --layout lattice --nx $PAIR_NX --steps K\` at K = $PAIR_C1 and $PAIR_C2, their"
    echo "summary.json's pairs and seconds (the stepping's wall time, set-up excluded) differenced:"
    echo "(pairs(K2) - pairs(K1)) / (seconds(K2) - seconds(K1)) / threads, the best of $REPEAT pairs"
    echo "of runs. Reported, no target."
    echo
    printf '| scheme |'
    for th in $THREADS; do printf ' %s thread(s), pairs/s/core |' "$th"; done
    echo
    printf '|---|'
    for th in $THREADS; do printf -- '---|'; done
    echo
    for s in $PAIR_SCHEMES; do
        printf '| %s |' "$s"
        for th in $THREADS; do
            printf ' %s |' "$(awk -v s="$s" -v th="$th" '$1 == s && $2 == th {
                if ($3 == "-") print "failed"; else printf "%.3g", $3 }' "$pairs")"
        done
        echo
    done
    echo
    echo "## Studies"
    echo
    echo "Default threads (OpenMP's: $(nproc) cores here); an empty layout cache is a fresh"
    echo "XDG_CACHE_HOME."
    echo
    echo "| study | target | measured | result |"
    echo "|---|---|---|---|"
    cat "$studies"
} > "$TMPMD"

if [ "$PROFILE" = 1 ] && [ -n "$missed" ]; then
    {
        echo
        echo "## Profiles of the schemes that missed a target"
        echo
        for s in $(echo $missed | tr ' ' '\n' | sort -u); do
            echo "\`bench/profile.sh $s 100\`:"
            echo
            echo '```'
            CONSPH=$CONSPH sh "$HERE/profile.sh" "$s" 100 2>&1 | head -n 25 || true
            echo '```'
            echo
        done
    } >> "$TMPMD"
fi

chmod 644 "$TMPMD" # mktemp made it private
mv "$TMPMD" "$OUT"
trap - EXIT
echo "wrote $OUT"
if [ "$have_pysph" = 0 ]; then
    echo "speed: PySPH is not installed for $PYTHON: its comparison was not measured" >&2
    exit 77
fi
