#!/bin/sh
# Where a scheme spends its time: `perf record` of one serial Taylor-Green run on the lattice
# (no packing in the profile), then the top symbols by self time.
# usage: bench/profile.sh SCHEME NX [STEPS]   (from the repository root, after make)
# environment: CONSPH (default build/consph), TOP (symbols printed, default 25), PERF (default
#   perf). Exit 77 when perf is missing or may not record here (perf_event_paranoid, a
#   container): nothing else needs it.
set -eu
scheme=${1:?usage: bench/profile.sh SCHEME NX [STEPS]}
nx=${2:?usage: bench/profile.sh SCHEME NX [STEPS]}
steps=${3:-50}
CONSPH=${CONSPH:-build/consph}
TOP=${TOP:-25}
PERF=${PERF:-perf}
[ -x "$CONSPH" ] || { echo "profile: $CONSPH not built (run make)" >&2; exit 2; }
command -v "$PERF" > /dev/null 2>&1 || { echo "profile: $PERF not found: no profile" >&2; exit 77; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
cmd="$CONSPH run taylor-green --scheme $scheme --nx $nx --layout lattice --steps $steps --threads 1"
# cycles where the hardware counts them, else the kernel's cpu-clock (a VM or container)
if ! "$PERF" record -o "$tmp/perf.data" -- $cmd > /dev/null 2> "$tmp/err" &&
    ! "$PERF" record -e cpu-clock -o "$tmp/perf.data" -- $cmd > /dev/null 2> "$tmp/err"; then
    echo "profile: perf record failed: $(tail -n 3 "$tmp/err")" >&2
    exit 77
fi
echo "$cmd"
"$PERF" report -i "$tmp/perf.data" --stdio --no-children --sort symbol 2> /dev/null |
    grep -v '^#' | grep -v '^$' | head -n "$TOP" | sed 's/ *- *- *$//'
