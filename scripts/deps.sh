#!/usr/bin/env bash
# Installs what consph needs to build and test, on Debian, when run as root; otherwise says what is missing.
set -euo pipefail
need=()
command -v cmake >/dev/null || need+=(cmake)
command -v gcc   >/dev/null || need+=(gcc)
command -v make  >/dev/null || need+=(make)
# zlib: the compressed blocks of .vtu files (CMake's find_package(ZLIB) needs the header).
[ -f /usr/include/zlib.h ] || need+=(zlib1g-dev)
# Optional: the VTK reader that checks our .vtu files, and gnuplot for study figures.
opt=()
/usr/bin/python3 -c 'import vtk' >/dev/null 2>&1 || opt+=(python3-vtk9)
/usr/bin/python3 -c 'import numpy' >/dev/null 2>&1 || opt+=(python3-numpy)
command -v gnuplot >/dev/null || opt+=(gnuplot-nox)
# Optional: the memory checker that `make check` runs every operator under.
command -v valgrind >/dev/null || opt+=(valgrind)
# Optional: OpenMPI for the decomposed solver (src/par) and its multi-rank tests.
{ command -v mpicc >/dev/null && [ -f /usr/lib/x86_64-linux-gnu/openmpi/include/mpi.h ]; } ||
  [ -f /usr/include/x86_64-linux-gnu/openmpi/mpi.h ] || opt+=(libopenmpi-dev openmpi-bin)
# Optional: the Python module (headers) and its example figure (matplotlib).
/usr/bin/python3 -c 'import sysconfig,os,sys; sys.exit(0 if os.path.exists(os.path.join(sysconfig.get_paths()["include"],"Python.h")) else 1)' >/dev/null 2>&1 || opt+=(python3-dev)
/usr/bin/python3 -c 'import matplotlib' >/dev/null 2>&1 || opt+=(python3-matplotlib)
[ ${#need[@]} -eq 0 ] && [ ${#opt[@]} -eq 0 ] && exit 0
if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
  export DEBIAN_FRONTEND=noninteractive
  stamp=/var/lib/apt/periodic/consph-update-stamp
  if ! apt-get install -y --no-install-recommends "${need[@]}" "${opt[@]}" >/tmp/consph-apt.log 2>&1; then
    apt-get update >>/tmp/consph-apt.log 2>&1 || true
    apt-get install -y --no-install-recommends "${need[@]}" >>/tmp/consph-apt.log 2>&1 || {
      echo "consph: could not install required packages: ${need[*]} (see /tmp/consph-apt.log)" >&2; exit 1; }
    [ ${#opt[@]} -eq 0 ] || apt-get install -y --no-install-recommends "${opt[@]}" >>/tmp/consph-apt.log 2>&1 ||
      echo "consph: optional packages not installed: ${opt[*]} (tests that need them are skipped)" >&2
  fi
  : >"$stamp" 2>/dev/null || true
else
  if [ ${#need[@]} -gt 0 ]; then
    echo "consph: missing required tools: ${need[*]}; install them with: sudo apt-get install ${need[*]}" >&2
    exit 1
  fi
  echo "consph: optional packages missing (tests that need them are skipped): ${opt[*]}" >&2
fi
