"""Every periodic solver of :mod:`gearjax.dynamics.solvers` gives the same steady orbit of
the linear te and perturbation formulations while contact holds (as diffrax's tests run
every solver on one problem): :class:`Transient` (diffrax from the quasi-static start,
automatic transient), :class:`Shooting` (Newton on the periodicity residual) and
:class:`HarmonicBalance` (the frequency domain, no integration) are three independent
methods, each compared here with a tightly converged shooting reference to its own
accuracy, on the sdof model and on the 3D rig."""

from __future__ import annotations

import numpy as np
import pytest

from gearjax import Mesh, baud_velex_pair, table1_relief
from gearjax.dynamics.harmonic_sweep import HarmonicBalance
from gearjax.dynamics.orbit import RESULTS, Orbit, measure, status_message
from gearjax.dynamics.solvers import AbstractPeriodicSolver, Fallback
from gearjax.dynamics.steady import Shooting
from gearjax.models.formulations import formulation_of
from gearjax.dynamics.sweep import Auto, Transient, sweep, tolerance_options
from gearjax.models.torsional import TorsionalModel
from gearjax.rigs import baud_velex_rig, build_model

# each solver at its default accuracy, and the tolerance on the dynamic factor it meets
# (the transient's periodicity test stops at 1e-3 of the extrema's change per period,
# extrapolated; the harmonic truncation at rtol 1e-6; the shooting at rtol 1e-9)
SOLVERS = {
    "transient": (Transient(), 1e-4),
    "shooting": (Shooting(), 1e-6),
    "harmonic": (HarmonicBalance(), 1e-5),
}
REFERENCE = Shooting(rtol=1e-11, atol=1e-13, measure_rtol=1e-11, measure_atol=1e-13)


@pytest.fixture(scope="module")
def sdof():
    mesh = Mesh.build(baud_velex_pair(False))
    return {f: TorsionalModel.build(mesh, table1_relief("short"), formulation=f,
                                    damping_ratio=0.1) for f in ("te", "perturbation")}


def _agree(model, solver, tol, speeds):
    ref = sweep(model, speeds, REFERENCE)
    res = sweep(model, speeds, solver)
    assert np.all(ref.converged) and not np.any(ref.contact_loss)  # the linear regime
    assert np.all(res.converged) and not np.any(res.contact_loss)
    assert np.all(res.status == RESULTS.successful)
    np.testing.assert_allclose(res.dynamic_factor, ref.dynamic_factor, rtol=0, atol=tol)
    np.testing.assert_allclose(res.dte_ptp_m, ref.dte_ptp_m, rtol=10 * tol)
    # a mesh-order amplitude (the fundamental) agrees like the peak
    f_s = float(model.static_force_N)
    np.testing.assert_allclose(res.mesh_force_orders_N[:, 0], ref.mesh_force_orders_N[:, 0],
                               rtol=0, atol=tol * f_s)
    return res


@pytest.mark.parametrize("name", SOLVERS)
@pytest.mark.parametrize("formulation", ["te", "perturbation"])
def test_every_solver_gives_the_linear_orbit_sdof(sdof, name, formulation):
    solver, tol = SOLVERS[name]
    res = _agree(sdof[formulation], solver, tol, np.array([300.0, 520.0]))
    assert set(res.solver) == {"harmonic" if name == "harmonic" else
                               "steady" if name == "shooting" else "transient"}


@pytest.mark.slow  # three 3D programs compile (~1 min on 2 cores); sdof above in the default run
@pytest.mark.parametrize("name", SOLVERS)
def test_every_solver_gives_the_linear_orbit_3d(name):
    model = build_model(baud_velex_rig(False), table1_relief("short"), formulation="te",
                        damping_ratio=0.1, max_frequency_hz=6000.0, cells_per_line=4,
                        n_table=64)
    solver, tol = SOLVERS[name]
    _agree(model, solver, tol, np.array([500.0]))


def test_fallback_hands_on_only_what_the_first_did_not_solve(sdof):
    """Near the tooth critical speed the sdof te orbit loses contact: the frequency domain
    keeps the speeds where its linear orbit is the model's, the transient takes the rest,
    and each speed says which solver gave it; the composition is itself a solver."""
    model = sdof["te"]
    speeds = np.array([400.0, 700.0])
    both = sweep(model, speeds, Fallback(HarmonicBalance(), Transient()))
    alone = sweep(model, speeds, Transient())
    lost = alone.contact_loss
    assert lost.tolist() == [False, True]
    assert both.solver.tolist() == ["harmonic", "transient"]
    np.testing.assert_allclose(both.max_mesh_force_N, alone.max_mesh_force_N, rtol=1e-4)
    # the frequency domain says why it handed 700 rad/s on; the transient solved both
    first = sweep(model, speeds, HarmonicBalance())
    assert first.status.tolist() == [RESULTS.successful, RESULTS.contact_lost]
    assert both.status.tolist() == alone.status.tolist() == [RESULTS.successful] * 2
    # and the Fallback keeps the first solver's reason at every speed
    assert both.stats["first_status"].tolist() == first.status.tolist()
    # where the first solved every speed, the same record (one result layout)
    held = sweep(model, speeds[:1], Fallback(HarmonicBalance(), Transient()))
    assert held.solver.tolist() == ["harmonic"]
    assert held.stats["first_status"].tolist() == [RESULTS.successful]
    np.testing.assert_array_equal(held.stats["first_spectral_radius"], held.spectral_radius)
    assert isinstance(Fallback(Shooting(), Transient()), AbstractPeriodicSolver)


def test_auto_is_a_rule_of_the_model():
    """Auto reads what the model declares and how many speeds it is asked for
    (benchmarks/results/auto.md): te, linear while contact holds, of a speed-scaled
    3D-sized model swept over enough speeds to repay the frequency domain's compilation
    goes to the frequency domain with the transient for the speeds it does not solve; the
    reference formulation, the sdof model, a short sweep and a model already started on its
    periodic orbit (the 3D perturbation model) take the transient (measured cheapest),
    started on the periodic orbit where the model's initial state already is one."""
    from gearjax.dynamics.sweep import FREQUENCY_DOMAIN_MIN_SPEEDS, FREQUENCY_DOMAIN_MIN_STATES

    class Fake:  # the capabilities Auto reads
        def __init__(self, formulation="reference", periodic_start=False, scaled=True,
                     state_size=292):
            self.formulation, self.periodic_start = formulation_of(formulation), periodic_start
            self.speed_scaled_state, self.state_size = scaled, state_size

    many, few = FREQUENCY_DOMAIN_MIN_SPEEDS, FREQUENCY_DOMAIN_MIN_SPEEDS - 1
    assert Auto(rtol=1e-9).choose(Fake(), many) == Transient(**tolerance_options(1e-9))
    assert Auto().choose(Fake(), many) == Transient()
    chosen = Auto().choose(Fake(periodic_start=True), many)
    assert chosen.n_transient_periods == 0 and chosen.start == "initial"
    for form in ("te", "perturbation"):
        assert Auto(rtol=1e-9).choose(Fake(form), many) == Fallback(
            HarmonicBalance(rtol=1e-9), Transient(**tolerance_options(1e-9)))
        assert Auto().choose(Fake(form), few) == Transient()  # compilation not repaid
        periodic = Auto().choose(Fake(form, periodic_start=True), many)
        assert periodic.n_transient_periods == 0 and periodic.start == "initial"
        assert Auto().choose(Fake(form, scaled=False), many) == Transient()
        assert Auto().choose(Fake(form, state_size=2), many) == Transient()  # the sdof model
        assert isinstance(Auto().choose(
            Fake(form, state_size=FREQUENCY_DOMAIN_MIN_STATES), many), Fallback)


def test_sweep_refuses_a_string_solver_and_a_boolean_progress(sdof):
    """Solvers and meters are objects: the strings and booleans of earlier versions get a
    one-line error naming the argument, before anything compiles."""
    from gearjax.dynamics.steady import steady_sweep
    from gearjax.errors import SimulationError

    with pytest.raises(SimulationError, match="solver"):
        sweep(sdof["te"], [300.0], "transient")
    for run in (lambda: sweep(sdof["te"], [300.0], progress=False),
                lambda: steady_sweep(sdof["te"], [300.0], progress=True)):
        with pytest.raises(SimulationError, match="progress meter"):
            run()


def test_the_shooting_orbit_and_its_measure(sdof):
    """:meth:`Shooting.orbit` is the periodic orbit: one period from its state returns to
    it, its Floquet radius is Liouville's ``exp(-zeta omega_n T)`` (sdof: the trace of
    df/dy is ``-2 zeta omega_n / Omega``, complex multipliers), its status ``successful``;
    :func:`measure` of that orbit gives the shooting sweep's metrics (to the round-off of
    another compiled program), and a step
    limit too small to integrate a period gives ``integration_failed``, not a NaN alone."""
    import math

    import equinox as eqx
    import jax.numpy as jnp

    model, w = sdof["te"], 300.0
    shoot = Shooting()
    orbit = eqx.filter_jit(lambda m: shoot.orbit(m, w))(model)
    assert isinstance(orbit, Orbit) and int(orbit.status) == RESULTS.successful
    t_period = float(model.period_rad) / w
    rho = math.exp(-0.1 * float(model.natural_frequency_rad_s()) * t_period)
    assert abs(float(orbit.floquet_radius) / rho - 1) < 1e-6
    metrics = eqx.filter_jit(lambda m, o: measure(m, o, shoot.measured()))(model, orbit)
    swept = sweep(model, [w], shoot)
    assert float(metrics.max_mesh_force_N) == pytest.approx(float(swept.max_mesh_force_N[0]),
                                                            rel=1e-9)
    from gearjax.dynamics.steady import orbit_of, periodic_state

    ps = eqx.filter_jit(lambda m: periodic_state(m, w, max_steps=2))(model)
    bad = orbit_of(model, w, ps, 1e-10)
    assert int(bad.status) == RESULTS.integration_failed
    assert not bool(jnp.all(jnp.isfinite(bad.state)))
    assert "integration" in status_message(bad.status)
