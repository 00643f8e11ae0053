#!/usr/bin/env bash
# A study stopped by SIGTERM or SIGINT while gnuplot draws: the gnuplot child
# is killed and reaped, its temporary SVG goes, and the study directory stays with a partial
# README.md that names the signal and the command that resumes, with exit status 128 + signal.
# SIGHUP (not a stop request) ends the study at once without a report: the rows it kept stay for
# --resume (001-fig2 keeps its one row before drawing), without temporaries. gnuplot is a fake first on PATH that starts its output and then sleeps, so
# the signal always arrives mid-drawing. A symbolic link at OUT/NAME is refused (exit 2) without
# writing through it. The same for the gnuplot of a shear-layer run stopped by SIGTERM.
# Usage: cli_study_signal.sh <path-to-consph> <source-dir>
set -u
bin=$1
work=$(mktemp -d)
pids=$work/gnuplot.pids
cleanup() {
    # Only the fake gnuplots this test started, should one have been left running.
    [ -f "$pids" ] && while read -r q; do kill "$q" 2>/dev/null; done <"$pids"
    rm -rf "$work"
}
trap cleanup EXIT
. "$(dirname "${BASH_SOURCE[0]}")/lib_cli.sh"
mkdir "$work/bin"
cat >"$work/bin/gnuplot" <<'EOF'
#!/bin/sh
# A study runs `gnuplot -e "outfile = 'NAME'" SCRIPT.gp` in the figure's directory, a
# shear-layer run `gnuplot vorticity.gp` (which sets its output to vorticity.png.tmp).
if [ "$1" = vorticity.gp ]; then
    out=vorticity.png.tmp
else
    case "$3" in *.gp) ;; *) exit 0 ;; esac
    out=${2#outfile = \'}
    out=${out%\'}
fi
printf '<svg' >"$out"
echo $$ >>"$FAKE_GNUPLOT_PIDS"
exec sleep 60
EOF
chmod +x "$work/bin/gnuplot"
export FAKE_GNUPLOT_PIDS=$pids
# stop SIGNAL STATUS OUT KEEP: a study into OUT, SIGNAL once gnuplot draws; KEEP 1 when
# OUT/001-fig2 existed before (it must stay), 0 when the run created it (it must go).
stop() {
    local sig=$1 want=$2 out=$3 keep=$4
    : >"$pids"
    # Job control: a background job of a script would otherwise ignore SIGINT.
    set -m
    PATH="$work/bin:$PATH" "$bin" study 001-fig2 --quick --out "$out" >/dev/null 2>&1 &
    local p=$!
    set +m
    for _ in $(seq 200); do
        [ -s "$pids" ] && break
        sleep 0.05
    done
    [ -s "$pids" ] || { bad "$sig: gnuplot never started"; kill "$p"; wait "$p"; return; }
    kill -"$sig" "$p"
    { wait "$p"; } 2>/dev/null
    local rc=$? q left
    q=$(cat "$pids")
    left=$(find "$out" -name '*.tmp*' 2>/dev/null)
    if [ $rc != "$want" ]; then
        bad "$sig: exit $rc, want $want"
    elif kill -0 "$q" 2>/dev/null; then
        bad "$sig: gnuplot $q still running"
    elif [ -n "$left" ]; then
        bad "$sig: temporaries left: $left"
    elif [ "$sig" != HUP ] && ! grep -q "^\*\*Partial results\*\*: stopped by SIG$sig" \
        "$out/001-fig2/README.md" 2>/dev/null; then
        bad "$sig: no partial README.md: $(ls -A "$out/001-fig2" 2>&1)"
    elif [ "$sig" != HUP ] && ! grep -qF -- "--out $out --resume" "$out/001-fig2/README.md"; then
        bad "$sig: the partial README.md lacks the command that resumes"
    elif [ "$sig" = HUP ] && [ -e "$out/001-fig2/README.md" ]; then
        bad "$sig: a README.md was written"
    elif [ "$sig" = HUP ] && [ -z "$(ls -A "$out/001-fig2" | grep '\.row$')" ]; then
        bad "$sig: the kept rows are gone: $(ls -A "$out/001-fig2" 2>&1)"
    elif [ "$keep" = 1 ] && [ ! -d "$out/001-fig2" ]; then
        bad "$sig: the study directory that existed before is gone"
    else
        pass=$((pass + 1))
    fi
}
mkdir "$work/a" "$work/b"
stop HUP 129 "$work/a" 0
stop TERM 143 "$work/a" 0
stop INT 130 "$work/a" 0
stop HUP 129 "$work/b/new" 0
mkdir -p "$work/a/001-fig2"
stop TERM 143 "$work/a" 1

# consph run draws the shear layer's vorticity after its last step, where SIGTERM ends it at
# once: gnuplot and vorticity.png.tmp must go with it.
: >"$pids"
set -m
PATH="$work/bin:$PATH" "$bin" run shear-layer --scheme wcsph --nx 8 --steps 1 --out "$work/rv" \
    >/dev/null 2>&1 &
p=$!
set +m
for _ in $(seq 200); do
    [ -s "$pids" ] && break
    sleep 0.05
done
kill -TERM "$p"
{ wait "$p"; } 2>/dev/null
rc=$?
q=$(cat "$pids")
if [ $rc != 143 ]; then
    bad "run, SIGTERM while gnuplot draws: exit $rc, want 143"
elif [ -n "$q" ] && kill -0 "$q" 2>/dev/null; then
    bad "run: gnuplot $q still running"
elif [ -e "$work/rv/vorticity.png.tmp" ]; then
    bad "run: vorticity.png.tmp left"
else
    pass=$((pass + 1))
fi

# A link at OUT/NAME would take the results elsewhere: refused, nothing written through it.
mkdir "$work/out" "$work/elsewhere"
ln -s "$work/elsewhere" "$work/out/001-fig2"
for target in "$work/elsewhere" "$work/nowhere"; do
    o=$work/out
    [ "$target" = "$work/nowhere" ] && { mkdir "$work/o2"; ln -s "$target" "$work/o2/001-fig2"; o=$work/o2; }
    if ! failing 2 "'$o/001-fig2' is a symbolic link" /dev/null -- "$bin" study 001-fig2 \
        --quick --out "$o"; then
        :
    elif [ -n "$(ls -A "$work/elsewhere")" ] || [ -e "$work/nowhere" ]; then
        bad "link to $target: written through the link"
    else
        pass=$((pass + 1))
    fi
done
summary cli_study_signal
