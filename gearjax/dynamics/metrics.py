"""Exact extrema of a periodic response: read on both sides of every jump, refined between
samples.

The dynamic mesh force of Eqs. (22)/(24) jumps wherever the mesh stiffness does (cell
engagement, quasi-static active-set changes): ``F_D = F_S + k(theta) cos(b_b) x_D`` with a
continuous state. Its maximum often sits *at* a jump, and a uniform sample grid reads it
one sample late; between jumps a sampled maximum reads low by the curvature times the
squared sample spacing; at low speed the free ringing after a jump is faster than the
grid. Three rules make the extrema exact to the integration tolerance:

1. The output grid holds, besides ``samples_per_mesh_period`` mid-cell samples per mesh
   period, the two one-sided points ``s_j -/+ delta`` of every jump angle ``s_j`` of the
   model (``delta = 1e-9`` excitation periods; the state is continuous, so the outputs
   there are the one-sided limits to ``delta`` times their slope).
2. Around the largest (smallest) grid value the solution is integrated again over the two
   adjacent grid intervals, the outputs are read on ``n_refine`` points per interval and
   the vertex of the quartic through the best five gives the extremum
   (:func:`refined_extrema`): the states there are as accurate as the integration, and
   the remaining error between jumps is of sixth order in ``h / n_refine``.
3. Where the period of the free mode that dominates the mesh deflection spans fewer than
   16 grid intervals (low speed: ``2 pi Omega / omega_n`` rad), the grid aliases the
   ringing that a jump starts, and rule 2 refines around a grid value elsewhere (the
   first undershoot after a pair engages is missed). The solution is
   then also integrated from the one-sided point after each of the largest jumps of the
   force and after the jumps where each output is nearest its extremes (:func:`jump_windows`;
   after every jump where there are few; jumps closer than a sixteenth of a grid interval
   ring as one) over two free periods (at most four grid intervals) and read on ``2 n_refine``
   points, the extremum from the quartic vertex again (:func:`jump_window_extrema`), or,
   where the output keeps rising for a moment after the jump and peaks before the
   window's second point, from the quartic through its first five points.

Re-integration rather than an interpolant of the state between grid points: the state
carries the static ripple of TE_S, so an interpolant has an error floor that
re-integration does not (``benchmarks/results/code_notes.md``, gearjax.dynamics.metrics).
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

__all__ = ["JUMP_SIDE", "OutputGrid", "output_grid", "refined_extrema", "refine_windows",
           "window_extrema", "JumpClusters", "jump_clusters", "ringing_length",
           "ringing_resolved", "n_jump_windows", "jump_windows", "jump_window_extrema"]

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
    or a cell that loses contact, would put a parabola's vertex beyond the signal); the
    vertex refined on the quartic through the five (:func:`_quartic_vertex`)."""
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
    vertex = _quartic_vertex(v[i - 2], y0, y1, y2, v[i + 2], vertex)
    return jnp.maximum(jnp.max(v), jnp.where(sound, vertex, -jnp.inf))


def _quartic(vm2, vm1, v0, v1, v2):
    """Coefficients ``(a1, a2, a3, a4)`` of the quartic ``v0 + a1 s + ... + a4 s^4``
    through five equally spaced values at ``s = -2..2`` (unit spacing), and the quartic
    and its first and second derivatives as functions of ``s``."""
    a1 = (vm2 - 8.0 * vm1 + 8.0 * v1 - v2) / 12.0
    a2 = (-vm2 + 16.0 * vm1 - 30.0 * v0 + 16.0 * v1 - v2) / 24.0
    a3 = (-vm2 + 2.0 * vm1 - 2.0 * v1 + v2) / 12.0
    a4 = (vm2 - 4.0 * vm1 + 6.0 * v0 - 4.0 * v1 + v2) / 24.0
    d1 = lambda s: a1 + s * (2.0 * a2 + s * (3.0 * a3 + s * 4.0 * a4))  # noqa: E731
    d2 = lambda s: 2.0 * a2 + s * (6.0 * a3 + s * 12.0 * a4)  # noqa: E731
    p = lambda s: v0 + s * (a1 + s * (a2 + s * (a3 + s * a4)))  # noqa: E731
    return (a1, a2, a3, a4), p, d1, d2


def _quartic_vertex(vm2, vm1, v0, v1, v2, parabola):
    """Maximum of the quartic through five equally spaced values (at s = -2..2, unit
    spacing) near s = 0: three Newton steps on its derivative from the parabola's vertex
    (sixth-order error: a free oscillation sampled 64 times per period is read to 1e-8 of
    its amplitude, the parabola to 4e-6); the parabola's ``parabola`` where Newton leaves
    ``|s| <= 1`` or the quartic is not concave there."""
    (a1, a2, _, _), p, d1, d2 = _quartic(vm2, vm1, v0, v1, v2)
    s = -a1 / jnp.where(a2 < 0, 2.0 * a2, -1.0)
    for _ in range(3):
        s = s - d1(s) / jnp.where(d2(s) < 0, d2(s), -1.0)
    good = (jnp.abs(s) <= 1.0) & (d2(s) < 0) & jnp.isfinite(s)
    s = jnp.where(good, s, 0.0)
    value = p(s)
    return jnp.where(good, value, parabola)


def refined_extrema(outputs, flow, ts, ys, n_refine: int = 64, jumps=None):
    """Max and min of each output over the grid, refined between grid points.

    Parameters
    ----------
    outputs : ``f(t, y) -> (q,)`` the observed quantities (mesh force, DTE, ...).
    flow : ``flow(t0, y0, ts) -> ys``, the states at the sorted angles ``ts`` of the
        solution started from ``y0`` at ``t0`` (the integrator, with its own tolerances).
    ts : (N,) grid angles, ``ys`` : (N, n) states on the grid.
    n_refine : points per grid interval in the refinement windows.
    jumps : ``(clusters, length)``: also the windows after the largest jumps
        (:func:`jump_windows`, ``2 n_refine`` points over ``length`` rad; ``clusters``
        (:func:`jump_clusters`) index ``ts`` as one period); None: none.

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
    v_max, v_min = window_extrema(vals, ts, j0, wvals)
    if jumps is not None:
        clusters, length = jumps
        jj, tj = jump_windows(vals, ts, clusters, ts.shape[0], length, 2 * n_refine)
        wj = jax.vmap(lambda j, t: jax.vmap(outputs)(t, flow(ts[j], ys[j], t)))(jj, tj)
        j_max, j_min = jump_window_extrema(vals, ts, jj, tj, wj)
        v_max, v_min = jnp.maximum(v_max, j_max), jnp.minimum(v_min, j_min)
    return vals, v_max, v_min


def refine_windows(vals, ts, n_refine: int = 64, n_valid=None):
    """The refinement windows of :func:`refined_extrema`: for each output ``c`` (in the
    order max of 0, min of 0, max of 1, ...), the index ``j0`` of the window's first grid
    point (the window is ``[ts[j0], ts[j0 + 2]]`` around the interior grid extreme
    ``j0 + 1``) and its ``2 n_refine`` interior angles ``tf`` (sorted). ``n_valid``: only
    the first ``n_valid`` grid points count (traced; the rest is padding). Returns
    ``(j0 (2q,), tf (2q, 2 n_refine))``."""
    n, q = vals.shape
    # windows [t_j-1, t_j+1] around the interior grid extreme j: an extreme at the first or
    # last grid point may lie outside the measured span, where no window reaches; its
    # periodic copy one period on is interior (two measured periods or more)
    inner = vals[1:-1]
    hi = lo = inner
    if n_valid is not None:
        inside = (jnp.arange(n - 2) < n_valid - 2)[:, None]
        hi, lo = jnp.where(inside, inner, -jnp.inf), jnp.where(inside, inner, jnp.inf)
    starts = []
    for c in range(q):
        starts += [jnp.argmax(hi[:, c]), jnp.argmin(lo[:, c])]
    j0 = jnp.stack(starts)  # window [t_j0, t_j0+2] around each interior extreme j0 + 1
    u = (jnp.arange(n_refine) + 1.0) / (n_refine + 1.0)

    def angles(j):
        a = ts[j] + u * (ts[j + 1] - ts[j])
        b = ts[j + 1] + u * (ts[j + 2] - ts[j + 1])
        return jnp.concatenate([a, b])

    return j0, jax.vmap(angles)(j0)


@jax.jit  # as jump_window_extrema
def window_extrema(vals, ts, j0, wvals, n_valid=None):
    """Max and min of each output over the grid values ``vals`` (N, q) and the refined
    window values ``wvals`` (2q, 2 n_refine) read at the angles of :func:`refine_windows`
    (window k refines output k // 2, its max for even k, its min for odd k); ``n_valid``:
    the grid's first ``n_valid`` points (the rest padding holding grid values). Returns
    ``(maxima (q,), minima (q,))``."""
    n, q = vals.shape
    n_refine = wvals.shape[1] // 2
    u = (jnp.arange(n_refine) + 1.0) / (n_refine + 1.0)
    if n_valid is None:
        short = 1e-6 * (ts[-1] - ts[0]) / n  # intervals this short straddle a jump
    else:
        short = 1e-6 * (ts[n_valid - 1] - ts[0]) / n_valid

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


def _start_max(v):
    """Largest value of a window that starts at a jump (``v`` (n,) equally spaced from the
    one-sided point after it, n >= 5) where its largest sample is one of the first two:
    the maximum of the quartic through the first five over the first two intervals, where
    it is sound (second differences alike: no kink or other jump among the five), else
    ``-inf``. A force that keeps rising for a moment after the jump (the deflection's
    velocity at the jump small and positive) peaks there, between the point after the
    jump and the next sample, where :func:`_vertex_max`, centred on the largest sample,
    has no five points around it (sdof, pitch errors, 5 rad/s: 4e-5 F_S low with 128
    points over the window)."""
    y = v[:5]
    c = y[:-2] - 2.0 * y[1:-1] + y[2:]  # second differences at s = -1, 0, 1
    smooth = jnp.all(jnp.abs(c - c[1]) <= 0.25 * jnp.abs(c[1])) & (c[1] < 0)
    _, p, d1, d2 = _quartic(*y)
    grid = jnp.linspace(-2.0, 0.0, 17)  # samples 0..2
    s = grid[jnp.argmax(p(grid))]
    for _ in range(3):  # Newton on the derivative, kept in [-2, 0]
        s = jnp.clip(s - d1(s) / jnp.where(d2(s) < 0, d2(s), -1.0), -2.0, 0.0)
    best = jnp.maximum(p(s), jnp.max(p(grid)))
    return jnp.where((jnp.argmax(v) <= 1) & smooth & jnp.isfinite(best), best, -jnp.inf)


# ------------------------------------------------------------------ ringing after jumps
# (rule 3 of the module docstring)
JUMP_WINDOW_FREE_PERIODS = 2.0
JUMP_WINDOW_MAX_INTERVALS = 4.0
MAX_JUMP_WINDOWS = 8  # windows after the largest jumps of the force; all where fewer
# and per extremum of each output, after the jumps where the output is nearest it on the
# grid: a smaller jump's ringing on top of an output's extreme level (helical teeth, pitch
# errors: the 3D helical te max force at 20 rad/s was 5.6e-5 F_S low with the largest 8)
NEAR_EXTREME_WINDOWS = 2
CLUSTER_INTERVALS = 1.0 / 16.0  # jumps closer than this (grid intervals) ring as one
RESOLVED_INTERVALS = 16.0  # grid intervals per free period from which no window is needed


class JumpClusters(NamedTuple):
    """Jump angles of a period grouped where closer than ``CLUSTER_INTERVALS`` of a grid
    interval (the cells of one 3D contact line engaging one after the other, within 0.04
    of a grid interval on the Baud-Velex rig), as indices into one period of the output
    grid (NumPy, build time).

    before : (n_c,) the one-sided point before each cluster's first jump (for a jump at
        0, the period's last point: the same jump one period on).
    after : (n_c,) the one-sided point after its last jump (the ringing's start).
    """

    before: np.ndarray
    after: np.ndarray


def jump_clusters(grid: OutputGrid, period: float, jump_thetas) -> JumpClusters:
    """The jump clusters of ``jump_thetas`` on ``grid`` (:func:`output_grid`, whose first
    ``grid.per_period`` offsets are one period from 0)."""
    period = float(period)
    one = np.asarray(grid.offsets[: grid.per_period], dtype=float)
    jumps = np.unique(np.mod(np.asarray(jump_thetas, dtype=float).reshape(-1), period))
    if jumps.size == 0:
        return JumpClusters(np.zeros(0, int), np.zeros(0, int))
    n_samples = int(np.sum(grid.samples[: grid.per_period]))
    gap = CLUSTER_INTERVALS * period / n_samples
    # cyclic clusters: break where the gap to the next jump is that or more
    nxt = np.roll(jumps, -1) + np.where(np.arange(jumps.size) == jumps.size - 1, period, 0.0)
    breaks = np.nonzero(nxt - jumps >= gap)[0]
    if breaks.size == 0:  # every jump close to the next: one cluster
        firsts, lasts = jumps[:1], jumps[-1:]
    else:
        lasts = jumps[breaks]
        firsts = jumps[(breaks + 1) % jumps.size]
        firsts = np.roll(firsts, 1)  # cluster k runs from firsts[k] to lasts[k]
    d = JUMP_SIDE * period

    def index(t):  # the grid point at angle t (mod period)
        i = int(np.argmin(np.abs(one - np.mod(t, period))))
        assert abs(one[i] - np.mod(t, period)) < 0.5 * d, t
        return i

    # a jump at 0: its point before is the period's last one (the same jump, a period on)
    before = np.array([index(f - d) for f in firsts])
    after = np.array([index(a + d) for a in lasts])
    return JumpClusters(before, after)


def ringing_resolved(omega, omega_n, interval):
    """True where the grid resolves the ringing of the free mode ``omega_n`` (rad/s) at
    pinion speed ``omega`` (rad/s): its period in theta spans at least
    ``RESOLVED_INTERVALS`` grid intervals ``interval`` (rad). The windows after the jumps
    are then not needed: the grid's extreme lies on the ringing's largest lobe (a sample
    is within ``1 - cos(pi / 16) = 2 %`` of the lobe's extremum, the next lobe of the
    same sign ``exp(-2 pi zeta)`` smaller: 17 % at zeta 0.03) and the window around it
    refines it."""
    return 2.0 * jnp.pi * omega / omega_n >= RESOLVED_INTERVALS * interval


def ringing_length(omega, omega_n, interval):
    """Length (rad of theta) of the window after a jump at pinion speed ``omega`` (rad/s):
    ``JUMP_WINDOW_FREE_PERIODS`` periods of the free mode ``omega_n`` (rad/s), at most
    ``JUMP_WINDOW_MAX_INTERVALS`` grid intervals ``interval`` (rad)."""
    free = 2.0 * jnp.pi * omega / omega_n
    return jnp.minimum(JUMP_WINDOW_FREE_PERIODS * free, JUMP_WINDOW_MAX_INTERVALS * interval)


def n_jump_windows(clusters: JumpClusters, n_outputs: int) -> int:
    """Windows after the jumps (static): ``MAX_JUMP_WINDOWS`` after the largest jumps and
    ``NEAR_EXTREME_WINDOWS`` per extremum of each of ``n_outputs`` outputs, all clusters
    where fewer."""
    return min(MAX_JUMP_WINDOWS + 2 * n_outputs * NEAR_EXTREME_WINDOWS,
               int(clusters.after.shape[0]))


def jump_windows(vals, ts, clusters: JumpClusters, per_period: int, length, n_points: int):
    """The windows after the jumps on the grid values ``vals`` (N, q) at ``ts`` (N,), N a
    whole number of periods of ``per_period`` points: every cluster where there are no
    more than :func:`n_jump_windows`; otherwise per cluster the period where its jump of
    output 0 (the mesh force) is largest, the ``MAX_JUMP_WINDOWS`` largest, then for each
    output's max and min the ``NEAR_EXTREME_WINDOWS`` clusters not yet taken after which
    the output is nearest that extreme. Returns ``(j (K,), tf (K, n_points))``: each
    window's start (a grid index, the point after the jump) and its angles
    ``ts[j] + length (1..n_points) / n_points``."""
    n, q = vals.shape
    n_per = n // per_period
    n_c = int(clusters.after.shape[0])
    base = per_period * np.arange(n_per)[:, None]
    ia = jnp.asarray(clusters.after[None, :] + base)  # (n_per, n_c)
    ib = jnp.asarray(clusters.before[None, :] + base)
    mag = jnp.abs(vals[ia, 0] - vals[ib, 0])  # (n_per, n_c)
    p = jnp.argmax(mag, axis=0)
    k = n_jump_windows(clusters, q)
    if k == n_c:
        _, top = jax.lax.top_k(jnp.max(mag, axis=0), n_c)
        j = ia[p[top], top]
    else:
        _, top = jax.lax.top_k(jnp.max(mag, axis=0), MAX_JUMP_WINDOWS)
        j = [ia[p[top], top]]
        taken = jnp.zeros(n_c, bool).at[top].set(True)
        for c in range(q):
            for sign in (1.0, -1.0):
                v = sign * vals[ia, c]  # (n_per, n_c)
                pc = jnp.argmax(v, axis=0)
                _, near = jax.lax.top_k(jnp.where(taken, -jnp.inf, jnp.max(v, axis=0)),
                                        NEAR_EXTREME_WINDOWS)
                taken = taken.at[near].set(True)
                j.append(ia[pc[near], near])
        j = jnp.concatenate(j)
    u = jnp.arange(1, n_points + 1) / n_points
    return j, ts[j][:, None] + length * u[None, :]


@jax.jit  # one program, not dozens of dispatched operations, where simulate runs unjitted
def jump_window_extrema(vals, ts, j, tf, wvals):
    """Max and min of each output over the windows after the jumps: ``wvals`` (K, n, q)
    the outputs at the angles ``tf`` (K, n) of :func:`jump_windows`, which start at the
    grid points ``j`` (K,), and the vertex of the quartic through the largest value and
    its four neighbours (:func:`_vertex_max`), or through the first five where the
    largest is one of the first two (:func:`_start_max`). Returns ``(maxima (q,), minima (q,))``;
    ``-inf``/``inf`` without windows."""
    q = vals.shape[1]
    if j.shape[0] == 0:
        return jnp.full(q, -jnp.inf), jnp.full(q, jnp.inf)
    tw = jnp.concatenate([ts[j][:, None], tf], axis=1)  # (K, n + 1), uniformly spaced
    vw = jnp.concatenate([vals[j][:, None, :], wvals], axis=1)  # (K, n + 1, q)

    def best(t, v):  # (n + 1,), (n + 1, q) -> max, min per output
        def one(s, c):
            return s * jnp.maximum(_vertex_max(t, s * c, 0.0), _start_max(s * c))

        return jax.vmap(lambda c: one(1.0, c), 1)(v), jax.vmap(lambda c: one(-1.0, c), 1)(v)

    mx, mn = jax.vmap(best)(tw, vw)
    return jnp.max(mx, axis=0), jnp.min(mn, axis=0)
