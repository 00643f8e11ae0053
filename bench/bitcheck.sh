#!/usr/bin/env bash
# Checks that a speed-up changed no result: runs every scheme with two consph binaries (say one
# built from main and one from the branch) and compares summary.json (all but "seconds"),
# log.csv and run.pvd byte for byte, and every snapshot array by array, value for value
# (bench/snapdiff.sh: the arrays renamed by the declared state are found under their old names;
# arrays the reference wrote and the new binary no longer does are not compared).
#   bench/bitcheck.sh REF_CONSPH NEW_CONSPH [WORKDIR]
# NEW_FLAGS (environment): options added to every run of NEW_CONSPH only, e.g.
# NEW_FLAGS="--skin 0" to compare a neighbour list that rebuilds every step with the reference.
# REF_CONSPH may instead be the "ref" directory of an earlier bitcheck's WORKDIR, whose results
# are then reused (the reference binary's runs are the same every time).
# Cases, each at 1 and 2 threads (nx 48: 2304 particles, above the 2048 at which passes go
# parallel): Taylor-Green 20 steps (the Lagrangian schemes from their packed start, IPST every
# 10 steps), Gresho-Chan and the shear layer 10 steps on the lattice; and for wcsph, tvf and edac
# h/Δs 2 (more than 64 neighbours: several blocks per visit), α = 0, and the cubic spline with
# α = 0.5; and, where the binary has it, the 3D Beltrami flow 5 steps on the 14³ lattice (2744
# particles), whose 1- and 2-thread results must also agree with each other. Takes a few minutes
# on 2 cores. Exit status 1 when anything differs.
set -uo pipefail
ref=${1:?usage: bitcheck.sh REF_CONSPH NEW_CONSPH [WORKDIR]}
new=${2:?usage: bitcheck.sh REF_CONSPH NEW_CONSPH [WORKDIR]}
work=${3:-$(mktemp -d)}
# fresh output directories: consph run refuses to overwrite an earlier run's files, and a stale
# one left from an earlier bitcheck in WORKDIR would be compared in place of a run that failed
rm -rf "$work/new" && mkdir -p "$work/new" || exit 2
if [ -d "$ref" ]; then
  refdir=$ref
else
  refdir=$work/ref
  rm -rf "$refdir" && mkdir -p "$refdir" || exit 2
fi
# every scheme of the new binary's registry (consph run --help, --scheme's allowed names); a
# scheme the reference binary lacks fails its reference runs and is not compared
schemes=$("$new" run --help 2>&1 | sed -n 's/^ *--scheme S .*(\([a-z0-9,+-]*\); default .*/\1/p' | tr , ' ')
[ -n "$schemes" ] || { echo "no scheme list in $new run --help"; exit 2; }

run_all() { # BIN DIR [FLAGS]
  local bin=$1 dir=$2 s th
  local -a flags
  read -r -a flags <<< "${3:-}"
  for s in $schemes; do
    for th in 1 2; do
      "$bin" run taylor-green --scheme "$s" --nx 48 --steps 20 --threads $th "${flags[@]}" --out "$dir/tg-$s-$th" >/dev/null 2>&1 || echo "run failed: tg $s $th"
      "$bin" run gresho-chan --scheme "$s" --nx 48 --steps 10 --threads $th "${flags[@]}" --layout lattice --out "$dir/gc-$s-$th" >/dev/null 2>&1 || echo "run failed: gc $s $th"
      "$bin" run shear-layer --scheme "$s" --nx 48 --steps 10 --threads $th "${flags[@]}" --out "$dir/sl-$s-$th" >/dev/null 2>&1 || echo "run failed: sl $s $th"
    done
  done
  if "$bin" run --help 2>&1 | grep beltrami > /dev/null; then
    for s in $schemes; do
      for th in 1 2; do
        "$bin" run beltrami --scheme "$s" --nx 14 --steps 5 --threads $th "${flags[@]}" --layout lattice --out "$dir/be-$s-$th" >/dev/null 2>&1 || echo "run failed: be $s $th"
      done
    done
  fi
  for s in wcsph tvf edac; do
    a0=""
    a5=""
    [ $s = wcsph ] && a0="--alpha 0" && a5="--alpha 0.5" # only wcsph of the three reads α
    for th in 1 2; do
      "$bin" run taylor-green --scheme $s --nx 48 --hdx 2 --steps 10 --threads $th "${flags[@]}" --out "$dir/h2-$s-$th" >/dev/null 2>&1 || echo "run failed: h2 $s $th"
      "$bin" run taylor-green --scheme $s --nx 48 $a0 --steps 10 --threads $th "${flags[@]}" --out "$dir/a0-$s-$th" >/dev/null 2>&1 || echo "run failed: a0 $s $th"
      "$bin" run taylor-green --scheme $s --nx 48 --kernel cubic $a5 --steps 10 --threads $th "${flags[@]}" --out "$dir/cu-$s-$th" >/dev/null 2>&1 || echo "run failed: cu $s $th"
    done
  done
}

[ -d "$ref" ] || run_all "$ref" "$refdir"
bad=0 cases=0
# a run of the new binary that fails is a difference (the reference's may fail where it lacks a
# scheme: those cases have no reference and are not compared)
failed=$(run_all "$new" "$work/new" "${NEW_FLAGS:-}")
[ -n "$failed" ] && { echo "$failed"; bad=1; }
for d in "$refdir"/*/; do
  n=$(basename "$d")
  cases=$((cases + 1))
  if ! diff <(grep -v '"seconds"' "$d/summary.json") <(grep -v '"seconds"' "$work/new/$n/summary.json" 2>/dev/null) >/dev/null; then
    echo "differs: $n summary.json"
    bad=1
  fi
  for f in "$d"/*.csv "$d"/run.pvd; do
    cmp -s "$f" "$work/new/$n/$(basename "$f")" || { echo "differs: $n $(basename "$f")"; bad=1; }
  done
  for f in "$d"/*.vtu; do
    g=$work/new/$n/$(basename "$f")
    cmp -s "$f" "$g" && continue # the same binary's snapshot: nothing renamed
    out=$(bash "$(dirname "$0")/snapdiff.sh" "$new" "$f" "$g" "$work/snapdiff") ||
      { echo "differs: $n $(basename "$f"): $(echo "$out" | head -3)"; bad=1; }
  done
done
# the thread count changes no bit of a 3D run either
for d in "$work"/new/be-*-1/; do
  [ -d "$d" ] || continue
  n=$(basename "$d" -1)
  cases=$((cases + 1))
  diff <(grep -v '"seconds"' "$d/summary.json") <(grep -v '"seconds"' "$work/new/$n-2/summary.json" 2>/dev/null) >/dev/null || { echo "differs: $n 1 vs 2 threads summary.json"; bad=1; }
  for f in "$d"/*.csv "$d"/*.vtu; do
    cmp -s "$f" "$work/new/$n-2/$(basename "$f")" || { echo "differs: $n 1 vs 2 threads $(basename "$f")"; bad=1; }
  done
done
echo "bitcheck: $cases cases in $work, $([ $bad = 0 ] && echo identical || echo DIFFERENT)"
exit $bad
