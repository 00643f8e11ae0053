#!/bin/sh
# consph against PySPH 1.0b1 on Taylor-Green (issue 15, "Agreement with PySPH"): the same scheme,
# particles and parameters in both codes (lattice, Re 100, c_o 10, quintic, h/Δs 1.2, t = 0.5,
# Δt = 0.25 h/(c_o + U)), PySPH's three error measures computed from both outputs by
# bench/pysph_errors.py, and the time per particle-step of both codes from the difference of two
# step counts (which takes out start-up and PySPH's compilation). Writes bench/pysph.md.
#
# usage: bench/pysph_compare.sh        (from the repository root, after make)
# environment: NXS (accuracy resolutions, default "50 100"), TNXS (timing resolutions, default
#   "100 250"), SCHEMES (default "wcsph tvf edac"), THREADS (default "1 2"), WORK (scratch
#   directory; PySPH outputs found there are reused), PYTHON (default /usr/bin/python3),
#   CONSPH (default build/consph), OUT (default bench/pysph.md).
# Exit 77 when PySPH is not installed (apt-get install -y python3-pysph).
set -eu

PYTHON=${PYTHON:-/usr/bin/python3}
CONSPH=${CONSPH:-build/consph}
OUT=${OUT:-bench/pysph.md}
NXS=${NXS:-"50 100"}
TNXS=${TNXS:-"100 250"}
SCHEMES=${SCHEMES:-"wcsph tvf edac"}
THREADS=${THREADS:-"1 2"}
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

now() { date +%s.%N; }
# h = 1.2/nx; PySPH's measures of the last snapshot of a run
errors() { "$PYTHON" "$HERE/pysph_errors.py" "$1" 0.5 100 "$(echo "1.2 / $2" | bc -l)"; }
last() { ls "$1"/$2 | sort | tail -n 1; }
# c / p to 3 digits, or - when p is 0
ratio() { awk -v c="$1" -v p="$2" 'BEGIN { if (p == 0) print "-"; else printf "%.3f", c / p }'; }

{
    echo "# consph against PySPH 1.0b1 on Taylor-Green"
    echo
    echo "Written by \`bench/pysph_compare.sh\` on $(date -u +%Y-%m-%d) ($(nproc) cores; the"
    echo "machine was shared, so times are indicative). PySPH: \`$TG\`"
    echo "(Debian python3-pysph $(dpkg-query -W -f '${Version}' python3-pysph 2>/dev/null || echo '?'))."
    echo
    echo "## Accuracy at t = 0.5"
    echo
    echo "Both codes: lattice, Re 100, c_o 10, quintic, h/Δs 1.2, Δt = 0.25 h/(c_o + U), α = 0 for"
    echo "wcsph (the example's choice). Measures as PySPH's post_process: L1(|u|) relative to the"
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
        "$CONSPH" run taylor-green --scheme "$s" --nx "$nx" --cfl 0.25 --alpha 0 --tf 0.5 \
            --out "$cs" > "$cs.log"
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
    echo "and PySPH's compilation cancel. PySPH serial is its default build; 2 threads is"
    echo "\`--openmp\` with OMP_NUM_THREADS=2; consph \`--threads T\`."
    echo
    echo "| scheme | nx | threads | PySPH s | consph s | PySPH / consph |"
    echo "|---|---|---|---|---|---|"
} >> "$TMPMD"

# seconds of one run of K steps; $1 = py|cs, $2 scheme, $3 nx, $4 threads, $5 K
timed() {
    t0=$(now)
    if [ "$1" = py ]; then
        omp=""
        [ "$4" -gt 1 ] && omp=--openmp
        OMP_NUM_THREADS=$4 "$PYTHON" "$TG" --scheme "$2" --nx "$3" --hdx 1.2 --tf 1000 \
            --max-steps "$5" --disable-output $omp -d "$WORK/t_py" > "$WORK/t_py.log" 2>&1
    else
        "$CONSPH" run taylor-green --scheme "$2" --nx "$3" --cfl 0.25 --alpha 0 --steps "$5" \
            --threads "$4" > /dev/null
    fi
    t1=$(now)
    echo "$t1 - $t0" | bc -l
}
for nx in $TNXS; do
    # about 20 s of PySPH stepping at nx 100 and 250 on one core
    if [ "$nx" -le 100 ]; then k1=10 k2=110; else k1=5 k2=25; fi
    for s in $SCHEMES; do
        for th in $THREADS; do
            timed py "$s" "$nx" "$th" "$k1" > /dev/null # compiles this configuration once
            a=$(timed py "$s" "$nx" "$th" "$k1") b=$(timed py "$s" "$nx" "$th" "$k2")
            c=$(timed cs "$s" "$nx" "$th" "$k1") d=$(timed cs "$s" "$nx" "$th" "$k2")
            py=$(echo "($b - $a) / (($k2 - $k1) * $nx * $nx)" | bc -l)
            cs=$(echo "($d - $c) / (($k2 - $k1) * $nx * $nx)" | bc -l)
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
