"""One measure of a periodic response, whichever solver found it: the metrics and mesh-order
amplitudes of :class:`gearjax.dynamics.simulate.SimulationResult` from the states on the
output grid and in the refinement windows.

The rules are those of :mod:`gearjax.dynamics.metrics` (read on both sides of every jump,
refined around the grid's extremes, and after the jumps where the grid does not resolve
the ringing) and the order amplitudes those of :mod:`gearjax.dynamics.orders`; this module
only composes them, so that every solver measures an orbit the same way:

* the transient and the shooting (:func:`gearjax.dynamics.simulate.simulate`) integrate the
  measured periods and re-integrate the windows (:mod:`gearjax.dynamics.legs`), then call
  :func:`windows`, :func:`extrema` and :func:`mesh_orders` on those states;
* a solver whose periodic orbit is a function of the angle (the frequency domain,
  :mod:`gearjax.dynamics.harmonic`) hands it to :func:`measure_orbit`, which reads it on the
  same grid and windows instead of integrating.

The observed quantities (:func:`observer`): the dynamic mesh force F_D (N, Eqs. (22)/(24)),
the DTE (m) and, where the model has one, an acceleration (m/s^2).
"""

from __future__ import annotations

from typing import Callable, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .metrics import (JumpClusters, OutputGrid, jump_clusters, jump_window_extrema,
                      jump_windows, n_jump_windows, output_grid, refine_windows,
                      ringing_length, ringing_resolved, window_extrema)
from .orders import mesh_order_amplitudes, order_matrix

__all__ = ["N_REFINE", "MeasureGrid", "measure_grid", "observer", "n_outputs", "ringing",
           "Windows", "windows", "n_windows", "extrema", "mesh_orders", "OrbitMeasure",
           "measure_orbit"]

N_REFINE = 64  # refined points per grid interval of the extremum windows (metrics rule 2)


class MeasureGrid(NamedTuple):
    """Where a response is read (NumPy, build time).

    grid : the output grid (:func:`gearjax.dynamics.metrics.output_grid`) over
        ``n_periods`` excitation periods from 0.
    n_samples : uniform mid-cell samples per excitation period.
    n_periods : measured excitation periods.
    clusters : the jump clusters of one period (:func:`gearjax.dynamics.metrics.jump_clusters`).
    n_refine : refined points per grid interval of a window (``2 n_refine`` per window).
    """

    grid: OutputGrid
    n_samples: int
    n_periods: int
    clusters: JumpClusters
    n_refine: int


def measure_grid(model, n_periods: int, samples_per_mesh_period: int,
                 n_refine: int = N_REFINE) -> MeasureGrid:
    """The :class:`MeasureGrid` of ``model`` (its excitation period and jump angles) over
    ``n_periods`` periods with ``samples_per_mesh_period`` samples per mesh period."""
    period = float(model.period_rad)
    n_samples = int(samples_per_mesh_period) * int(round(period / model.mesh_period_rad))
    jumps = np.asarray(model.jump_thetas, dtype=float)
    grid = output_grid(period, n_samples, jumps, int(n_periods))
    return MeasureGrid(grid, n_samples, int(n_periods), jump_clusters(grid, period, jumps),
                       int(n_refine))


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
    interval = float(model.period_rad) / mg.n_samples
    return (ringing_length(omega, omega_n, interval),
            ringing_resolved(omega, omega_n, interval))


class Windows(NamedTuple):
    """The refinement windows of one measurement (traced).

    j0, tf : (2q,) first grid point and (2q, 2 n_refine) angles of the windows around the
        grid's extremes (:func:`gearjax.dynamics.metrics.refine_windows`; window k refines
        output k // 2, its max for even k).
    jj, tj : (K,) the grid point after each windowed jump and (K, 2 n_refine) the angles
        after it (:func:`gearjax.dynamics.metrics.jump_windows`).
    """

    j0: jax.Array
    tf: jax.Array
    jj: jax.Array
    tj: jax.Array

    def angles(self):
        """(2q + K, 2 n_refine) the angles of every window, extremum windows first."""
        return jnp.concatenate([self.tf, self.tj])


def n_windows(mg: MeasureGrid, q: int) -> tuple[int, int]:
    """(extremum windows ``2 q``, windows after the jumps) for ``q`` outputs (static)."""
    return 2 * q, n_jump_windows(mg.clusters, q)


def windows(mg: MeasureGrid, vals, ts, ring) -> Windows:
    """The windows of the grid values ``vals`` (N, q) at the grid angles ``ts`` (N,):
    around each output's grid extremes and after the jumps (``ring``: their length, rad)."""
    j0, tf = refine_windows(vals, ts, mg.n_refine)
    jj, tj = jump_windows(vals, ts, mg.clusters, mg.grid.per_period, ring, 2 * mg.n_refine)
    return Windows(j0, tf, jj, tj)


def extrema(vals, ts, win: Windows, wvals, resolved):
    """Max and min (q,) of each output: the grid values ``vals`` (N, q), the values
    ``wvals`` (2q + K, 2 n_refine, q) of every output in the windows ``win`` (in the order
    of :meth:`Windows.angles`), the windows after the jumps used unless ``resolved``."""
    q = vals.shape[1]
    n_ref = 2 * q
    cols = jnp.repeat(jnp.arange(q), 2)  # window k refines output k // 2
    v_max, v_min = window_extrema(vals, ts, win.j0, wvals[jnp.arange(n_ref), :, cols])
    j_max, j_min = jump_window_extrema(vals, ts, win.jj, win.tj, wvals[n_ref:])
    return (jnp.where(resolved, v_max, jnp.maximum(v_max, j_max)),
            jnp.where(resolved, v_min, jnp.minimum(v_min, j_min)))


def mesh_orders(model, mg: MeasureGrid, vals):
    """(q, 5) single-sided amplitudes of mesh orders 1..5 of each output over the measured
    periods (:mod:`gearjax.dynamics.orders`), from the grid values ``vals`` (N, q)."""
    per = vals.reshape(mg.n_periods, -1, vals.shape[-1])
    return mesh_order_amplitudes(order_matrix(
        float(model.period_rad), model.mesh_period_rad, mg.n_samples,
        np.asarray(model.jump_thetas, dtype=float)), per)


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
    per = mg.grid.per_period
    ts = jnp.asarray(mg.grid.offsets)
    one = jax.vmap(observed)(ts[:per], states(ts[:per]))
    vals = jnp.tile(one, (mg.n_periods, 1))
    ring, resolved = ringing(model, omega, mg)
    win = windows(mg, vals, ts, ring)

    def read(t):  # (k, m) angles -> (k, m, q) outputs
        flat = t.reshape(-1)
        return jax.vmap(observed)(flat, states(flat)).reshape(t.shape + (vals.shape[1],))

    w_ref = read(win.tf)
    w_jump = jax.lax.cond(resolved, lambda: jnp.zeros(win.tj.shape + (vals.shape[1],),
                                                      vals.dtype), lambda: read(win.tj))
    v_max, v_min = extrema(vals, ts, win, jnp.concatenate([w_ref, w_jump]), resolved)
    return OrbitMeasure(ts, vals, v_max, v_min, mesh_orders(model, mg, vals))
