#!/usr/bin/env bash
# Runs a program with its arguments (tests/test_ops_triples: every op/form/corr triple; the
# consph CLI on small runs) under valgrind's
# memcheck with new memory filled with NaN bytes (0xff) and freed memory with 0xfe, so that a
# read of memory never written both is reported by valgrind and turns a result non-finite,
# which the program checks. Skipped (77) without valgrind, and in the sanitizer build
# (CONSPH_SANITIZED=1), whose shadow memory valgrind cannot run.
set -u
prog=$1
shift
if [ "${CONSPH_SANITIZED:-0}" = 1 ]; then
  echo "skipped: sanitizer build (CONSPH_SANITIZED=1)"
  exit 77
fi
if ! command -v valgrind >/dev/null; then
  echo "skipped: valgrind is not installed (scripts/deps.sh installs it)"
  exit 77
fi
# 3: valgrind found an error; the program's own failures keep their status (1).
valgrind -q --tool=memcheck --error-exitcode=3 --malloc-fill=0xff --free-fill=0xfe \
  --undef-value-errors=yes --leak-check=no "$prog" "$@"
rc=$?
[ $rc -eq 3 ] && echo "memcheck: valgrind reported errors in $prog (see above)" >&2
exit $rc
