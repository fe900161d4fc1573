"""Mesh-order amplitudes of a periodic response: the spectra that gear NVH engineers read
against speed (order tracks).

Mesh order ``k`` is the ``k``-th harmonic of the mesh frequency ``f_m = Z1 Omega1 / (2 pi)``
(Hz), i.e. of the pinion angle with period ``2 pi / Z1`` (``model.mesh_period_rad``).
Over an excitation period ``P = model.period_rad`` holding ``n_mesh = P / (2 pi / Z1)``
mesh periods (one, or a pinion revolution with pitch errors or eccentricity), order ``k``
is harmonic ``m = k n_mesh`` of the period; the shaft-order sidebands between them are
not mesh orders and are not reported.

Convention: the *single-sided peak amplitude* ``A_k = 2 |c_m|`` of the complex Fourier
coefficient ``c_m = (1/P) int_0^P f(theta) e^{-i m 2 pi theta / P} dtheta``, in the unit
of the signal (DTE: m, mesh force F_D of Eqs. (22)/(24): N, acceleration: m/s^2), so that
``f = c_0 + sum_k A_k cos(k Z1 theta + phi_k) + (shaft orders)``.

How the coefficients are read (one constant linear map of the output grid, built once in
NumPy, so it costs one small matrix product per speed inside the jitted, vmapped solvers
of every method): the grid of :func:`gearjax.dynamics.metrics.output_grid` holds ``N``
uniform mid-cell samples per period and the two one-sided points ``theta_j -/+ delta`` of
every jump angle. The mesh force (and the 3D acceleration) jumps with the mesh stiffness at
``model.jump_thetas``, so a plain DFT of the samples would misplace each jump by up to half
a sample, an error ``O(J / N)`` in every coefficient. The jumps are removed exactly, as in
:mod:`gearjax.dynamics.harmonic`: with ``J_j = f(theta_j + delta) - f(theta_j - delta)``
and the periodic sawtooth ``S0(u) = 1/2 - frac(u / P)`` (unit upward jump at 0, Fourier
coefficients ``1 / (2 pi i m)``, mean 0)::

    f = f_c + sum_j J_j S0(theta - theta_j),
    c_m = DFT_m(f_c on the samples) + sum_j J_j e^{-i m 2 pi theta_j / P} / (2 pi i m),

with ``f_c`` continuous (kinks only: aliasing error ``O(N^-2)`` relative). Jump angles
closer than ``4 delta`` are merged into one step (the one-sided points of the cluster's
ends bound it).
"""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np

from .metrics import JUMP_SIDE, output_grid

__all__ = ["N_MESH_ORDERS", "order_matrix", "mesh_order_amplitudes"]

N_MESH_ORDERS = 5  # mesh orders 1..5 are reported


def _merged_jumps(jump_thetas, period: float):
    """Sorted jump angles in [0, period) with clusters closer than 4 delta merged:
    ``(lo, hi)`` arrays, the first and last angle of each cluster."""
    j = np.sort(np.mod(np.asarray(jump_thetas, dtype=float).reshape(-1), period))
    if j.size == 0:
        return j, j
    gap = 4.0 * JUMP_SIDE * period
    starts = np.concatenate([[True], np.diff(j) > gap])
    ends = np.concatenate([starts[1:], [True]])
    lo, hi = j[starts], j[ends]
    # a cluster that wraps past the period end joins the first one
    if lo.size > 1 and (lo[0] + period) - hi[-1] <= gap:
        lo, hi = np.concatenate([[lo[-1] - period], lo[1:-1]]), np.concatenate([[hi[0]], hi[1:-1]])
    return lo, hi


def order_matrix(period: float, mesh_period: float, n_samples: int, jump_thetas,
                 n_orders: int = N_MESH_ORDERS) -> np.ndarray:
    """The constant map from the values of a signal on one period of the output grid
    (``output_grid(period, n_samples, jump_thetas, 1)``, ``per_period`` points) to its
    complex Fourier coefficients ``c_m`` at the mesh orders ``m = k n_mesh``, ``k = 1..
    n_orders`` (module docstring). Returns ``(2, n_orders, per_period)``: real and
    imaginary parts. NumPy, build time."""
    period, mesh_period = float(period), float(mesh_period)
    n_mesh = int(round(period / mesh_period))
    grid = output_grid(period, n_samples, jump_thetas, 1)
    t = grid.offsets
    mid = np.nonzero(grid.samples)[0]
    m = np.arange(1, n_orders + 1) * n_mesh  # harmonics of the period
    nu = 2.0 * math.pi / period
    e = np.exp(-1j * nu * np.outer(m, t[mid])) / mid.size  # (K, N) the DFT
    a = np.zeros((n_orders, t.size), dtype=complex)
    a[:, mid] = e
    lo, hi = _merged_jumps(jump_thetas, period)
    if lo.size:
        d = JUMP_SIDE * period

        def at(angle):  # grid index of the point nearest to angle (mod period)
            dist = np.abs(np.mod(t - np.mod(angle, period)[:, None] + period / 2, period)
                          - period / 2)
            return np.argmin(dist, axis=1)

        minus, plus = at(lo - d), at(hi + d)
        tj = np.mod(0.5 * (lo + hi), period)
        saw = 0.5 - np.mod((t[mid][:, None] - tj[None, :]) / period, 1.0)  # (N, J)
        exact = np.exp(-1j * nu * np.outer(m, tj)) / (2j * math.pi * m[:, None])  # (K, J)
        w = exact - e @ saw  # per unit jump: its exact coefficient minus what the DFT sees
        np.add.at(a.T, plus, w.T)
        np.add.at(a.T, minus, -w.T)
    return np.stack([a.real, a.imag])


def mesh_order_amplitudes(matrix, values):
    """Single-sided peak amplitudes ``2 |c_m|`` of the mesh orders (module docstring).

    Parameters
    ----------
    matrix : ``(2, K, per_period)`` from :func:`order_matrix`.
    values : ``(n_periods, per_period, q)`` the outputs on the output grid of
        ``n_periods`` consecutive whole excitation periods (the coefficients are averaged
        over them: a DFT over the whole window at the harmonics of the period).

    Returns
    -------
    ``(q, K)`` amplitudes in the units of the outputs. Traceable (jit, vmap, jvp).
    """
    v = jnp.mean(jnp.asarray(values), axis=0)  # (per_period, q)
    mat = jnp.asarray(matrix)
    re, im = mat[0] @ v, mat[1] @ v  # (K, q)
    return 2.0 * jnp.sqrt(re**2 + im**2).T
