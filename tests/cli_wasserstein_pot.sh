#!/usr/bin/env bash
# consph wasserstein against POT, the Python Optimal Transport library (Debian python3-pot), on
# random weighted measures of unequal sizes: exact 1D W_p and ot.emd2 (network simplex) agree to
# round-off; Sinkhorn lies within its own error bound of ot.emd2's exact 2D/3D W_p; sliced SW_p
# agrees with ot.sliced_wasserstein_distance within the two Monte Carlo errors. Exit 77
# (skipped) when POT is not installed.
# Usage: cli_wasserstein_pot.sh <path-to-consph> <source-dir>
set -u
bin=$1
py=/usr/bin/python3
"$py" -c 'import ot' 2>/dev/null || { echo "python3-pot not installed: skipped"; exit 77; }
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
export OMP_NUM_THREADS=${OMP_NUM_THREADS:-1}
"$py" - "$bin" "$work" <<'PYEOF'
import json, subprocess, sys
import numpy as np
import ot

binary, work = sys.argv[1], sys.argv[2]
rng = np.random.default_rng(17)
failures = 0
checks = 0


def write(path, x, m):
    dim = x.shape[1]
    with open(path, "w") as f:
        f.write("# dim %d\n# box %s\n" % (dim, " ".join(["-1:3"] * dim)))
        f.write(",".join("xyz"[:dim]) + ",m\n")
        for row, mass in zip(x, m):
            f.write(",".join("%.17g" % v for v in row) + ",%.17g\n" % mass)


def consph(a, b, *opts):
    out = subprocess.run([binary, "wasserstein", a, b, "--format", "json", *opts],
                         capture_output=True, text=True, check=True).stdout
    return json.loads(out)


def check(cond, what):
    global failures, checks
    checks += 1
    if not cond:
        failures += 1
        print("FAIL:", what)


for dim in (1, 2, 3):
    for trial in range(2):
        n, m = 60 + 7 * trial, 45
        x = rng.uniform(0, 1, (n, dim))
        y = rng.uniform(0.2, 1.5, (m, dim))
        wx = rng.uniform(0.2, 1, n)
        wy = rng.uniform(0.2, 1, m)
        fa, fb = "%s/a%d%d.csv" % (work, dim, trial), "%s/b%d%d.csv" % (work, dim, trial)
        write(fa, x, wx)
        write(fb, y, wy)
        a, b = wx / wx.sum(), wy / wy.sum()
        for p in (1, 2):
            cost = ot.dist(x, y, metric="euclidean") ** p
            exact = ot.emd2(a, b, cost) ** (1.0 / p)
            tag = "%dD trial %d p=%d" % (dim, trial, p)
            if dim == 1:
                r = consph(fa, fb, "--p", str(p))
                check(abs(r["distance"] - exact) <= 1e-9 * exact,
                      "%s exact %.15g vs ot.emd2 %.15g" % (tag, r["distance"], exact))
            r = consph(fa, fb, "--method", "sinkhorn", "--p", str(p), "--eps", "1e-4")
            check(abs(r["distance"] - exact) <= r["error"],
                  "%s sinkhorn %.12g vs ot.emd2 %.12g, bound %.3g" % (tag, r["distance"], exact,
                                                                     r["error"]))
            check(r["error"] < 0.1 * exact, "%s sinkhorn bound %.3g vs W %.3g" % (tag, r["error"],
                                                                                 exact))
            if dim > 1:
                r = consph(fa, fb, "--p", str(p), "--directions", "2000", "--seed", str(trial + 1))
                # POT's estimate from its own 20000 directions; its standard error is estimated
                # from 20 independent batches.
                batches = [ot.sliced_wasserstein_distance(x, y, a, b, 1000, p=p, seed=s) ** p
                           for s in range(20)]
                pot = np.mean(batches) ** (1.0 / p)
                se_pot = np.std(batches, ddof=1) / np.sqrt(20) / (p * pot ** (p - 1))
                tol = 4 * np.hypot(r["error"], se_pot)
                check(abs(r["distance"] - pot) <= tol,
                      "%s sliced %.8g vs POT %.8g (tol %.3g)" % (tag, r["distance"], pot, tol))
print("cli_wasserstein_pot: %d checks, %d failed" % (checks, failures))
sys.exit(1 if failures else 0)
PYEOF
