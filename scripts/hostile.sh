#!/usr/bin/env bash
# The hostile tester's matrix: each case is a command line that a user
# might type, the exit status it must give, and what else must hold (a message, a file left or
# not). Prints one row per case and the totals; exits 1 if any case misbehaves.
#   bash scripts/hostile.sh build/consph
# Cases write only under a temporary directory; a case that runs past its limit misbehaves.
set -u
BIN=$(readlink -f "${1:?usage: hostile.sh CONSPH}")
W=$(mktemp -d)
trap 'rm -rf "$W"' EXIT
cd "$W" || exit 1
pass=0
fail=0
# check EXPECTED_RC 'PATTERN in stderr or -' DESCRIPTION -- COMMAND...
check() {
    local want=$1 pat=$2 what=$3
    shift 4
    local rc
    timeout 120 "$@" >out.txt 2>err.txt
    rc=$?
    local ok=1
    [ "$rc" = "$want" ] || ok=0
    if [ "$ok" = 1 ] && [ "$pat" != - ] && ! grep -Eq -- "$pat" err.txt; then ok=0; fi
    if [ "$ok" = 1 ]; then
        pass=$((pass + 1))
        printf 'ok    %-58s exit %s\n' "$what" "$rc"
    else
        fail=$((fail + 1))
        printf 'WRONG %-58s exit %s (want %s): %s\n' "$what" "$rc" "$want" \
            "$(head -c 160 err.txt | tr '\n' ' ')"
    fi
}

# 1. Runs that leave the weakly-compressible model stop with exit 3
check 3 'step' "1: tvf nx 8 dt 1e6" -- "$BIN" run taylor-green --scheme tvf --nx 8 --dt 1e6 --steps 5
# every scheme, as the registry lists them (consph run --help, --scheme's allowed names)
schemes=$("$BIN" run --help 2>&1 | sed -n 's/^ *--scheme S .*(\([a-z0-9,+-]*\); default .*/\1/p' | tr , ' ')
[ -n "$schemes" ] || { echo "WRONG no scheme list in consph run --help"; fail=$((fail + 1)); }
for s in $schemes; do
    check 3 'step' "1: $s nx 8 dt 10 steps 5" -- "$BIN" run taylor-green --scheme "$s" --nx 8 \
        --dt 10 --steps 5
done
check 3 'step' "1: wcsph nx 16 dt 0.01 tf 2 (4.4x default dt)" -- "$BIN" run taylor-green \
    --scheme wcsph --nx 16 --dt 0.01 --tf 2
check 0 - "1: a valid run still passes" -- "$BIN" run taylor-green --scheme l-ipst-c --nx 16 \
    --steps 20

# 3. A failed write on standard output is never exit 0
for cmd in "approx --op grad --nx 10" "layout --kind lattice --dim 2 --nx 10" \
    "run taylor-green --nx 8 --steps 2" "run taylor-green --nx 8 --steps 2 --format json" \
    "run heat --laplacian s4 --nx 8 --eta 1.5 --steps 2" "study --list" "--help" "--version" \
    "run --help" "approx --help" "kernels" "kernel quintic --dim 2"; do
    # shellcheck disable=SC2086
    check 1 'writ|space' "3: $cmd > /dev/full" -- sh -c "\"\$0\" $cmd >/dev/full" "$BIN"
done

# 5. A used --out is refused unless told to overwrite
"$BIN" run taylor-green --nx 8 --steps 4 --checkpoint-every 2 --out used >/dev/null 2>&1
check 2 'used|--out' "5: run into a used --out" -- "$BIN" run taylor-green --nx 8 --steps 2 --out used

# 7. No size the machine cannot hold
check 2 'nx' "7: run --nx 100000" -- "$BIN" run taylor-green --nx 100000 --steps 1

# 8. An unwritable --out is refused first, with exit 2
check 2 'out' "8: run --out /proc/1" -- "$BIN" run taylor-green --nx 8 --steps 2 --out /proc/1
check 2 'out' "8: run heat --out /proc/1" -- "$BIN" run heat --laplacian s4 --nx 8 --eta 1.5 \
    --steps 2 --out /proc/1
check 2 'out' "8: study --out /proc/1" -- "$BIN" study 003-m0 --quick --out /proc/1
check 2 'out' "8: layout --out /proc/1.vtu" -- "$BIN" layout --kind packed --dim 2 --nx 10 \
    --out /proc/1/consph.vtu

# 9. Options that would be ignored are refused
check 2 'tf' "9: run --steps with --tf" -- "$BIN" run taylor-green --nx 8 --steps 2 --tf 1
check 2 'out' "9: --checkpoint-every without --out" -- "$BIN" run taylor-green --nx 8 --steps 2 \
    --checkpoint-every 1
check 2 'out' "9: --snapshot-every without --out" -- "$BIN" run taylor-green --nx 8 --steps 2 \
    --snapshot-every 1
"$BIN" layout --kind lattice --dim 2 --nx 8 --out a.csv >/dev/null 2>&1
"$BIN" layout --kind lattice --dim 2 --nx 16 --out b.csv >/dev/null 2>&1
check 2 'eps' "9: wasserstein --method sliced --eps" -- "$BIN" wasserstein a.csv b.csv \
    --method sliced --eps 0.1
# a parameter the scheme does not read (the scheme table's 'reads'), a seed with no randomness
check 2 'alpha.*tvf' "9: run --scheme tvf --alpha" -- "$BIN" run taylor-green --scheme tvf --nx 8 \
    --steps 2 --alpha 0.3
check 2 'alpha.*edac' "9: run --scheme edac --alpha 0" -- "$BIN" run taylor-green --scheme edac \
    --nx 8 --steps 2 --alpha 0
check 2 'delta.*l-ipst-c' "9: run --scheme l-ipst-c --delta" -- "$BIN" run taylor-green --nx 8 \
    --steps 2 --delta 0.2
check 2 'delta.*ewcsph' "9: run --scheme ewcsph --delta" -- "$BIN" run taylor-green \
    --scheme ewcsph --nx 8 --steps 2 --delta 0.2
check 2 'eos.*edac' "9: run --scheme edac --eos tait" -- "$BIN" run taylor-green --scheme edac \
    --nx 8 --steps 2 --eos tait
check 2 'eos.*pe-ipst-c' "9: run --scheme pe-ipst-c --eos linear" -- "$BIN" run taylor-green \
    --scheme pe-ipst-c --nx 8 --steps 2 --eos linear
check 2 'eos.*tvf' "9: run --scheme tvf --eos tait" -- "$BIN" run taylor-green --scheme tvf \
    --nx 8 --steps 2 --eos tait
check 2 'seed.*lattice' "9: run --scheme e-c --seed (lattice)" -- "$BIN" run taylor-green \
    --scheme e-c --nx 8 --steps 2 --seed 7
check 2 'seed.*lattice' "9: run gresho-chan --seed (lattice)" -- "$BIN" run gresho-chan --nx 8 \
    --steps 2 --seed 7
check 2 'seed.*quasi-random' "9: run --layout quasi-random --seed" -- "$BIN" run taylor-green \
    --layout quasi-random --nx 8 --steps 2 --seed 7
check 2 'seed.*eps' "9: run heat --seed without --eps" -- "$BIN" run heat --nx 8 --steps 2 \
    --seed 7
check 0 - "9: run --scheme wcsph --alpha 0 still runs" -- "$BIN" run taylor-green --scheme wcsph \
    --nx 8 --steps 2 --alpha 0
check 0 - "9: run --layout random --seed 7 still runs" -- "$BIN" run taylor-green \
    --layout random --nx 8 --steps 2 --seed 7
mkdir -p dirent/snap_000001.vtu
echo kept >dirent/log.csv
check 2 'is a directory' "9: --overwrite over a directory snap_000001.vtu/" -- sh -c \
    '"$0" run taylor-green --nx 8 --steps 2 --out dirent --overwrite; rc=$?; \
     [ -f dirent/log.csv ] || rc=9; exit $rc' "$BIN"

# 10. Study files: what would be ignored or misread is refused with file:line
study() { # NAME EXTRA-FIGURE-LINES EXTRA-SERIES-LINES: a tiny run study
    printf 'study = %s\ntitle = t\n[figure conv]\nkind = run\nproblem = taylor-green\nlayout = lattice\nc0 = 80\nnx = 8,12\ntf = 0.01\n%b[series E-C]\nscheme = e-c\n%b' "$1" "$2" "$3" >"$1.study"
}
study s_ok '' ''
check 0 - "10: a valid tiny run study" -- "$BIN" study s_ok.study --quick --out so
study s_trref '' 'tr_ref = E-C\n'
check 2 'study:[0-9]+' "10: tr_ref inside [series]" -- "$BIN" study s_trref.study --quick --out st
study s_op 'op = grad\n' ''
check 2 'study:[0-9]+' "10: op on a run figure" -- "$BIN" study s_op.study --quick --out sop
study s_steps 'steps = 3\n' ''
check 2 'study:[0-9]+' "10: steps and tf together" -- "$BIN" study s_steps.study --quick --out sst
study s_seed '' 'seed = 3\n'
check 2 'study:[0-9]+.*seed' "10: seed in a lattice series" -- "$BIN" study s_seed.study --quick \
    --out ssd
printf 'study = s_fseed\ntitle = t\nseed = 3\n[figure conv]\nkind = run\nproblem = taylor-green\nlayout = lattice\nc0 = 80\nnx = 8,12\ntf = 0.01\n[series E-C]\nscheme = e-c\n' >s_fseed.study
check 0 - "10: a study-level seed, lattice series (a default)" -- "$BIN" study s_fseed.study \
    --quick --out sfs
printf 'study = s_list\ntitle = t\n[figure conv]\nkind = run\nproblem = taylor-green\nlayout = lattice\nc0 = 80\nnx = 8,,12\ntf = 0.01\n[series E-C]\nscheme = e-c\n' >s_list.study
check 2 'study:[0-9]+' "10: nx = 8,,12" -- "$BIN" study s_list.study --quick --out sl
printf 'study = s_noscheme\ntitle = t\n[figure conv]\nkind = run\nproblem = taylor-green\nlayout = lattice\nc0 = 80\nnx = 8,12\ntf = 0.01\n[series E-C]\npaper.order_u = 2\n' >s_noscheme.study
check 2 'study:[1-9]' "10: a series without scheme (line > 0)" -- "$BIN" study s_noscheme.study \
    --quick --out sn
cauchy() { # NAME DIM NX EXTRA-FIGURE-LINES EXTRA-SERIES-LINES: a tiny cauchy study
    printf 'study = %s\ntitle = t\nkind = cauchy\nlayout = random\n[figure w]\ndim = %s\nnx = %s\n%b[series s]\n%b' \
        "$1" "$2" "$3" "$4" "$5" >"$1.study"
}
cauchy c_ok 2 8,16 'grid = 16\ndirections = 8\n' 'measure = smoothed\n'
check 0 - "10: a valid tiny cauchy study" -- "$BIN" study c_ok.study --out cok
cauchy c_exact 1 50,100 'ot_method = exact\ndirections = 16\n' ''
check 2 'c_exact.study:9: .*directions.*ot_method here is exact' "10: cauchy directions with exact" \
    -- "$BIN" study c_exact.study --out cex
cauchy c_sink 2 8,16 'ot_method = sinkhorn\n' 'directions = 8\n'
check 2 'c_sink.study:10: .*directions.*sinkhorn' "10: cauchy directions with sinkhorn" -- \
    "$BIN" study c_sink.study --out csk
cauchy c_1d 1 50,100 'ot_method = sliced\ndirections = 8\n' ''
check 2 'c_1d.study:9: .*directions.*1D' "10: cauchy directions with 1D sliced" -- \
    "$BIN" study c_1d.study --out c1d
cauchy c_grid 2 8,16 '' 'grid = 64\n'
check 2 'c_grid.study:9: .*grid.*measure here is particles' "10: cauchy grid with particles" -- \
    "$BIN" study c_grid.study --out cgr

# 11. Restarts: only into the checkpoint's own run
"$BIN" run taylor-green --nx 8 --steps 4 --checkpoint-every 2 --out runa >/dev/null 2>&1
"$BIN" run taylor-green --nx 8 --steps 4 --out runb >/dev/null 2>&1
check 2 'runb|--out' "5: restart into another run's --out" -- "$BIN" run \
    --restart runa/checkpoint.ckpt --out runb

# 12. Bad input is exit 2, not 1 and not 0
check 2 'periodic' "12: approx --layout packed --periodic no" -- "$BIN" approx --op grad \
    --layout packed --periodic no --nx 10
printf 'x,y\n0.5,0.5\n' >one.csv
# one particle has no spacing: n/a, not inf or nan (the file is valid, so exit 0)
check 0 - "12: layout --in with one particle prints no inf/nan" -- sh -c \
    '"$0" layout --in one.csv --box 0:1,0:1 >l.txt && ! grep -Eiq "nan|inf" l.txt' "$BIN"

# 13. Work that cannot fit is refused up front
check 2 'grid' "13: wasserstein A uniform --grid 100000" -- "$BIN" wasserstein a.csv uniform \
    --grid 100000 --directions 2

cauchy c_mem 2 8,16 '' 'measure = smoothed\ngrid = 100000\n'
check 2 'c_mem.study:10: .*grid.*GB.*the limit is' "13: cauchy smoothed grid 100000 in 2D" -- \
    "$BIN" study c_mem.study --out cme
cauchy c_nx 3 8,400 '' ''
check 2 'c_nx.study:7: .*nx.*GB.*the limit is' "13: cauchy 3D nx 400 particles" -- \
    "$BIN" study c_nx.study --out cnx
check 2 'option --hdx: 100 .*--nx 10.*the limit is' "13: approx 3D gaussian hdx 100 nx 10" -- \
    "$BIN" approx --op grad --dim 3 --kernel gaussian --hdx 100 --nx 10
check 124 'estimate \(rough\): about [0-9]+ s' "13: approx 3D gaussian hdx 30 announced" -- \
    timeout 3 "$BIN" approx --op grad --dim 3 --kernel gaussian --hdx 30 --nx 10
echo "hostile matrix: $pass passed, $fail failed"
[ "$fail" = 0 ]
