"""003 Fig. 1 (section 6.2, Table 1): the mean absolute error (eq. 58) of the standard SPH
interpolant of f = Π sin(πx_a) on quasi-random particles in the unit square and cube, Wendland C4
with support h (eq. 55), h = N^(-1/6), no boundary treatment, against the error bounds of
eqs. 56 (2D) and 57 (3D), plotted against N^(1/2) and N^(1/3).

It runs the study studies/003-table1.study through `import consph` (consph.study: the tables
`consph study 003-table1` writes, MAE and bound per resolution) and draws them with matplotlib.
The right panel sets the measured neighbour count beside 003's Table 1 (𝒩 and h, the paper's
values, read from the study file's paper.nnbr / paper.h): in 2D they agree; in 3D the support h
holds far fewer neighbours than Table 1 lists (docs/deviations.md). 003 prints no MAE values,
only Fig. 1; the open markers are eqs. 56/57 evaluated by hand at γ = 0.5772 as a check of the
library's bound column.

    PYTHONPATH=build/python /usr/bin/python3 examples/python/fig1_003.py [OUT.png] [--quick]

Writes fig1_003.png (or OUT.png). The full study runs 2D N = 25² to 1000² and 3D N = 25³ to 200³
as 003 does (it prints consph.study_estimate's figure first, 792 s; measured: 1193 s of CPU time
on one thread, about 20 minutes, on a loaded 2-core machine); --quick runs the
study's quick resolutions, 2D 25² to 200² and 3D 10³ to 30³ (about 2 s).
"""

import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import consph  # noqa: E402

args = [a for a in sys.argv[1:] if not a.startswith("--")]
out = args[0] if args else "fig1_003.png"
quick = "--quick" in sys.argv
STUDY = "003-table1"


def paper_table1(path):
    """003 Table 1 as the study file quotes it: {figure: (nx, 𝒩, h)} from its nx, paper.nnbr and
    paper.h keys (the full resolutions, the paper's)."""
    tables, fig, keys = {}, None, {}
    with open(path, encoding="utf-8") as f:
        for line in list(f) + ["[figure end]"]:
            line = line.strip()
            if line.startswith("[figure"):
                if fig and "paper.h" in keys:
                    tables[fig] = tuple(np.array([float(v) for v in keys[k].split(",")])
                                        for k in ("nx", "paper.nnbr", "paper.h"))
                fig, keys = line[len("[figure"):-1].strip(), {}
            elif "=" in line and not line.startswith("#") and fig:
                k, v = line.split("=", 1)
                keys[k.strip()] = v.strip()
    return tables


# eqs. 56/57 evaluated by hand with γ = 0.5772 and Table 1's 𝒩 (not printed in 003):
# (dim, N^(1/n), bound)
HAND_BOUNDS = [(2, 25, 2.537), (2, 100, 0.937), (2, 1000, 0.198), (3, 25, 1.828), (3, 200, 0.222)]

est = consph.study_estimate(STUDY, quick=quick)
print(f"consph.study('{STUDY}', quick={quick}): estimated {est:.0f} s")
tables = consph.study(STUDY, quick=quick)
paper = paper_table1(consph.study_path(STUDY))

fig, (ax, axn) = plt.subplots(1, 2, figsize=(12.8, 5.0))
style = {2: ("tab:blue", "o", "s", "eq. 56"), 3: ("tab:red", "^", "D", "eq. 57")}
ranges = []
for dim, figure in ((2, "table1_2d"), (3, "table1_3d")):
    t = tables[figure]
    colour, m_mae, m_bound, eq = style[dim]
    x = t["n"] ** (1.0 / dim)
    sup = "²³"[dim - 2]
    ranges.append(f"{dim}D N = {int(t['nx'][0])}{sup} to {int(t['nx'][-1])}{sup}")
    ax.loglog(x, t["mae"], "-", color=colour, marker=m_mae, label=f"{dim}D MAE (consph)")
    ax.loglog(x, t["bound"], "--", color=colour, marker=m_bound, mfc="none",
              label=f"{dim}D bound, {eq} (consph)")
    hx = [(n, b) for d, n, b in HAND_BOUNDS if d == dim]
    ax.loglog([n for n, _ in hx], [b for _, b in hx], "x", color="k", ms=9,
              label="eqs. 56/57 by hand (γ = 0.5772)" if dim == 2 else None)
    for n, b in hx:
        ax.annotate(f"{b:g}", (n, b), textcoords="offset points", fontsize=7,
                    xytext=(6, 4) if dim == 2 else (-30, -12))
    print(f"{dim}D  N^(1/{dim}): " + " ".join(f"{v:.0f}" for v in x))
    print("    MAE:   " + " ".join(f"{v:.3e}" for v in t["mae"]))
    print("    bound: " + " ".join(f"{v:.3e}" for v in t["bound"]))

    nx_p, nnbr_p, h_p = paper[figure]
    axn.loglog(x, t["nbr_mean"], "-", color=colour, marker=m_mae,
               label=f"{dim}D measured neighbours, support h = N^(-1/6)")
    axn.loglog(nx_p, nnbr_p, linestyle="none", color=colour, marker=m_bound, mfc="none", ms=8,
               label=f"003 Table 1, {dim}D $\\mathcal{{N}}$ (h labelled)")
    for n, nn, h in zip(nx_p, nnbr_p, h_p):
        if n in (nx_p[0], nx_p[len(nx_p) // 2], nx_p[-1]):
            axn.annotate(f"h={h:.3f}", (n, nn), textcoords="offset points", xytext=(5, -11),
                         fontsize=7, color=colour)

# 003's range starts at N^(1/n) = 25; the quick 3D rows start lower
xlo = min(25.0, min(tables[f]["n"].min() ** (1 / d) for d, f in ((2, "table1_2d"),
                                                               (3, "table1_3d"))))
for a in (ax, axn):
    a.set_xlim(0.8 * xlo, 1250)  # the data and 003's range, N^(1/n) up to 1000
    a.set_xlabel("N^(1/2) in 2D, N^(1/3) in 3D (particles per side)")
    a.grid(True, which="both", lw=0.3)
    a.legend(fontsize=8, loc="best")
ax.set_ylabel("MAE of Π sin(πx_a) (eq. 58) and its bound")
ax.set_title("MAE against the bounds of eqs. 56/57", fontsize=10)
axn.set_ylabel(r"neighbours per particle $\mathcal{N}$")
axn.set_title("neighbour count against 003 Table 1", fontsize=10)
fig.suptitle(f"003 Fig. 1: Wendland C4, support h = N^(-1/6), Halton points, ΔV = 1/N; "
             f"{'quick: ' if quick else ''}{', '.join(ranges)}", fontsize=11)
fig.tight_layout()
fig.savefig(out, dpi=120)
print("wrote", out)
