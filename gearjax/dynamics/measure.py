"""One measure of a periodic response, whichever solver found it: the metrics and mesh-order
amplitudes of :class:`gearjax.dynamics.simulate.SimulationResult` from the states on the
output grid and in the refinement windows.

The rules are those of :mod:`gearjax.dynamics.metrics` (read on both sides of every jump,
refined around the grid's extremes, and after the jumps where the grid does not resolve
the ringing) and the order amplitudes those of :mod:`gearjax.dynamics.orders`, built in the
program from the model's jump set (:class:`~gearjax.excitation.jumps.JumpSet`, padded to a
static bound) by :mod:`gearjax.dynamics.grid`, so that a design that moves its jumps is
measured by the same program. This module only composes them, so that every solver
measures an orbit the same way:

* the transient and the shooting (:func:`gearjax.dynamics.simulate.simulate`) integrate the
  measured periods and re-integrate the windows (:mod:`gearjax.dynamics.legs`), then call
  :func:`windows`, :func:`extrema` and :func:`mesh_orders` on those states;
* a solver whose periodic orbit is a function of the angle (the frequency domain,
  :mod:`gearjax.dynamics.harmonic`) hands it to :func:`measure_orbit`, which reads it on the
  same grid and windows instead of integrating.

The grid of ``n_periods`` periods holds per period the valid points first and the padding
(the one-sided points of padding jumps) after them; the windows read the valid points of
all periods side by side (:func:`gearjax.dynamics.grid.compact_index`).

The observed quantities (:func:`observer`): the dynamic mesh force F_D (N, Eqs. (22)/(24)),
the DTE (m) and, where the model has one, an acceleration (m/s^2).
"""

from __future__ import annotations

from typing import Callable, NamedTuple

import jax
import jax.numpy as jnp

from ..excitation.jumps import JumpSet
from . import grid as grids
from .metrics import (MAX_JUMP_WINDOWS, NEAR_EXTREME_WINDOWS, jump_window_extrema,
                      refine_windows, ringing_length, ringing_resolved, window_extrema)
from .orders import N_MESH_ORDERS

__all__ = ["N_REFINE", "MeasureGrid", "measure_grid", "observer", "n_outputs", "ringing",
           "Windows", "windows", "n_windows", "extrema", "mesh_orders", "OrbitMeasure",
           "measure_orbit"]

N_REFINE = 64  # refined points per grid interval of the extremum windows (metrics rule 2)


class MeasureGrid(NamedTuple):
    """Where a response is read (traced where the model's jump set is).

    grid : one period of the output grid (:func:`gearjax.dynamics.grid.period_grid`).
    n_samples : uniform mid-cell samples per excitation period (static).
    n_periods : measured excitation periods (static).
    clusters : the jump clusters of one period (:func:`gearjax.dynamics.grid.jump_clusters`).
    n_refine : refined points per grid interval of a window (``2 n_refine`` per window).
    jumps : the model's :class:`~gearjax.excitation.jumps.JumpSet`.
    period, mesh_period : the excitation and mesh periods (rad, static).
    """

    grid: grids.PeriodGrid
    n_samples: int
    n_periods: int
    clusters: grids.Clusters
    n_refine: int
    jumps: JumpSet
    period: float
    mesh_period: float

    @property
    def per_period(self) -> int:
        """Grid points per period, padding included (static)."""
        return self.grid.per_period

    def offsets(self):
        """(n_periods * per_period,) the grid angles (rad) from the start of the first
        measured period (each period's padding after its valid points)."""
        return (self.grid.offsets[None, :]
                + self.period * jnp.arange(self.n_periods)[:, None]).ravel()

    def compact(self):
        """``(index, n_valid)``: :func:`gearjax.dynamics.grid.compact_index` of the
        measured periods (the valid points side by side, in time order)."""
        return grids.compact_index(self.grid, self.n_periods)

    def sample_index(self):
        """(n_periods * n_samples,) positions of the uniform mid-cell samples in
        :meth:`offsets` (the uniformly sampled signals)."""
        return (self.grid.mid[None, :]
                + self.per_period * jnp.arange(self.n_periods)[:, None]).ravel()

    def valued(self, vals):
        """The grid values ``vals`` (n_periods * per_period, q) with each padding point
        holding its period's first value (the padding is never read as a point of the
        response)."""
        valid = grids.valid_points(self.grid, self.n_periods)
        first = (jnp.arange(vals.shape[0]) // self.per_period) * self.per_period
        return jnp.where(valid[:, None], vals, vals[first])


def measure_grid(model, n_periods: int, samples_per_mesh_period: int,
                 n_refine: int = N_REFINE) -> MeasureGrid:
    """The :class:`MeasureGrid` of ``model`` (its excitation period and jump set) over
    ``n_periods`` periods with ``samples_per_mesh_period`` samples per mesh period."""
    period = float(model.period_rad)
    n_samples = int(samples_per_mesh_period) * int(round(period / model.mesh_period_rad))
    jumps = model.jumps
    pg = grids.period_grid(period, n_samples, jumps)
    return MeasureGrid(pg, n_samples, int(n_periods),
                       grids.jump_clusters(pg, period, n_samples, jumps), int(n_refine),
                       jumps, period, float(model.mesh_period_rad))


def observer(model, omega, contact: bool = True) -> Callable:
    """``observed(theta, y) -> (q,)``: mesh force F_D (N), DTE (m) and, where the model has
    one, the acceleration (m/s^2) of ``model.outputs`` at pinion speed ``omega`` (rad/s);
    ``contact=False``: te/perturbation without the contact law (the linear force)."""

    def observed(t, y):
        o = model.outputs(t, y, omega, contact=contact)
        cols = [o.mesh_force_N, o.dte_m] + ([] if o.accel_m_s2 is None else [o.accel_m_s2])
        return jnp.stack(cols)

    return observed


def n_outputs(model, omega, y) -> int:
    """Number of observed quantities (2, or 3 with an acceleration), static."""
    return int(jax.eval_shape(observer(model, omega), jnp.zeros(()), y).shape[0])


def ringing(model, omega, mg: MeasureGrid):
    """(length (rad) of the windows after the jumps, whether the grid resolves the ringing
    so that they are not needed) at pinion speed ``omega`` (rad/s), from the model's
    dominant mesh mode (:func:`gearjax.dynamics.metrics.ringing_length`, ``ringing_resolved``)."""
    omega_n = model.natural_frequency_rad_s()
    interval = mg.period / mg.n_samples
    return (ringing_length(omega, omega_n, interval),
            ringing_resolved(omega, omega_n, interval))


class Windows(NamedTuple):
    """The refinement windows of one measurement (traced).

    j0, tf : (2q,) first point in the compacted grid (:meth:`MeasureGrid.compact`) and
        (2q, 2 n_refine) angles of the windows around the grid's extremes
        (:func:`gearjax.dynamics.metrics.refine_windows`; window k refines output k // 2,
        its max for even k).
    jj, tj : (K,) the compacted grid point after each windowed jump and (K, 2 n_refine)
        the angles after it (:func:`gearjax.dynamics.grid.jump_windows`).
    first : (2q + K,) the grid point (in :meth:`MeasureGrid.offsets`) each window starts
        from, in the order of :meth:`angles`.
    """

    j0: jax.Array
    tf: jax.Array
    jj: jax.Array
    tj: jax.Array
    first: jax.Array

    def angles(self):
        """(2q + K, 2 n_refine) the angles of every window, extremum windows first."""
        return jnp.concatenate([self.tf, self.tj])


def n_windows(mg: MeasureGrid, q: int) -> tuple[int, int]:
    """(extremum windows ``2 q``, windows after the jumps) for ``q`` outputs (static): the
    ``MAX_JUMP_WINDOWS`` after the largest jumps and ``NEAR_EXTREME_WINDOWS`` per
    extremum of each output, every cluster where the jump set's bound is smaller."""
    return 2 * q, min(MAX_JUMP_WINDOWS + 2 * q * NEAR_EXTREME_WINDOWS, mg.jumps.bound)


def windows(mg: MeasureGrid, vals, ts, ring) -> Windows:
    """The windows of the grid values ``vals`` (N, q) at the grid angles ``ts`` (N,) (of
    :meth:`MeasureGrid.offsets`): around each output's grid extremes and after the jumps
    (``ring``: their length, rad)."""
    cidx, n_valid = mg.compact()
    vals_c, ts_c = vals[cidx], ts[cidx]
    j0, tf = refine_windows(vals_c, ts_c, mg.n_refine, n_valid)
    n_jw = n_windows(mg, vals.shape[1])[1]
    jj, tj = grids.jump_windows(vals_c, ts_c, mg.clusters, mg.grid.n_valid, mg.n_periods,
                                n_jw, ring, 2 * mg.n_refine)
    return Windows(j0, tf, jj, tj, cidx[jnp.concatenate([j0, jj])])


def extrema(mg: MeasureGrid, vals, ts, win: Windows, wvals, resolved):
    """Max and min (q,) of each output: the grid values ``vals`` (N, q) at ``ts``, the
    values ``wvals`` (2q + K, 2 n_refine, q) of every output in the windows ``win`` (in the
    order of :meth:`Windows.angles`), the windows after the jumps used unless ``resolved``."""
    cidx, n_valid = mg.compact()
    vals_c, ts_c = vals[cidx], ts[cidx]
    q = vals.shape[1]
    n_ref = 2 * q
    cols = jnp.repeat(jnp.arange(q), 2)  # window k refines output k // 2
    v_max, v_min = window_extrema(vals_c, ts_c, win.j0, wvals[jnp.arange(n_ref), :, cols],
                                  n_valid)
    j_max, j_min = jump_window_extrema(vals_c, ts_c, win.jj, win.tj, wvals[n_ref:])
    return (jnp.where(resolved, v_max, jnp.maximum(v_max, j_max)),
            jnp.where(resolved, v_min, jnp.minimum(v_min, j_min)))


def mesh_orders(model, mg: MeasureGrid, vals):
    """(q, 5) single-sided amplitudes of mesh orders 1..5 of each output over the measured
    periods (:mod:`gearjax.dynamics.orders`' jump-corrected rule,
    :func:`gearjax.dynamics.grid.order_amplitudes`), from the grid values ``vals`` (N, q)."""
    per = vals.reshape(mg.n_periods, -1, vals.shape[-1])
    return grids.order_amplitudes(mg.grid, mg.jumps, mg.period, mg.mesh_period,
                                  mg.n_samples, per, N_MESH_ORDERS)


class OrbitMeasure(NamedTuple):
    """What :func:`measure_orbit` reads of a periodic orbit (traced).

    ts, vals : (N,) grid angles and (N, q) the outputs there.
    maxima, minima : (q,) exact extrema of each output.
    orders : (q, 5) mesh-order amplitudes.
    """

    ts: jax.Array
    vals: jax.Array
    maxima: jax.Array
    minima: jax.Array
    orders: jax.Array


def measure_orbit(model, omega, states: Callable, mg: MeasureGrid,
                  contact: bool = True) -> OrbitMeasure:
    """The measure of a periodic orbit given as a function: ``states(theta)`` the model's
    states (m, n) at the angles ``theta`` (m,) (rad, any real angles: periodic with the
    excitation period). The grid's first period is read and repeated (the orbit is
    periodic), the windows are read from ``states`` where an integrating solver
    re-integrates them, and the windows after the jumps only where the grid does not
    resolve the ringing (a ``lax.cond``: skipped for real where the speeds are mapped).
    ``contact``: as :func:`observer`."""
    observed = observer(model, omega, contact)
    ts = mg.offsets()
    t1 = mg.grid.offsets
    one = jax.vmap(observed)(t1, states(t1))
    vals = mg.valued(jnp.tile(one, (mg.n_periods, 1)))
    ring, resolved = ringing(model, omega, mg)
    win = windows(mg, vals, ts, ring)

    def read(t):  # (k, m) angles -> (k, m, q) outputs
        flat = t.reshape(-1)
        return jax.vmap(observed)(flat, states(flat)).reshape(t.shape + (vals.shape[1],))

    w_ref = read(win.tf)
    w_jump = jax.lax.cond(resolved, lambda: jnp.zeros(win.tj.shape + (vals.shape[1],),
                                                      vals.dtype), lambda: read(win.tj))
    v_max, v_min = extrema(mg, vals, ts, win, jnp.concatenate([w_ref, w_jump]), resolved)
    return OrbitMeasure(ts, vals, v_max, v_min, mesh_orders(model, mg, vals))
