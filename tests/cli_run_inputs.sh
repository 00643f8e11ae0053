#!/usr/bin/env bash
# consph run from the user's inputs. --particles: a run started from a `consph layout` file
# (lattice CSV, packed VTU, 3D lattice) equals the run started with --layout bit for bit; a file
# with velocity and pressure starts from them; a count that is not nx^d runs with the spacing of
# box volume / N; files that do not fit the problem are refused with the file (and line or field),
# exit 2, nothing written. --config: a run parameter file equals the same options, an option
# replaces its key, bad keys and values are refused at FILE:LINE. --restart with a later --tf or
# more --steps equals the uninterrupted run (snapshots, run.pvd, log.csv, summary.json but its
# timings); what cannot be made equal is refused.
# Usage: bash cli_run_inputs.sh PATH-TO-CONSPH
set -u
consph=$1
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
. "$(dirname "$0")/lib_cli.sh"

# same_run A B WHAT: the two output directories hold the same files, equal byte for byte but the
# timings of summary.json
same_run() {
    local a=$1 b=$2 what=$3
    if [ "$(cd "$a" && ls | grep -v '^checkpoint.ckpt$\|^run.id$')" != \
        "$(cd "$b" && ls | grep -v '^checkpoint.ckpt$\|^run.id$')" ]; then
        bad "$what: other files: $(ls "$a" | tr '\n' ' ') vs $(ls "$b" | tr '\n' ' ')"
        return
    fi
    local f
    for f in "$a"/snap_*.vtu "$a"/run.pvd "$a"/log.csv; do
        cmp -s "$f" "$b/${f##*/}" || { bad "$what: ${f##*/} differs"; return; }
    done
    grep -v '"seconds"' "$a/summary.json" >"$work/sa"
    grep -v '"seconds"' "$b/summary.json" >"$work/sb"
    cmp -s "$work/sa" "$work/sb" || { bad "$what: summary.json differs"; return; }
    pass=$((pass + 1))
}

# nothing_written WHAT DIR: a refused run left no DIR
nothing_written() {
    if [ -e "$2" ]; then bad "$1: wrote $2"; else pass=$((pass + 1)); fi
}

# --- --particles: a layout file equals --layout ---
"$consph" layout --kind lattice --dim 2 --nx 12 --out "$work/lat.csv" >/dev/null || bad "layout lattice"
"$consph" layout --kind packed --dim 2 --nx 12 --no-cache --out "$work/pk.vtu" >/dev/null ||
    bad "layout packed"
"$consph" layout --kind lattice --dim 3 --nx 6 --out "$work/b.csv" >/dev/null || bad "layout 3D"
tg() { "$consph" run taylor-green --steps 6 --snapshot-every 3 "$@" >/dev/null; }
tg --scheme l-ipst-c --nx 12 --layout lattice --out "$work/lat-a" || bad "run --layout lattice"
tg --scheme l-ipst-c --particles "$work/lat.csv" --out "$work/lat-b" || bad "run lattice file"
same_run "$work/lat-a" "$work/lat-b" "lattice file"
tg --scheme tvf --nx 12 --layout packed --no-cache --out "$work/pk-a" || bad "run --layout packed"
tg --scheme tvf --particles "$work/pk.vtu" --out "$work/pk-b" || bad "run packed file"
same_run "$work/pk-a" "$work/pk-b" "packed file"
bel() { "$consph" run beltrami --scheme l-ipst-c --steps 2 "$@" >/dev/null; }
bel --nx 6 --layout lattice --out "$work/b-a" || bad "run beltrami --layout lattice"
bel --particles "$work/b.csv" --out "$work/b-b" || bad "run beltrami file"
same_run "$work/b-a" "$work/b-b" "3D lattice file"

# velocity and pressure from the file: a zero field stays zero
awk -F, '/^#/ { print; next } /^x/ { print "x,y,u_0,u_1,p"; next } { print $1 "," $2 ",0,0,0" }' \
    "$work/lat.csv" >"$work/rest.csv"
"$consph" run taylor-green --scheme l-ipst-c --particles "$work/rest.csv" --steps 2 --format json \
    >"$work/rest.json" || bad "run from a fluid at rest"
grep -q '"kinetic_energy": 0,' "$work/rest.json" && pass=$((pass + 1)) ||
    bad "a fluid at rest moved: $(grep kinetic "$work/rest.json")"

# 140 particles (no perfect square): nx 12, Δs from box volume / N; l-rr-c needs a lattice
grep -v '^# n ' "$work/lat.csv" | head -n 146 >"$work/n140.csv"
"$consph" run taylor-green --scheme l-ipst-c --particles "$work/n140.csv" --steps 2 --format json \
    >"$work/n140.json" || bad "run of 140 particles"
grep -q '"n": 140,' "$work/n140.json" && pass=$((pass + 1)) || bad "140 particles: $(head -5 "$work/n140.json")"
# its checkpoint carries n: a restart continues it bit for bit
"$consph" run taylor-green --scheme l-ipst-c --particles "$work/n140.csv" --steps 4 \
    --checkpoint-every 2 --out "$work/n140-a" >/dev/null || bad "140 particles, checkpointed"
"$consph" run --restart "$work/n140-a/checkpoint.ckpt" --out "$work/n140-b" >/dev/null ||
    bad "140 particles, restarted"
cmp -s "$work/n140-a/snap_000004.vtu" "$work/n140-b/snap_000004.vtu" && pass=$((pass + 1)) ||
    bad "140 particles: the restart differs"
failing 2 "n = 140 particles, not nx^2: scheme 'l-rr-c'" "$work/out" -- "$consph" run taylor-green \
    --scheme l-rr-c --particles "$work/n140.csv" --steps 2 --out "$work/no1" && pass=$((pass + 1))
nothing_written "l-rr-c on 140 particles" "$work/no1"

# files that do not fit: box, periodicity, dimension, an option the file replaces, a bad line
sed 's/^# box 0:1 0:1/# box 0:2 0:2/' "$work/lat.csv" >"$work/box2.csv"
failing 2 "box2.csv: its '# box' comment says [0, 2]x[0, 2], but problem taylor-green is [0, 1]x[0, 1]" \
    "$work/out" -- "$consph" run taylor-green --particles "$work/box2.csv" --out "$work/no2" &&
    pass=$((pass + 1))
sed 's/^# periodic 1 1/# periodic 1 0/' "$work/lat.csv" >"$work/per.csv"
failing 2 "its '# periodic' comment says periodic x, but problem taylor-green is periodic xy" \
    "$work/out" -- "$consph" run taylor-green --particles "$work/per.csv" --out "$work/no2" &&
    pass=$((pass + 1))
failing 2 "lat.csv:7: the header row has no column 'z'" "$work/out" -- "$consph" run beltrami \
    --particles "$work/lat.csv" --out "$work/no2" && pass=$((pass + 1))
failing 2 "option --nx: not with --particles" "$work/out" -- "$consph" run taylor-green \
    --particles "$work/lat.csv" --nx 12 --out "$work/no2" && pass=$((pass + 1))
sed '10s/.*/0.5,nan,0.1/' "$work/lat.csv" >"$work/nan.csv"
failing 2 "nan.csv:10:" "$work/out" -- "$consph" run taylor-green --particles "$work/nan.csv" \
    --out "$work/no2" && pass=$((pass + 1))
nothing_written "refused particle files" "$work/no2"

# --- --config ---
cat >"$work/case.run" <<'EOF'
# Taylor-Green with PySPH's transport-velocity scheme
problem = taylor-green
scheme = tvf   # 001's comparison
nx = 12
steps = 6
log_every = 2
EOF
"$consph" run --config "$work/case.run" --snapshot-every 3 --out "$work/cf-a" >/dev/null ||
    bad "run --config"
"$consph" run taylor-green --scheme tvf --nx 12 --steps 6 --log-every 2 --snapshot-every 3 \
    --out "$work/cf-b" >/dev/null || bad "run with the options"
same_run "$work/cf-a" "$work/cf-b" "--config"
# options replace the file's keys, and the key they clash with (--tf replaces steps)
"$consph" run --config "$work/case.run" --nx 14 --tf 0.01 --format json >"$work/cf.json" ||
    bad "run --config with options"
grep -q '"n": 196,' "$work/cf.json" && grep -q '"t": 0.01,' "$work/cf.json" && pass=$((pass + 1)) ||
    bad "--nx/--tf did not replace the file's keys: $(head -8 "$work/cf.json")"
# the example of examples/ reads (shortened by options)
"$consph" run --config "$(dirname "$0")/../examples/taylor-green.run" --nx 12 --steps 1 >/dev/null &&
    pass=$((pass + 1)) || bad "examples/taylor-green.run"
# refusals: FILE:LINE, the key, exit 2, nothing written
cfg_refused() { # TEXT LINES...: a file of those lines is refused with TEXT
    local text=$1
    shift
    printf '%s\n' "$@" >"$work/bad.run"
    failing 2 "$text" "$work/out" -- "$consph" run --config "$work/bad.run" --out "$work/no3" &&
        pass=$((pass + 1))
}
cfg_refused "bad.run:2: unknown key 'nxx' (allowed: problem, scheme," "problem = taylor-green" "nxx = 20"
cfg_refused "bad.run:2: key 'nx': nx 'abc' is not an integer" "problem = taylor-green" "nx = abc"
cfg_refused "bad.run:3: key 'nx' set twice (first on line 2)" "problem = taylor-green" "nx = 20" "nx = 30"
cfg_refused "bad.run:3: keys 'steps' and 'tf' (line 2) both set the end of the run" \
    "problem = taylor-green" "tf = 1" "steps = 3"
cfg_refused "bad.run:2: key 'alpha' does nothing for --scheme l-ipst-c" "problem = taylor-green" \
    "alpha = 0.2" "steps = 2"
cfg_refused "bad.run:1: expected 'key = value'" "problem taylor-green"
cfg_refused "bad.run:2: '[figure a]': a run file has no sections" "problem = taylor-green" "[figure a]"
cfg_refused "bad.run:1: key 'problem': problem 'nosuch'" "problem = nosuch"
cfg_refused "a problem is required" "nx = 20"
nothing_written "refused run files" "$work/no3"

# --- --restart to another end ---
ext() { "$consph" run --snapshot-every 4 --checkpoint-every 4 "$@" >/dev/null; }
ext taylor-green --scheme l-ipst-c --nx 12 --steps 16 --out "$work/st-a" || bad "16 steps"
ext taylor-green --scheme l-ipst-c --nx 12 --steps 10 --out "$work/st-b" || bad "10 steps"
ext --restart "$work/st-b/checkpoint.ckpt" --steps 16 --out "$work/st-b" || bad "restart --steps 16"
same_run "$work/st-a" "$work/st-b" "restart with more --steps"
# to a later t_f: the first run ends past its last checkpoint (its last step shortened to land
# on t_f), and so does its last snapshot: the restart rewrites from there and removes that one
ext taylor-green --scheme tvf --nx 12 --tf 0.05 --out "$work/tf-a" || bad "tf 0.05"
ext taylor-green --scheme tvf --nx 12 --tf 0.028 --out "$work/tf-b" || bad "tf 0.028"
ext --restart "$work/tf-b/checkpoint.ckpt" --tf 0.05 --out "$work/tf-b" || bad "restart --tf 0.05"
same_run "$work/tf-a" "$work/tf-b" "restart with a later --tf"
# a run of steps continued to a time
ext taylor-green --scheme tvf --nx 12 --steps 9 --out "$work/mix" || bad "9 steps"
ext --restart "$work/mix/checkpoint.ckpt" --tf 0.05 --out "$work/mix" || bad "restart steps -> tf"
same_run "$work/tf-a" "$work/mix" "a run of steps continued to --tf"
# refused: an end not after the checkpoint, the authors' measure, another option
failing 2 "option --steps: checkpoint '$work/st-b/checkpoint.ckpt': steps = 8 is not after the checkpoint's step 12" \
    "$work/out" -- "$consph" run --restart "$work/st-b/checkpoint.ckpt" --steps 8 --out "$work/no4" &&
    pass=$((pass + 1))
ext taylor-green --scheme tvf --nx 12 --tf 0.03 --error authors --error-times 4 --out "$work/au" ||
    bad "authors run"
failing 2 "error = authors: its 4 output times divide the run's own end" "$work/out" -- \
    "$consph" run --restart "$work/au/checkpoint.ckpt" --tf 0.05 --out "$work/no4" &&
    pass=$((pass + 1))
failing 2 "option --nx cannot change a restarted run" "$work/out" -- "$consph" run --restart \
    "$work/au/checkpoint.ckpt" --nx 14 --out "$work/no4" && pass=$((pass + 1))
nothing_written "refused restarts" "$work/no4"

summary cli_run_inputs
