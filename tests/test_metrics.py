"""Exact response metrics (issue 14, item 1) against a closed-form periodic orbit.

Perfect spur teeth with the uniform stiffness law have a square-wave mesh stiffness: two
tooth pairs (k2) for (eps_alpha - 1) of each mesh period from the engagement at theta = 0,
one pair (k1) for the rest. The TE-based Eq. (20) is then, in time and with NLTE = 0,
``m x_tt + c x_t + k(t) x = F_S`` (spur: cos b_b = 1, k x_S = F_S), piecewise linear with
constant coefficients: the periodic orbit is the fixed point of the segments' flows, written
out in :mod:`gearjax.dynamics.closed_form` (checked here against scipy.linalg.expm),
independent of gearjax's integration, and the mesh force of Eq. (24) is
``F_D = F_S + k (x - x_S) = k(t) x(t)``. Its maximum sits at a stiffness jump at low
speed, where a sampled grid reads it late (-5.7e-2 F_S at 100 rad/s with 128 samples).
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.linalg import expm, solve

from gearjax import Mesh, ToothModifications, baud_velex_pair, static_mesh_force
from gearjax.dynamics.closed_form import piecewise_oscillator_orbit, square_wave_segments
from gearjax.dynamics.metrics import jump_clusters, output_grid, refined_extrema
from gearjax.dynamics.steady import steady_sweep
from gearjax.models.torsional import TorsionalModel

ZETA = 0.1
TORQUE = 254.8


def exact_force_extrema(pair, k1, k2, inertias, omega, f_s):
    """(max, min) of F_D = k(t) x(t) on the periodic orbit of m x'' + c x' + k(t) x = F
    (:func:`gearjax.dynamics.closed_form.piecewise_oscillator_orbit`)."""
    m, c, segments = _oscillator(pair, k1, k2, inertias, omega)
    orbit = piecewise_oscillator_orbit(m, c, segments, f_s)
    return orbit.max_force_N, orbit.min_force_N


def _oscillator(pair, k1, k2, inertias, omega):
    j1, j2 = inertias
    rb1, rb2 = pair.base_radii_m
    m = j1 * j2 / (j1 * rb2**2 + j2 * rb1**2)
    eps = pair.transverse_contact_ratio
    k_m = (eps - 1) * k2 + (2 - eps) * k1
    c = 2 * ZETA * math.sqrt(k_m * m)
    return m, c, square_wave_segments(eps, pair.mesh_period_rad / omega, k1, k2)


def test_closed_form_orbit_against_matrix_exponentials(square_wave):
    """The closed form (written-out damped oscillations, stationary points solved for) against
    an independent evaluation: scipy.linalg.expm of each segment's state matrix for the
    periodic start, and the force sampled densely along the orbit for its extrema (the dense
    samples can only under-read them, by less than the sampling step's change)."""
    model, pair, k1, k2 = square_wave
    f_s = static_mesh_force(pair, TORQUE)
    inert = tuple(np.asarray(model.inertias_kg_m2))
    for omega in (100.0, 600.0, 1200.0):
        m, c, segments = _oscillator(pair, k1, k2, inert, omega)
        b = np.array([0.0, f_s / m])
        flows = []
        for k, tau in segments:
            a = np.array([[0.0, 1.0], [-k / m, -c / m]])
            e = expm(a * tau)
            flows.append((a, e, solve(a, (e - np.eye(2)) @ b)))
        (_, e2, g2), (_, e1, g1) = flows
        z0 = solve(np.eye(2) - e1 @ e2, e1 @ g2 + g1)
        orbit = piecewise_oscillator_orbit(m, c, segments, f_s)
        np.testing.assert_allclose([orbit.x0_m, orbit.v0_m_s], z0, rtol=1e-9, atol=1e-15)
        forces, z = [], z0
        for (k, tau), (a, e, g) in zip(segments, flows):
            w, v = np.linalg.eig(a)
            zp = solve(a, -b)
            coef = solve(v, z - zp)
            t = np.linspace(0.0, tau, 20001)
            forces.append(k * (np.real((v[0] * coef) @ np.exp(np.outer(w, t))) + zp[0]))
            z = e @ z + g
        forces = np.concatenate(forces)
        assert orbit.max_force_N >= forces.max() - 1e-9 * f_s
        assert orbit.min_force_N <= forces.min() + 1e-9 * f_s
        assert orbit.max_force_N == pytest.approx(forces.max(), abs=1e-6 * f_s)
        assert orbit.min_force_N == pytest.approx(forces.min(), abs=1e-6 * f_s)


@pytest.fixture(scope="module")
def square_wave():
    pair = baud_velex_pair(False)
    mesh = Mesh.build(pair, "uniform")
    model = TorsionalModel.build(mesh, ToothModifications.none(), formulation="te",
                                 damping_ratio=ZETA, pinion_torque_Nm=TORQUE)
    p = pair.mesh_period_rad
    eps = pair.transverse_contact_ratio
    k2 = float(mesh.stiffness(0.5 * (eps - 1) * p))
    k1 = float(mesh.stiffness(0.5 * (eps - 1) * p + 0.5 * p))
    assert k2 == pytest.approx(2 * k1)
    return model, pair, k1, k2


def test_peak_mesh_force_is_exact_at_every_speed(square_wave):
    """Max and min mesh force within 5e-6 F_S of the closed-form orbit from the
    quasi-static range to above the critical speed (the issue's target was 2e-4 F_S; the
    sampled grid alone missed the low-speed peak, which sits at a stiffness jump, by
    5.7e-2 F_S at 100 rad/s). At 353 and 800 rad/s the linear orbit's force turns tensile
    (closed form): there the contact law holds the mesh force at zero, so the minimum is
    exactly 0 and ``contact_loss`` is set."""
    model, pair, k1, k2 = square_wave
    f_s = static_mesh_force(pair, TORQUE)
    speeds = np.array([100.0, 226.0, 353.0, 600.0, 800.0, 1200.0])
    res = steady_sweep(model, speeds)
    inert = tuple(np.asarray(model.inertias_kg_m2))
    for i, w in enumerate(speeds):
        f_max, f_min = exact_force_extrema(pair, k1, k2, inert, w, f_s)
        assert bool(res.contact_loss[i]) == (f_min <= 0.0), w
        if f_min <= 0.0:  # not the linear orbit any more
            assert float(res.min_mesh_force_N[i]) == 0.0, w
            continue
        # measured |error| / F_S: max <= 1.2e-7 (1200 rad/s), min <= 7.9e-7 (100 rad/s; the
        # shooting's Dopri8 at rtol 1e-9), so 5e-6 is ~6x the worst. A 1e-4 relative shift
        # of the speed or of k1, k2 in the closed form moves an extremum by 6.2e-6 to
        # 2.6e-4 F_S at each linear speed here: this bound catches all of them, 2e-4 only
        # the speed shift at 100 rad/s.
        assert float(res.max_mesh_force_N[i]) == pytest.approx(f_max, abs=5e-6 * f_s), w
        assert float(res.min_mesh_force_N[i]) == pytest.approx(f_min, abs=5e-6 * f_s), w
    assert np.sum(res.contact_loss) == 2  # the closed form separates at 353 and 800 rad/s


def test_grid_has_both_sides_of_every_jump_and_refines_between():
    """A step plus a parabola: the grid reads both one-sided values of the step, the
    refinement window finds the vertex between samples (exact flow of y = t)."""
    period = 1.0
    offsets, per, samples = output_grid(period, 8, [0.3], 2)
    assert per == 10 and offsets.size == 20 and np.all(np.diff(offsets) > 0)
    assert samples.sum() == 16
    np.testing.assert_allclose(offsets[~samples], [0.3 - 1e-9, 0.3 + 1e-9, 1.3 - 1e-9,
                                                   1.3 + 1e-9], atol=1e-15)

    def flow(t0, y0, tf):  # y' = 1
        return y0[None, :] + (tf - t0)[:, None]

    def out(t, y):  # a jump of +1 at 0.3 (mod 1) and a vertex at t = 0.62
        tt = jnp.mod(t, 1.0)
        return jnp.stack([jnp.where(tt >= 0.3, 1.0, 0.0) - (y[0] - 0.62) ** 2])

    ts = jnp.asarray(offsets[:per])
    ys = ts[:, None]
    vals, mx, mn = refined_extrema(out, flow, ts, ys)
    # vertex between the samples 0.5625 and 0.6875: found to the window spacing squared
    assert float(mx[0]) == pytest.approx(1.0, abs=1e-5)
    assert float(jnp.max(vals[:, 0])) < 1.0 - 1e-3  # the grid alone misses it
    # both one-sided values of the step are on the grid, exactly
    side = lambda t: float(vals[int(np.argmin(np.abs(offsets[:per] - t))), 0])  # noqa: E731
    assert side(0.3 - 1e-9) == pytest.approx(-(0.3 - 1e-9 - 0.62) ** 2, abs=1e-12)
    assert side(0.3 + 1e-9) == pytest.approx(1.0 - (0.3 + 1e-9 - 0.62) ** 2, abs=1e-12)
    assert float(mn[0]) <= float(jnp.min(vals[:, 0]))


def test_rtol_option_tightens_the_transient_to_the_closed_form(square_wave):
    """``--rtol`` (:func:`gearjax.dynamics.sweep.tolerance_options`): the transient sweep
    at rtol 1e-10 gives max and min mesh force within 1e-7 F_S of the closed-form orbit
    where contact holds (measured 3e-8, the closed form's own dense sampling; the default
    tolerances: 1.6e-6 F_S at 600 rad/s), and the achieved periodicity measure below the
    test it asked for (min(1e-3, 1e5 rtol))."""
    from gearjax.dynamics.sweep import Transient, sweep, tolerance_options

    model, pair, k1, k2 = square_wave
    f_s = static_mesh_force(pair, TORQUE)
    speeds = np.array([226.0, 600.0])
    opts = tolerance_options(1e-10)
    assert opts["convergence_tol"] == pytest.approx(1e-5)
    res = sweep(model, speeds, Transient(**opts))
    assert np.all(res.converged) and np.all(np.asarray(res.convergence) <= 1e-5)
    inert = tuple(np.asarray(model.inertias_kg_m2))
    for i, w in enumerate(speeds):
        f_max, f_min = exact_force_extrema(pair, k1, k2, inert, w, f_s)
        assert float(res.max_mesh_force_N[i]) == pytest.approx(f_max, abs=1e-7 * f_s), w
        assert float(res.min_mesh_force_N[i]) == pytest.approx(f_min, abs=1e-7 * f_s), w
    with pytest.raises(Exception, match="rtol"):
        tolerance_options(0.5)


def test_closed_form_refuses_what_it_does_not_cover():
    """Overdamped segments and a contact ratio outside (1, 2) are named errors, not NaNs."""
    from gearjax.errors import ModelError

    with pytest.raises(ModelError, match="underdamped"):
        piecewise_oscillator_orbit(1.0, 10.0, [(1.0, 0.1)], 1.0)
    with pytest.raises(ModelError, match="contact_ratio"):
        square_wave_segments(2.3, 1e-3, 1e8, 2e8)


def test_low_speed_ringing_extrema(square_wave):
    """At 2-10 rad/s the force jumps to 2 F_S where the second pair engages and rings about
    F_S (170 free periods per mesh period at 5 rad/s); its first undershoot, half a free
    period later, is the minimum, 0.2537 F_S (closed form, zeta 0.1). The 128-sample grid
    aliases the ringing: its smallest value is the F_S/2 one-sided point where a pair
    leaves, and before the windows after the jumps (metrics, rule 3) simulate read 0.5000
    F_S (+0.246 F_S). Measured since: |error| <= 4.6e-7 F_S at the default rtol (2.3e-8 at
    rtol 1e-10), so 5e-6 F_S as in the test above; a window of one free period, or the
    parabola vertex instead of the quartic one, reads 1-5e-6 F_S low."""
    from gearjax.dynamics.simulate import simulate

    model, pair, k1, k2 = square_wave
    f_s = static_mesh_force(pair, TORQUE)
    speeds = np.array([2.0, 5.0, 10.0])
    res = jax.vmap(lambda w: simulate(model, w))(speeds)
    inert = tuple(np.asarray(model.inertias_kg_m2))
    for i, w in enumerate(speeds):
        f_max, f_min = exact_force_extrema(pair, k1, k2, inert, w, f_s)
        assert f_min < 0.3 * f_s  # the ringing's undershoot, not the grid's F_S / 2
        assert float(res.max_mesh_force_N[i]) == pytest.approx(f_max, abs=5e-6 * f_s), w
        assert float(res.min_mesh_force_N[i]) == pytest.approx(f_min, abs=5e-6 * f_s), w


def test_jump_clusters_are_cyclic_and_index_both_sides():
    """Jumps closer than a sixteenth of a grid interval form one cluster, also across the
    period's end; its window starts at the point after its last jump and its size is read
    against the point before its first."""
    grid = output_grid(1.0, 8, [0.0, 0.3, 0.3 + 1e-4, 0.999], 1)
    cl = jump_clusters(grid, 1.0, [0.0, 0.3, 0.3 + 1e-4, 0.999])
    one = grid.offsets[: grid.per_period]
    got = sorted(zip(one[cl.before], one[cl.after]))
    np.testing.assert_allclose(got, [(0.3 - 1e-9, 0.3001 + 1e-9), (0.999 - 1e-9, 1e-9)],
                               atol=1e-15)


def test_window_after_a_jump_finds_a_peak_before_its_second_point():
    """After a jump the output keeps rising for a moment: ``1 + exp(-a t) sin(w t + phi)``,
    ``phi`` chosen so that its first maximum (closed form, ``w t + phi = atan(w / a)``)
    lies 5e-5 rad after the jump, a third of the window's point spacing (0.02 / 128), and
    the ringing is faster than the grid. Read from the quartic through the window's first
    five points to 1e-6 of the closed form (measured +4.0e-7: its interpolation error at
    s = -1.68 of the stencil -2..2, about 2.5 times the centred vertex's 7.5e-8 of the
    test below at the same spacing); the window's samples alone were 5.5e-4 low. Also at
    the minimum (the same signal turned over)."""
    w = 2 * np.pi / 0.01
    a = 0.5 * w
    t_peak = 5e-5
    phi = np.arctan(w / a) - w * t_peak
    peak = 1.0 + np.exp(-a * t_peak) * np.sin(w * t_peak + phi)
    start, period = 0.3, 1.0
    grid = output_grid(period, 8, [start], 1)
    ts = jnp.asarray(grid.offsets)
    ys = ts[:, None]
    cl = jump_clusters(grid, period, [start])

    def flow(t0, y0, tf):  # y' = 1
        return y0[None, :] + (tf - t0)[:, None]

    def out(t, y):
        tau = y[0] - start
        up = jnp.where(tau >= 0, 1.0 + jnp.exp(-a * tau) * jnp.sin(w * tau + phi), 0.0)
        return jnp.stack([up, -up])

    _, mx, mn = refined_extrema(out, flow, ts, ys, jumps=(cl, 2 * 0.01))
    samples = 1.0 + np.exp(-a * np.arange(3) * 0.02 / 128) * np.sin(
        w * np.arange(3) * 0.02 / 128 + phi)
    assert peak - samples.max() > 5e-4  # what the window's points alone read
    assert float(mx[0]) == pytest.approx(peak, abs=1e-6)
    assert float(mn[1]) == pytest.approx(-peak, abs=1e-6)


def test_windows_after_jumps_find_ringing_between_samples():
    """A decaying free oscillation started by each of many jumps, its period a twelfth of a
    grid interval: the grid and the windows around its extremes miss its peak, the windows
    after the jumps read it (closed form: the first stationary point of exp(-a t) sin(w t))
    to 1e-7. Of more jumps than :func:`n_jump_windows` they keep the largest of output 0
    and, per extremum of each output, those after which it is nearest that extreme on the
    grid:

    * output 0, a staircase of the jumps with their ringing: its peak after the last jump,
      the largest or (sizes reversed) the smallest; the second read through the nearest
      rule (missed before it, when only the largest jumps had windows);
    * output 1, a staircase that climbs over the first three jumps and steps down after,
      ringing after every jump: its peak after the third, among the smallest jumps of
      output 0 where the sizes grow, so only the nearest rule reads it."""
    from gearjax.dynamics.metrics import (MAX_JUMP_WINDOWS, NEAR_EXTREME_WINDOWS,
                                          n_jump_windows)

    w = 2 * np.pi / 0.01  # free period 0.01 = h / 12.5
    a = 0.5 * w  # decays between jumps 0.08 apart to exp(-25)
    t_peak = np.arctan(w / a) / w
    peak = np.exp(-a * t_peak) * np.sin(w * t_peak)
    n_jumps = MAX_JUMP_WINDOWS + 4 * NEAR_EXTREME_WINDOWS + 3  # more than the windows
    starts = 0.05 + 0.08 * np.arange(n_jumps)
    period = 2.0
    grid = output_grid(period, 16, starts, 1)  # h = 0.125
    ts = jnp.asarray(grid.offsets)
    ys = ts[:, None]
    cl = jump_clusters(grid, period, starts)
    assert cl.after.size == starts.size
    assert n_jump_windows(cl, 2) < starts.size
    steps = np.where(np.arange(n_jumps) < 3, 0.3, -0.1)  # output 1's steps

    def flow(t0, y0, tf):  # y' = 1
        return y0[None, :] + (tf - t0)[:, None]

    for sizes in (np.linspace(0.1, 1.0, starts.size), np.linspace(1.0, 0.1, starts.size)):
        def out(t, y, sizes=jnp.asarray(sizes)):
            tau = y[0] - jnp.asarray(starts)
            ring = jnp.where(tau >= 0, jnp.exp(-a * tau) * jnp.sin(w * tau), 0.0)
            return jnp.stack([jnp.sum(sizes * ((tau >= 0) + ring)),
                              jnp.sum(jnp.asarray(steps) * ((tau >= 0) + ring))])

        top = np.array([sizes.sum() + sizes[-1] * peak,  # the peak after the last jump
                        0.9 + 0.3 * peak])  # output 1's after the third
        _, grid_max, _ = refined_extrema(out, flow, ts, ys)
        assert np.all(np.asarray(grid_max) < top - 1e-3)  # missed without these windows
        _, mx, _ = refined_extrema(out, flow, ts, ys, jumps=(cl, 2 * 0.01))
        # the quartic vertex's own error at this spacing, 0.02 / 128: 7.5e-8
        np.testing.assert_allclose(np.asarray(mx), top, rtol=0, atol=1e-7)
