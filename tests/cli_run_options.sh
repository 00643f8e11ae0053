#!/usr/bin/env bash
# consph run refuses a parameter its scheme or layout does not read (Hardening II, silently
# ignored options): --alpha, --delta, --eos and --ipst-* where the scheme table says the scheme
# does not read them, --seed where the layout draws no random numbers, heat's --seed without
# --eps; each exit 2 naming the option, the scheme or layout and where the option acts, --out
# untouched. Every accepted one must act: for every scheme, an option it accepts changes the
# result (so the table cannot claim a reader that ignores it). An --out entry named like a run
# file that is a directory is refused (exit 2) before --overwrite removes anything.
# Usage: bash cli_run_options.sh PATH-TO-CONSPH
set -u
consph=$1
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
. "$(dirname "$0")/lib_cli.sh"
tg() { "$consph" run taylor-green --nx 8 --steps 2 --format json "$@"; }
# every scheme, as the registry lists them (consph run --help, --scheme's allowed names)
schemes=$("$consph" run --help 2>&1 | sed -n 's/^ *--scheme S .*(\([a-z0-9,+-]*\); default .*/\1/p' | tr , ' ')
[ -n "$schemes" ] || bad "no scheme list in consph run --help"

# refused WHAT TEXT ARGS...: exit 2 naming TEXT, nothing written in $work/o
mkdir -p "$work/o"
refused() {
    local what=$1 text=$2
    shift 2
    if failing 2 "$text" "$work/out" -- "$consph" run "$@" --out "$work/o"; then
        pass=$((pass + 1))
    fi
    [ -z "$(ls -A "$work/o")" ] || bad "$what: wrote $(ls -A "$work/o")"
}
refused "alpha tvf" "option --alpha does nothing for --scheme tvf (it acts on: wcsph, delta-sph" \
    taylor-green --scheme tvf --nx 8 --steps 2 --alpha 0.3
refused "alpha edac" "option --alpha does nothing for --scheme edac" \
    taylor-green --scheme edac --nx 8 --steps 2 --alpha 0
refused "alpha l-ipst-c" "option --alpha does nothing for --scheme l-ipst-c" \
    taylor-green --nx 8 --steps 2 --alpha 0.3
refused "delta l-ipst-c" "option --delta does nothing for --scheme l-ipst-c (it acts on: pe-ipst-c, tv-c, e-c" \
    taylor-green --nx 8 --steps 2 --delta 0.2
refused "delta wcsph" "option --delta does nothing for --scheme wcsph" \
    taylor-green --scheme wcsph --nx 8 --steps 2 --delta 0.2
refused "eos edac" "option --eos does nothing for --scheme edac (it acts on: l-ipst-c" \
    taylor-green --scheme edac --nx 8 --steps 2 --eos tait
refused "eos pe-ipst-c" "option --eos does nothing for --scheme pe-ipst-c" \
    taylor-green --scheme pe-ipst-c --nx 8 --steps 2 --eos linear
refused "eos tvf" "option --eos does nothing for --scheme tvf" \
    taylor-green --scheme tvf --nx 8 --steps 2 --eos tait
refused "ipst-tol wcsph" "option --ipst-tol does nothing for --scheme wcsph (it acts on: l-ipst-c" \
    taylor-green --scheme wcsph --nx 8 --steps 2 --ipst-tol 1e-4
refused "seed, lattice by the scheme" "option --seed does nothing for --layout lattice (the problem's or scheme's default)" \
    taylor-green --scheme e-c --nx 8 --steps 2 --seed 3
refused "seed, lattice by the problem" "option --seed does nothing for --layout lattice" \
    gresho-chan --nx 8 --steps 2 --seed 3
refused "seed, quasi-random" "option --seed does nothing for --layout quasi-random (given), which draws no random numbers (it acts on: random, packed, packed-polished)" \
    taylor-green --layout quasi-random --nx 8 --steps 2 --seed 3
refused "heat seed without eps" "option --seed does nothing for heat without --eps" \
    heat --nx 8 --steps 2 --seed 3

# accepted: the option acts. For every scheme, each of --alpha/--delta/--eos is refused or
# changes the result against the scheme's defaults.
strip() { grep -v '"seconds"'; }
for s in $schemes; do
    base=$(tg --scheme "$s" --layout lattice | strip) || { bad "$s: the default run failed"; continue; }
    for o in "--alpha 0.3" "--delta 0.4" "--eos tait" "--eos linear"; do
        # shellcheck disable=SC2086
        tg --scheme "$s" --layout lattice $o >"$work/r" 2>"$work/err"
        rc=$?
        r=$(strip <"$work/r")
        if [ "$rc" = 2 ]; then
            grep -qF "does nothing for --scheme $s" "$work/err" || bad "$s $o: $(cat "$work/err")"
            continue
        fi
        [ "$rc" = 0 ] || { bad "$s $o: exit $rc"; continue; }
        # --eos naming the scheme's own EOS is the default: the same result is right there
        [ "${o%% *}" = --eos ] && continue
        [ "$r" != "$base" ] && pass=$((pass + 1)) || bad "$s $o: accepted but the result is the same"
    done
    # a scheme that reads the EOS must give two results for its two choices
    if [ -n "$(tg --scheme "$s" --layout lattice --eos tait 2>/dev/null)" ]; then
        [ "$(tg --scheme "$s" --layout lattice --eos tait | strip)" != \
            "$(tg --scheme "$s" --layout lattice --eos linear | strip)" ] &&
            pass=$((pass + 1)) || bad "$s: --eos tait and linear give the same result"
    fi
done
tg --scheme edac --eos default >/dev/null && pass=$((pass + 1)) || bad "--eos default refused"
tg --layout random --seed 3 >/dev/null && pass=$((pass + 1)) || bad "--seed with random refused"
[ "$(tg --layout random --seed 3 | strip)" != "$(tg --layout random --seed 4 | strip)" ] &&
    pass=$((pass + 1)) || bad "--seed does not act on the random layout"
"$consph" run heat --nx 8 --steps 2 --eps 0.2 --seed 3 >/dev/null && pass=$((pass + 1)) ||
    bad "heat --seed with --eps refused"

# an --out entry named like a run file that is a directory: refused before anything is removed
mkdir -p "$work/d/snap_000001.vtu"
echo "earlier" >"$work/d/log.csv"
if failing 2 "snap_000001.vtu' is a directory named like a run's file" "$work/out" -- \
    "$consph" run taylor-green --scheme e-c --nx 8 --steps 2 --out "$work/d" --overwrite; then
    pass=$((pass + 1))
fi
[ -f "$work/d/log.csv" ] || bad "--overwrite removed log.csv before refusing the directory entry"
failing 2 "is a directory named like a run's file" "$work/out" -- \
    "$consph" run heat --nx 8 --steps 2 --out "$work/d" --overwrite && pass=$((pass + 1))

# a study: a series' own seed for a layout without randomness is refused with file:line; the
# study's or a figure's seed is a default for every series and stays allowed
printf '%s\n' "study = seeds" "title = t" "seed = 2" "[figure conv]" "kind = run" \
    "problem = taylor-green" "nx = 8" "steps = 1" "[series A]" "scheme = e-c" "[series B]" \
    "scheme = l-ipst-c" "layout = random" "seed = 5" >"$work/seeds.study"
"$consph" study "$work/seeds.study" --out "$work/s1" >/dev/null 2>"$work/err" &&
    pass=$((pass + 1)) || bad "study with a study-level seed refused: $(cat "$work/err")"
printf '%s\n' "[series C]" "scheme = e-c" "seed = 5" >>"$work/seeds.study"
failing 2 "seeds.study:17: figure 'conv', series 'C': key 'seed': does nothing for the layout lattice" \
    "$work/out" -- "$consph" study "$work/seeds.study" --out "$work/s2" && pass=$((pass + 1))
[ ! -e "$work/s2" ] || bad "the refused study wrote $work/s2"
printf '%s\n' "study = hseeds" "title = t" "kind = heat" "seed = 3" "[figure f]" "nx = 6" \
    "[series A]" "laplacian = s3" "[series B]" "laplacian = s3" "seed = 4" >"$work/hseeds.study"
failing 2 "hseeds.study:11: figure 'f', series 'B': key 'seed': does nothing without eps > 0" \
    "$work/out" -- "$consph" study "$work/hseeds.study" --out "$work/s3" && pass=$((pass + 1))

summary cli_run_options
