#!/usr/bin/env bash
# A disk that fills during a write (issue 23, item 4): the command exits 1 with one line naming
# the file and the reason, "cannot write 'PATH': No space left on device", and leaves neither the
# file nor a temporary. The disk is a 64 KiB tmpfs, so this needs root (mount); skipped without.
# Usage: cli_disk_full.sh <path-to-consph> <source-dir>
set -u
bin=$1
[ "$(id -u)" = 0 ] || { echo "cli_disk_full: needs root to mount a small tmpfs, skipped"; exit 77; }
disk=$(mktemp -d)
mount -t tmpfs -o size=64k consph_test "$disk" 2>/dev/null ||
    { rmdir "$disk"; echo "cli_disk_full: cannot mount a tmpfs, skipped"; exit 77; }
errf=$(mktemp)
trap 'umount "$disk"; rmdir "$disk"; rm -f "$errf"' EXIT
pass=0
fail=0
bad() {
    echo "FAIL: $*"
    fail=$((fail + 1))
}
# fills FILE -- command...: exit 1, the message names FILE, nothing left on the disk.
fills() {
    local file=$1
    shift 2
    "$@" >/dev/null 2>"$errf"
    local rc=$? err
    err=$(cat "$errf")
    if [ $rc != 1 ]; then
        bad "$*: exit $rc, want 1: $err"
    elif ! grep -qF "cannot write '$file': No space left on device" <<<"$err"; then
        bad "$*: message '$err' does not name '$file' and the reason"
    elif [ -n "$(find "$disk" -type f)" ]; then
        bad "$*: left $(find "$disk" -type f)"
    else
        pass=$((pass + 1))
    fi
    rm -rf "${disk:?}"/*
}
for enc in ascii binary zlib; do
    fills "$disk/p.vtu" -- "$bin" layout --kind lattice --dim 2 --nx 200 --out "$disk/p.vtu" \
        --vtu-encoding $enc
done
fills "$disk/p.csv" -- "$bin" layout --kind lattice --dim 2 --nx 200 --out "$disk/p.csv"
mkdir "$disk/run"
fills "$disk/run/snap_000000.vtu" -- "$bin" run taylor-green --scheme wcsph --nx 40 --steps 2 \
    --out "$disk/run"
echo "cli_disk_full: $pass passed, $fail failed"
[ $fail = 0 ]
