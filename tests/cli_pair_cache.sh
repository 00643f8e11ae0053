#!/usr/bin/env bash
# The pair cache's memory budget (CONSPH_PAIR_CACHE_MB, docs/mpi.md): a run whose budget refuses
# the cache writes the files of the run with it bit for bit (summary.json's timings and the
# neighbour list's bytes and note aside), its summary says the cache is off and counts fewer
# bytes per particle; on 2 ranks (where mpirun runs) the same; a bad value exits 2 naming the
# variable.
# Usage: cli_pair_cache.sh <path-to-consph> <source-dir>
set -u
bin=$1
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
. "$(dirname "${BASH_SOURCE[0]}")/lib_cli.sh"

# the budget may change the neighbour list's bytes and note in summary.json
SUMMARY_MASK_NLIST=1
bytes() { sed -n 's/.*"nlist_bytes_per_particle": *\([0-9.eE+]*\).*/\1/p' "$1/summary.json"; }

# skin > 0: the summary reports the list; skin 0: the cache is filled by the search's gather
for skin in 0.2 0; do
    args=(run beltrami --scheme l-ipst-c --nx 10 --steps 3 --snapshot-every 3 --skin $skin)
    "$bin" "${args[@]}" --out "$work/a$skin" >/dev/null 2>"$work/err" ||
        { bad "skin $skin: $(cat "$work/err")"; continue; }
    CONSPH_PAIR_CACHE_MB=0.001 "$bin" "${args[@]}" --out "$work/b$skin" >/dev/null 2>"$work/err" ||
        { bad "skin $skin, budget 1 kB: $(cat "$work/err")"; continue; }
    same_run "$work/a$skin" "$work/b$skin" "skin $skin, budget 1 kB" && pass=$((pass + 1))
    [ "$skin" = 0 ] && continue
    if ! grep -q '"nlist_note": "pair cache off: its pairs would exceed the budget' \
        "$work/b$skin/summary.json" || grep -q '"nlist_note": "pair' "$work/a$skin/summary.json"; then
        bad "skin $skin: the notes: $(grep nlist_note "$work/a$skin/summary.json" "$work/b$skin/summary.json")"
    elif ! awk -v a="$(bytes "$work/a$skin")" -v b="$(bytes "$work/b$skin")" \
        'BEGIN { exit !(b > 0 && 3 * b < a) }'; then
        bad "skin $skin: bytes per particle $(bytes "$work/b$skin") without the cache, $(bytes "$work/a$skin") with"
    else
        pass=$((pass + 1))
    fi
done

for v in abc -1 1e999 "5 MB" 12x; do
    failing 2 "CONSPH_PAIR_CACHE_MB '$v': expected the pair cache's budget in megabytes" /dev/null -- \
        env CONSPH_PAIR_CACHE_MB="$v" "$bin" run beltrami --scheme l-ipst-c --nx 6 --steps 1 \
        --out "$work/bad" && [ ! -e "$work/bad/summary.json" ] && pass=$((pass + 1))
done

# 2 ranks, the cache refused on each: the serial run's files
if ! "$bin" --version | grep -qx 'MPI not built in' && command -v mpirun >/dev/null; then
    export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_rmaps_base_oversubscribe=1
    if CONSPH_PAIR_CACHE_MB=0.001 timeout 120 mpirun --oversubscribe -np 2 -x CONSPH_PAIR_CACHE_MB \
        "$bin" run beltrami --scheme l-ipst-c --nx 10 --steps 3 --snapshot-every 3 --skin 0 \
        --out "$work/m2" >/dev/null 2>"$work/err"; then
        same_run "$work/a0" "$work/m2" "2 ranks, budget 1 kB" && pass=$((pass + 1))
    else
        bad "2 ranks, budget 1 kB: $(cat "$work/err")"
    fi
fi
summary cli_pair_cache
