"""Floquet stability of the TE-based equation (Eq. (20)) with a time-varying stiffness.

Perfect spur gears with the uniform stiffness law have an exact square-wave mesh stiffness:
two tooth pairs (stiffness k2) for (eps_alpha - 1) of each mesh period from the engagement
at theta = 0, one pair (k1) for the rest. The monodromy matrix of
``m x_tt + c x_t + k(t) x = 0`` is then a product of two matrix exponentials, written here
with scipy.linalg.expm, independently of gearjax's integration.
"""

from __future__ import annotations

import math

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.linalg import expm

from gearjax import Mesh, ToothModifications, baud_velex_pair, table1_relief
from gearjax.models.base import without_contact_law
from gearjax.models.torsional import TorsionalModel
from gearjax.dynamics.simulate import SimulationError, simulate
from gearjax.dynamics.stability import floquet_multipliers, monodromy, spectral_radius

ZETA = 0.02


@pytest.fixture(scope="module")
def square_wave():
    pair = baud_velex_pair(False)
    mesh = Mesh.build(pair, "uniform")
    model = TorsionalModel.build(mesh, ToothModifications.none(), formulation="te",
                                 damping_ratio=ZETA)
    p = pair.mesh_period_rad
    eps = pair.transverse_contact_ratio
    k2 = float(mesh.stiffness(0.5 * (eps - 1) * p))
    k1 = float(mesh.stiffness(0.5 * (eps - 1) * p + 0.5 * p))
    assert k2 == pytest.approx(2 * k1)
    return model, pair, k1, k2


def _expm_multipliers(pair, k1, k2, inertias, omega):
    """Floquet multipliers of m x_tt + c x_t + k(t) x = 0 over one mesh period (in time)."""
    j1, j2 = inertias
    rb1, rb2 = pair.base_radii_m
    m = j1 * j2 / (j1 * rb2**2 + j2 * rb1**2)
    eps = pair.transverse_contact_ratio
    k_m = (eps - 1) * k2 + (2 - eps) * k1
    c = 2 * ZETA * math.sqrt(k_m * m)
    t_mesh = pair.mesh_period_rad / omega

    def a(k):
        return np.array([[0.0, 1.0], [-k / m, -c / m]])

    phi = expm(a(k1) * (2 - eps) * t_mesh) @ expm(a(k2) * (eps - 1) * t_mesh)
    mu = np.linalg.eigvals(phi)
    return mu[np.argsort(-np.abs(mu))], k_m, m


def test_square_wave_multipliers_match_matrix_exponentials(square_wave):
    model, pair, k1, k2 = square_wave
    inert = tuple(np.asarray(model.inertias_kg_m2))
    speeds = [600.0, 850.0, 1000.0, 1700.0]  # stable, 2nd zone, stable, principal zone
    rho = spectral_radius(model, speeds)
    for omega, r in zip(speeds, rho):
        mu_ref, k_m, _ = _expm_multipliers(pair, k1, k2, inert, omega)
        assert float(model.mean_stiffness_N_per_m()) == pytest.approx(k_m, rel=1e-10)
        mu = floquet_multipliers(model, omega)
        # multipliers are invariant under the (diagonal) state scaling: compare directly
        np.testing.assert_allclose(np.sort_complex(mu), np.sort_complex(mu_ref), atol=1e-8)
        assert r == pytest.approx(np.abs(mu_ref).max(), abs=1e-8)
    assert rho[0] < 1 and rho[2] < 1 and rho[1] > 1 and rho[3] > 1


def test_growth_inside_principal_zone_and_decay_outside(square_wave):
    """Time integration of Eq. (20): the dynamic response grows by rho per period inside the
    principal instability zone (mesh frequency near 2 omega_n) and converges outside."""
    model, pair, k1, k2 = square_wave
    inert = tuple(np.asarray(model.inertias_kg_m2))
    speeds = np.linspace(1550.0, 1850.0, 31)
    rho_ref = np.array([np.abs(_expm_multipliers(pair, k1, k2, inert, w)[0]).max() for w in speeds])
    w_bad = float(speeds[np.argmax(rho_ref)])
    rho = float(spectral_radius(model, [w_bad])[0])
    assert rho > 1.1
    run = eqx.filter_jit(eqx.filter_vmap(
        lambda m, w: simulate(m, w, n_transient_periods=80, n_measured_periods=4,
                              save_signals=True), in_axes=(None, 0)))
    # Eq. (20) as printed (linear, no contact law): the force may turn tensile and grow
    res = run(without_contact_law(model), jnp.asarray([w_bad, 1000.0]))
    # per-period peak-to-peak of DTE after 80 periods: the growing Floquet solution dominates
    dte = np.asarray(res.signals.dte_m[0]).reshape(4, -1)
    ptp = np.ptp(dte, axis=1)
    growth = ptp[1:] / ptp[:-1]
    np.testing.assert_allclose(growth, rho, rtol=1e-3)
    assert not bool(res.converged[0])
    # outside: rho = 0.90 per period, 0.9^80 = 2e-4 below the convergence threshold 1e-3
    assert bool(res.converged[1]) and float(spectral_radius(model, [1000.0])[0]) < 0.91
    # with the contact law (the model's default) the teeth separate and the growth stops:
    # the force never turns tensile and stays within a few times the static force
    bounded = run(model, jnp.asarray([w_bad]))
    assert float(res.min_mesh_force_N[0]) < 0.0 < float(bounded.contact_loss[0])
    assert float(bounded.min_mesh_force_N[0]) == 0.0
    assert float(bounded.max_mesh_force_N[0]) < 10.0 * float(model.static_force_N)


def test_perturbation_multipliers_are_constant_coefficient(square_wave):
    """Eq. (47a) has constant stiffness: |mu| = exp(-zeta omega_n T_mesh)."""
    model, pair, _, _ = square_wave
    pert = TorsionalModel.build(model.mesh, model.mods, formulation="perturbation",
                                damping_ratio=ZETA)
    w_n = float(pert.natural_frequency_rad_s())
    for omega in (500.0, 1700.0):
        mu = floquet_multipliers(pert, omega)
        expected = math.exp(-ZETA * w_n * pair.mesh_period_rad / omega)
        np.testing.assert_allclose(np.abs(mu), expected, rtol=1e-8)


def test_relief_model_and_errors():
    """Gear model with Table 1 short relief: vmapped spectral radius equals the per-speed
    multipliers, whose product obeys Liouville's formula (independent of k(theta)): the
    trace of ``m x'' + c x' + k(t) x = 0`` is -c/m = -2 zeta omega_n whatever the relief,
    so mu_1 mu_2 = det Phi = exp(-2 zeta omega_n T) with T = P / Omega (P the period in
    theta); bad speeds and models without a linear part give clear errors."""
    model = TorsionalModel.build(Mesh.build(baud_velex_pair(False)), table1_relief("short"),
                                 formulation="te", damping_ratio=0.03)
    speeds = [400.0, 1550.0]
    rho = spectral_radius(model, speeds)
    omega_n = float(model.natural_frequency_rad_s())
    for w, r in zip(speeds, rho):
        mu = floquet_multipliers(model, w)
        assert r == pytest.approx(np.abs(mu).max(), rel=1e-12)
        # Liouville: measured |mu_1 mu_2 / exp(-2 zeta omega_n T) - 1| = 6.0e-11 (400 rad/s,
        # complex pair) and 5.7e-12 (1550 rad/s, real pair) with the monodromy's rtol 1e-10;
        # 1e-8 leaves 100x (zeta 1e-5 relative off moves it by 7e-6)
        liouville = math.exp(-2 * 0.03 * omega_n * float(model.period_rad) / w)
        assert abs(np.prod(mu) / liouville - 1) < 1e-8, (w, np.prod(mu), liouville)
    assert rho[0] < 1 < rho[1]
    with pytest.raises(SimulationError, match="speeds_rad_s"):
        spectral_radius(model, [100.0, -1.0])
    with pytest.raises(SimulationError, match="homogeneous_vector_field"):
        monodromy(object(), 100.0)
