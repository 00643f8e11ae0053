#!/usr/bin/env bash
# An output directory that cannot be written is refused before any work:
# `run` (WCSPH, heat, restart), `layout` and `study` exit 2 with one line naming --out, for
# directories that exist but take no files (/proc/self, /sys/kernel: for root too, where
# access() says yes), a path under a regular file, a directory without write permission
# (non-root), and, as root, a full and a read-only file system (small tmpfs mounts). The check
# really writes a probe file, so the full disk is caught up front, and it leaves nothing behind.
# Usage: cli_out_dir.sh <path-to-consph> <source-dir>
set -u
bin=$1
work=$(mktemp -d)
mounts=()
cleanup() {
    for m in "${mounts[@]}"; do umount "$m"; done
    chmod -R u+w "$work"
    rm -rf "$work"
}
trap cleanup EXIT
. "$(dirname "${BASH_SOURCE[0]}")/lib_cli.sh"
"$bin" run taylor-green --scheme wcsph --nx 8 --steps 2 --checkpoint-every 1 --out "$work/ck" \
    >/dev/null || bad "setup: checkpoint run"
ckpt=$work/ck/checkpoint.ckpt
# refused DIR: every command with an output, into DIR.
refused() {
    local d=$1 c
    local cmds=("run taylor-green --scheme wcsph --nx 8 --steps 2 --out $d"
        "run taylor-green --scheme wcsph --nx 8 --steps 2 --out $d/new"
        "run taylor-green --scheme l-ipst-c --nx 8 --layout packed --steps 2 --out $d"
        "run heat --laplacian s3 --nx 8 --eta 2 --steps 2 --out $d"
        "run --restart $ckpt --out $d"
        "layout --kind lattice --dim 2 --nx 8 --out $d/p.csv"
        "layout --kind packed --dim 2 --nx 8 --out $d/p.vtu"
        "study 003-appc --quick --out $d/s")
    for c in "${cmds[@]}"; do
        # shellcheck disable=SC2086 # the words of c are the arguments; no path has a space
        failing 2 "option --out: cannot write" /dev/null -- "$bin" $c || continue
        [ "$(wc -l <"$work/err")" = 1 ] && pass=$((pass + 1)) ||
            bad "consph $c: more than one line: $(cat "$work/err")"
    done
}
[ -d /proc/self ] && refused /proc/self
[ -d /sys/kernel ] && refused /sys/kernel
touch "$work/file"
refused "$work/file"
if [ "$(id -u)" != 0 ]; then
    mkdir "$work/readonly"
    chmod 555 "$work/readonly"
    refused "$work/readonly"
else
    mkdir "$work/full" "$work/ro"
    if mount -t tmpfs -o size=64k consph_test "$work/full" 2>/dev/null; then
        mounts+=("$work/full")
        dd if=/dev/zero of="$work/full/fill" bs=4k 2>/dev/null
        refused "$work/full"
        [ "$(ls -A "$work/full")" = fill ] || bad "probe files left: $(ls -A "$work/full")"
    fi
    if mount -t tmpfs -o size=64k,ro consph_test "$work/ro" 2>/dev/null; then
        mounts+=("$work/ro")
        refused "$work/ro"
    fi
fi
# A writable --out still works, and the probe leaves nothing there.
"$bin" layout --kind lattice --dim 2 --nx 8 --out "$work/ok/p.csv" >/dev/null 2>&1 &&
    bad "layout into a missing directory succeeded"
mkdir "$work/ok"
"$bin" layout --kind lattice --dim 2 --nx 8 --out "$work/ok/p.csv" >/dev/null &&
    [ "$(ls -A "$work/ok")" = p.csv ] && pass=$((pass + 1)) ||
    bad "layout into a writable directory: $(ls -A "$work/ok")"
summary cli_out_dir
