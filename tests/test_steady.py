"""Periodic steady state by shooting (gearjax.dynamics.steady) against independent results.

* a constant-stiffness oscillator under harmonic excitation: the periodic start and the
  peak-to-peak response against the closed-form frequency response;
* the monodromy matrix of the shooting against :func:`gearjax.dynamics.stability.monodromy` (the
  model's own homogeneous equation, a different integration);
* the sdof model (te, perturbation, reference; spur and helical pairs) against long
  diffrax transients of :func:`gearjax.dynamics.simulate.simulate` with the decay of the transient
  guaranteed by the Floquet multipliers of :mod:`gearjax.dynamics.stability`;
* the 3D rigs (spur and helical, te formulation) against long transients (slow).
"""

from __future__ import annotations

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from gearjax.dynamics.orbit import RESULTS
import pytest

from gearjax import Mesh, baud_velex_pair, table1_relief
from gearjax.rigs import baud_velex_rig, build_model
from gearjax.models.torsional import TorsionalModel
from gearjax.dynamics.simulate import SimulationError, simulate
from gearjax.dynamics.stability import spectral_radius
from gearjax.dynamics.steady import (
    Shooting,
    periodic_state,
    spectral_radius_of,
    steady_state,
    steady_sweep,
)
from gearjax.dynamics.sweep import SweepResult
from oscillators import HarmonicOscillator

SAMPLES = 128


def Oscillator(**kw):
    """The constant-stiffness harmonic 'TE' oscillator of tests/oscillators.py, te-labelled."""
    return HarmonicOscillator(formulation="te", **kw)


def _frf(osc, omega):
    nu = osc.order * omega
    c = 2 * osc.damping_ratio * math.sqrt(osc.stiffness * osc.mass)
    return osc.stiffness / (osc.stiffness - osc.mass * nu**2 + 1j * c * nu)


def test_harmonic_excitation_closed_form():
    """Lightly damped (zeta = 0.005: a transient would need ~900 periods at resonance):
    the periodic start is x(0) = a Re H, x'(0) = -n a Im H and ptp(x) = 2 |H| a."""
    osc = Oscillator(mass=2.0, stiffness=8e8, damping_ratio=0.005, amplitude=1e-5, order=26)
    w_n = osc.omega_n / osc.order
    speeds = np.array([0.3 * w_n, w_n, 2.5 * w_n])
    run = eqx.filter_jit(eqx.filter_vmap(
        lambda m, w: steady_state(m, w, Shooting(rtol=1e-11, atol=1e-13, measure_rtol=1e-12,
                                                 measure_atol=1e-14)), in_axes=(None, 0)))
    out = run(osc, jnp.asarray(speeds))
    for i, w in enumerate(speeds):
        h = _frf(osc, w)
        y0 = np.asarray(out.orbit.state[i])
        scale = abs(h) * osc.amplitude
        assert abs(y0[0] - osc.amplitude * h.real) < 1e-8 * scale
        assert abs(y0[1] + osc.order * osc.amplitude * h.imag) < 1e-8 * scale * osc.order
        ratio = float(out.result.dte_ptp_m[i]) / (2 * scale)
        # exact peak-to-peak (refined between samples; the 128 samples alone read up to a
        # factor cos(pi/128) low), measured at rtol 1e-12 from the periodic start
        assert abs(ratio - 1) < 1e-8
        assert bool(out.result.converged[i])
        # free decay over one period exp(-zeta w_n T): the Floquet radius of the oscillator
        rho = math.exp(-osc.damping_ratio * osc.omega_n * 2 * math.pi / (osc.order * w))
        assert abs(float(out.orbit.floquet_radius[i]) / rho - 1) < 1e-6


def test_spectral_radius_by_squaring_matches_eigenvalues():
    rng = np.random.default_rng(0)
    for scale in (0.3, 1.0, 2.0):
        a = rng.normal(size=(6, 6))
        a = scale * a / np.max(np.abs(np.linalg.eigvals(a)))
        assert abs(float(spectral_radius_of(jnp.asarray(a))) / scale - 1) < 1e-6
    rot = np.array([[0.0, -0.9], [0.9, 0.0]])  # complex pair, |mu| = 0.9
    assert abs(float(spectral_radius_of(jnp.asarray(rot))) - 0.9) < 1e-9


@pytest.fixture(scope="module")
def spur():
    return Mesh.build(baud_velex_pair(False))


def _model(mesh, formulation):
    return TorsionalModel.build(mesh, table1_relief("short"), formulation=formulation,
                                damping_ratio=0.03)


@pytest.fixture(scope="module")
def te_model(spur):
    return _model(spur, "te")


@pytest.mark.xdist_group("steady_te_sweep")
def test_monodromy_matches_stability_and_unstable_is_flagged(te_model):
    """The shooting's Phi (linearised full vector field, augmented solve) has the Floquet
    spectral radius of gearjax.dynamics.stability (homogeneous equation, separate solve) where
    the orbit keeps contact (with separation the contact law changes Phi). 1500 rad/s
    lies in a parametric instability zone of the linear te equation with this relief: its
    periodic orbit exists but is unstable (spectral_radius > 1), so the sweep does not
    report it: it continues that speed by a transient, which grows until the teeth
    separate and the contact law bounds it (contact_loss, min force exactly 0)."""
    speeds = np.array([300.0, 1000.0, 1500.0])  # (380, 753: the teeth separate)
    st = steady_sweep(te_model, speeds)
    rho_ref = spectral_radius(te_model, speeds)
    # the shooting's radius at every speed; at the speed it handed on (unstable) it stays
    # in the Fallback's stats, the transient's orbit there has none
    np.testing.assert_allclose(st.stats["first_spectral_radius"], rho_ref, rtol=1e-6)
    np.testing.assert_allclose(st.spectral_radius[:2], rho_ref[:2], rtol=1e-6)
    assert np.isnan(st.spectral_radius[2])
    assert st.stats["first_status"][2] == RESULTS.unstable
    assert rho_ref[-1] > 1.0 and np.all(rho_ref[:2] < 1.0)
    np.testing.assert_array_equal((st.solver == "transient"), [False, False, True])
    np.testing.assert_array_equal(st.contact_loss, [False, False, True])
    assert st.min_mesh_force_N[-1] == 0.0 and np.all(st.converged[:2])
    assert np.all(st.solver_ok) and np.all(np.isfinite(st.dynamic_factor))


def _agrees_with_long_transient(model, speeds, n_transient):
    rho = spectral_radius(model, speeds)
    assert np.all(rho**n_transient < 1e-9), rho
    long = eqx.filter_jit(eqx.filter_vmap(
        lambda m, w: simulate(m, w, n_transient_periods=n_transient, n_measured_periods=2,
                              rtol=1e-10, atol=1e-12), in_axes=(None, 0)))(model, jnp.asarray(speeds))
    st = steady_sweep(model, speeds, Shooting(measure_rtol=1e-10, measure_atol=1e-12))
    assert isinstance(st, SweepResult)
    cl = np.asarray(long.contact_loss)
    for name in ("max_mesh_force_N", "min_mesh_force_N", "dte_ptp_m"):
        a, b = getattr(st, name), np.asarray(getattr(long, name))
        scale = model.static_force_N if "force" in name else np.abs(b)
        ok = np.abs(a - b) <= 1e-6 * scale
        # contact loss (any formulation, with the contact law): continued by simulate,
        # not shot; same attractor
        assert np.all(ok | cl), (name, a, b)
    assert np.all(st.converged) and np.all(np.asarray(long.converged))
    np.testing.assert_array_equal(st.contact_loss, cl)
    assert np.all((st.solver == "transient") == cl)
    assert np.all(st.transient_periods[~(st.solver == "transient")] == 0)


@pytest.mark.slow
def test_te_agrees_with_long_transient(te_model):
    """Against simulate with 600 transient periods at rtol 1e-10 (Floquet radius <= 0.97
    at these speeds, checked with gearjax.dynamics.stability: the transient has decayed by
    rho^600 < 1e-9). At 753 rad/s (rho = 0.96) the automatic transient of sweep() is too
    short and reads converged=False; the shooting needs none."""
    _agrees_with_long_transient(te_model, np.array([380.0, 753.3]), 600)


@pytest.mark.slow
@pytest.mark.parametrize("formulation", ["perturbation", "reference"])
def test_sdof_agrees_with_long_transient(spur, formulation):
    """Same check for Eq. (47a) and the reference Eq. (16) (660 rad/s: contact loss,
    continued by simulate from the periodic orbit)."""
    _agrees_with_long_transient(_model(spur, formulation),
                                np.array([193.3, 380.0, 660.0, 1100.0]), 700)


# ---------------------------------------------------------------------- helical sdof
@pytest.fixture(scope="module")
def helical():
    return Mesh.build(baud_velex_pair(True))


def test_helical_te_agrees_with_long_transient(helical):
    """Helical pair (its sdof k_m was negative until the switching-event fix): shooting
    against a 120-period transient at 660 rad/s, near its main tooth critical speed
    (omega_n / z1 = 639 rad/s, dynamic factor 1.19). The decay of the transient is
    guaranteed in closed form: the te equation has the constant trace -2 zeta omega_n, so
    |mu_1 mu_2| = det Phi = exp(-2 zeta omega_n T) (Liouville, T = (2 pi / z1) / Omega),
    and the shooting's monodromy must show the complex pair |mu| = exp(-zeta omega_n T) =
    0.833 of a response outside the instability zones (the helical k(theta) varies
    little): 0.833^120 < 1e-9. (The stability-module radius: the slow test below.)"""
    model = _model(helical, "te")
    w = 660.0
    w_n = float(model.natural_frequency_rad_s())
    assert 600 < w_n / 26 < 700
    rho = math.exp(-0.03 * w_n * model.period_rad / w)
    n = 120
    assert rho**n < 1e-9
    st = steady_sweep(model, [w], Shooting(measure_rtol=1e-10, measure_atol=1e-12))
    assert st.spectral_radius[0] == pytest.approx(rho, rel=1e-8)
    long = eqx.filter_jit(lambda m, w: simulate(m, w, n_transient_periods=n,
                                                n_measured_periods=2, rtol=1e-10,
                                                atol=1e-12))(model, jnp.asarray(w))
    assert st.converged[0] and bool(long.converged)
    assert not st.contact_loss[0] and not bool(long.contact_loss)
    for name in ("max_mesh_force_N", "min_mesh_force_N", "dte_ptp_m"):
        a, b = float(getattr(st, name)[0]), float(getattr(long, name))
        scale = model.static_force_N if "force" in name else abs(b)
        assert abs(a - b) <= 1e-6 * scale, (name, a, b)
    assert st.dynamic_factor[0] > 1.1  # near resonance: the dynamics matter


@pytest.mark.slow
@pytest.mark.parametrize("formulation", ["te", "perturbation", "reference"])
def test_helical_sdof_agrees_with_long_transient(helical, formulation):
    """Helical pair, the three formulations from 193 to 1500 rad/s (Floquet radius 0.54 to
    0.92: rho^260 < 1e-9). Measured: forces agree to 1.4e-8 F_S, DTE peak-to-peak to 3.1e-7
    (reference at 1500 rad/s), no contact loss; ~35 s (te, perturbation) and ~60 s
    (reference) on 2 shared cores."""
    _agrees_with_long_transient(_model(helical, formulation),
                                np.array([193.3, 380.0, 660.0, 1100.0, 1500.0]), 260)


@pytest.mark.xdist_group("steady_te_sweep")  # one worker compiles the 3-speed steady sweep
def test_newton_into_free_flight_stops_at_once(te_model, monkeypatch):
    """At 381.1 and 394.1 rad/s (zeta 0.03, the contact-loss band) Newton's iterates leave
    the orbit's basin into states whose next period is wholly out of contact: the free
    rigid-body motion gives Phi the multiplier 1, so I - Phi is singular and the step
    infinite. That speed stops (ok False); under vmap its loop body still runs in lockstep
    with the others, and it used to integrate a period from the infinite iterate to
    max_steps (a 1,000-speed sweep over 10 min; 25 s now). Watched here: no period is
    ever started from a non-finite state, in any lane (the watch is on each period's start,
    ``steady._one_period``; a watch on every vector-field call cost ~6 s more).
    The sweep continues those speeds by a transient, which settles on a periodic orbit
    with contact loss."""
    import gearjax.dynamics.steady as steady_mod

    starts = []
    one_period = steady_mod._one_period

    def watched(model, omega, y_start, *args):
        jax.debug.callback(lambda f: starts.append(np.asarray(f)),
                           jnp.all(jnp.isfinite(y_start)))
        return one_period(model, omega, y_start, *args)

    monkeypatch.setattr(steady_mod, "_one_period", watched)
    speeds = np.array([300.0, 381.1, 394.1])
    run = eqx.filter_jit(eqx.filter_vmap(lambda w: periodic_state(te_model, w, max_steps=20_000)))
    ps = run(jnp.asarray(speeds))
    np.testing.assert_array_equal(np.asarray(ps.ok), [True, False, False])
    # vmap calls the callback once per lane: every lane, stopped ones too, at every start
    assert len(starts) >= 2 * speeds.size and len(starts) % speeds.size == 0
    assert all(bool(f) for f in starts)
    calm = run(jnp.full(speeds.size, speeds[0]))  # the same program, no lane in free flight
    assert np.all(np.asarray(calm.ok))
    np.testing.assert_allclose(ps.y0[0], calm.y0[0], rtol=1e-9, atol=1e-12)
    st = steady_sweep(te_model, speeds)
    np.testing.assert_array_equal((st.solver == "transient"), [False, True, True])
    np.testing.assert_array_equal(st.contact_loss, [False, True, True])
    assert np.all(st.converged) and np.all(st.min_mesh_force_N[1:] == 0.0)


def test_clear_errors(te_model):
    model = te_model
    with pytest.raises(SimulationError):
        steady_sweep(model, [])
    with pytest.raises(SimulationError):
        steady_sweep(model, [-1.0])
    with pytest.raises(SimulationError):
        steady_state(model, 300.0, Shooting(n_measured_periods=1))


# ---------------------------------------------------------------------- 3D rigs (slow)
def _rig(helical):

    # mesh_vectors="mean": the fast te excitation until the tabulated cell-vector
    # quasi-static solve lands
    return build_model(baud_velex_rig(helical), table1_relief("short"), formulation="te",
                                    damping_ratio=0.1, max_frequency_hz=6000.0,
                                    mesh_vectors="mean")


@pytest.mark.slow
@pytest.mark.parametrize("helical,n_transient", [(False, None), (True, 600)])
def test_3d_te_agrees_with_long_transient(helical, n_transient):
    """Both built-in rigs at 300 rad/s. The slowest mode (61.8 rad/s, weakly coupled to the
    mesh) decays like exp(-zeta w_min t) (structure data, independent of the shooting):
    spur: a transient long enough for exp(-zeta w_min t) < 1e-5, compared to 1e-5.
    Helical (one period costs ~750 steps): 600 periods, compared to the bound
    exp(-zeta w_min t) |metric(start) - metric(steady)| of the decaying free response
    (metric(start): simulate with no transient)."""
    model = _rig(helical)
    w = 300.0
    w_min = float(np.min(np.asarray(model.omega_r)))
    t_period = model.period_rad / w
    zeta = float(model.damping_ratio)
    if n_transient is None:
        n_transient = int(math.ceil(math.log(1e5) / (zeta * w_min * t_period)))
    decay = math.exp(-zeta * w_min * t_period * n_transient)
    run = eqx.filter_jit(lambda m, w, n: simulate(m, w, n_transient_periods=n,
                                                  n_measured_periods=2, rtol=1e-10,
                                                  atol=1e-12))
    long = run(model, jnp.asarray(w), n_transient)
    st = steady_sweep(model, [w], Shooting(measure_rtol=1e-10, measure_atol=1e-12))
    assert st.converged[0] and bool(long.solver_ok) and st.spectral_radius[0] < 1
    # the Floquet radius is the decay of the slowest mode over one period
    assert abs(st.spectral_radius[0] / math.exp(-zeta * w_min * t_period) - 1) < 1e-3
    start = None if not helical else run(model, jnp.asarray(w), 0)
    for name in ("max_mesh_force_N", "dte_ptp_m", "accel_ptp_m_s2"):
        a, b = float(getattr(st, name)[0]), float(getattr(long, name))
        if start is None:
            tol = 1e-5 * abs(b)
        else:
            tol = 1e-7 * abs(b) + 2 * decay * abs(float(getattr(start, name)) - a)
        assert abs(a - b) <= tol, (name, a, b, tol)


def test_loose_requested_accuracy_keeps_the_shooting_tight():
    """``--rtol 1e-4`` with the shooting (:meth:`gearjax.dynamics.steady.Shooting.for_transient`,
    shared by ``sweep`` and ``optimise``): the measured periods run at 1e-4 and the
    shooting keeps its own 1e-9, because the error of one period integration reaches the
    periodic start amplified by 1 / (1 - rho). Lightly damped oscillator at resonance
    (zeta 0.005, rho 0.969, amplification 32): the peak-to-peak within the requested 1e-4
    of the closed-form frequency response (measured 2.1e-5; the shooting integrated at
    1e-4 too: 1.1e-3)."""
    from gearjax.dynamics.sweep import Transient, tolerance_options

    osc = Oscillator(mass=2.0, stiffness=8e8, damping_ratio=0.005, amplitude=1e-5, order=26)
    w = osc.omega_n / osc.order
    shoot = Shooting.for_transient(Transient(**tolerance_options(1e-4)))
    assert shoot.measure_rtol == 1e-4 and shoot.rtol is None
    assert not hasattr(shoot, "transient_decay")  # the transient's own option
    out = eqx.filter_jit(lambda m: steady_state(m, w, shoot))(osc)
    ratio = float(out.result.dte_ptp_m) / (2 * abs(_frf(osc, w)) * osc.amplitude)
    assert bool(out.result.converged) and abs(ratio - 1) < 1e-4
