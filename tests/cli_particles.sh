#!/usr/bin/env bash
# consph approx/study --particles.
# 1. Round trip: `consph layout ... --out FILE` then `consph approx --particles FILE` prints the
#    same numbers, to the last printed digit, as the equivalent `--layout` run (every column but
#    seconds), for every layout kind in 2D and 3D, through CSV and VTU.
# 2. The .vtu encodings ParaView/VTK write (binary, appended raw/base64, zlib, big-endian) give
#    the same numbers as consph's own ASCII file (skipped without the python3 VTK module).
# 3. Every bad-file case: exit status 2, one line on stderr naming the file, the line (or VTU
#    element) and the problem, nothing on stdout, no output written.
# Usage: cli_particles.sh <path-to-consph> <source-dir>
set -u
bin=$1
src=$2
work=$(mktemp -d)
trap 'chmod -R u+rwx "$work" 2>/dev/null; rm -rf "$work"' EXIT
export OMP_NUM_THREADS=${OMP_NUM_THREADS:-1}
pass=0
fail=0
ok() { pass=$((pass + 1)); }
bad() {
    echo "FAIL: $*"
    fail=$((fail + 1))
}

# ---- 1. round trip ------------------------------------------------------------------------
# roundtrip KIND DIM "NX NX" "layout options" "approx options": the files alternate .csv/.vtu.
roundtrip() {
    local kind=$1 dim=$2 nxs=$3 lopt=$4 aopt=$5 files="" ext=csv
    for n in $nxs; do
        local f="$work/$kind-$dim-$n.$ext"
        # shellcheck disable=SC2086
        "$bin" layout --kind "$kind" --dim "$dim" --nx "$n" $lopt --out "$f" >/dev/null ||
            { bad "layout $kind $dim $n"; return; }
        files="$files,$f"
        [ $ext = csv ] && ext=vtu || ext=csv
    done
    local op="--op grad --form asym --corr bc --format csv"
    # shellcheck disable=SC2086
    "$bin" approx $op --layout "$kind" --dim "$dim" --nx "${nxs// /,}" --volume given $aopt |
        cut -d, -f1-9,11 >"$work/a.txt"
    # shellcheck disable=SC2086
    "$bin" approx $op --particles "${files#,}" 2>"$work/info.txt" | cut -d, -f1-9,11 >"$work/b.txt"
    if [ "$(wc -l <"$work/a.txt")" -ge 3 ] && cmp -s "$work/a.txt" "$work/b.txt"; then
        ok
    else
        bad "round trip $kind ${dim}D ($lopt): --layout and --particles differ"
        diff "$work/a.txt" "$work/b.txt" | head -6
    fi
    grep -q "volumes given (file column 'volume')" "$work/info.txt" ||
        bad "round trip $kind ${dim}D: the volume rule is not reported: $(head -2 "$work/info.txt")"
}
roundtrip lattice 2 "8 12" "" ""
roundtrip random 2 "8 12" "--seed 3 --eps 0.4" "--seed 3 --eps 0.4"
roundtrip random 2 "8 12" "--periodic no" "--periodic no"
roundtrip quasi-random 2 "8 12" "" ""
roundtrip packed 2 "8 12" "" ""
roundtrip packed-polished 2 "8 12" "--tol 1e-2" "--pack-tol 1e-2"
roundtrip lattice 3 "5 6" "" ""
roundtrip random 3 "5 6" "" ""
roundtrip quasi-random 3 "5 6" "--periodic no" "--periodic no"
roundtrip packed 3 "5 6" "" ""
roundtrip packed-polished 3 "5 6" "--tol 1e-2" "--pack-tol 1e-2"

# Without the file's volumes (--volume shepard = number, the layouts' default): also the same.
"$bin" approx --op laplacian --form fatehi --corr fatehi --field quadratic --layout random \
    --periodic no --nx 8,12 --format csv | cut -d, -f1-9,11 >"$work/a.txt"
"$bin" approx --op laplacian --form fatehi --corr fatehi --field quadratic --volume shepard \
    --particles "$work/random-2-8.csv,$work/random-2-12.vtu" --format csv 2>"$work/info.txt" |
    cut -d, -f1-9,11 >"$work/b.txt"
cmp -s "$work/a.txt" "$work/b.txt" && ok || bad "round trip with --volume shepard differs"
grep -q "volumes number (--volume)" "$work/info.txt" && ok || bad "shepard not reported: $(cat "$work/info.txt")"

# A file of N particles that is no perfect power: nx = N^(1/dim) in the output.
{
    echo "# box 0:1 0:1"
    echo "x,y"
    awk 'BEGIN { for (i = 0; i < 50; ++i) printf "%.17g,%.17g\n", (i % 7 + 0.5) / 7, (int(i / 7) + 0.5) / 8 }'
} >"$work/odd.csv"
"$bin" approx --op function --periodic no --mask all --particles "$work/odd.csv" --format csv \
    >"$work/o.txt" 2>"$work/info.txt"
[ "$(sed -n 2p "$work/o.txt" | cut -d, -f1-2)" = "7.07107,50" ] && ok ||
    bad "nx of 50 particles in 2D: $(cat "$work/o.txt")"
grep -q "number (1/sum W, 001 eq. 5: no volumes in the file)" "$work/info.txt" && ok ||
    bad "fallback volume rule not reported: $(cat "$work/info.txt")"

# A study on particle files.
"$bin" study "$src/tests/data/engine.study" --quick --out "$work/st" \
    --particles "$work/random-2-8.csv,$work/random-2-12.vtu" >"$work/st.log" 2>&1
if [ -s "$work/st/engine/grad.csv" ] && grep -q "file:.*random-2-12.vtu" "$work/st/engine/grad.csv"; then
    ok
else
    bad "study --particles: $(tail -3 "$work/st.log")"
fi

# `consph layout --in FILE --out FILE2` converts (CSV -> VTU -> CSV is the same file) and prints
# the layout summary; a bad file exits 2 and writes nothing.
"$bin" layout --in "$work/random-2-8.csv" --out "$work/conv.vtu" >"$work/conv.log" 2>&1 &&
    "$bin" layout --in "$work/conv.vtu" --out "$work/conv.csv" >/dev/null 2>&1 &&
    cmp -s "$work/random-2-8.csv" "$work/conv.csv" && ok || bad "layout --in conversion: $(cat "$work/conv.log")"
grep -q "read .*random-2-8.csv (csv): 64 particles, dim 2" "$work/conv.log" &&
    grep -q "^min spacing" "$work/conv.log" && grep -q "^density (quintic" "$work/conv.log" && ok ||
    bad "layout --in summary: $(cat "$work/conv.log")"
"$bin" layout --in "$work/odd.csv" --box 0:1,0:1 --periodic no --out "$work/odd.vtu" >"$work/conv.log" 2>&1 &&
    grep -q "50 particles, dim 2, spacing 0.141421 ((V/N)^(1/D))" "$work/conv.log" && ok ||
    bad "layout --in on a foreign file: $(cat "$work/conv.log")"
printf '# box 0:1 0:1\nx,y\n0.1,0.2\n0.4,0.4\n0.1,0.2\n' >"$work/dup.csv"
"$bin" layout --in "$work/dup.csv" --out "$work/dup.vtu" >"$work/out" 2>"$work/err"
rc=$?
[ $rc = 2 ] && [ "$(wc -l <"$work/err")" = 1 ] && grep -q "dup.csv:5: particle at the same position" "$work/err" &&
    [ ! -e "$work/dup.vtu" ] && ! ls "$work" | grep -q '\.tmp\.' && ok ||
    bad "layout --in with a bad file: exit $rc, $(cat "$work/err")"

# ---- 2. VTK's own encodings -----------------------------------------------------------------
py=/usr/bin/python3
if [ -x "$py" ] && "$py" -c 'import vtk' >/dev/null 2>&1; then
    "$bin" layout --kind random --dim 3 --nx 6 --out "$work/ref.vtu" >/dev/null
    "$py" - "$work" <<'EOF'
import sys, vtk
work = sys.argv[1]
r = vtk.vtkXMLUnstructuredGridReader(); r.SetFileName(work + "/ref.vtu"); r.Update()
for name, mode, comp, enc, be in [("bin", 1, 0, 0, 0), ("app", 2, 0, 0, 1), ("b64", 2, 0, 1, 0),
                                  ("zbin", 1, 1, 0, 1), ("zapp", 2, 1, 0, 0)]:
    w = vtk.vtkXMLUnstructuredGridWriter(); w.SetInputData(r.GetOutput())
    w.SetFileName(f"{work}/vtk-{name}.vtu"); w.SetDataMode(mode); w.SetEncodeAppendedData(enc)
    w.SetCompressorTypeToZLib() if comp else w.SetCompressorTypeToNone()
    w.SetByteOrderToBigEndian() if be else w.SetByteOrderToLittleEndian()
    w.SetHeaderTypeToUInt64() if mode == 2 else w.SetHeaderTypeToUInt32()
    w.Write()
EOF
    "$bin" approx --op grad --particles "$work/ref.vtu" --format csv 2>/dev/null | cut -d, -f1-9,11 >"$work/a.txt"
    for m in bin app b64 zbin zapp; do
        "$bin" approx --op grad --particles "$work/vtk-$m.vtu" --format csv 2>/dev/null |
            cut -d, -f1-9,11 >"$work/b.txt"
        cmp -s "$work/a.txt" "$work/b.txt" && ok || bad "VTK-written vtk-$m.vtu differs from ref.vtu"
        "$bin" layout --in "$work/vtk-$m.vtu" --out "$work/vtk-$m.csv" >/dev/null 2>&1 &&
            "$bin" layout --in "$work/ref.vtu" --out "$work/ref.csv" >/dev/null 2>&1 &&
            cmp -s "$work/ref.csv" "$work/vtk-$m.csv" && ok || bad "layout --in vtk-$m.vtu: not ref.vtu's particles"
    done
else
    echo "python3 VTK module not available: VTK-written encodings not checked here (test_io_read reads the fixtures)"
fi

# ---- 3. bad files ---------------------------------------------------------------------------
# rejects NAME "expected text" FILE [approx options]: exit 2, one stderr line naming the file.
rejects() {
    local what=$1 expect=$2 file=$3
    shift 3
    "$bin" approx --op function --particles "$file" "$@" >"$work/out" 2>"$work/err"
    local rc=$? name
    name=$(basename "$file")
    if [ $rc != 2 ]; then
        bad "$what: exit $rc, expected 2"
    elif [ "$(wc -l <"$work/err")" != 1 ]; then
        bad "$what: $(wc -l <"$work/err") lines on stderr: $(cat "$work/err")"
    elif ! grep -qF -- "$name" "$work/err" || ! grep -qF -- "$expect" "$work/err"; then
        bad "$what: message '$(cat "$work/err")' lacks '$name' or '$expect'"
    elif [ -s "$work/out" ]; then
        bad "$what: printed output before failing"
    else
        ok
    fi
}
box='# box 0:1 0:1'
printf '%s\nx,yy,rho\n0.1,0.2,1\n' "$box" >"$work/header.csv"
rejects "misspelled column" "header.csv:2: the header row has no column 'y'" "$work/header.csv"
printf '%s\nx,y\n0.1,0.2\n0.3\n' "$box" >"$work/short.csv"
rejects "short row" "short.csv:4: short row" "$work/short.csv"
printf '%s\nx,y\n0.1,0.2,0.7\n' "$box" >"$work/extra.csv"
rejects "extra column" "extra.csv:3: extra column" "$work/extra.csv"
printf '%s\nx,y\n0.1,0.2\n0.1,zero\n' "$box" >"$work/word.csv"
rejects "not a number" "word.csv:4: column 'y': 'zero' is not a number" "$work/word.csv"
printf '%s\nx,y\nnan,0.2\n' "$box" >"$work/nan.csv"
rejects "nan" "nan.csv:3: column 'x': 'nan' is not a finite number" "$work/nan.csv"
printf '%s\nx,y\n0.5,inf\n' "$box" >"$work/inf.csv"
rejects "inf" "inf.csv:3: column 'y': 'inf' is not a finite number" "$work/inf.csv"
: >"$work/empty.csv"
rejects "empty file" "empty.csv: empty file" "$work/empty.csv"
printf '%s\nx,y\n' "$box" >"$work/headonly.csv"
rejects "header alone" "headonly.csv:2: a header row but no particles" "$work/headonly.csv"
printf '%s\nx,y\n0.1,0.2\n0.4,0.4\n0.1,0.2\n' "$box" >"$work/dup.csv"
rejects "duplicate" "dup.csv:5: particle at the same position as the particle on line 3" "$work/dup.csv"
printf '%s\n# periodic 0 0\nx,y\n0.1,0.2\n0.4,1.25\n' "$box" >"$work/out.csv"
rejects "outside the box" "out.csv:5: particle outside the box: y = 1.25" "$work/out.csv"
printf '%s\n# periodic 1 1\nx,y\n0.1,0.2\n0.4,1.25\n-0.5,0.5\n' "$box" >"$work/wrap.csv"
"$bin" approx --op function --particles "$work/wrap.csv" --format csv >/dev/null 2>"$work/err" &&
    grep -q "2 particles wrapped into the periodic box" "$work/err" && ok ||
    bad "periodic wrap: $(cat "$work/err")"
"$bin" layout --kind lattice --dim 2 --nx 6 --out "$work/good.vtu" >/dev/null
head -c 700 "$work/good.vtu" >"$work/trunc.vtu"
rejects "truncated VTU" "trunc.vtu:" "$work/trunc.vtu"
grep -q "truncated" "$work/err" || bad "truncated VTU message: $(cat "$work/err")"
printf '<?xml version="1.0"?>\n<svg width="3"></svg>\n' >"$work/svg.vtu"
rejects "non-VTU XML" "svg.vtu:2: not a VTK XML file: the root element is <svg>" "$work/svg.vtu"
cp "$work/good.vtu" "$work/notxml.csv"
rejects "XML named .csv" "notxml.csv:1: this is XML" "$work/notxml.csv"
cp "$work/short.csv" "$work/csv.vtu"
rejects "CSV named .vtu" "csv.vtu:1: not an XML file" "$work/csv.vtu"
rejects "--dim disagrees (CSV)" "lattice-2-8.csv:7: the header row has no column 'z' (found: x,y,volume), but 3D particles were asked for" "$work/lattice-2-8.csv" --dim 3
rejects "--dim disagrees (VTU)" "the FieldData array 'box' makes the particles 2D, but 3D particles were asked for" "$work/good.vtu" --dim 3
rejects "missing file" "nosuch.csv: cannot open" "$work/nosuch.csv"
mkdir "$work/dir.csv"
rejects "a directory" "dir.csv: cannot read" "$work/dir.csv"
cp "$work/lattice-2-8.csv" "$work/locked.csv"
chmod 000 "$work/locked.csv"
if cat "$work/locked.csv" >/dev/null 2>&1; then
    echo "running with permission to read mode-000 files (root): unreadable-file case covered by the missing file and directory cases"
else
    rejects "unreadable file" "locked.csv: cannot open: Permission denied" "$work/locked.csv"
fi
chmod 600 "$work/locked.csv"
rejects "no box" "nobox.csv: the file has no box" "$(printf 'x,y\n0.1,0.2\n' >"$work/nobox.csv"; echo "$work/nobox.csv")"
"$bin" approx --op function --particles "$work/nobox.csv" --box 0:1,0:2 --periodic no --format csv >/dev/null 2>&1 &&
    ok || bad "--box for a file without one"
# A file without volumes has box volume / N as its given volumes (the one rule of approx and
# study, include/consph/study.h): --volume given then measures what --volume lattice does.
for v in given lattice; do
    "$bin" approx --op function --particles "$work/nobox.csv" --box 0:1,0:2 --periodic no \
        --volume $v --format csv 2>"$work/err-$v" | cut -d, -f1-9 >"$work/vol-$v.csv"
done
[ -s "$work/vol-given.csv" ] && cmp -s "$work/vol-given.csv" "$work/vol-lattice.csv" &&
    grep -q "given (--volume: box volume / N, none in the file)" "$work/err-given" && ok ||
    bad "--volume given without volumes in the file: $(cat "$work/err-given")"
# Options that do not fit the files: exit 2, one line naming the option.
for args in "lattice-2-8.csv|--box 0:1,2:1|option --box: '0:1,2:1' is not a box" \
    "lattice-2-8.csv|--nx 8|option --nx: not with --particles" \
    "lattice-2-8.csv|--periodic xz|option --periodic: axis z"; do
    IFS='|' read -r file opt expect <<<"$args"
    # shellcheck disable=SC2086
    "$bin" approx --op function --particles "$work/$file" $opt >"$work/out" 2>"$work/err"
    rc=$?
    [ $rc = 2 ] && [ "$(wc -l <"$work/err")" = 1 ] && grep -qF -- "$expect" "$work/err" &&
        [ ! -s "$work/out" ] && ok || bad "$opt: exit $rc, $(cat "$work/err")"
done
# A study with a bad file writes nothing.
"$bin" study "$src/tests/data/engine.study" --quick --out "$work/st2" --particles "$work/dup.csv" \
    >/dev/null 2>"$work/err"
rc=$?
[ $rc = 2 ] && grep -q "dup.csv:5:" "$work/err" && [ ! -e "$work/st2" ] && ok ||
    bad "study with a bad file: exit $rc, $(cat "$work/err"), output $(ls "$work/st2" 2>&1 | head -1)"
# A 3D file for a 2D study: refused before anything is written.
"$bin" study "$src/tests/data/engine.study" --quick --out "$work/st3" \
    --particles "$work/lattice-3-5.csv" >/dev/null 2>"$work/err"
rc=$?
[ $rc = 2 ] && grep -q "is 2D, but the particles of .*lattice-3-5.csv are 3D" "$work/err" && [ ! -e "$work/st3" ] && ok ||
    bad "study with 3D files: exit $rc, $(cat "$work/err")"

echo "cli_particles: $pass passed, $fail failed"
[ $fail = 0 ]
