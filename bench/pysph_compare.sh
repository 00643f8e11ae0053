#!/bin/sh
# consph against PySPH 1.0b1 on Taylor-Green: the same scheme,
# particles and parameters in both codes (lattice, Re 100, c_o 10, quintic, h/Δs 1.2, t = 0.5,
# Δt = 0.25 h/(c_o + U)), PySPH's three error measures computed from both outputs by
# bench/pysph_errors.py, and the time per particle-step of both codes from the difference of two
# step counts (which takes out start-up and PySPH's compilation). Writes bench/pysph.md.
#
# usage: bench/pysph_compare.sh        (from the repository root, after make)
# environment: NXS (accuracy resolutions, default "50 100"), TNXS (timing resolutions, default
#   "100 250"; an empty NXS or TNXS skips that part), SCHEMES (default "wcsph tvf edac"),
#   THREADS (default "1 2"), REPEAT (timed runs per configuration, the fastest kept; default 3),
#   WORK (scratch
#   directory; PySPH outputs found there are reused), PYTHON (default /usr/bin/python3),
#   CONSPH (default build/consph), OUT (default bench/pysph.md).
# Exit 77 when PySPH is not installed (apt-get install -y python3-pysph).
set -eu

PYTHON=${PYTHON:-/usr/bin/python3}
CONSPH=${CONSPH:-build/consph}
OUT=${OUT:-bench/pysph.md}
NXS=${NXS-"50 100"}
TNXS=${TNXS-"100 250"}
SCHEMES=${SCHEMES:-"wcsph tvf edac"}
THREADS=${THREADS:-"1 2"}
REPEAT=${REPEAT:-3}
WORK=${WORK:-${TMPDIR:-/tmp}/consph_pysph}
HERE=$(cd "$(dirname "$0")" && pwd)

if ! "$PYTHON" -c "import pysph, numpy" 2>/dev/null; then
    echo "pysph_compare: PySPH is not installed for $PYTHON (apt-get install -y python3-pysph)" >&2
    exit 77
fi
[ -x "$CONSPH" ] || { echo "pysph_compare: $CONSPH not built (run make)" >&2; exit 2; }
TG=$("$PYTHON" -c "import os, pysph.examples.taylor_green as t; print(os.path.abspath(t.__file__))")
mkdir -p "$WORK"
TMPMD=$(mktemp "$OUT.XXXXXX")
trap 'rm -f "$TMPMD"' EXIT

# now, ratio, step_counts, run_pysph, run_consph_rival, fastest, per_particle_step
. "$HERE/timing.sh"
# h = 1.2/nx; PySPH's measures of the last snapshot of a run
errors() { "$PYTHON" "$HERE/pysph_errors.py" "$1" 0.5 100 "$(echo "1.2 / $2" | bc -l)"; }
last() { ls "$1"/$2 | sort | tail -n 1; }

{
    echo "# consph against PySPH 1.0b1 on Taylor-Green"
    echo
    echo "Written by \`bench/pysph_compare.sh\` on $(date -u +%Y-%m-%d) ($(nproc) cores, load"
    echo "average $(cut -d' ' -f1-3 /proc/loadavg) at the start). PySPH: \`$TG\`"
    echo "(Debian python3-pysph $(dpkg-query -W -f '${Version}' python3-pysph 2>/dev/null || echo '?'))."
    echo
    echo "## Accuracy at t = 0.5"
    echo
    echo "Both codes: lattice, Re 100, c_o 10, quintic, h/Δs 1.2, Δt = 0.25 h/(c_o + U), α = 0 for"
    echo "wcsph (the example's choice), which both codes start from ϱ = ρ_o (consph \`--rho-init rho0\`). Measures as PySPH's post_process: L1(|u|) relative to the"
    echo "mean exact |u|, L1(p - p_avg) relative to max |p_exact|, and |max|u| - e^{bt}|/e^{bt}."
    echo
    echo "| scheme | nx | PySPH L1(u) | consph L1(u) | ratio | PySPH L1(p) | consph L1(p) | ratio | PySPH Linf decay | consph Linf decay | ratio |"
    echo "|---|---|---|---|---|---|---|---|---|---|---|"
} > "$TMPMD"

for nx in $NXS; do
    for s in $SCHEMES; do
        py="$WORK/py_${s}_$nx" cs="$WORK/cs_${s}_$nx"
        if [ ! -f "$py/results.npz" ]; then
            rm -rf "$py"
            "$PYTHON" "$TG" --scheme "$s" --nx "$nx" --hdx 1.2 --tf 0.5 --pfreq 100000 -d "$py" \
                > "$py.log" 2>&1
        fi
        rm -rf "$cs"
        # PySPH's example starts every particle at rho0 (p = 0 for wcsph's Tait EOS)
        # and sets α = 0, which only wcsph reads (consph refuses --alpha for tvf and edac)
        init=""
        [ "$s" = wcsph ] && init="--rho-init rho0 --alpha 0"
        "$CONSPH" run taylor-green --scheme "$s" --nx "$nx" --cfl 0.25 --tf 0.5 \
            $init --out "$cs" > "$cs.log"
        "$CONSPH" layout --in "$(last "$cs" 'snap_*.vtu')" --out "$cs/last.csv" > /dev/null
        set -- $(errors "$(last "$py" 'taylor_green_*.hdf5')" "$nx") $(errors "$cs/last.csv" "$nx")
        echo "| $s | $nx | $1 | $4 | $(ratio "$4" "$1") | $2 | $5 | $(ratio "$5" "$2") | $3 | $6 | $(ratio "$6" "$3") |" >> "$TMPMD"
    done
done

{
    echo
    echo "## Time per particle-step"
    echo
    echo "Wall time of K2 steps minus that of K1 steps, over (K2 - K1) N: start-up, particle set-up"
    echo "and PySPH's compilation cancel. Each run is timed $REPEAT times and the fastest kept. PySPH"
    echo "serial is its default build; 2 threads is \`--openmp\` with OMP_NUM_THREADS=2; consph"
    echo "\`--threads T\`, with each scheme's default integrator (one evaluation per step, as PySPH)."
    echo
    echo "| scheme | nx | threads | PySPH s | consph s | PySPH / consph |"
    echo "|---|---|---|---|---|---|"
} >> "$TMPMD"

for nx in $TNXS; do
    set -- $(step_counts "$nx")
    k1=$1 k2=$2 c1=$3 c2=$4
    for s in $SCHEMES; do
        for th in $THREADS; do
            run_pysph "$s" "$nx" "$th" "$k1" # compiles this configuration once
            a=$(fastest run_pysph "$s" "$nx" "$th" "$k1") b=$(fastest run_pysph "$s" "$nx" "$th" "$k2")
            c=$(fastest run_consph_rival "$s" "$nx" "$th" "$c1")
            d=$(fastest run_consph_rival "$s" "$nx" "$th" "$c2")
            py=$(per_particle_step "$a" "$b" "$k1" "$k2" $((nx * nx)))
            cs=$(per_particle_step "$c" "$d" "$c1" "$c2" $((nx * nx)))
            printf '| %s | %s | %s | %.3e | %.3e | %s |\n' "$s" "$nx" "$th" "$py" "$cs" \
                "$(ratio "$py" "$cs")" >> "$TMPMD"
        done
    done
done

if [ -f "$HERE/pysph_notes.md" ]; then
    echo >> "$TMPMD"
    cat "$HERE/pysph_notes.md" >> "$TMPMD"
fi
mv "$TMPMD" "$OUT"
trap - EXIT
echo "wrote $OUT"
