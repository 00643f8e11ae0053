#!/usr/bin/env bash
# Compares two run snapshots array by array, value for value (bits, through the %.17g text of
# `consph layout --in X.vtu --out X.csv`, which reads back to the same doubles):
#   bench/snapdiff.sh CONSPH REF.vtu NEW.vtu [WORKDIR]
# REF may be a snapshot of a binary from before the declared state (docs/solver-files.md,
# "Snapshot arrays"), whose arrays had the fields' own names; NEW's arrays are then looked up
# under the renames below. Every array of NEW must match one of REF (positions, the box,
# periodicity and spacing too); REF's arrays that NEW no longer writes (integrator scratch,
# intermediate derivatives) are not compared. A vector is written with 3 components in both; a
# tensor was written with d² (row-major) and is now 3 × 3: its entries beyond d must be zero.
# NEW's TimeValue must equal REF's time in REF's run.pvd, when there is one. Exit status 1 when
# anything differs, printing what.
set -uo pipefail
bin=${1:?usage: snapdiff.sh CONSPH REF.vtu NEW.vtu [WORKDIR]}
ref=${2:?usage: snapdiff.sh CONSPH REF.vtu NEW.vtu [WORKDIR]}
new=${3:?usage: snapdiff.sh CONSPH REF.vtu NEW.vtu [WORKDIR]}
work=${4:-$(mktemp -d)}
mkdir -p "$work" || exit 2
# new name -> old name (the renames of docs/solver-files.md)
renames="velocity=u pressure=p density=rhof summation_density=rhof velocity_exact=u_exact
pressure_exact=p_exact velocity_gradient=gradu"
tensors="velocity_gradient"

"$bin" layout --in "$ref" --out "$work/ref.csv" >/dev/null || { echo "cannot read $ref"; exit 1; }
"$bin" layout --in "$new" --out "$work/new.csv" >/dev/null || { echo "cannot read $new"; exit 1; }
bad=0
if [ -f "$(dirname "$ref")/run.pvd" ]; then
  t_ref=$(sed -n "s/.*timestep=\"\([^\"]*\)\" file=\"$(basename "$ref")\".*/\1/p" "$(dirname "$ref")/run.pvd")
  t_new=$(grep -ao 'Name="TimeValue"[^>]*> *[^<]*' "$new" | sed 's/.*> *//')
  [ -n "$t_new" ] && [ "$t_new" = "$t_ref" ] || { echo "TimeValue '$t_new' is not the time $t_ref of $(basename "$ref")"; bad=1; }
fi
awk -F, -v renames="$renames" -v tensors="$tensors" '
  BEGIN {
    n = split(renames, rr, /[ \n]+/)
    for (k = 1; k <= n; ++k) { split(rr[k], kv, "="); old_of[kv[1]] = kv[2] }
    n = split(tensors, tt, " ")
    for (k = 1; k <= n; ++k) tensor[tt[k]] = 1
  }
  FNR == 1 { file++ }
  /^#/ { if (file == 1) rc[++nrc] = $0; else if ($0 != rc[++mrc]) { print "differs: " $0; bad = 1 }
         if ($0 ~ /^# dim /) dim = substr($0, 7) + 0; next }
  !seen[file]++ {
    if (file == 1) { for (k = 1; k <= NF; ++k) rcol[$k] = k; next }
    # the header of NEW: the column of REF each of its columns holds (0: a zero)
    for (k = 1; k <= NF; ++k) {
      name = hname[k] = $k; base = name; comp = ""
      if (match(name, /_[0-9]+$/)) { base = substr(name, 1, RSTART - 1); comp = substr(name, RSTART + 1) + 0 }
      old = (base in old_of) ? old_of[base] : base
      if ((base in tensor) && comp != "") {
        r = int(comp / 3); c = comp % 3
        src[k] = (r < dim && c < dim) ? rcol[old "_" (r * dim + c)] : 0
        if (r < dim && c < dim && !src[k]) { print "no array in REF for " name; bad = 1; exit }
      } else {
        key = comp == "" ? old : old "_" comp
        if (!(key in rcol)) { print "no array in REF for " name " (" key ")"; bad = 1; exit }
        src[k] = rcol[key]
      }
    }
    ncol = NF; next
  }
  file == 1 { row[FNR] = $0; nrow = FNR; next }
  {
    if (!(FNR in row)) { print "NEW has more particles"; bad = 1; exit }
    split(row[FNR], rv, ",")
    for (k = 1; k <= ncol; ++k) {
      want = src[k] ? rv[src[k]] : "0"
      if ($k != want && !reported[k]++) { print "differs: " hname[k] " at line " FNR ": " $k " vs " want; bad = 1 }
    }
    last = FNR
  }
  END { if (!bad && last != nrow) { print "NEW has " last " lines, REF " nrow; bad = 1 } exit bad }
' "$work/ref.csv" "$work/new.csv" || bad=1
exit $bad
