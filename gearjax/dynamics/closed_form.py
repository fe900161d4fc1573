"""Closed-form periodic orbits, independent of every integrator in gearjax: references for
tests and benchmarks (issue 14) and for users who want to check a solver on a case with a
known answer.

Perfect spur teeth with the ``uniform`` stiffness law have a square-wave mesh stiffness:
two tooth pairs (k2) for ``(eps_alpha - 1)`` of each mesh period from the engagement at
theta = 0, one pair (k1) for the rest. With NLTE = 0 the TE-based sdof Eq. (20) is then, in
time, the piecewise-constant linear oscillator

    m x'' + c x' + k(t) x = F_S,    mesh force  F_D = k(t) x  (Eq. (24), cos b_b = 1),

whose flow over each segment is a damped harmonic oscillation about ``F_S / k`` written
out below (no matrix exponential, no time stepping). The periodic orbit is the fixed point
of the product of the segments' affine maps, and the extrema of ``k x`` are exact: the
segment ends (both sides of every jump of k) and the stationary points of ``x`` inside a
segment, where ``x' = e^(-s t) R cos(w_d t - phi)`` vanishes. NumPy float64 only.
"""

from __future__ import annotations

import math
from typing import NamedTuple, Sequence

import numpy as np

from ..errors import ModelError

__all__ = ["OrbitExtrema", "piecewise_oscillator_orbit", "square_wave_segments"]


class OrbitExtrema(NamedTuple):
    """Periodic orbit of a piecewise-constant oscillator, read exactly."""
    x0_m: float          # x at the start of the period (the first segment)
    v0_m_s: float        # x' there
    max_force_N: float   # max of k(t) x(t) over the period
    min_force_N: float   # min of k(t) x(t) over the period


def _segment(m, c, k, tau):
    """``(E, s, w_d)``: ``z(tau) - z_p = E (z(0) - z_p)`` for ``m x'' + c x' + k x = F``,
    ``z = (x, x')``, ``z_p = (F / k, 0)``, underdamped."""
    s = c / (2.0 * m)
    wd2 = k / m - s * s
    if not wd2 > 0.0:
        raise ModelError("segments", (k, tau), "closed form written for underdamped segments "
                         f"(c^2 < 4 k m); here c={c:.6g}, k={k:.6g}, m={m:.6g}")
    wd = math.sqrt(wd2)
    co, si, ex = math.cos(wd * tau), math.sin(wd * tau), math.exp(-s * tau)
    e = ex * np.array([[co + s / wd * si, si / wd],
                       [-(wd + s * s / wd) * si, co - s / wd * si]])
    return e, s, wd


def piecewise_oscillator_orbit(mass_kg: float, damping_N_s_m: float,
                               segments: Sequence[tuple[float, float]],
                               force_N: float) -> OrbitExtrema:
    """Periodic orbit of ``m x'' + c x' + k(t) x = F`` with ``k(t)`` piecewise constant.

    Parameters
    ----------
    mass_kg, damping_N_s_m : m > 0 and c >= 0 (every segment underdamped).
    segments : ``[(k_i, tau_i), ...]``: stiffness (N/m) and duration (s) of each piece of
        one period, in order; the period is ``sum(tau_i)``.
    force_N : the constant load F.

    Returns the start of the period on the orbit and the exact max and min of ``k(t) x(t)``
    (both one-sided values at every jump of k count).
    """
    m, c, f = float(mass_kg), float(damping_N_s_m), float(force_N)
    if not (m > 0.0 and c >= 0.0 and math.isfinite(m) and math.isfinite(c)):
        raise ModelError("mass_kg/damping_N_s_m", (mass_kg, damping_N_s_m),
                         "need m > 0 and c >= 0, finite")
    if not segments or any(not (k > 0.0 and tau > 0.0) for k, tau in segments):
        raise ModelError("segments", segments, "need [(k > 0, tau > 0), ...], at least one")
    maps = []  # z_end = E z + g
    for k, tau in segments:
        e, _, _ = _segment(m, c, k, tau)
        zp = np.array([f / k, 0.0])
        maps.append((e, zp - e @ zp))
    phi, g = np.eye(2), np.zeros(2)
    for e, gg in maps:
        phi, g = e @ phi, e @ g + gg
    z = np.linalg.solve(np.eye(2) - phi, g)
    z0 = z.copy()
    f_max, f_min = -math.inf, math.inf
    for (k, tau), (e, gg) in zip(segments, maps):
        _, s, wd = _segment(m, c, k, tau)
        a = z[0] - f / k                       # x - x_p = e^(-s t)(a cos + b sin)
        b = (z[1] + s * a) / wd
        p, q = z[1], -s * b - wd * a           # x' = e^(-s t)(p cos + q sin)
        phase = math.atan2(q, p)
        n0 = math.ceil((-phase - 0.5 * math.pi) / math.pi)
        n1 = math.floor((wd * tau - phase - 0.5 * math.pi) / math.pi)
        ts = [0.0, tau] + [(phase + 0.5 * math.pi + n * math.pi) / wd
                           for n in range(n0, n1 + 1)]
        for t in ts:
            if 0.0 <= t <= tau:
                x = f / k + math.exp(-s * t) * (a * math.cos(wd * t) + b * math.sin(wd * t))
                f_max, f_min = max(f_max, k * x), min(f_min, k * x)
        z = e @ z + gg
    return OrbitExtrema(float(z0[0]), float(z0[1]), float(f_max), float(f_min))


def square_wave_segments(contact_ratio: float, mesh_period_s: float, k1_N_m: float,
                         k2_N_m: float) -> list[tuple[float, float]]:
    """The ``uniform`` law's spur stiffness over one mesh period from the engagement: two
    pairs (``k2``) for ``(eps_alpha - 1) T``, one pair (``k1``) for ``(2 - eps_alpha) T``
    (``1 < eps_alpha < 2``)."""
    eps = float(contact_ratio)
    if not 1.0 < eps < 2.0:
        raise ModelError("contact_ratio", contact_ratio, "square wave written for 1 < eps < 2")
    return [(float(k2_N_m), (eps - 1.0) * mesh_period_s), (float(k1_N_m), (2.0 - eps) * mesh_period_s)]
