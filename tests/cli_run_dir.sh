#!/usr/bin/env bash
# consph run's refusals before any work: a new run refuses an --out
# DIR holding another run's files unless --overwrite, which removes exactly those; a restart
# continues only its own run's directory (run.id) and refuses a run.pvd that does not read back;
# options that would do nothing in their combination are refused; a size past the stated limit
# or the machine's memory is refused naming --nx, the estimate and the limit (in a study too,
# with file:line). Every refusal: exit 2, DIR untouched. test_solver checks the memory rule.
# Usage: bash cli_run_dir.sh PATH-TO-CONSPH
set -u
consph=$1
fail=0
bad() { echo "FAIL: $*"; fail=1; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
run() { "$consph" run taylor-green --scheme e-c --nx 12 "$@"; }
# a listing with checksums: what "untouched" means
state() { (cd "$1" && for f in $(ls -A | sort); do printf '%s ' "$f"; cksum <"$f"; done); }

# expect_refused WHAT PATTERN DIR ARGS...: exit 2, a message matching PATTERN, DIR unchanged
expect_refused() {
    local what=$1 pattern=$2 dir=$3
    shift 3
    local before
    before=$(state "$dir")
    # within seconds: the pre-change consph spent them allocating a size it could not hold
    timeout 20 "$consph" "$@" >"$tmp/out" 2>"$tmp/err"
    local rc=$?
    [ $rc -eq 2 ] || bad "$what: exit $rc, expected 2"
    grep -q -- "$pattern" "$tmp/err" || bad "$what: message '$(cat "$tmp/err")' lacks '$pattern'"
    [ "$(state "$dir")" = "$before" ] || bad "$what: $dir changed"
}

# --- a new, shorter run in a used directory ---
run --steps 8 --checkpoint-every 4 --out "$tmp/a" >/dev/null || bad "first run"
[ -s "$tmp/a/checkpoint.ckpt" ] && [ -s "$tmp/a/snap_000008.vtu" ] && [ -s "$tmp/a/run.id" ] ||
    bad "first run: files missing: $(ls "$tmp/a")"
echo "mine" >"$tmp/a/notes.txt"
echo "mine" >"$tmp/a/snap_final.vtu"
expect_refused "used --out" "'$tmp/a' already holds the files of a run.*--overwrite" "$tmp/a" \
    run taylor-green --scheme e-c --nx 12 --steps 4 --out "$tmp/a"
run --steps 4 --out "$tmp/a" --overwrite >/dev/null || bad "--overwrite: exit $?"
[ ! -e "$tmp/a/checkpoint.ckpt" ] || bad "--overwrite: the earlier run's checkpoint is left"
[ ! -e "$tmp/a/snap_000008.vtu" ] || bad "--overwrite: the earlier run's later snapshot is left"
[ -s "$tmp/a/snap_000004.vtu" ] || bad "--overwrite: the new run's last snapshot is missing"
[ "$(grep -c '<DataSet' "$tmp/a/run.pvd")" -eq 2 ] || bad "--overwrite: run.pvd is not the new run's"
[ "$(cat "$tmp/a/notes.txt" "$tmp/a/snap_final.vtu")" = "$(printf 'mine\nmine')" ] ||
    bad "--overwrite removed files that are not a run's"

# --- restart into another run's directory, and into its own ---
run --steps 8 --checkpoint-every 4 --out "$tmp/b" >/dev/null || bad "run b"
cp "$tmp/b/checkpoint.ckpt" "$tmp/b.ckpt"
expect_refused "restart into another run's directory" "holds the files of another run" "$tmp/a" \
    run --restart "$tmp/b.ckpt" --out "$tmp/a"
"$consph" run --restart "$tmp/b/checkpoint.ckpt" --out "$tmp/b" >/dev/null || bad "restart into its own directory"
"$consph" run --restart "$tmp/b.ckpt" --out "$tmp/b2" >/dev/null || bad "restart into a new directory"
cmp -s "$tmp/b/snap_000008.vtu" "$tmp/b2/snap_000008.vtu" || bad "restart into a new directory differs"
"$consph" run heat --nx 8 --steps 3 --out "$tmp/h" >/dev/null || bad "heat run"
expect_refused "restart into a directory without run.id" "no valid run.id" "$tmp/h" \
    run --restart "$tmp/b.ckpt" --out "$tmp/h"
# a run.pvd that does not read back is named, not replaced
printf 'garbage\n' >>"$tmp/b/run.pvd"
expect_refused "corrupt run.pvd" "run.pvd:.*unexpected line" "$tmp/b" \
    run --restart "$tmp/b/checkpoint.ckpt" --out "$tmp/b"

# --- run heat: the same rule ---
expect_refused "heat: used --out" "already holds the files of a run" "$tmp/h" \
    run heat --nx 8 --steps 2 --out "$tmp/h"
"$consph" run heat --nx 8 --steps 2 --out "$tmp/h" --overwrite >/dev/null || bad "heat --overwrite"
[ ! -e "$tmp/h/snap_000003.vtu" ] || bad "heat --overwrite: the earlier run's last snapshot is left"

# --- options that would do nothing ---
mkdir -p "$tmp/e"
expect_refused "--steps with --tf" "--steps and --tf" "$tmp/e" \
    run taylor-green --steps 5 --tf 0.1 --out "$tmp/e"
expect_refused "heat --steps with --tf" "--steps and --tf" "$tmp/e" run heat --steps 5 --tf 0.1
for o in --snapshot-every --checkpoint-every; do
    expect_refused "$o without --out" "option $o .*--out" "$tmp/e" run taylor-green --steps 2 $o 1
done
expect_refused "--overwrite without --out" "option --overwrite .*--out" "$tmp/e" \
    run taylor-green --steps 2 --overwrite
expect_refused "--overwrite with --restart" "option --overwrite is for a new run" "$tmp/e" \
    run --restart "$tmp/b.ckpt" --out "$tmp/e" --overwrite
expect_refused "--cfl with --dt" "option --cfl .*--dt" "$tmp/e" \
    run taylor-green --steps 2 --dt 0.001 --cfl 0.2
expect_refused "--h-dt with --dt" "option --h-dt .*--dt" "$tmp/e" \
    run taylor-green --steps 2 --dt 0.001 --h-dt 0.02
expect_refused "--ipst-every without IPST" "option --ipst-every does nothing for --scheme e-c (it acts on: l-ipst-c" "$tmp/e" \
    run taylor-green --scheme e-c --steps 2 --ipst-every 5
run --steps 2 --dt 0.001 >/dev/null || bad "--dt alone refused"

# --- size: the stated limit, the machine's memory, a study's key ---
expect_refused "--nx 100000" "--nx must be an integer in \[4, 10000\].*not 100000 (1e+10 particles, about .* GiB)" \
    "$tmp/e" run taylor-green --nx 100000 --steps 1 --out "$tmp/e"
expect_refused "--nx 20000" "--nx must be an integer in \[4, 10000\].*not 20000" "$tmp/e" \
    run taylor-green --scheme e-c --nx 20000 --steps 1
expect_refused "--nx 10001" "--nx .*10001" "$tmp/e" run gresho-chan --nx 10001 --steps 1 --out "$tmp/e"
# run heat: its estimate (512 bytes per particle) against this machine's memory, where the
# 20000² particles cannot fit (191 GiB)
mem_kib=$(awk '/^MemTotal:/ { print $2 }' /proc/meminfo 2>/dev/null)
if [ -n "$mem_kib" ] && [ "$mem_kib" -lt 190000000 ]; then
    expect_refused "heat --nx 20000" "option --nx 20000: 4e+08 particles need about 191 GiB" "$tmp/e" \
        run heat --nx 20000 --out "$tmp/e"
fi
printf '%s\n' "study = big" "title = a quick resolution that cannot be held" "[figure conv]" \
    "kind = run" "problem = taylor-green" "layout = lattice" "nx = 12,16" "quick.nx = 16,100000" \
    "steps = 1" "[series E-C]" "scheme = e-c" >"$tmp/big.study"
expect_refused "study quick.nx = 100000" "big.study:8: .*quick.nx.*--nx must be an integer in \[4, 10000\]" \
    "$tmp/e" study "$tmp/big.study" --quick --out "$tmp/e"

[ $fail -eq 0 ] && echo "cli_run_dir: ok"
exit $fail
