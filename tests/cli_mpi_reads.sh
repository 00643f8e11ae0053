#!/usr/bin/env bash
# The passes' declarations of what they read at their neighbours (consph_sys_next_reads) are
# complete: with CONSPH_TEST_HALO_POISON set, every halo column a narrowed refresh leaves out is
# NaN until a refresh brings it, so a pass (or a pack fill, check or re-sort) that reads one
# would move the results. Every scheme but l-rr-c (refused on ranks) on 2 and 3 ranks writes
# the serial run's files, 2D on a random layout (particles change cells and ranks) with IPST
# every other step, and two 3D schemes of 001's family and δ+-SPH on Beltrami. Then 001's schemes
# that make their volumes each step again with their passes chained on every rank
# (CONSPH_TEST_CHAIN_SPLIT: the sweep runs a pass only where the one before is known at every
# neighbour, the rest after the refresh, so a visit the sweep should have left shows as NaN).
# Skips (77) without MPI, mpirun or where mpirun cannot start 2 ranks.
# Usage: cli_mpi_reads.sh <path-to-consph> <source-dir>
set -u
bin=$1
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
. "$(dirname "${BASH_SOURCE[0]}")/lib_cli.sh"
"$bin" --version | grep -qx 'MPI not built in' && { echo "skipped: no MPI"; exit 77; }
command -v mpirun >/dev/null || { echo "skipped: no mpirun"; exit 77; }
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_rmaps_base_oversubscribe=1
export OMP_NUM_THREADS=1 OMPI_MCA_mpi_yield_when_idle=1
chain=()
mpi() {
    local np=$1
    shift
    timeout 120 mpirun --oversubscribe -np "$np" env CONSPH_TEST_HALO_POISON=1 "${chain[@]}" "$@"
}
mpi 2 "$bin" --version >"$work/v" 2>&1 && [ "$(grep -c '^MPI ranks 2$' "$work/v")" = 1 ] ||
    { echo "skipped: mpirun cannot start 2 ranks here: $(head -3 "$work/v")"; exit 77; }

check() { # name, run arguments
    local name=$1 np
    shift
    "$bin" run "$@" --out "$work/$name.1" >/dev/null 2>"$work/err" ||
        { bad "$name serial: $(cat "$work/err")"; return; }
    for np in 2 3; do
        mpi $np "$bin" run "$@" --out "$work/$name.$np" >/dev/null 2>"$work/err" ||
            { bad "$name on $np ranks: exit $?: $(head -3 "$work/err")"; continue; }
        same_run "$work/$name.1" "$work/$name.$np" "$name on $np ranks (poisoned halo${chain[*]:+, chained})" &&
            pass=$((pass + 1))
    done
}
for scheme in l-ipst-c l-ipst-f l-ipst-k l-pst-c pe-ipst-c tv-c e-c ewcsph wcsph tvf edac \
    delta-sph delta-plus-sph delta-plus-sph-d; do
    extra=()
    case $scheme in l-ipst-* | pe-ipst-c) extra=(--ipst-every 2) ;; esac
    check "$scheme" taylor-green --scheme "$scheme" --layout random --nx 40 --steps 4 \
        --snapshot-every 2 --log-every 1 "${extra[@]}"
done
for scheme in l-ipst-c e-c delta-plus-sph; do
    check "$scheme-3d" beltrami --scheme "$scheme" --layout lattice --nx 12 --steps 3 \
        --snapshot-every 3 --log-every 1
done
chain=(CONSPH_TEST_CHAIN_SPLIT=1)
for scheme in l-ipst-c l-ipst-f l-ipst-k l-pst-c pe-ipst-c tv-c; do
    extra=()
    case $scheme in l-ipst-* | pe-ipst-c) extra=(--ipst-every 2) ;; esac
    check "$scheme-chained" taylor-green --scheme "$scheme" --layout random --nx 40 --steps 4 \
        --snapshot-every 2 --log-every 1 "${extra[@]}"
done
check l-ipst-c-3d-chained beltrami --scheme l-ipst-c --layout lattice --nx 12 --steps 3 \
    --snapshot-every 3 --log-every 1
# two threads a rank, each rank above the passes' parallel_min (2048): the sweep's blocks shared
# among the threads, some left for after it; what ran in the sweep does not depend on the share
check l-ipst-c-chained-threads taylor-green --scheme l-ipst-c --layout random --nx 72 --steps 3 \
    --snapshot-every 3 --log-every 1 --ipst-every 2 --threads 2
# ranks that choose apart (each by its own halo): the chain forced on some ranks only, by an
# MPMD launch; the passes one by one make the refreshes the chain makes, so none waits alone
apart=(taylor-green --scheme l-ipst-c --layout random --nx 40 --steps 4 --snapshot-every 2
    --log-every 1 --ipst-every 2)
if "$bin" run "${apart[@]}" --out "$work/apart.1" >/dev/null 2>"$work/err"; then
    for spec in "1 1" "1 2"; do
        set -- $spec
        timeout 120 mpirun --oversubscribe -np "$1" env CONSPH_TEST_HALO_POISON=1 \
            CONSPH_TEST_CHAIN_SPLIT=1 "$bin" run "${apart[@]}" --out "$work/apart.$spec" : \
            -np "$2" env CONSPH_TEST_HALO_POISON=1 "$bin" run "${apart[@]}" \
            --out "$work/apart.$spec" >/dev/null 2>"$work/err" ||
            { bad "chained on $1 rank(s), not on $2: exit $?: $(head -3 "$work/err")"; continue; }
        same_run "$work/apart.1" "$work/apart.$spec" "chained on $1 rank(s), not on $2" &&
            pass=$((pass + 1))
    done
else
    bad "apart serial: $(cat "$work/err")"
fi
summary cli_mpi_reads
