#!/usr/bin/env bash
# `make bench`: every benchmark binary under BUILD/bench, one after the other (never in parallel:
# they measure speed), then the speed targets (bench/speed.sh, which writes bench/speed.md; its
# knobs NXS, SCHEMES, THREADS, REPEAT, FULL, ... pass through the environment). Results are printed
# and kept in out/bench/.
set -euo pipefail
build=${1:-build}
mkdir -p out/bench
shopt -s nullglob
for b in "$build"/bench/bench_*; do
  name=$(basename "$b")
  echo "== $name"
  "$b" | tee "out/bench/$name.txt"
done
echo "== bench/speed.sh"
# 77: PySPH is not installed; everything else was measured and written
rc=0
CONSPH=${CONSPH:-$build/consph} sh bench/speed.sh || rc=$?
if [ "$rc" = 77 ]; then
  echo "bench/speed.sh: PySPH comparison skipped (apt-get install -y python3-pysph)"
elif [ "$rc" != 0 ]; then
  exit "$rc"
fi
cp "${OUT:-bench/speed.md}" out/bench/speed.md
