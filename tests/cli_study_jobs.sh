#!/usr/bin/env bash
# consph study --jobs J (docs/studies.md): the rows on J forked workers write the files a serial
# study writes (every file byte for byte, the wall-time columns masked), and so does the default,
# a worker per core (OMP_NUM_THREADS); a study stopped on 2
# workers exits 130 with the partial report and the resume command once, and resumes on 3 to the
# serial report; a SIGINT to the study stops every worker; a row that fails in a worker gives
# the serial exit status and message, once; a worker killed by a signal is reported, not waited
# on forever; the packed layouts are made ahead of the workers, once, into the cache (not with
# --no-cache), each packing line with the whole study's ETA, and a SIGINT then stops before any
# worker starts; rows that pack their own layouts leave them out of the ETA's rate; bad values,
# --estimate: exit 2.
# Usage: cli_study_jobs.sh <path-to-consph> <source-dir>
set -u
bin=$1 src=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
. "$(dirname "${BASH_SOURCE[0]}")/lib_cli.sh"

study=$src/tests/data/resume.study
"$bin" study "$study" --quick --jobs 1 --out "$work/s1" >/dev/null 2>"$work/err" ||
    { bad "serial study: $(cat "$work/err")"; summary cli_study_jobs; exit; }
for j in 2 3; do
    timeout 120 "$bin" study "$study" --quick --jobs $j --out "$work/s$j" >"$work/out" 2>"$work/err" ||
        { bad "--jobs $j: exit $?: $(cat "$work/err")"; continue; }
    same_study "$work/s1/resume" "$work/s$j/resume" "--jobs $j" && pass=$((pass + 1))
    [ "$(grep -c '^done in' "$work/out")" = 1 ] && pass=$((pass + 1)) ||
        bad "--jobs $j: stdout: $(cat "$work/out")"
done

# Fewer rows than workers: one approx row and one m0 figure on 3 workers.
two=$src/tests/data/two.study
"$bin" study "$two" --quick --jobs 1 --out "$work/t1" >/dev/null 2>&1 &&
    timeout 60 "$bin" study "$two" --quick --jobs 3 --out "$work/t3" >/dev/null 2>"$work/err" &&
    same_study "$work/t1/two" "$work/t3/two" "2 rows on 3 workers" && pass=$((pass + 1)) ||
    bad "2 rows on 3 workers: $(cat "$work/err")"

# Without --jobs: a worker per core OpenMP would use (OMP_NUM_THREADS), the same files; the m0
# figure's report line says a worker ran it. A build without OpenMP has one thread and so no
# worker whatever OMP_NUM_THREADS says.
if "$bin" --version | grep -q "without OpenMP"; then
    workers_line='^'
else
    workers_line='run by a worker process'
fi
OMP_NUM_THREADS=2 timeout 60 "$bin" study "$two" --quick --out "$work/d2" >"$work/out" 2>"$work/err" &&
    same_study "$work/t1/two" "$work/d2/two" "default --jobs on 2 cores" &&
    grep -q "$workers_line" "$work/out" && pass=$((pass + 1)) ||
    bad "default --jobs on 2 cores: $(cat "$work/out" "$work/err")"
OMP_NUM_THREADS=1 "$bin" study "$two" --quick --out "$work/d1" >"$work/out" 2>&1 &&
    ! grep -q 'worker' "$work/out" && pass=$((pass + 1)) ||
    bad "default --jobs on 1 core: $(cat "$work/out")"

# Stopped on 2 workers (each stops after its first row), resumed on 3.
CONSPH_TEST_STOP_AFTER_ROWS=1 timeout 120 "$bin" study "$study" --quick --jobs 2 --out "$work/k" \
    >/dev/null 2>"$work/err"
rc=$?
if [ $rc != 130 ]; then
    bad "stop on 2 workers: exit $rc, want 130: $(cat "$work/err")"
elif ! grep -q '^\*\*Partial results\*\*: stopped by SIGINT after 2 of 12 rows' "$work/k/resume/README.md"; then
    bad "stop on 2 workers: README.md: $(head -3 "$work/k/resume/README.md")"
elif [ "$(grep -c 'resume with' "$work/err")" != 1 ]; then
    bad "stop on 2 workers: the resume command not printed once: $(cat "$work/err")"
elif ! timeout 120 "$bin" study "$study" --quick --jobs 3 --out "$work/k" --resume >/dev/null 2>"$work/err"; then
    bad "resume on 3 workers: $(cat "$work/err")"
else
    same_study "$work/s1/resume" "$work/k/resume" "stopped on 2 workers, resumed on 3" && pass=$((pass + 1))
fi

# A study whose rows take minutes: a SIGINT to it stops both workers at their next step.
cat >"$work/long.study" <<'STUDY'
study = long
[figure tgv]
kind = run
problem = taylor-green
nx = 24,28
steps = 1000000
[series EWCSPH]
scheme = ewcsph
STUDY
# --foreground: GNU timeout otherwise sends the signal it forwards to its whole process group as
# well, so the study would see two SIGINTs, and a second stop signal kills on purpose
timeout --foreground 60 "$bin" study "$work/long.study" --quick --jobs 2 --out "$work/l" >/dev/null 2>"$work/err" &
pid=$!
# the signal once the study has made its directory (its stop handler is in place by then), not
# after a fixed sleep that a loaded machine may not honour
for _ in $(seq 300); do [ -d "$work/l/long" ] && break; sleep 0.1; done
sleep 1
kill -INT $pid
wait $pid
rc=$?
[ $rc = 130 ] && grep -q '^\*\*Partial results\*\*: stopped by SIGINT' "$work/l/long/README.md" &&
    pass=$((pass + 1)) || bad "SIGINT on 2 workers: exit $rc: $(cat "$work/err")"

# A worker killed by a signal: reported (exit 1, naming it), the other worker stopped.
timeout 60 "$bin" study "$work/long.study" --quick --jobs 2 --out "$work/x" >/dev/null 2>"$work/err" &
pid=$!
sleep 2
# $pid is timeout's; its child is the study, whose children are the workers
kill -KILL "$(pgrep -P "$(pgrep -P $pid | head -1)" | head -1)"
wait $pid
rc=$?
[ $rc = 1 ] && grep -q '^consph study: --jobs: worker [01] of 2 (pid [0-9]*) ended by signal 9$' "$work/err" &&
    pass=$((pass + 1)) || bad "worker killed: exit $rc: $(cat "$work/err")"

# A row that fails in a worker (its row file cannot be written: a directory holds the name).
cat >"$work/g.study" <<'STUDY'
study = g
[figure g]
op = grad
nx = 8,10
STUDY
for j in 1 2; do
    mkdir -p "$work/f$j/g/.g.s0.r1.row/x"
    timeout 60 "$bin" study "$work/g.study" --quick --jobs $j --out "$work/f$j" >/dev/null 2>"$work/e$j"
    echo $? >"$work/rc$j"
done
msg="'$work/f2/g/.g.s0.r1.row' is a directory"
if [ "$(cat "$work/rc1")" = 0 ] || [ "$(cat "$work/rc2")" != "$(cat "$work/rc1")" ]; then
    bad "a row failing in worker 1: exit $(cat "$work/rc2"), serial $(cat "$work/rc1")"
elif [ "$(grep -cF "consph study: $msg" "$work/e2")" != 1 ]; then
    bad "a row failing in worker 1: message not printed once: $(cat "$work/e2")"
else
    pass=$((pass + 1))
fi

# Packed layouts are made before the rows start (--jobs 1 too): once each, largest first, into the cache
# the rows then read (the operator rows' at the sweep's nx, the solver rows' through their run
# parameters), the same files as a serial study; none where the cache holds them; with
# --no-cache into the study's private cache, which is removed after.
cat >"$work/p.study" <<'STUDY'
study = p
[figure grad]
op = grad
layout = packed
nx = 10,12
series.form = asym,sym1
[figure tgv]
kind = run
problem = taylor-green
layout = packed
nx = 8,12
steps = 2
[series EWCSPH]
scheme = ewcsph
STUDY
XDG_CACHE_HOME=$work/c1 "$bin" study "$work/p.study" --quick --jobs 1 --out "$work/p1" >/dev/null 2>"$work/e1"
XDG_CACHE_HOME=$work/c2 timeout 120 "$bin" study "$work/p.study" --quick --jobs 2 --out "$work/p2" \
    >/dev/null 2>"$work/e2"
rc=$?
want="study: packing layout packed dim 2 nx 12 (1 of 3, 1 thread) before the rows start
study: packing layout packed dim 2 nx 10 (2 of 3, 1 thread) before the rows start
study: packing layout packed dim 2 nx 8 (3 of 3, 1 thread) before the rows start"
# The packing lines without their times (elapsed, and the whole study's ETA: a time, never `--`,
# from the packing and estimate models before any row ran).
packing_lines() {
    grep '^study: packing' "$1" | sed 's/ (elapsed [0-9:]*, ETA [0-9:]*)$//'
}
# Each packing line has them, and one line says the packing is done, with the rows' ETA.
packing_times() {
    [ "$(grep -c '^study: packing layout .* before the rows start (elapsed [0-9][0-9]:[0-9][0-9], ETA [0-9][0-9]:[0-9][0-9])$' "$1")" = 3 ] &&
        [ "$(grep -c '^study: packed 3 layouts ahead in [0-9][0-9]:[0-9][0-9]; the rows start (elapsed [0-9][0-9]:[0-9][0-9], ETA [0-9][0-9]:[0-9][0-9])$' "$1")" = 1 ]
}
if [ $rc != 0 ]; then
    bad "packing ahead: exit $rc: $(cat "$work/e2")"
elif [ "$(packing_lines "$work/e2")" != "$want" ] || [ "$(packing_lines "$work/e1")" != "$want" ] ||
    ! packing_times "$work/e1" || ! packing_times "$work/e2"; then
    bad "packing ahead: lines $(grep '^study: pack' "$work/e1" "$work/e2")"
elif [ "$(ls "$work/c2/consph" | grep -c '^layout-.*\.bin$')" != 3 ] ||
    [ "$(ls "$work/c2/consph" | grep '^layout-.*\.bin$')" != "$(ls "$work/c1/consph" | grep '^layout-.*\.bin$')" ]; then
    bad "packing ahead: cache $(ls "$work/c2/consph") want $(ls "$work/c1/consph")"
else
    same_study "$work/p1/p" "$work/p2/p" "packing ahead" && pass=$((pass + 1))
fi
XDG_CACHE_HOME=$work/c2 timeout 120 "$bin" study "$work/p.study" --quick --jobs 2 --out "$work/p3" \
    >/dev/null 2>"$work/e3" && ! grep -q '^study: packing' "$work/e3" &&
    XDG_CACHE_HOME=$work/c3 timeout 120 "$bin" study "$work/p.study" --quick --jobs 2 --no-cache \
        --out "$work/p4" >/dev/null 2>"$work/e4" && [ "$(packing_lines "$work/e4")" = "$want" ] &&
    [ ! -e "$work/c3/consph" ] && same_study "$work/p1/p" "$work/p3/p" "packing ahead, cached" &&
    same_study "$work/p1/p" "$work/p4/p" "packing ahead, --no-cache" && pass=$((pass + 1)) ||
    bad "packing ahead with the cache full or off: $(cat "$work/e3" "$work/e4")"

# Rows that pack their own layouts (none made ahead, as on MPI ranks; the test hook
# CONSPH_TEST_NO_PACK_AHEAD=1): the ETA leaves a packing row's time out of the rows' rate and
# prices the rows by the estimate's model until a row gives a rate, so every row, the two first
# each packing its layout, has one; the report is the one made with the packing ahead.
XDG_CACHE_HOME=$work/c6 CONSPH_TEST_NO_PACK_AHEAD=1 "$bin" study "$work/p.study" --quick --jobs 1 \
    --out "$work/p6" >/dev/null 2>"$work/e6" && ! grep -q '^study: pack' "$work/e6" &&
    grep -q '^study: row 1/6 done: grad, form=asym, nx=10 (elapsed [0-9:]*, ETA [0-9][0-9]:[0-9][0-9])$' "$work/e6" &&
    grep -q '^study: row 2/6 done: grad, form=asym, nx=12 (elapsed [0-9:]*, ETA [0-9][0-9]:[0-9][0-9])$' "$work/e6" &&
    grep -q '^study: row 3/6 done: grad, form=sym1, nx=10 (elapsed [0-9:]*, ETA [0-9][0-9]:[0-9][0-9])$' "$work/e6" &&
    same_study "$work/p1/p" "$work/p6/p" "rows packing their layouts" && pass=$((pass + 1)) ||
    bad "rows packing their layouts: $(cat "$work/e6")"

# A SIGINT while a layout is packed ahead: the packing ends, no worker starts, the partial
# report and resume command follow (exit 130), and the layout stays in the cache.
# (--foreground: one SIGINT, as above.)
cat >"$work/q.study" <<'STUDY'
study = q
[figure grad]
op = grad
layout = packed
nx = 64
series.form = asym,sym1
STUDY
XDG_CACHE_HOME=$work/c5 timeout --foreground 60 "$bin" study "$work/q.study" --jobs 2 --out "$work/q" \
    >/dev/null 2>"$work/e5" &
pid=$!
for _ in $(seq 200); do grep -q '^study: packing' "$work/e5" && break; sleep 0.05; done
kill -INT $pid
wait $pid
rc=$?
[ $rc = 130 ] && grep -q 'stopped by SIGINT; partial report' "$work/e5" &&
    ! grep -q 'ended by signal' "$work/e5" &&
    [ "$(ls "$work/c5/consph" | grep -c '^layout-.*\.bin$')" = 1 ] && pass=$((pass + 1)) ||
    bad "SIGINT while packing ahead: exit $rc: $(cat "$work/e5")"

# Bad values.
for j in 0 257 x; do
    failing 2 "option --jobs" /dev/null -- "$bin" study "$study" --quick --jobs $j --out "$work/b" &&
        pass=$((pass + 1))
done
failing 2 "option --jobs: not with --estimate" /dev/null -- "$bin" study "$study" --estimate --jobs 2 &&
    pass=$((pass + 1))
summary cli_study_jobs
