#!/bin/sh
# Runs a command with this machine's OpenMPI hidden, so that only a folder packed by
# bench/mpi_carry.sh can serve it: in a private mount namespace (unshare -m, as root), empty
# tmpfs over OpenMPI's and PMIx's folders and /dev/null over each of their libraries and
# programs. What the command loads from the hidden files fails; the host is not touched.
#
# usage: bench/mpi_carry_check.sh COMMAND [ARG...]
#   e.g. bench/mpi_carry_check.sh bash mpi-carry/scripts/bench/mpi_device.sh /tmp/out
set -eu
[ $# -gt 0 ] || { echo "usage: $0 COMMAND [ARG...]" >&2; exit 2; }
if [ "${MPI_CARRY_HIDDEN:-}" != 1 ]; then
    exec env MPI_CARRY_HIDDEN=1 unshare -m --propagation private "$0" "$@"
fi
L=/usr/lib/x86_64-linux-gnu
for d in "$L/openmpi" "$L/pmix2" /usr/share/openmpi /etc/openmpi; do
    [ -d "$d" ] && mount -t tmpfs none "$d"
done
for f in "$L"/libmpi.so.* "$L"/libopen-rte.so.* "$L"/libopen-pal.so.* "$L"/libpmix.so.* \
    "$L"/libhwloc.so.* "$L"/libevent*.so.* "$L"/libmunge.so.* "$L"/libmca_common_*.so.* \
    /usr/bin/orterun /usr/bin/orted /usr/bin/ompi_info /usr/bin/mpirun.openmpi; do
    [ -f "$f" ] && [ ! -L "$f" ] && mount --bind /dev/null "$f"
done
echo "mpi_carry_check: system OpenMPI hidden ($(ls "$L/openmpi" | wc -l) entries in $L/openmpi; mpirun on PATH: $(command -v mpirun || echo none))" >&2
exec "$@"
