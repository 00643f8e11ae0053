#!/usr/bin/env bash
# The top-level CLI: help, version, unknown commands.
set -u
consph=$1
fail=0
expect() { # expect STATUS DESCRIPTION -- command...
  local want=$1 what=$2; shift 3
  "$@" >/tmp/cli_main.$$.out 2>/tmp/cli_main.$$.err
  local got=$?
  if [ "$got" != "$want" ]; then echo "FAIL: $what: exit $got, want $want"; cat /tmp/cli_main.$$.err; fail=1; fi
}
expect 0 "--help" -- "$consph" --help
grep -q "commands:" /tmp/cli_main.$$.out || { echo "FAIL: --help lists no commands"; fail=1; }
expect 0 "--version" -- "$consph" --version
grep -q "^consph [0-9]" /tmp/cli_main.$$.out || { echo "FAIL: --version"; fail=1; }
expect 2 "no command" -- "$consph"
expect 2 "unknown command" -- "$consph" frobnicate
grep -q "unknown command 'frobnicate'; allowed:" /tmp/cli_main.$$.err || { echo "FAIL: unknown command message"; fail=1; }
for cmd in $("$consph" --help | awk '/^commands:/{f=1;next} f&&!NF{exit} f{print $1}'); do
  expect 0 "$cmd --help" -- "$consph" "$cmd" --help
  grep -q "^usage: consph $cmd" /tmp/cli_main.$$.out || { echo "FAIL: $cmd --help has no usage line"; fail=1; }
  expect 2 "$cmd unknown option" -- "$consph" "$cmd" --no-such-option
  [ "$(wc -l </tmp/cli_main.$$.err)" = 1 ] || { echo "FAIL: $cmd: error is not one line"; fail=1; }
  grep -q -- "--no-such-option" /tmp/cli_main.$$.err || { echo "FAIL: $cmd: error does not name the option"; fail=1; }
done
# Without a user's choice the CLI runs with a short spin, GOMP_SPINCOUNT=2000 (libgomp's default
# spinning makes 2 threads slower than 1 on a loaded machine, sleeping at once makes every fork
# and join a wake-up); a user's policy or spin count is kept; arguments and exit status survive
# the re-execution.
# (a build without OpenMP has no policy to report: its --version says so)
if "$consph" --version | grep -q "^threads 1 (built without OpenMP)$"; then
    :
else
expect 0 "--version, no policy" -- env -u OMP_WAIT_POLICY -u GOMP_SPINCOUNT "$consph" --version
grep -q "OMP_WAIT_POLICY unset (libgomp default), GOMP_SPINCOUNT 2000$" /tmp/cli_main.$$.out || { echo "FAIL: default wait policy: $(cat /tmp/cli_main.$$.out)"; fail=1; }
expect 0 "--version, active" -- env OMP_WAIT_POLICY=active "$consph" --version
grep -q "OMP_WAIT_POLICY active$" /tmp/cli_main.$$.out || { echo "FAIL: user's wait policy not kept: $(cat /tmp/cli_main.$$.out)"; fail=1; }
expect 0 "--version, spin count" -- env -u OMP_WAIT_POLICY GOMP_SPINCOUNT=1000 "$consph" --version
grep -q "OMP_WAIT_POLICY unset (libgomp default), GOMP_SPINCOUNT 1000$" /tmp/cli_main.$$.out || { echo "FAIL: GOMP_SPINCOUNT not respected: $(cat /tmp/cli_main.$$.out)"; fail=1; }
fi
expect 0 "re-executed run" -- env -u OMP_WAIT_POLICY -u GOMP_SPINCOUNT "$consph" kernel cubic --dim 2 --points 3 --format csv
[ "$(wc -l </tmp/cli_main.$$.out)" -ge 3 ] || { echo "FAIL: re-executed kernel table: $(cat /tmp/cli_main.$$.out)"; fail=1; }
expect 2 "re-executed bad usage" -- env -u OMP_WAIT_POLICY -u GOMP_SPINCOUNT "$consph" kernel cubic --dim 7
# valgrind cannot run an ASan binary: the sanitizer build checks the rest.
if command -v valgrind >/dev/null && [ "${CONSPH_SANITIZED:-0}" != 1 ]; then
    expect 0 "under valgrind" -- env -u OMP_WAIT_POLICY -u GOMP_SPINCOUNT valgrind -q --error-exitcode=3 "$consph" --version
fi
rm -f /tmp/cli_main.$$.out /tmp/cli_main.$$.err
[ $fail = 0 ] && echo "cli_main: 1 passed, 0 failed" || echo "cli_main: 0 passed, 1 failed"
exit $fail
