#!/bin/bash
# Rank 0's memory at the samples and outputs (docs/mpi.md, "Costs and limits"): the peak
# resident MB of every rank (/usr/bin/time -f %M per rank) and the bytes the run's MPI line
# reports, for each consph binary given, on the 3D Beltrami flow with L-IPST-C (lattice, one
# thread per rank, no pair cache: CONSPH_PAIR_CACHE_MB=0, so that the gathers weigh), sampling
# every step (--log-every 1). Runs per rank count (FILES): without files (no), with a directory
# whose snapshots are rare (yes: the first and the last), and with a checkpoint at every step
# but the last besides (ckpt). Oversubscribed on a small machine the times mean nothing; the
# memory and the bytes do.
#
# Usage: bench/mpi_rss.sh CONSPH... (each a binary built with MPI; a label "name=path" names
# one). Environment: NX (40), STEPS (4), RANKS ("2 4"), FILES ("no yes"; "no yes ckpt"),
# MPIRUN (default "mpirun --oversubscribe"), WORK.
# Prints one markdown row per binary, rank count and kind of run: binary, K, files, rank 0 MB,
# largest other rank MB, bytes sent in all, bytes per particle-step.
set -u
NX=${NX:-40}
STEPS=${STEPS:-4}
RANKS=${RANKS:-"2 4"}
FILES=${FILES:-"no yes"}
MPIRUN=${MPIRUN:-mpirun --oversubscribe}
WORK=${WORK:-${TMPDIR:-/tmp}/consph_mpi_rss}
export OMP_NUM_THREADS=1 CONSPH_PAIR_CACHE_MB=0
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_mpi_yield_when_idle=1
mkdir -p "$WORK"
N=$((NX * NX * NX))
echo "| binary | ranks | files | rank 0 MB | others MB (max) | bytes sent | per particle-step |"
echo "|---|---|---|---|---|---|---|"
for arg in "$@"; do
    label=${arg%%=*} bin=${arg#*=}
    [ "$label" = "$arg" ] && label=$(basename "$bin")
    for k in $RANKS; do
        for files in $FILES; do
            rm -rf "$WORK"/rss.* "$WORK/out"
            extra=()
            [ $files = yes ] && extra=(--out "$WORK/out" --snapshot-every 0)
            [ $files = ckpt ] && extra=(--out "$WORK/out" --snapshot-every 0 --checkpoint-every 1)
            # shellcheck disable=SC2016
            if ! $MPIRUN -np "$k" sh -c '/usr/bin/time -f %M -o "$0.${OMPI_COMM_WORLD_RANK:-0}" "$@"' \
                "$WORK/rss" "$bin" run beltrami --scheme l-ipst-c --layout lattice --threads 1 \
                --nx "$NX" --steps "$STEPS" --log-every 1 "${extra[@]}" >/dev/null 2>"$WORK/err"; then
                echo "| $label | $k | $files | FAIL: $(head -n 2 "$WORK/err" | tr '\n' ' ') |"
                continue
            fi
            b=$(sed -n 's/^consph run: MPI [0-9]* ranks: \([0-9]*\) bytes sent.*/\1/p' "$WORK/err")
            r0=$(tail -n 1 "$WORK/rss.0")
            rmax=$(for f in "$WORK"/rss.*; do [ "$f" = "$WORK/rss.0" ] || tail -n 1 "$f"; done |
                sort -n | tail -n 1)
            echo "| $label | $k | $files | $((r0 / 1024)) | $((rmax / 1024)) | ${b:-?} |" \
                "$(awk -v b="${b:-0}" -v n=$N -v s="$STEPS" 'BEGIN { printf "%.0f", b / (n * s) }') |"
        done
    done
done
