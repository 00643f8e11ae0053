# Helpers sourced by CLI tests (not a test itself: CTest runs tests/cli_*.sh): the pass/fail
# counters, the check of a command that must fail, and the summary line. Needs $work, a scratch
# directory the test removes.
pass=0
fail=0
bad() {
    echo "FAIL: $*"
    fail=$((fail + 1))
}
# failing STATUS TEXT STDOUT -- command...: runs the command with its stdout to STDOUT and its
# stderr to $work/err; 0 when it exited STATUS and the stderr holds TEXT (a fixed string), else
# 1 after saying why.
failing() {
    local want=$1 text=$2 to=$3
    shift 4
    "$@" >"$to" 2>"$work/err"
    local rc=$?
    if [ $rc != "$want" ]; then
        bad "$* >$to: exit $rc, want $want: $(cat "$work/err")"
        return 1
    fi
    grep -qF -- "$text" "$work/err" && return 0
    bad "$* >$to: message '$(cat "$work/err")' lacks '$text'"
    return 1
}
# summary_masked FILE: summary.json with its timings blanked (and, with SUMMARY_MASK_NLIST=1,
# the neighbour list's bytes and note, which a pair-cache budget changes).
summary_masked() {
    if [ "${SUMMARY_MASK_NLIST:-0}" = 1 ]; then
        sed -E -e 's/"([a-z_]*seconds)": *[-0-9.eE+]+/"\1": -/g' \
            -e 's/"(nlist_bytes_per_particle|nlist_note)": *.*/"\1": -/' "$1"
    else
        sed -E 's/"([a-z_]*seconds)": *[-0-9.eE+]+/"\1": -/g' "$1"
    fi
}
# same_run A B WHAT: run directories A and B hold the same files, each equal byte for byte
# (summary.json through summary_masked; run.id and the checkpoint, which carries the run's id,
# skipped); else 1 after saying which differ.
same_run() {
    local f ok=0
    [ "$(ls -A "$1")" = "$(ls -A "$2")" ] || { bad "$3: files $(ls -A "$2" | tr '\n' ' ')"; return 1; }
    for f in "$1"/*; do
        case $f in
        *run.id | *checkpoint.ckpt) true ;;
        *summary.json) cmp -s <(summary_masked "$f") <(summary_masked "$2/${f##*/}") ;;
        *) cmp -s "$f" "$2/${f##*/}" ;;
        esac || { bad "$3: ${f##*/} differs"; ok=1; }
    done
    return $ok
}
# summary NAME: the counts; the exit status of the test.
summary() {
    echo "$1: $pass passed, $fail failed"
    [ $fail = 0 ]
}
# masked FILE: a study output file with its wall-time columns blanked (CSV columns and markdown
# table columns named seconds, setup_seconds, s or T_r (a ratio of wall times); the last column
# of a .dat block whose header line ends in "seconds").
masked() {
    awk '
    FNR == 1 { delete cols; mode = -1; datsec = 0 }
    {
        md = ($0 ~ /^\|/)
        n = md ? split($0, a, "|") : split($0, a, ",")
        hit = 0
        for (i = 1; i <= n; i++) {
            t = a[i]; gsub(/ /, "", t)
            if (t == "seconds" || t == "setup_seconds" || (md && (t == "s" || t == "T_r"))) hit = 1
        }
        if (hit) {
            delete cols
            for (i = 1; i <= n; i++) {
                t = a[i]; gsub(/ /, "", t)
                if (t == "seconds" || t == "setup_seconds" || (md && (t == "s" || t == "T_r"))) cols[i] = 1
            }
            mode = md; print; next
        }
        if (length(cols) && md == mode && n > 1) {
            for (i in cols) a[i] = "X"
            s = a[1]
            for (i = 2; i <= n; i++) s = s (md ? "|" : ",") a[i]
            print s; next
        }
        delete cols
        if (FILENAME ~ /[.]dat$/) {
            if ($0 ~ /^#/) datsec = ($NF == "seconds")
            else if (datsec && NF > 1) $NF = "X"
        }
        print
    }' "$1"
}

# same_study A B WHAT: the study directories hold the same files, equal once masked, svg included.
same_study() {
    local f ok=0
    if [ "$(ls -A "$1")" != "$(ls -A "$2")" ]; then
        bad "$3: files $(ls -A "$2" | tr '\n' ' ') want $(ls -A "$1" | tr '\n' ' ')"
        return 1
    fi
    for f in "$1"/*; do
        cmp -s <(masked "$f") <(masked "$2/${f##*/}") ||
            { bad "$3: ${f##*/} differs: $(diff <(masked "$f") <(masked "$2/${f##*/}") | head -4)"; ok=1; }
    done
    return $ok
}
