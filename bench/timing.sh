# Timing helpers shared by bench/pysph_compare.sh and bench/speed.sh (POSIX sh, sourced).
# The method: the wall time of K2 steps minus that of K1 steps, over (K2 - K1) N, so that start-up,
# particle set-up (packing included) and PySPH's compilation cancel; each run is timed REPEAT
# times and the fastest kept, because load from elsewhere only ever adds time.
# The caller sets PYTHON, TG (PySPH's taylor_green.py), CONSPH, WORK and REPEAT.

now() { date +%s.%N; }

# c / p to 3 digits, or - when either is missing or not positive (a failed run, or noise)
ratio() {
    awk -v c="$1" -v p="$2" 'BEGIN {
        if (c == "-" || p == "-" || c == "" || p == "" || c + 0 <= 0 || p + 0 <= 0) print "-"
        else printf "%.3f\n", c / p }'
}

# PASS or MISS of VALUE against a target: verdict VALUE ge|le TARGET; n/a when VALUE is not a
# positive number (a failed run, or a step difference that noise made zero or negative)
verdict() {
    awk -v v="$1" -v op="$2" -v t="$3" 'BEGIN {
        if (v !~ /^[0-9.eE+-]+$/ || v + 0 <= 0) { print "n/a"; exit }
        if (op == "ge") print (v + 0 >= t + 0) ? "PASS" : "MISS"
        else if (op == "le") print (v + 0 <= t + 0) ? "PASS" : "MISS"
        else print "n/a" }'
}

# the step counts of the timed runs at nx $1: "K1 K2 C1 C2" (PySPH K1 < K2, consph C1 < C2),
# a few seconds of stepping per run for each code on one core; QUICK=1: a smoke test's few steps
step_counts() {
    if [ "${QUICK:-0}" = 1 ]; then
        echo "1 3 1 3"
    elif [ "$1" -le 100 ]; then
        echo "10 110 10 410"
    else
        echo "5 25 5 85"
    fi
}

# one PySPH run of Taylor-Green: scheme nx threads K (2 threads and more: --openmp)
run_pysph() {
    omp=""
    [ "$3" -gt 1 ] && omp=--openmp
    OMP_NUM_THREADS=$3 "$PYTHON" "$TG" --scheme "$1" --nx "$2" --hdx 1.2 --tf 1000 \
        --max-steps "$4" --disable-output $omp -d "$WORK/t_py" > "$WORK/t_py.log" 2>&1
}

# one consph run with PySPH's set-up (its Δt rule, α = 0 for wcsph): scheme nx threads K
run_consph_rival() {
    al=""
    [ "$1" = wcsph ] && al="--alpha 0"
    "$CONSPH" run taylor-green --scheme "$1" --nx "$2" --cfl 0.25 $al --steps "$4" \
        --threads "$3" > /dev/null
}

# the fastest wall seconds of REPEAT runs of the command "$@"; fails when a run fails
fastest() {
    best=""
    r=0
    while [ "$r" -lt "$REPEAT" ]; do
        t0=$(now)
        "$@" || return 1
        t1=$(now)
        t=$(echo "$t1 - $t0" | bc -l)
        if [ -z "$best" ] || [ "$(echo "$t < $best" | bc -l)" = 1 ]; then best=$t; fi
        r=$((r + 1))
    done
    echo "$best"
}

# seconds per particle-step from the fastest times T1 (K1 steps) and T2 (K2 steps) of N
# particles: per_particle_step T1 T2 K1 K2 N
per_particle_step() { echo "($2 - $1) / (($4 - $3) * $5)" | bc -l; }
