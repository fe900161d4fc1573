"""Pseudo-arclength continuation in speed (gearjax.dynamics.arclength) against independent
results, on the sdof spur rig (Table 1 short relief, iso6336 stiffness, damping 0.03,
reference Eq. (16): contact loss and a fold near 660 rad/s) and its te formulation:

* every traced point is a periodic orbit: one period of a plain diffrax solve (Dopri5, its
  own step control, no Newton, no monodromy) from the returned start comes back to it;
  Liouville: complex multipliers have modulus exp(-zeta omega_n T);
* at the located fold the largest multiplier is 1, by the trace's own monodromy and by
  central differences of that plain period map (no variational equations);
* the unstable branch lies between the two stable ones (max force and DTE, at every
  unstable point, against the stable branches interpolated at its speed);
* the jump up at the fold lands on the traced high branch, and the natural-parameter up
  sweep jumps between the neighbouring grid speeds around it;
* stable points equal a transient (simulate, automatic transient) started on the
  neighbouring traced orbit, wherever that transient settles;
* the linear case (te, damping 0.1, contact kept) equals the harmonic-balance orbit
  (frequency domain) and its Floquet radius the homogeneous monodromy's
  (gearjax.dynamics.stability);
* period doubling: on perfect teeth with the uniform stiffness law (square-wave k) the
  trace flags two multipliers through -1 while contact is kept, at the edges of the
  parametric instability zone that the homogeneous monodromy of the linearised equation
  finds on its own.
"""

from __future__ import annotations

import math

import diffrax
import equinox as eqx
import jax.numpy as jnp
import numpy as np
import pytest

from gearjax import table1_relief
from gearjax.dynamics.arclength import Arclength, trace_speed
from gearjax.dynamics.bifurcation import coexistence, crossing_kinds
from gearjax.dynamics.continuation import continuation_sweep
from gearjax.errors import SimulationError
from gearjax.rigs import build_model
from gearjax.rigs.registry import get_rig

from oscillators import plain_period_map

ZETA = 0.03

# one worker runs both continuation files: they share the corrector's compiled programs
pytestmark = pytest.mark.xdist_group("sdof_continuation")


@pytest.fixture(scope="module")
def model():
    return build_model(get_rig("baud-velex-spur"), table1_relief("short"), model="torsional",
                       formulation="reference", law="iso6336", damping_ratio=ZETA)


@pytest.fixture(scope="module")
def traced(model):
    """640-670 rad/s: the low branch to its fold (~660 rad/s), the unstable branch back down
    and the high branch (from the orbit at 670 rad/s and the jump's landing)."""
    return trace_speed(model, [640.0, 655.0, 670.0])


def _period_map(model, omega, y0):
    return plain_period_map(model, omega, y0, 1e-12, 1e-14, 500_000)


def _stable_at(res, w, branches):
    """Max force and DTE p-p of each stable branch interpolated at speed ``w``."""
    out = []
    for b in branches:
        sel = res.branch == b
        ws = res.points.speed_rad_s[sel]
        if ws.min() <= w <= ws.max():
            o = np.argsort(ws)
            out.append((np.interp(w, ws[o], res.points.max_mesh_force_N[sel][o]),
                        np.interp(w, ws[o], res.points.dte_ptp_m[sel][o])))
    return out


def test_traced_points_are_periodic_orbits(model, traced):
    """Every point (stable, unstable, the fold) returns to itself after one period of an
    independent integration; Liouville's modulus where the multipliers are complex."""
    omega_n = float(model.natural_frequency_rad_s())
    for w, y0, mu in zip(traced.points.speed_rad_s, traced.y0, traced.multipliers):
        y_p = np.asarray(_period_map(model, jnp.asarray(w), jnp.asarray(y0)))
        # the trace's Newton stops at a step below 1e-8 (1 + |y|)
        assert np.linalg.norm(y_p - y0) < 1e-7 * (1 + np.linalg.norm(y0)), w
        if np.all(mu.imag != 0):
            assert abs(abs(mu[0]) / math.exp(-ZETA * omega_n * model.period_rad / w) - 1) < 1e-6
        else:  # det Phi = exp(-2 zeta omega_n T) for real ones too
            assert abs(np.prod(mu).real / math.exp(-2 * ZETA * omega_n * model.period_rad / w)
                       - 1) < 1e-6


def test_fold_multiplier_is_one(model, traced):
    """One fold in 640-670 rad/s, located: the speed component of the tangent vanishes to
    the location tolerance and the largest multiplier is +1, by the trace's monodromy and
    by central differences of the plain period map at the fold orbit."""
    (fold,) = traced.folds()
    assert fold.located and fold.ends_stable_branch and 655.0 < fold.speed_rad_s < 670.0
    tol = Arclength().locate_tol
    assert abs(traced.tangent_speed[fold.index]) <= tol
    # mu - 1 = -t_p (w . dG/dp) / (w . t_y) (w the left null vector): of the order of the
    # tangent's speed component, here within ten times its tolerance
    assert abs(fold.multiplier - 1.0) < 10 * tol
    y0, w = traced.y0[fold.index], jnp.asarray(fold.speed_rad_s)
    h = 1e-5 * (1 + np.linalg.norm(y0))
    cols = []
    for k in range(y0.size):
        e = np.zeros_like(y0)
        e[k] = h
        cols.append((np.asarray(_period_map(model, w, jnp.asarray(y0 + e)))
                     - np.asarray(_period_map(model, w, jnp.asarray(y0 - e)))) / (2 * h))
    mu = np.linalg.eigvals(np.stack(cols, axis=1))
    assert np.min(np.abs(mu - 1.0)) < 1e-4
    # either side of it: one side stable, the other a saddle (a real multiplier above 1)
    rho = traced.points.spectral_radius
    before, after = rho[fold.index - 1], rho[fold.index + 1]
    assert min(before, after) < 1.0 < max(before, after)


def test_unstable_branch_lies_between_the_stable_ones(traced):
    """At every unstable point, the two stable branches there (low: contact kept up to the
    fold; high: contact lost) bracket its max force and its DTE."""
    stable = [b for b, ok in traced.branch_stable().items() if ok]
    unstable = [b for b, ok in traced.branch_stable().items() if not ok]
    assert len(stable) == 2 and len(unstable) == 1
    pts = np.flatnonzero((traced.branch == unstable[0]) & (traced.point == "regular"))
    assert pts.size >= 3
    for i in pts:
        both = _stable_at(traced, traced.points.speed_rad_s[i], stable)
        assert len(both) == 2, traced.points.speed_rad_s[i]
        (f_lo, d_lo), (f_hi, d_hi) = sorted(both)
        assert f_lo < traced.points.max_mesh_force_N[i] < f_hi
        assert d_lo < traced.points.dte_ptp_m[i] < d_hi
    assert traced.coexistence_rad_s()[0][1] == pytest.approx(traced.folds()[0].speed_rad_s)


def test_jump_up_lands_on_the_high_branch(model, traced):
    """The sweep leaving the low branch at the fold lands on the traced high branch (a
    transient then Newton at half a grid step beyond it); the natural-parameter up sweep
    on a 5 rad/s grid jumps between the grid speeds around the fold."""
    (fold,) = traced.folds()
    (jump,) = [j for j in traced.jumps if j.index == fold.index]
    assert jump.sweep == "up" and jump.landed_periodic and jump.discontinuous and jump.rises
    assert traced.branch_stable()[jump.landed_branch]
    assert traced.jump_up_rad_s() == [fold.speed_rad_s] and traced.jump_down_rad_s() == []
    grid = np.arange(645.0, 671.0, 5.0)
    up = continuation_sweep(model, grid, "up")
    k = np.searchsorted(grid, fold.speed_rad_s)
    assert up.stats["restarted"][k] and not up.stats["restarted"][:k].any()
    assert up.max_mesh_force_N[k] > 1.5 * up.max_mesh_force_N[k - 1]


def _transient_end(model, omega, y0, n_periods):
    """The state after ``n_periods`` excitation periods from ``y0`` (plain diffrax,
    Dopri5 at rtol 1e-10, the jumps of k(theta) as jump_ts, read on the host)."""
    p = float(model.period_rad)
    jumps = np.asarray(model.jump_thetas, dtype=float) % p
    jumps = np.sort((jumps[None, :] + p * np.arange(n_periods)[:, None]).ravel())
    return _transient_end_jit(model, omega, y0, n_periods, jnp.asarray(jumps[jumps > 0]))


@eqx.filter_jit
def _transient_end_jit(model, omega, y0, n_periods, jumps):
    p = float(model.period_rad)
    sol = diffrax.diffeqsolve(
        diffrax.ODETerm(lambda t, y, a: model.vector_field(t, y, a)), diffrax.Dopri5(),
        t0=0.0, t1=n_periods * p, dt0=None, y0=jnp.asarray(y0), args=jnp.asarray(omega),
        stepsize_controller=diffrax.PIDController(rtol=1e-10, atol=1e-12,
                                                  jump_ts=jumps),
        max_steps=2_000_000)
    return sol.ys[-1]


@pytest.mark.slow  # 150-period transients at rtol 1e-10 (~40 s on 2 shared cores)
def test_stable_points_equal_transients_from_the_neighbouring_orbit(model, traced):
    """Brute force: a transient of 150 excitation periods (an independent diffrax
    integration at rtol 1e-10) started on the neighbouring traced orbit of the same stable
    branch, wherever 150 periods settle it (Floquet radius^150 < 1e-9; not next to the
    fold, where the radius tends to 1), ends on the traced orbit; both measured alike
    (simulate over two periods at rtol 1e-10, so that the comparison sees the orbits and
    not the measurement's tolerance) give the same max force and DTE."""
    from gearjax import simulate

    n = 150
    meas = eqx.filter_jit(lambda m, w, y: simulate(m, w, n_transient_periods=0, y0=y,
                                                   rtol=1e-10, atol=1e-12))
    f_s, x_ref = float(model.static_force_N), float(model.x_ref)
    checked = 0
    for b, ok in traced.branch_stable().items():
        idx = np.flatnonzero((traced.branch == b) & np.isin(traced.point, ("regular", "end")))
        for i, j in zip(idx[1:], idx[:-1]):
            if not (ok and traced.points.spectral_radius[i] ** n < 1e-9):
                continue
            w, y_i = jnp.asarray(traced.points.speed_rad_s[i]), traced.y0[i]
            y_end = np.asarray(_transient_end(model, w, jnp.asarray(traced.y0[j]), n))
            assert np.linalg.norm(y_end - y_i) < 1e-7 * (1 + np.linalg.norm(y_i))
            brute, mine = meas(model, w, jnp.asarray(y_end)), meas(model, w, jnp.asarray(y_i))
            assert bool(brute.converged) and bool(mine.converged)
            assert abs(float(brute.max_mesh_force_N - mine.max_mesh_force_N)) < 1e-6 * f_s
            assert abs(float(brute.dte_ptp_m - mine.dte_ptp_m)) < 1e-6 * x_ref
            checked += 1
    assert checked >= 3


@pytest.mark.slow  # compiles the harmonic balance and the monodromy (~25 s)
def test_linear_case_equals_harmonic_balance():
    """te (Eq. (20)) at damping 0.1 below the critical speed: contact kept, a linear
    time-periodic system; the traced orbits are the harmonic-balance ones and their Floquet
    radius the homogeneous monodromy's; no bifurcation, one stable branch."""
    from gearjax.dynamics.corrector import measure
    from gearjax.dynamics.harmonic_sweep import harmonic_sweep
    from gearjax.dynamics.stability import spectral_radius

    te = build_model(get_rig("baud-velex-spur"), table1_relief("short"), model="torsional",
                     formulation="te", law="iso6336", damping_ratio=0.1)
    res = trace_speed(te, [300.0, 350.0, 400.0])
    assert not res.points.contact_loss.any() and res.stable.all() and res.bifurcations == ()
    assert np.unique(res.branch).tolist() == [0]
    hb = harmonic_sweep(te, res.points.speed_rad_s, rtol=1e-8)
    assert hb.stats["contact_holds"].all()
    scale = 1 + np.linalg.norm(hb.stats["y0"], axis=1)
    assert np.all(np.linalg.norm(res.y0 - hb.stats["y0"], axis=1) < 1e-6 * scale)
    # the same orbits measured the same way (simulate over two periods, the sweep's
    # metrics): the harmonic orbit's measured metrics, to 1e-6 of F_S and of x_ref
    hb_met = [measure(te, w, y) for w, y in zip(res.points.speed_rad_s, hb.stats["y0"])]
    f_s, x_ref = float(te.static_force_N), float(te.x_ref)
    assert np.all(np.abs(res.points.max_mesh_force_N - [float(m[1]) for m in hb_met]) < 1e-6 * f_s)
    assert np.all(np.abs(res.points.dte_ptp_m - [float(m[4]) for m in hb_met]) < 1e-6 * x_ref)
    np.testing.assert_allclose(res.points.spectral_radius,
                               spectral_radius(te, res.points.speed_rad_s),
                               rtol=1e-6)


@pytest.mark.slow  # two traces and the monodromy of the linearised equation (~30 s)
def test_period_doubling_at_the_parametric_instability_zone():
    """Perfect teeth, uniform stiffness (a square-wave k(theta)): with contact kept the
    reference formulation is the linear te equation, and near 2 omega_n / (3 z1) its
    parametric instability zone is bounded by multipliers through -1. The trace flags a
    period doubling at each edge (multiplier -1) where the homogeneous monodromy
    (gearjax.dynamics.stability, its own integration) has its radius cross 1."""
    from gearjax.dynamics.stability import spectral_radius

    m = build_model(get_rig("baud-velex-spur"), table1_relief("none"), model="torsional",
                    formulation="reference", law="uniform", damping_ratio=ZETA)
    res = trace_speed(m, [545.0, 560.0, 575.0])
    pd = [b for b in res.bifurcations if b.kind == "period_doubling"]
    assert len(pd) == 2 and not res.points.contact_loss.any()
    for b in pd:
        assert b.located and abs(b.multiplier + 1.0) < 1e-6
        rho = spectral_radius(m, [b.speed_rad_s - 0.05, b.speed_rad_s + 0.05])
        assert (rho[0] - 1.0) * (rho[1] - 1.0) < 0, (b.speed_rad_s, rho)
    lo, hi = sorted(b.speed_rad_s for b in pd)
    inside = (res.points.speed_rad_s > lo) & (res.points.speed_rad_s < hi)
    assert inside.any() and not res.stable[inside].any() and res.stable[~inside & (
        res.point == "regular")].all()


def test_crossing_kinds_and_coexistence():
    """The classification of a step by its end points' multipliers and tangents."""
    pair = np.array([0.5 + 0.5j, 0.5 - 0.5j])
    assert crossing_kinds(pair, np.array([1.2, 0.3]), 1.0, -1.0) == ["fold"]
    assert crossing_kinds(pair, np.array([1.2, 0.3]), 1.0, 1.0) == ["branch_point"]
    assert crossing_kinds(np.array([-0.9, 0.3]), np.array([-1.1, 0.3]), 1, 1) == [
        "period_doubling"]
    e = np.exp(1j)
    torus_a, torus_b = (np.array([r * e, r * np.conj(e), 0.1]) for r in (0.9, 1.1))
    assert crossing_kinds(torus_a, torus_b, 1, 1) == ["torus"]
    # a complex pair colliding on the real axis outside the circle crosses nothing
    assert crossing_kinds(np.array([1.5 + 0.1j, 1.5 - 0.1j]), np.array([1.7, 1.3]), 1, 1) == []
    assert coexistence([(0, 2), (1, 3), (5, 6)]) == [[1, 2]]
    assert coexistence([(0, 2), (3, 4)]) == []


def test_bad_input(model):
    with pytest.raises(SimulationError, match="speeds_rad_s"):
        trace_speed(model, [600.0])
    with pytest.raises(SimulationError, match="speeds_rad_s"):
        trace_speed(model, [600.0, -1.0])
    with pytest.raises(SimulationError, match="step"):
        Arclength(step=10.0)
    with pytest.raises(SimulationError, match="min_cos"):
        Arclength(min_cos=1.5)
    with pytest.raises(SimulationError, match="landing_offset_rad_s"):
        Arclength(landing_offset_rad_s=-1.0)
    with pytest.raises(SimulationError, match="progress"):
        trace_speed(model, [600.0, 610.0], progress=True)
