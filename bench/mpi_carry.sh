#!/bin/sh
# Packs this machine's OpenMPI 4.1 run-time and an MPI build of consph into one folder that
# another Linux machine without OpenMPI (same architecture, glibc at least this one's) can run
# from: bench/mpi_device.sh inside it sets OPAL_PREFIX, PMIX_PREFIX and LD_LIBRARY_PATH to it.
#
# Layout (Debian's prefix /usr mirrored, so OPAL_PREFIX=DIR/usr relocates every path):
#   DIR/usr/bin/            orterun (also as mpirun), orted, ompi_info
#   DIR/usr/lib/x86_64-linux-gnu/  libmpi, libopen-rte, libopen-pal and every library they, the
#                           components and consph need that is not glibc's (ldd), by soname,
#                           as plain files (no links: the copy may travel without them)
#   .../openmpi/lib/openmpi3/  the MCA components of a single-node shared-memory run (COMPONENTS)
#   .../pmix2/              PMIx (external in Debian's OpenMPI): library, components, help
#   DIR/usr/share/openmpi/  help and data files
#   DIR/bin/                consph and bench_par (Release, -DCONSPH_MPI=ON, -DCONSPH_CUDA=OFF)
#   DIR/scripts/            bench/mpi.sh, bench/mpi_device.sh, bench/mpi_strong.sh,
#                           tests/lib_cli.sh: the folder is
#                           self-contained, a checkout without this branch can run it
#
# With BEFORE=BINARY in the environment, that consph (an MPI build of an earlier commit) goes in
# as DIR/bin/consph-before, with BEFORE_NOTE (what it is) in DIR/bin/consph-before.txt:
# mpi_device.sh then measures its largest weak case too.
#
# usage: bench/mpi_carry.sh [DIR] [BUILD]   (from anywhere; DIR default mpi-carry, BUILD default
#   build, both relative to the repository root unless absolute; BUILD is configured (Release,
#   MPI, no CUDA) where it has no CMakeCache.txt, and consph and bench_par rebuilt in it, so never
#   older than the sources). consph's RUNPATH names the
#   system's OpenMPI folder, which LD_LIBRARY_PATH overrides and the target does not have.
set -eu

DIR=${1:-mpi-carry}
BUILD=${2:-build}
ROOT=$(cd "$(dirname "$0")/.." && pwd)
ARCH=x86_64-linux-gnu
SYSLIB=/usr/lib/$ARCH
# What `mpirun -np K consph` needs on one node with btl self,vader and pml ob1 (checked by
# running 2 ranks with the system's OpenMPI hidden: bench/mpi_carry_check.sh). Left out: the
# network transports (btl tcp/openib/ofi, mtl, pml ucx/cm), MPI-IO, OpenSHMEM, Slurm, Flux,
# monitoring, debugger support.
COMPONENTS=${COMPONENTS:-"allocator_basic allocator_bucket bml_r2 btl_self btl_vader
    coll_basic coll_libnbc coll_self coll_sm coll_tuned crs_none
    errmgr_default_app errmgr_default_hnp errmgr_default_orted errmgr_default_tool
    ess_env ess_hnp ess_pmi ess_singleton ess_tool filem_raw grpcomm_direct
    iof_hnp iof_orted iof_tool mpool_hugepage odls_default odls_pspawn oob_tcp op_avx
    osc_pt2pt osc_rdma osc_sm patcher_overwrite plm_isolated plm_rsh pml_ob1 pmix_ext3x
    pstat_linux rcache_grdma reachable_weighted regx_fwd regx_naive regx_reverse
    rmaps_mindist rmaps_ppr rmaps_rank_file rmaps_resilient rmaps_round_robin rmaps_seq
    rml_oob routed_binomial routed_direct routed_radix rtc_hwloc schizo_ompi schizo_orte
    shmem_mmap shmem_posix shmem_sysv state_app state_hnp state_novm state_orted state_tool
    topo_basic"}

cd "$ROOT"
[ -x /usr/bin/orterun ] || { echo "mpi_carry: no OpenMPI here (/usr/bin/orterun)" >&2; exit 2; }
# configured where it is not yet; built (incrementally) always, so that binaries older than the
# sources are never carried
[ -f "$BUILD/CMakeCache.txt" ] ||
    cmake -S . -B "$BUILD" -DCMAKE_BUILD_TYPE=Release -DCONSPH_MPI=ON -DCONSPH_CUDA=OFF >/dev/null
cmake --build "$BUILD" -j "$(nproc)" --target consph bench_par >/dev/null ||
    { echo "mpi_carry: building consph and bench_par in $BUILD failed" >&2; exit 2; }
"$BUILD/consph" --version | grep -qx 'MPI ranks 1' ||
    { echo "mpi_carry: $BUILD/consph is not an MPI build" >&2; exit 2; }

rm -rf "$DIR"
L=$DIR/usr/lib/$ARCH
mkdir -p "$DIR/usr/bin" "$DIR/bin" "$L/openmpi/lib/openmpi3" "$L/pmix2/lib/pmix" \
    "$L/pmix2/share" "$DIR/usr/share" "$DIR/scripts/bench" "$DIR/scripts/tests"
cp -L /usr/bin/orterun /usr/bin/orted /usr/bin/ompi_info "$DIR/usr/bin/"
cp -L /usr/bin/orterun "$DIR/usr/bin/mpirun"
cp -L "$BUILD/consph" "$BUILD/bench/bench_par" "$DIR/bin/"
strip "$DIR/bin/consph" "$DIR/bin/bench_par"
if [ -n "${BEFORE:-}" ]; then
    cp -L "$BEFORE" "$DIR/bin/consph-before"
    strip "$DIR/bin/consph-before" 2>/dev/null || true
    echo "${BEFORE_NOTE:-an earlier commit}" >"$DIR/bin/consph-before.txt"
fi
for c in $COMPONENTS; do
    cp -L "$SYSLIB/openmpi/lib/openmpi3/mca_$c.so" "$L/openmpi/lib/openmpi3/"
done
cp -L "$SYSLIB"/pmix2/lib/pmix/*.so "$L/pmix2/lib/pmix/"
cp -RL "$SYSLIB/pmix2/share/." "$L/pmix2/share/"
cp -RL /usr/share/openmpi "$DIR/usr/share/"
cp bench/mpi.sh bench/mpi_device.sh bench/mpi_strong.sh "$DIR/scripts/bench/"
cp tests/lib_cli.sh "$DIR/scripts/tests/"

# Every library the binaries and components load, glibc's own left to the target: by soname,
# as plain files, in the flat folder (and PMIx's copy where its prefix expects it).
GLIBC='^(linux-vdso|ld-linux|libc|libm|libpthread|libdl|librt|libresolv|libutil|libmvec)\.so'
ldd "$DIR"/usr/bin/* "$DIR"/bin/consph* "$DIR"/bin/bench_par "$L"/openmpi/lib/openmpi3/*.so "$L"/pmix2/lib/pmix/*.so 2>/dev/null |
    awk '$2 == "=>" && $3 ~ /^\// { print $1, $3 } $2 == "=>" && $3 == "not" { print $1, "MISSING" }' |
    sort -u >"$DIR/libs.txt"
if grep -q MISSING "$DIR/libs.txt"; then
    echo "mpi_carry: libraries not found here:" >&2
    grep MISSING "$DIR/libs.txt" >&2
    exit 1
fi
grep -Ev "$GLIBC" "$DIR/libs.txt" | while read -r so path; do
    cp -L "$path" "$L/$so"
done
cp -L "$SYSLIB/libpmix.so.2" "$L/pmix2/lib/libpmix.so.2"
rm -f "$DIR/libs.txt"
echo "mpi_carry: $DIR: $(du -sh "$DIR" | cut -f1), $(find "$DIR" -type f | wc -l) files" >&2
