"""Exact extrema of a periodic response: read on both sides of every jump, refined between
samples.

The dynamic mesh force of Eqs. (22)/(24) jumps wherever the mesh stiffness does (cell
engagement, quasi-static active-set changes): ``F_D = F_S + k(theta) cos(b_b) x_D`` with a
continuous state. Its maximum often sits *at* a jump, and a uniform sample grid reads it
one sample late; between jumps a sampled maximum reads low by the curvature times the
squared sample spacing. Two rules make the extrema exact to the integration tolerance:

1. The output grid holds, besides ``samples_per_mesh_period`` mid-cell samples per mesh
   period, the two one-sided points ``s_j -/+ delta`` of every jump angle ``s_j`` of the
   model (``delta = 1e-9`` excitation periods; the state is continuous, so the outputs
   there are the one-sided limits to ``delta`` times their slope).
2. Around the largest (smallest) grid value the solution is integrated again over the two
   adjacent grid intervals, the outputs are read on ``n_refine`` points per interval and
   the vertex of a parabola through the best three gives the extremum
   (:func:`refined_extrema`): the states there are as accurate as the integration, and
   the remaining error between jumps is of fourth order in ``h / n_refine``.

A cubic Hermite interpolant of the state between grid points (from the states and the
vector field) was tried first: its fourth-order interpolation error reached 1.7e-6 F_S at
128 samples per mesh period on the sdof long-relief case (the state carries the static
ripple of TE_S), more than the closed-form checks allow; re-integration has no such floor.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

__all__ = ["JUMP_SIDE", "OutputGrid", "output_grid", "refined_extrema", "refine_windows",
           "window_extrema"]

JUMP_SIDE = 1e-9  # one-sided points at s_j -/+ JUMP_SIDE * period


class OutputGrid(NamedTuple):
    """The output grid of :func:`output_grid` (NumPy arrays, build time).

    offsets : (n_periods * per_period,) sorted angles (rad) from the start of the first
        measured period.
    per_period : grid points per period (the grid reshapes to ``(n_periods, per_period)``).
    samples : (len(offsets),) bool, True at the uniform mid-cell samples (False at the
        one-sided jump points): the uniformly sampled signals.
    """

    offsets: np.ndarray
    per_period: int
    samples: np.ndarray


def output_grid(period: float, n_samples: int, jump_thetas, n_periods: int) -> OutputGrid:
    """The output grid over ``n_periods`` excitation periods: ``n_samples`` mid-cell samples
    ``(j + 1/2) period / n_samples`` and the two one-sided points of every jump per period."""
    period = float(period)
    mid = (np.arange(n_samples) + 0.5) * (period / n_samples)
    jumps = np.mod(np.asarray(jump_thetas, dtype=float).reshape(-1), period)
    d = JUMP_SIDE * period
    one = np.concatenate([mid, jumps - d, jumps + d])
    is_sample = np.concatenate([np.ones(mid.size, bool), np.zeros(2 * jumps.size, bool)])
    # a one-sided point outside [0, period) belongs to the neighbouring period
    one = np.mod(one, period)
    order = np.argsort(one, kind="stable")
    one, is_sample = one[order], is_sample[order]
    offsets = (one[None, :] + period * np.arange(n_periods)[:, None]).ravel()
    return OutputGrid(offsets, one.size, np.tile(is_sample, n_periods))


def _vertex_max(t, v, short):
    """Largest value of the samples ``v`` at the sorted angles ``t`` and of the parabola
    through the largest sample and its two neighbours, where that fit is sound: the five
    points around it equally spaced, farther apart than ``short`` (no jump between them),
    the middle one the largest (interpolation, no extrapolation) and the three second
    differences alike (no kink: a mesh force that stays at zero while the teeth separate,
    or a cell that loses contact, would put a parabola's vertex beyond the signal).
    Fourth-order error."""
    i = jnp.clip(jnp.argmax(v), 2, v.shape[0] - 3)
    y0, y1, y2 = v[i - 1], v[i], v[i + 1]
    dt = jnp.diff(jax.lax.dynamic_slice(t, (i - 2,), (5,)))
    d1 = dt[2]
    curv = y0 - 2.0 * y1 + y2
    c_lo = v[i - 2] - 2.0 * y0 + y1
    c_hi = y1 - 2.0 * y2 + v[i + 2]
    tol = 0.25 * jnp.abs(curv)
    smooth = (jnp.abs(c_lo - curv) <= tol) & (jnp.abs(c_hi - curv) <= tol)
    sound = ((jnp.max(jnp.abs(dt - d1)) <= 1e-6 * d1) & (jnp.min(dt) > short) & (y1 >= y0)
             & (y1 >= y2) & (curv < 0) & smooth)
    vertex = y1 - (y0 - y2) ** 2 / (8.0 * jnp.where(curv < 0, curv, -1.0))
    return jnp.maximum(jnp.max(v), jnp.where(sound, vertex, -jnp.inf))


def refined_extrema(outputs, flow, ts, ys, n_refine: int = 64):
    """Max and min of each output over the grid, refined between grid points.

    Parameters
    ----------
    outputs : ``f(t, y) -> (q,)`` the observed quantities (mesh force, DTE, ...).
    flow : ``flow(t0, y0, ts) -> ys``, the states at the sorted angles ``ts`` of the
        solution started from ``y0`` at ``t0`` (the integrator, with its own tolerances).
    ts : (N,) grid angles, ``ys`` : (N, n) states on the grid.
    n_refine : points per grid interval in the refinement windows.

    Returns
    -------
    (grid_values (N, q), maxima (q,), minima (q,)); each extremum is at least as extreme
    as the grid's.

    Each extremum is refined on the window of the two grid intervals around the grid's
    interior extreme: the solution is integrated again from the window's first grid point,
    the outputs are read on ``n_refine`` interior points of each interval, and a parabola
    through the largest of them and its neighbours gives the vertex (intervals that
    straddle a jump, ``[s_j - delta, s_j + delta]``, are read but not fitted). All windows
    of a call are integrated together (one vmapped solve). With one measured period only,
    an extreme that lies before the first or after the last grid point is read from the
    grid alone.
    """
    vals = jax.vmap(outputs)(ts, ys)
    j0, tf = refine_windows(vals, ts, n_refine)
    cols = jnp.repeat(jnp.arange(vals.shape[1]), 2)
    wvals = jax.vmap(lambda j, c, t: jax.vmap(outputs)(t, flow(ts[j], ys[j], t))[:, c])(
        j0, cols, tf)
    return (vals,) + window_extrema(vals, ts, j0, wvals)


def refine_windows(vals, ts, n_refine: int = 64):
    """The refinement windows of :func:`refined_extrema`: for each output ``c`` (in the
    order max of 0, min of 0, max of 1, ...), the index ``j0`` of the window's first grid
    point (the window is ``[ts[j0], ts[j0 + 2]]`` around the interior grid extreme
    ``j0 + 1``) and its ``2 n_refine`` interior angles ``tf`` (sorted). Returns
    ``(j0 (2q,), tf (2q, 2 n_refine))``."""
    n, q = vals.shape
    # windows [t_j-1, t_j+1] around the interior grid extreme j: an extreme at the first or
    # last grid point may lie outside the measured span, where no window reaches; its
    # periodic copy one period on is interior (two measured periods or more)
    inner = vals[1:-1]
    starts = []
    for c in range(q):
        starts += [jnp.argmax(inner[:, c]), jnp.argmin(inner[:, c])]
    j0 = jnp.stack(starts)  # window [t_j0, t_j0+2] around each interior extreme j0 + 1
    u = (jnp.arange(n_refine) + 1.0) / (n_refine + 1.0)

    def angles(j):
        a = ts[j] + u * (ts[j + 1] - ts[j])
        b = ts[j + 1] + u * (ts[j + 2] - ts[j + 1])
        return jnp.concatenate([a, b])

    return j0, jax.vmap(angles)(j0)


def window_extrema(vals, ts, j0, wvals):
    """Max and min of each output over the grid values ``vals`` (N, q) and the refined
    window values ``wvals`` (2q, 2 n_refine) read at the angles of :func:`refine_windows`
    (window k refines output k // 2, its max for even k, its min for odd k). Returns
    ``(maxima (q,), minima (q,))``."""
    n, q = vals.shape
    n_refine = wvals.shape[1] // 2
    u = (jnp.arange(n_refine) + 1.0) / (n_refine + 1.0)
    short = 1e-6 * (ts[-1] - ts[0]) / n  # intervals this short straddle a jump

    def window(j, c, out):
        """Times and values of output c on [t_j, t_j+2]: grid points and refined ones."""
        a = ts[j] + u * (ts[j + 1] - ts[j])
        b = ts[j + 1] + u * (ts[j + 2] - ts[j + 1])
        tw = jnp.concatenate([ts[j][None], a, ts[j + 1][None], b, ts[j + 2][None]])
        vw = jnp.concatenate([vals[j, c][None], out[:n_refine], vals[j + 1, c][None],
                              out[n_refine:], vals[j + 2, c][None]])
        return tw, vw

    cols = jnp.repeat(jnp.arange(q), 2)  # window k refines output k // 2
    tw, vw = jax.vmap(window)(j0, cols, wvals)  # (2q, 2 n_refine + 3)
    sign = jnp.tile(jnp.asarray([1.0, -1.0]), q)  # max windows, min windows
    best = jax.vmap(lambda tt, vv, sg: sg * _vertex_max(tt, sg * vv, short / (n_refine + 1)))(
        tw, vw, sign)
    maxima = [jnp.maximum(jnp.max(vals[:, c]), best[2 * c]) for c in range(q)]
    minima = [jnp.minimum(jnp.min(vals[:, c]), best[2 * c + 1]) for c in range(q)]
    return jnp.stack(maxima), jnp.stack(minima)
