#!/usr/bin/env bash
# consph study --jobs 1 (one process, so that "the k-th row" and the progress lines count every
# row; tests/cli_study_jobs.sh stops and resumes worker processes): a study stopped after k rows
# (CONSPH_TEST_STOP_AFTER_ROWS raises SIGINT after the k-th row it runs) exits 130 with a partial README.md and the command that resumes; that
# command finishes the study to the report of an uninterrupted run (every file equal, the
# columns of wall times aside), running none of the rows kept; a resume of a finished study
# rewrites every file byte for byte; a resume with another study file, --quick or --particles
# is refused (exit 2, naming it); the estimate prints finite seconds in the expected units.
# Usage: cli_study_resume.sh <path-to-consph> <source-dir>
set -u
bin=$1 src=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
. "$(dirname "${BASH_SOURCE[0]}")/lib_cli.sh"
study=$src/tests/data/resume.study

# same A B: every output of study directory A equals B's, masked.
same() {
    local f ok=0
    for f in "$1"/*; do
        case $f in *.svg) continue ;; esac
        if ! cmp -s <(masked "$f") <(masked "$2/${f##*/}"); then
            bad "$3: ${f##*/} differs from the uninterrupted run: $(diff <(masked "$f") <(masked "$2/${f##*/}") | head -4)"
            ok=1
        fi
    done
    [ "$(ls "$1")" = "$(ls "$2")" ] || { bad "$3: files $(ls "$2" | tr '\n' ' ') want $(ls "$1" | tr '\n' ' ')"; ok=1; }
    return $ok
}

"$bin" study "$study" --quick --jobs 1 --out "$work/ref" >/dev/null 2>"$work/ref.err" ||
    { bad "uninterrupted run: $(cat "$work/ref.err")"; summary cli_study_resume; exit; }
ref=$work/ref/resume
total=$(grep -c '^study: row .* done:' "$work/ref.err")
[ "$total" = 12 ] && pass=$((pass + 1)) || bad "uninterrupted run: $total progress lines, want 12"

# Stops inside the approx figure, the run figure and the heat figure; the resume reads back the
# rows of the figure that stopped (the finished figures are kept whole: 6 rows, then 3).
for kk in 3:3 7:1 10:1; do
    k=${kk%:*} back=${kk#*:}
    out=$work/k$k
    CONSPH_TEST_STOP_AFTER_ROWS=$k "$bin" study "$study" --quick --jobs 1 --out "$out" >/dev/null \
        2>"$work/err"
    rc=$?
    d=$out/resume
    cmd=$(grep -A1 'resume with' "$work/err" | tail -1 | sed 's/^ *//')
    if [ $rc != 130 ]; then
        bad "stop after $k rows: exit $rc, want 130: $(cat "$work/err")"
        continue
    fi
    rows=$(ls -A "$d" | grep -c '\.row$')
    if [ "$rows" != "$k" ]; then
        bad "stop after $k rows: $rows rows kept"
    elif ! grep -q '^\*\*Partial results\*\*: stopped by SIGINT after '"$k"' of 12 rows' "$d/README.md"; then
        bad "stop after $k rows: README.md: $(head -5 "$d/README.md")"
    elif ! grep -q 'not run' "$d/README.md" || ! grep -qF -- "$cmd" "$d/README.md"; then
        bad "stop after $k rows: README.md lacks the rows not run or the command '$cmd'"
    elif [ "$cmd" != "consph study $study --quick --jobs 1 --out $out --resume" ]; then
        bad "stop after $k rows: resume command '$cmd'"
    elif [ -n "$(find "$out" -name '*.tmp*')" ]; then
        bad "stop after $k rows: temporaries left: $(find "$out" -name '*.tmp*')"
    else
        pass=$((pass + 1))
    fi
    # The printed command, as a user would paste it (consph from the build).
    eval "\"\$bin\" ${cmd#consph }" >/dev/null 2>"$work/err2" || {
        bad "resume after $k rows: exit $?: $(cat "$work/err2")"
        continue
    }
    kept=$(grep -c '^study: row .* kept from the earlier run' "$work/err2")
    [ "$kept" = "$back" ] && pass=$((pass + 1)) ||
        bad "resume after $k rows: $kept rows read back, want $back"
    grep -q "study: row 12/12" "$work/err2" && pass=$((pass + 1)) ||
        bad "resume after $k rows: no progress line for the last row"
    same "$ref" "$d" "resume after $k rows" && pass=$((pass + 1))
done

# A resume of a finished study (its figure marks removed, so that every figure reads its rows
# back) writes every report byte for byte as before, wall times included: nothing ran again.
d=$work/k7/resume
mkdir "$work/before"
cp "$d"/*.csv "$d"/*.md "$d"/*.dat "$work/before/"
rm "$d"/.*.done
"$bin" study "$study" --quick --jobs 1 --out "$work/k7" --resume >/dev/null 2>"$work/err" ||
    bad "second resume: $(cat "$work/err")"
kept=$(grep -c '^study: row .* kept from the earlier run' "$work/err")
[ "$kept" = 11 ] && pass=$((pass + 1)) || bad "second resume: $kept of the 11 kept rows read back"
for f in "$work/before"/*; do
    cmp -s "$f" "$d/${f##*/}" || bad "second resume: ${f##*/} changed"
done
pass=$((pass + 1))

# Refusals: exit 2 naming the difference; nothing of the kept run is touched.
failing 2 "made with --quick, this run is without it" /dev/null -- \
    "$bin" study "$study" --out "$work/k7" --resume && pass=$((pass + 1))
sed 's/^title = Stop and resume self-test/title = changed/' "$study" >"$work/resume.study"
mkdir -p "$work/ch" && cp -r "$work/k3/resume" "$work/ch/"
failing 2 "the study file's contents differ from the run that kept the rows" /dev/null -- \
    "$bin" study "$work/resume.study" --quick --out "$work/ch" --resume && pass=$((pass + 1))
failing 2 "nothing to resume" /dev/null -- \
    "$bin" study "$study" --quick --out "$work/empty" --resume && pass=$((pass + 1))
[ -e "$work/empty" ] && bad "a refused resume created its output directory"
"$bin" layout --kind lattice --dim 2 --nx 16 --out "$work/p16.csv" >/dev/null
CONSPH_TEST_STOP_AFTER_ROWS=2 "$bin" study "$src/tests/data/engine.study" --quick --jobs 1 \
    --out "$work/eng" >/dev/null 2>&1
failing 2 "the particle files (--particles) differ" /dev/null -- \
    "$bin" study "$src/tests/data/engine.study" --quick --out "$work/eng" --resume \
    --particles "$work/p16.csv" && pass=$((pass + 1))

# A real SIGINT while a solver row runs: the row stops at its next step and is not kept, the
# rows before it are, and the partial report names the command that resumes.
cat >"$work/long.study" <<'STUDY'
study = long
title = A short row, then a long solver row
[figure a]
op = grad
nx = 12
[figure b]
kind = run
problem = taylor-green
nx = 24,32
steps = 20000
[series EWCSPH]
scheme = ewcsph
STUDY
set -m
"$bin" study "$work/long.study" --jobs 1 --out "$work/long" >/dev/null 2>"$work/long.err" &
p=$!
set +m
for _ in $(seq 600); do
    grep -q '^study: row 1/3 done' "$work/long.err" && break
    sleep 0.05
done
sleep 0.3
kill -INT "$p"
{ wait "$p"; } 2>/dev/null
rc=$?
d=$work/long/long
if [ $rc != 130 ]; then
    bad "SIGINT in a solver row: exit $rc, want 130: $(cat "$work/long.err")"
elif [ "$(ls -A "$d" | grep -c '\.row$')" != 1 ]; then
    bad "SIGINT in a solver row: kept $(ls -A "$d" | grep '\.row$' | tr '\n' ' '), want the first row only"
elif ! grep -q '^## b: not run' "$d/README.md" || ! grep -q "^## a: " "$d/README.md" ||
    ! grep -qF -- "--out $work/long --resume" "$d/README.md"; then
    bad "SIGINT in a solver row: README.md: $(cat "$d/README.md")"
else
    pass=$((pass + 1))
fi

# The estimate: finite seconds, then minutes for a short study, hours (with days above two) for
# a long one (001-table9's is near the two days on a loaded machine: either form); nothing
# written.
line=$("$bin" study "$study" --quick --estimate --out "$work/est" | grep '^estimated run time')
echo "$line" | grep -Eq '^estimated run time: [0-9]+ s \([0-9]+\.[0-9] min\)' &&
    pass=$((pass + 1)) || bad "quick estimate: '$line'"
line=$("$bin" study 001-table9 --estimate --out "$work/est" | grep '^estimated run time')
echo "$line" | grep -Eq '^estimated run time: [0-9]+ s \(([0-9]+\.[0-9] days, )?[0-9]+\.[0-9] hours\)' &&
    pass=$((pass + 1)) || bad "001-table9 estimate: '$line'"
[ -e "$work/est" ] && bad "--estimate wrote $work/est"
summary cli_study_resume
