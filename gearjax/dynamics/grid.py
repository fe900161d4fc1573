"""The output grid of a periodic response, computed in the program from the model's jump
angles (:class:`~gearjax.excitation.jumps.JumpSet`, padded to a static bound).

:mod:`gearjax.dynamics.metrics` states the rules (mid-cell samples, the two one-sided
points ``s_j -/+ delta`` of every jump, refinement windows around the extremes and after
the largest jumps) and :mod:`gearjax.dynamics.orders` the jump-corrected mesh orders; the
NumPy functions there build them from concrete angles. Here the same grid is built from
traced angles, so that a design that moves its jumps, or has another number of them
within the bound, runs in the same program:

* :func:`period_grid`: one period of ``n_samples + 2 bound`` points, sorted, the valid
  ones first and the padding (for the one-sided points of padding jumps) repeating the
  last of them, with the positions of the samples and of each jump's two points;
* :func:`compact_index`: the valid points of several periods side by side (the padding
  after them), the order in which the refinement and jump windows read their neighbours;
* :func:`jump_clusters` and :func:`order_amplitudes`: the windows' clusters and the mesh
  orders as there, on the traced grid.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ..excitation.jumps import JumpSet
from .metrics import CLUSTER_INTERVALS, JUMP_SIDE

__all__ = ["PeriodGrid", "period_grid", "compact_index", "Clusters", "jump_clusters",
           "order_amplitudes"]


class PeriodGrid(NamedTuple):
    """One excitation period of the output grid (:func:`period_grid`).

    offsets : (per_period,) sorted angles (rad) in ``[0, period)``: the ``n_valid`` grid
        points, then the padding (the last of them repeated).
    n_valid : () int, ``n_samples + 2 count`` of the jump set.
    mid : (n_samples,) positions of the uniform mid-cell samples in ``offsets``.
    minus, plus : (bound,) positions of each jump's points ``s_j - delta``,
        ``s_j + delta`` (padding jumps: those of the last valid one).
    """

    offsets: jax.Array
    n_valid: jax.Array
    mid: jax.Array
    minus: jax.Array
    plus: jax.Array

    @property
    def per_period(self) -> int:
        return int(self.offsets.shape[0])


def period_grid(period: float, n_samples: int, jumps: JumpSet) -> PeriodGrid:
    """The output grid over one period (:func:`gearjax.dynamics.metrics.output_grid`'s
    points and order, from traced jumps): ``n_samples`` mid-cell samples ``(k + 1/2)
    period / n_samples`` and the two one-sided points of every valid jump, sorted (stable:
    samples, then left points, then right points at equal angles), then the padding."""
    period = float(period)
    mid = (np.arange(n_samples) + 0.5) * (period / n_samples)
    b = jumps.bound
    d = JUMP_SIDE * period
    valid = jumps.valid
    minus = jnp.where(valid, jnp.mod(jumps.thetas - d, period), period)
    plus = jnp.where(valid, jnp.mod(jumps.thetas + d, period), period)
    one = jnp.concatenate([jnp.asarray(mid), minus, plus])
    order = jnp.argsort(one, stable=True)
    pos = jnp.zeros(one.shape[0], jnp.int32).at[order].set(jnp.arange(one.shape[0],
                                                                        dtype=jnp.int32))
    n_valid = n_samples + 2 * jumps.count
    pos_minus = pos[n_samples:n_samples + b]
    pos_plus = pos[n_samples + b:]
    if b == 0:
        return PeriodGrid(offsets=one[order], n_valid=jnp.asarray(n_samples),
                          mid=pos[:n_samples], minus=pos_minus, plus=pos_plus)
    last = jnp.maximum(jumps.count - 1, 0)
    offsets = one[order]
    inside = jnp.arange(offsets.shape[0]) < n_valid  # padding: the last valid point again
    offsets = jnp.where(inside, offsets, offsets[n_valid - 1])
    return PeriodGrid(offsets=offsets, n_valid=n_valid, mid=pos[:n_samples],
                      minus=jnp.where(valid, pos_minus, pos_minus[last]),
                      plus=jnp.where(valid, pos_plus, pos_plus[last]))


def compact_index(grid: PeriodGrid, n_periods: int):
    """Indices into the ``(n_periods * per_period)`` grid of ``n_periods`` consecutive
    periods that put the valid points of all periods side by side, in time order, and the
    padding after them (each padding slot pointing at the last valid point). Returns
    ``(index (n_periods * per_period,), n_valid_total)``."""
    per = grid.per_period
    k = jnp.arange(n_periods * per)
    nv = grid.n_valid
    total = n_periods * nv
    src = (k // nv) * per + k % nv
    last = (n_periods - 1) * per + nv - 1
    return jnp.where(k < total, src, last), total


def valid_points(grid: PeriodGrid, n_periods: int):
    """(n_periods * per_period,) bool: True at the valid points of the uncompacted grid."""
    return jnp.tile(jnp.arange(grid.per_period) < grid.n_valid, n_periods)


class Clusters(NamedTuple):
    """Jump clusters as :class:`gearjax.dynamics.metrics.JumpClusters`, traced: ``before``,
    ``after`` (bound,) positions in one period of the compacted grid, ``count`` () the
    number of clusters (the first ``count`` entries are valid)."""

    before: jax.Array
    after: jax.Array
    count: jax.Array


def jump_clusters(grid: PeriodGrid, period: float, n_samples: int,
                  jumps: JumpSet) -> Clusters:
    """The jump clusters of :func:`gearjax.dynamics.metrics.jump_clusters` (jumps closer
    than ``CLUSTER_INTERVALS`` of a grid interval ring as one, cyclically), traced."""
    b = jumps.bound
    if b == 0:
        z = jnp.zeros(0, jnp.int32)
        return Clusters(z, z, jnp.asarray(0))
    period = float(period)
    n = jumps.count
    j = jumps.thetas
    i = jnp.arange(b)
    nxt = jnp.where(i + 1 < n, jnp.roll(j, -1), j[0] + period)
    gap = CLUSTER_INTERVALS * period / n_samples
    brk = (i < n) & (nxt - j >= gap)
    n_br = jnp.sum(brk)
    bi = jnp.nonzero(brk, size=b, fill_value=0)[0]  # cluster k ends at jump bi[k]
    prev = jnp.roll(bi, 1).at[0].set(bi[jnp.maximum(n_br - 1, 0)])
    first = jnp.mod(prev + 1, jnp.maximum(n, 1))
    one = n_br == 0  # every jump close to the next: one cluster, first to last
    last_j = jnp.maximum(n - 1, 0)
    first = jnp.where(one, 0, first)
    lastk = jnp.where(one, last_j, bi)
    count = jnp.where(n == 0, 0, jnp.where(one, 1, n_br))
    valid = i < count
    before = jnp.where(valid, grid.minus[first], grid.minus[first[0]])
    after = jnp.where(valid, grid.plus[lastk], grid.plus[lastk[0]])
    return Clusters(before.astype(jnp.int32), after.astype(jnp.int32), count)


def _merged(jumps: JumpSet, period: float):
    """Jump indices (first, last) of each cluster closer than ``4 delta`` (the merged
    steps of :mod:`gearjax.dynamics.orders`, a cluster wrapping past the period end joined
    to the first), their count and the cluster's angles ``(lo, hi)`` (lo may be negative
    for the joined cluster)."""
    b, n, j = jumps.bound, jumps.count, jumps.thetas
    i = jnp.arange(b)
    gap = 4.0 * JUMP_SIDE * period
    valid = i < n
    starts = valid & ((i == 0) | (j - jnp.roll(j, 1) > gap))
    ends = valid & ((i == n - 1) | (jnp.roll(j, -1) - j > gap))
    n_m = jnp.sum(starts)
    si = jnp.nonzero(starts, size=b, fill_value=0)[0]
    ei = jnp.nonzero(ends, size=b, fill_value=0)[0]
    lo, hi = j[si], j[ei]
    last = jnp.maximum(n_m - 1, 0)
    wrap = (n_m > 1) & ((lo[0] + period) - hi[last] <= gap)
    si = si.at[0].set(jnp.where(wrap, si[last], si[0]))
    lo = lo.at[0].set(jnp.where(wrap, lo[last] - period, lo[0]))
    n_m = n_m - wrap
    return si, ei, lo, hi, n_m


def order_amplitudes(grid: PeriodGrid, jumps: JumpSet, period: float, mesh_period: float,
                     n_samples: int, values, n_orders: int):
    """Single-sided peak amplitudes ``2 |c_m|`` of mesh orders ``1..n_orders`` of the
    outputs ``values`` (n_periods, per_period, q) on :func:`period_grid` (averaged over
    the periods), with the jumps removed exactly (:mod:`gearjax.dynamics.orders`): the DFT
    of the samples plus, per merged jump of size ``J``, ``J`` times its exact
    coefficient less what the DFT of its sawtooth sees (in closed form: the sawtooth's
    samples ``1/2 - frac((t_k - t_j) / P)`` sum, against ``e^(-i m nu t_k)``, to the
    linear ramp's sum and a partial geometric sum). Returns ``(q, n_orders)``."""
    period, mesh_period = float(period), float(mesh_period)
    n_mesh = int(round(period / mesh_period))
    v = jnp.mean(jnp.asarray(values), axis=0)  # (per_period, q)
    m = np.arange(1, n_orders + 1) * n_mesh
    nu = 2.0 * math.pi / period
    t = (np.arange(n_samples) + 0.5) * (period / n_samples)
    e = np.exp(-1j * nu * np.outer(m, t)) / n_samples  # (K, N)
    re = jnp.asarray(e.real) @ v[grid.mid]
    im = jnp.asarray(e.imag) @ v[grid.mid]
    if jumps.bound:
        ramp = e @ (t / period)  # (K,)
        partial = np.concatenate([np.zeros((m.size, 1)), np.cumsum(e, axis=1)], axis=1)
        si, ei, lo, hi, n_m = _merged(jumps, period)
        tj = jnp.mod(0.5 * (lo + hi), period)
        k_star = jnp.searchsorted(jnp.asarray(t), tj, side="left")  # samples below t_j
        seen_re = -ramp.real[:, None] - jnp.asarray(partial.real)[:, k_star]
        seen_im = -ramp.imag[:, None] - jnp.asarray(partial.imag)[:, k_star]
        ph = -nu * jnp.asarray(m)[:, None] * tj[None, :]
        denom = 2.0 * math.pi * m[:, None]  # exact: e^(i ph) / (2 pi i m)
        ex_re, ex_im = jnp.sin(ph) / denom, -jnp.cos(ph) / denom
        use = jnp.arange(jumps.bound) < n_m
        jump = jnp.where(use[:, None], v[grid.plus[ei]] - v[grid.minus[si]], 0.0)  # (B, q)
        re = re + (ex_re - seen_re) @ jump
        im = im + (ex_im - seen_im) @ jump
    return 2.0 * jnp.sqrt(re**2 + im**2).T


def jump_windows(vals, ts, clusters: Clusters, n_per_valid, n_periods: int, n_windows: int,
                 length, n_points: int):
    """The windows after the jumps (:func:`gearjax.dynamics.metrics.jump_windows`'s rule,
    traced) on the compacted grid values ``vals`` (N, q) at ``ts`` (N,) of ``n_periods``
    periods of ``n_per_valid`` valid points: every cluster where there are at most
    ``n_windows`` of them, else the ``MAX_JUMP_WINDOWS`` where the mesh force jumps most,
    then per extremum of each output the ``NEAR_EXTREME_WINDOWS`` after which it is
    nearest that extremum. ``n_windows`` is static (:func:`gearjax.dynamics.metrics.
    n_jump_windows` of the bound); slots beyond the clusters there are repeat the
    largest jump's window. Returns ``(j (n_windows,), tf (n_windows, n_points))``."""
    from .metrics import MAX_JUMP_WINDOWS, NEAR_EXTREME_WINDOWS

    q = vals.shape[1]
    b = clusters.after.shape[0]
    if b == 0 or n_windows == 0:
        return jnp.zeros(0, jnp.int32), jnp.zeros((0, n_points), ts.dtype)
    base = n_per_valid * jnp.arange(n_periods)[:, None]
    ia = clusters.after[None, :] + base  # (n_per, b)
    ib = clusters.before[None, :] + base
    use = jnp.arange(b) < clusters.count
    mag = jnp.where(use[None, :], jnp.abs(vals[ia, 0] - vals[ib, 0]), -jnp.inf)
    p = jnp.argmax(mag, axis=0)
    if n_windows >= b:  # every cluster
        _, top = jax.lax.top_k(jnp.max(mag, axis=0), b)
        picks = [top]
        pers = [p[top]]
    else:
        _, top = jax.lax.top_k(jnp.max(mag, axis=0), MAX_JUMP_WINDOWS)
        picks, pers = [top], [p[top]]
        taken = jnp.zeros(b, bool).at[top].set(True)
        for c in range(q):
            for sign in (1.0, -1.0):
                v = jnp.where(use[None, :], sign * vals[ia, c], -jnp.inf)
                pc = jnp.argmax(v, axis=0)
                _, near = jax.lax.top_k(jnp.where(taken, -jnp.inf, jnp.max(v, axis=0)),
                                        NEAR_EXTREME_WINDOWS)
                taken = taken.at[near].set(True)
                picks.append(near)
                pers.append(pc[near])
    k = jnp.concatenate(picks)
    per = jnp.concatenate(pers)
    ok = k < clusters.count
    k = jnp.where(ok, k, top[0])
    per = jnp.where(ok, per, p[top[0]])
    j = ia[per, k]
    u = jnp.arange(1, n_points + 1) / n_points
    return j, ts[j][:, None] + length * u[None, :]
