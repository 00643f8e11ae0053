#!/usr/bin/env bash
# A failed write on standard output is never exit 0: every command, its
# --help, and consph's own --help and --version, run with stdout on /dev/full (every write fails
# with ENOSPC), exit 1 with one line "consph[ COMMAND]: cannot write standard output: No space
# left on device"; a command that fails for its own reason keeps its status (2 for bad usage).
# Usage: cli_stdout.sh <path-to-consph> <source-dir>
set -u
bin=$1
[ -w /dev/full ] || { echo "cli_stdout: no /dev/full, skipped"; exit 77; }
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
. "$(dirname "${BASH_SOURCE[0]}")/lib_cli.sh"
# full NAME -- command...: exit 1 and the message, naming the command (NAME "" for consph's own).
full() {
    local name=$1
    shift 2
    local want="consph${name:+ $name}: cannot write standard output: No space left on device"
    failing 1 "$want" /dev/full -- "$@" || return
    # That line alone (besides a study's progress lines, `study: row ...`).
    [ "$(grep -v '^study: row ' "$work/err")" = "$want" ] && pass=$((pass + 1)) || bad "$*: stderr '$(cat "$work/err")'"
}
"$bin" layout --kind lattice --dim 1 --nx 16 --out "$work/a.csv" >/dev/null || bad "layout setup"
full "" -- "$bin" --help
full "" -- "$bin" help
full "" -- "$bin" --version
for cmd in kernels kernel layout approx study wasserstein run; do
    full "$cmd" -- "$bin" "$cmd" --help
done
full kernels -- "$bin" kernels
full kernels -- "$bin" kernels --format csv
full kernel -- "$bin" kernel cubic --dim 2
# More than a buffer's worth: the reason of the first failed write is kept.
full kernel -- "$bin" kernel cubic --dim 2 --points 5000
full layout -- "$bin" layout --kind lattice --dim 2 --nx 10
full layout -- "$bin" layout --in "$work/a.csv"
for fmt in table csv json; do full approx -- "$bin" approx --op grad --nx 10 --format $fmt; done
full run -- "$bin" run taylor-green --scheme wcsph --nx 8 --steps 2
full run -- "$bin" run taylor-green --scheme wcsph --nx 8 --steps 2 --format json
full run -- "$bin" run heat --laplacian s3 --nx 8 --eta 2 --steps 2
full run -- "$bin" run heat --laplacian s3 --nx 8 --eta 2 --steps 2 --format json
full study -- "$bin" study --list
full study -- "$bin" study 003-appc --quick --out "$work"
full wasserstein -- "$bin" wasserstein "$work/a.csv" "$work/a.csv"
# Bad usage keeps its status 2 and its own message.
failing 2 "option --op" /dev/full -- "$bin" approx --op nosuch && pass=$((pass + 1))
# A working stdout is unchanged: exit 0, the output there, nothing on stderr.
"$bin" --version >"$work/out" 2>"$work/err" && grep -q "^consph [0-9]" "$work/out" &&
    [ ! -s "$work/err" ] && pass=$((pass + 1)) || bad "--version to a file"
summary cli_stdout
