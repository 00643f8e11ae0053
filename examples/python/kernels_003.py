"""003 section 6.3 (Table 2, the kernel dependence of Fig. 1): the mean absolute error of the SPH
interpolation of f = sin(πx) sin(πy) on quasi-random particles in the unit square, for five
kernels, with h following 003's scaling law h = N^(-1/6), against √N. The super-Gaussian's
vanishing second moment makes it converge faster than the others.

The settings are those of studies/003-kernels.study (figure table2_2d), measured through
`import consph` (consph.approx: the numbers `consph approx` prints) and drawn with matplotlib.

    PYTHONPATH=build/python /usr/bin/python3 examples/python/kernels_003.py [OUT.png] [--quick]

Writes kernels_003.png (or OUT.png). N runs from 25² to 400² (about 50 s of CPU time, measured
on 2 shared cores; set OMP_WAIT_POLICY=passive on a loaded machine); --quick stops at 100²
(about 2 s).
"""

import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import consph  # noqa: E402

args = [a for a in sys.argv[1:] if not a.startswith("--")]
out = args[0] if args else "kernels_003.png"
quick = "--quick" in sys.argv
nx = [25, 50, 75, 100] if quick else [25, 50, 75, 100, 150, 200, 300, 400]

kernels = [("Lucy", "lucy"), ("super-Gaussian", "super-gaussian"),
           ("Wendland C2", "wendland-c2:h"), ("Wendland C4", "wendland-c4:h"),
           ("Wendland C6", "wendland-c6:h")]
markers = ["o", "s", "^", "D", "v"]

fig, ax = plt.subplots(figsize=(6.4, 4.8))
for (label, kernel), marker in zip(kernels, markers):
    r = consph.approx("function", nx=nx, form="standard", kernel=kernel, h_policy="scaling",
                      layout="quasi-random", periodic=False, mask="all", volume="given",
                      field="sinprod", dim=2)
    sqrt_n = np.sqrt(r["rows"]["n"])
    mae = r["rows"]["mae"]
    order = r["order"]["mae"]["order"]
    # the order is fitted against nx = √N in 2D: MAE ∝ (√N)^-order
    ax.loglog(sqrt_n, mae, marker=marker, label=f"{label} (slope {-order:.2f})")
    print(f"{label:15s} " + " ".join(f"{v:.3e}" for v in mae) + f"  order {order:.2f}")

# slope guides: h² = N^(-1/3) = (√N)^(-2/3) for a second-order kernel, h⁴ for the super-Gaussian
s = np.array([sqrt_n[0], sqrt_n[-1]])
for p, style in ((2.0 / 3.0, ":"), (4.0 / 3.0, "--")):
    ax.loglog(s, 0.5 * mae[0] * (s / s[0]) ** (-p), "k" + style, lw=0.8,
              label=f"slope -{p:.2f} (h^{round(p * 3)})")
ax.set_xlabel("√N (particles per side)")
ax.set_ylabel("MAE of Π sin(πx_a)  (003 eq. 58)")
ax.set_title(f"003 §6.3: kernels in 2D, quasi-random, h = N^(-1/6), "
             f"N = {nx[0]}² to {nx[-1]}²", fontsize=10)
ax.grid(True, which="both", lw=0.3)
ax.legend(fontsize=8)
fig.tight_layout()
fig.savefig(out, dpi=120)
print("wrote", out)
