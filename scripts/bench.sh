#!/usr/bin/env bash
# `make bench`: every benchmark binary under BUILD/bench, one after the other (never in parallel:
# they measure speed). Results are printed and kept in out/bench/.
set -euo pipefail
build=${1:-build}
mkdir -p out/bench
shopt -s nullglob
for b in "$build"/bench/bench_*; do
  name=$(basename "$b")
  echo "== $name"
  "$b" | tee "out/bench/$name.txt"
done
