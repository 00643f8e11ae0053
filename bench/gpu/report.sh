#!/usr/bin/env bash
# Writes the GPU probe's markdown report on stdout from run_probe.sh's OUTDIR (results.txt,
# compare.txt, status.txt, raw/environment.log).   usage: bash report.sh OUTDIR THREADS
set -u
OUT=$1
NT=${2:-16}
env=$OUT/raw/environment.log
echo "# GPU probe (bench/gpu/run_probe.sh)"
echo
echo "Run $(date -u '+%Y-%m-%d %H:%M UTC') on $(uname -n)."
echo
echo '```'
grep -A1 '^name, driver_version' "$env" 2>/dev/null | tail -1 | sed 's/^/GPU: /'
grep -m1 'Model name' "$env" 2>/dev/null | sed 's/^ *Model name: */CPU: /'
echo "cores: $(nproc), CPU runs threads: 1 and $NT"
grep -A1 '^== glibc' "$env" 2>/dev/null | tail -1 | sed 's/^/glibc: /'
grep -A1 '^== gcc' "$env" 2>/dev/null | tail -1 | sed 's/^/gcc: /'
[ -s "$OUT/raw/nvcc_version.log" ] && tail -n 2 "$OUT/raw/nvcc_version.log" | head -1 | sed 's/^/nvcc: /'
grep -h -m1 '^DEVICE' "$OUT"/raw/cuda_*.log 2>/dev/null | head -1
grep -h -m1 '^OFFLOAD' "$OUT"/raw/omp_fma_*.log 2>/dev/null | head -1
echo '```'
echo
echo "## Builds and failures"
echo
sed 's/^/- /' "$OUT/status.txt"
echo
echo "## Throughput"
echo
echo "Minimum over the repetitions (GPU runs after one untimed warm-up). (a) summation density,"
echo "pairs counted with j = i; (b) Tait EOS + continuity + pressure gradient + Morris viscosity,"
echo "pairs j != i within 3h. Cells: index, sort and permutation of the particles into cell order."
echo "B/particle: GPU memory of the step's arrays (CUDA: cudaMemGetInfo before/after allocating;"
echo "omp and cpu: the arrays' sizes). x serial: the same size's cpu_fma_t1 time over this one."
echo
awk '
function kv(line, arr,   n, i, f, p) {
    n = split(line, f, " ")
    for (i = 2; i <= n; ++i) { p = index(f[i], "="); if (p) arr[substr(f[i], 1, p - 1)] = substr(f[i], p + 1) }
}
FNR == NR {
    delete r; kv($0, r)
    if (r["tag"] ~ /^cpu_fma_t1_/) { sa[r["dim"] ":" r["nx"]] = r["t_a"]; sb[r["dim"] ":" r["nx"]] = r["t_b"] }
    next
}
{
    delete r; kv($0, r)
    if (r["tag"] ~ /^smoke_|_again_/) next
    key = r["dim"] ":" r["nx"]
    label = r["tag"]; sub(/_[23]d_[0-9]+$/, "", label)
    xa = (key in sa) ? sprintf("%.1f", sa[key] / r["t_a"]) : "-"
    xb = (key in sb) ? sprintf("%.1f", sb[key] / r["t_b"]) : "-"
    rows[++nrow] = sprintf("%s %012d %s", r["dim"], r["N"], label)
    line[nrow] = sprintf("| %s | %s | %s | %s | %s | %.1f | %.3g | %.2f | %.3g | %.2f | %.2f | %.0f | %s | %s |",
        label, r["where"], r["threads"], r["dim"] "D", r["N"], r["pairs_per_particle"],
        r["pairs_per_s_a"], r["ns_per_particle_a"], r["pairs_per_s_b"], r["ns_per_particle_b"],
        r["ns_per_particle_cells"], r["bytes_per_particle"], xa, xb)
}
END {
    print "| build | where | threads | dim | N | pairs/particle | (a) pairs/s | (a) ns/particle | (b) pairs/s | (b) ns/particle | cells ns/particle | B/particle | (a) x serial | (b) x serial |"
    print "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"
    for (i = 1; i <= nrow; ++i) order[i] = i
    for (i = 2; i <= nrow; ++i)         # insertion sort by dim, N, label
        for (j = i; j > 1 && rows[order[j - 1]] > rows[order[j]]; --j) { t = order[j]; order[j] = order[j - 1]; order[j - 1] = t }
    for (i = 1; i <= nrow; ++i) print line[order[i]]
}' "$OUT/results.txt" "$OUT/results.txt"
echo
echo "## Determinism and agreement"
echo
echo "Dumps of (a) rho and (b) drho, du in the shared cell order. Differing: values not bitwise"
echo "equal; max rel: max |x - y| / max |x| per quantity (the largest over (b)'s four)."
echo "fma: nvcc's default -fmad=true, gcc -ffp-contract=fast (-march=native on the host);"
echo "nofma: nvcc -fmad=false, gcc -ffp-contract=off."
echo
echo "| comparison | N | (a) differing / values | (a) max rel | (b) differing / values | (b) max rel |"
echo "|---|---|---|---|---|---|"
awk '{
    delete r
    for (i = 2; i <= NF; ++i) { p = index($i, "="); if (p) r[substr($i, 1, p - 1)] = substr($i, p + 1) }
    if ("missing" in r) { printf "| %s | - | not run (%s missing) | | | |\n", r["label"], r["missing"]; next }
    printf "| %s | %s | %s / %s | %s | %s / %s | %s |\n", r["label"], r["N"], r["ndiff_a"], r["values_a"],
        r["maxrel_a"], r["ndiff_b"], r["values_b"], r["maxrel_b"]
}' "$OUT/compare.txt"
echo
echo "Raw logs: raw/*.log (one per part), results.txt, compare.txt, run.log."
