"""Baselines shared by the benchmarks (no side effects on import)."""

from __future__ import annotations

import time

import numpy as np


def solve_ivp_piecewise(f, y, period, jumps, t_tr, t_end, grid, method, rtol, atol):
    """``scipy.integrate.solve_ivp`` from 0 to ``t_end``, restarted at every jump angle
    (``jumps`` within one ``period``), sampled on ``grid``: (samples (n, len(y)), seconds).
    The SciPy baseline of every benchmark here (same jumps as the diffrax controller)."""
    from scipy.integrate import solve_ivp

    ks = np.arange(int(np.ceil(t_end / period)) + 1)
    cuts = (ks[:, None] * period + np.asarray(jumps)[None, :]).ravel()
    cuts = np.unique(np.concatenate([[0.0, t_end], cuts[(cuts > 0) & (cuts < t_end)]]))
    ys = np.empty((grid.size, y.size))
    t0 = time.perf_counter()
    for a, b in zip(cuts[:-1], cuts[1:]):
        sel = (grid >= a) & (grid < b)
        sol = solve_ivp(f, (a, b), y, method=method, rtol=rtol, atol=atol,
                        t_eval=np.concatenate([grid[sel], [b]]))
        ys[sel] = sol.y[:, :-1].T
        y = sol.y[:, -1]
    return ys, time.perf_counter() - t0
