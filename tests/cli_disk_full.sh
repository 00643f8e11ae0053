#!/usr/bin/env bash
# A disk that fills during a write: the command exits 1 with one line naming
# the file and the reason, "cannot write 'PATH': No space left on device", and leaves neither the
# file nor a temporary. The disk is a 64 KiB tmpfs, so this needs root (mount); skipped without.
# Usage: cli_disk_full.sh <path-to-consph> <source-dir>
set -u
bin=$1
[ "$(id -u)" = 0 ] || { echo "cli_disk_full: needs root to mount a small tmpfs, skipped"; exit 77; }
disk=$(mktemp -d)
mount -t tmpfs -o size=64k consph_test "$disk" 2>/dev/null ||
    { rmdir "$disk"; echo "cli_disk_full: cannot mount a tmpfs, skipped"; exit 77; }
work=$(mktemp -d)
trap 'umount "$disk"; rmdir "$disk"; rm -rf "$work"' EXIT
. "$(dirname "${BASH_SOURCE[0]}")/lib_cli.sh"
# fills FILE -- command...: exit 1, the message names FILE, neither FILE nor a temporary left
# (files committed before it stay).
fills() {
    local file=$1
    shift 2
    if ! failing 1 "cannot write '$file': No space left on device" /dev/null -- "$@"; then
        :
    elif [ -e "$file" ] || [ -n "$(find "$disk" -name '*.tmp*')" ]; then
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
# The snapshot at step 0 fits (nx 24: 28 kB), the first checkpoint (48 kB) does not.
mkdir "$disk/run"
fills "$disk/run/checkpoint.ckpt" -- "$bin" run taylor-green --scheme wcsph --nx 24 --steps 3 \
    --checkpoint-every 1 --snapshot-every 1000 --out "$disk/run"
# Which of the study's files fills the disk depends on whether gnuplot draws SVGs; without it the
# study writes about 23 kB, which the 64 KiB fit: a filler leaves it two pages (8 KiB).
mkdir "$disk/st"
head -c $((56 * 1024)) /dev/zero > "$disk/filler"
if failing 1 "cannot write '$disk/st/003-m0/" /dev/null -- "$bin" study 003-m0 --quick \
    --out "$disk/st"; then
    grep -q "': No space left on device$" "$work/err" && [ ! -e "$disk/st/003-m0" ] &&
        pass=$((pass + 1)) || bad "study: $(cat "$work/err"), left $(find "$disk/st")"
fi
summary cli_disk_full
