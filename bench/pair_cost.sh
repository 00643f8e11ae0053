#!/usr/bin/env bash
# CPU cost of one scheme's steps, robust enough for a shared machine: the user + system CPU
# time of a K2-step run minus that of a K1-step run (the best of REPS each, so start-up and
# particle set-up cancel and other processes' load mostly drops out), over the pairs the extra
# steps visited and over their particle-steps. Serial, lattice start, Taylor-Green.
#   bench/pair_cost.sh CONSPH SCHEME [NX=250] [K1=2] [K2=22] [REPS=5]
# prints: SCHEME ns/pair X us/particle-step Y (cpu T2-T1 s, pairs per particle-step P)
set -euo pipefail
bin=${1:?usage: pair_cost.sh CONSPH SCHEME [NX] [K1] [K2] [REPS]}
scheme=${2:?usage: pair_cost.sh CONSPH SCHEME [NX] [K1] [K2] [REPS]}
nx=${3:-250} k1=${4:-2} k2=${5:-22} reps=${6:-5}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
best_cpu() { # STEPS -> the least CPU seconds over reps; leaves the run's JSON in $tmp/STEPS.json
  local best=1e30 t r
  for r in $(seq "$reps"); do
    t=$( { /usr/bin/time -f "%U %S" "$bin" run taylor-green --scheme "$scheme" --nx "$nx" \
            --steps "$1" --threads 1 --layout lattice --format json >"$tmp/$1.json"; } 2>&1 |
         tail -1 | awk '{print $1 + $2}')
    best=$(awk -v a="$t" -v b="$best" 'BEGIN{print (a < b) ? a : b}')
  done
  echo "$best"
}
key() { grep -o "\"$1\": *[0-9]*" "$2" | grep -o '[0-9]*$'; }
t1=$(best_cpu "$k1")
t2=$(best_cpu "$k2")
p1=$(key pairs "$tmp/$k1.json") p2=$(key pairs "$tmp/$k2.json") n=$(key n "$tmp/$k2.json")
awk -v s="$scheme" -v t1="$t1" -v t2="$t2" -v p1="$p1" -v p2="$p2" -v n="$n" -v k=$((k2 - k1)) \
  'BEGIN{printf "%-16s ns/pair %6.2f  us/particle-step %6.3f  (cpu %s-%s s, pairs per particle-step %.1f)\n",
         s, (t2 - t1) / (p2 - p1) * 1e9, (t2 - t1) / (k * n) * 1e6, t2, t1, (p2 - p1) / (k * n)}'
