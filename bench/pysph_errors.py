#!/usr/bin/python3
"""PySPH's three Taylor-Green error measures (pysph/examples/taylor_green.py, post_process) for
one particle set at time t: the L1 of |u| relative to the mean exact |u|, the L1 of p - p_avg
relative to max |p_exact|, and the L-infinity of the decay of max |u|. p_avg is the average of p
over the neighbours within 3h (the quintic's support, i itself included), computed here afresh
from the final positions for either code, so both go through the same post-processing.

usage: pysph_errors.py FILE T RE H     FILE: a PySPH .hdf5 output or a consph .csv snapshot
prints: l1_u p_l1 linf
"""
import sys

import numpy as np


def read(path):
    if path.endswith(".csv"):
        with open(path) as f:
            lines = [ln for ln in f if not ln.startswith("#")]
        names = lines[0].strip().split(",")
        data = np.loadtxt(lines[1:], delimiter=",", ndmin=2)
        col = {n: data[:, k] for k, n in enumerate(names)}
        if "velocity_0" in col:
            return col["x"], col["y"], col["velocity_0"], col["velocity_1"], col["pressure"]
        return col["x"], col["y"], col["u_0"], col["u_1"], col["p"]  # snapshots before the renaming
    from pysph.solver.utils import load

    a = load(path)["arrays"]["fluid"]
    # copies: the arrays are views of memory the particle array frees with itself
    return tuple(np.array(q, copy=True) for q in (a.x, a.y, a.u, a.v, a.p))


def neighbour_average(x, y, p, radius, L=1.0):
    """Mean of p over the periodic neighbourhood r < radius (brute force, in blocks)."""
    n = len(x)
    out = np.empty(n)
    for s in range(0, n, 512):
        dx = x[s:s + 512, None] - x[None, :]
        dy = y[s:s + 512, None] - y[None, :]
        dx -= L * np.round(dx / L)
        dy -= L * np.round(dy / L)
        near = dx * dx + dy * dy < radius * radius
        out[s:s + 512] = (near * p[None, :]).sum(axis=1) / near.sum(axis=1)
    return out


def main():
    path, t, re, h = sys.argv[1], float(sys.argv[2]), float(sys.argv[3]), float(sys.argv[4])
    x, y, u, v, p = read(path)
    b = -8.0 * np.pi ** 2 / re
    e = np.exp(b * t)
    ue = -e * np.cos(2 * np.pi * x) * np.sin(2 * np.pi * y)
    ve = e * np.sin(2 * np.pi * x) * np.cos(2 * np.pi * y)
    pe = -0.25 * e * e * (np.cos(4 * np.pi * x) + np.cos(4 * np.pi * y))
    p = p - neighbour_average(x, y, p, 3.0 * h)
    vmag, vmag_e = np.hypot(u, v), np.hypot(ue, ve)
    l1 = np.average(np.abs(vmag - vmag_e)) / np.average(np.abs(vmag_e))
    p_l1 = np.average(np.abs(p - pe)) / np.abs(pe).max()
    linf = abs((vmag.max() - e) / e)
    print("%.6e %.6e %.6e" % (l1, p_l1, linf))


if __name__ == "__main__":
    main()
