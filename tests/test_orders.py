"""Mesh-order amplitudes (gearjax.dynamics.orders) against independent results.

* the order map alone: a signal of known Fourier series (harmonics of the excitation
  period, steps at arbitrary angles, one pair of steps closer than the one-sided offset,
  one step at the period's start) -- exact but for the one-sided offset delta of the jump
  points (a step there reads the smooth part's slope times 2 delta), where a plain DFT
  of the uniform samples is off by O(step / N);
* the sdof perturbation formulation, Eq. (47a), Table 1 long relief (NLTE and its
  NLTE'' forcing active), contact held: DTE orders against the closed-form receptance
  ``H(w) = 1 / (k_m cos^2 b_b - m_eq w^2 + i c w)`` applied to the forcing harmonics
  ``k_m cos^2 b_b X_S,k + kappa m_eq w_k^2 NLTE_k`` (``x_S = TE_S - NLTE``; Fourier
  coefficients by a plain NumPy FFT of quasi_static() samples, 65536 per mesh period, not
  of the model's tables; k_m, m_eq, kappa, F_S rebuilt from them and the inertias and base
  radii), ``DTE_k = X_k + NLTE_k``; mesh-force orders against the FFT of
  ``F_S + k_S cos b_b (x - x_S)`` (Eq. (24)) with x rebuilt from all its closed-form
  harmonics.
"""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np
import pytest

from gearjax import Mesh, baud_velex_pair, table1_relief
from gearjax.dynamics.metrics import JUMP_SIDE, output_grid
from gearjax.dynamics.orders import mesh_order_amplitudes, order_matrix
from gearjax.dynamics.sweep import sweep
from gearjax.gears.quasistatic import quasi_static
from gearjax.models.torsional import TorsionalModel


def test_order_map_is_exact_for_steps_and_harmonics():
    period = 2 * (2 * math.pi / 26)  # two mesh periods (a pinion revolution's layout)
    a, b = 0.13 * period, 0.61 * period
    jumps = [0.0, a, a + 1e-12, b, 0.999999 * period]  # 0 and ~P: jumps without a step

    def f(t):
        u = np.mod(t, period)
        nu = 2 * math.pi / period
        return (3 * np.cos(2 * nu * u + 0.3) + 0.5 * np.sin(6 * nu * u)
                + 0.7 * np.cos(7 * nu * u) + 2.0 * ((u >= a) & (u < b)))

    m = 2 * np.arange(1, 6)  # mesh orders 1..5 = harmonics 2, 4, ..., 10 of the period
    step = 2.0 * (np.exp(-2j * np.pi * m * a / period) - np.exp(-2j * np.pi * m * b / period)) \
        / (2j * np.pi * m)
    exact = np.abs(step)
    exact[0] = abs(step[0] + 1.5 * np.exp(0.3j))  # 3 cos(2 nu u + 0.3): c_2 = 1.5 e^{0.3 i}
    exact[2] = abs(step[2] - 0.25j)  # 0.5 sin(6 nu u): c_6 = -0.25 i
    exact *= 2.0
    for n in (64, 128):
        grid = output_grid(period, n, jumps, 1)
        vals = f(grid.offsets)
        got = np.asarray(mesh_order_amplitudes(order_matrix(period, period / 2, n, jumps),
                                               jnp.asarray(vals)[None, :, None]))[0]
        # bound: 5 jumps, each read with an error <= 2 delta max|f'| (max|f'| <= 13.9 nu),
        # entering c_m with a weight <= 1/2 + 1/(2 pi); amplitudes 2 |c_m|
        bound = 2 * 5 * 2 * JUMP_SIDE * period * 13.9 * (2 * math.pi / period) * 0.66
        np.testing.assert_allclose(got, exact, rtol=0, atol=bound)
        plain = 2 * np.abs(np.fft.fft(vals[grid.samples]) / n)[m]
        assert np.max(np.abs(plain - exact)) > 1e3 * bound  # what the step correction removes


def _closed_form_orders(model, omega, zeta, n_per_mesh=65536):
    """(DTE orders (m), F_D orders (N), min F_D (N), k_m (N/m)) of the linear Eq. (47a)
    orbit, from inputs rebuilt independently of the model's excitation tables and derived
    constants (as tests/test_dynamics_sdof.py::_closed_form_perturbation): x_S, k_S and NLTE
    by quasi_static() at the samples, F_S = C_m0 / (Rb1 cos b_b), m_eq and kappa from the
    inertias and base radii, and k_m the mean of the sampled k_S with its steps at the
    switching angles taken out as sawtooths of exact (zero) mean, so that the rectangle
    rule sees a continuous function (error O(n^-2) at the kinks instead of O(step / n))."""
    mesh, mods = model.mesh, model.mods
    pair = mesh.pair
    period = model.period_rad
    n_mesh = round(period / pair.mesh_period_rad)
    n = n_per_mesh * n_mesh
    theta = np.arange(n) * (period / n)
    rb1, rb2 = pair.base_radii_m
    cb = math.cos(pair.base_helix_angle_rad)
    f_s = float(model.pinion_torque_Nm) / (rb1 * cb)
    qs = quasi_static(mesh, mods, jnp.asarray(theta), f_s)
    x_s, nlte = np.asarray(qs.x_s_m), np.asarray(qs.nlte_m)
    k_s = np.asarray(qs.loaded_stiffness_N_per_m)
    jumps = np.asarray(model.jump_thetas, dtype=float)
    sides = quasi_static(mesh, mods, jnp.asarray(np.concatenate([jumps - 1e-9 * period,
                                                                  jumps + 1e-9 * period])), f_s)
    k_j = np.asarray(sides.loaded_stiffness_N_per_m)
    step = k_j[jumps.size:] - k_j[:jumps.size]
    saw = 0.5 - np.mod((theta[:, None] - jumps) / period, 1.0)
    k_m = float(np.mean(k_s - saw @ step))
    j1, j2 = np.asarray(model.inertias_kg_m2)
    m_eq = j1 * j2 / (j1 * rb2**2 + j2 * rb1**2)
    kappa = j2 / (rb2**2 * m_eq) if model.nlte_reaction == "pinion" else 1.0
    stiff = k_m * cb**2
    c = 2 * zeta * math.sqrt(stiff * m_eq)
    w = np.fft.fftfreq(n, 1.0 / n) * (2 * math.pi / period) * omega  # rad/s
    xs_h, nl_h = np.fft.fft(x_s) / n, np.fft.fft(nlte) / n
    x_h = (stiff * xs_h + kappa * m_eq * w**2 * nl_h) / (stiff - m_eq * w**2 + 1j * c * w)
    x = np.real(np.fft.ifft(x_h * n))
    f_d = f_s + k_s * cb * (x - x_s)
    k = n_mesh * np.arange(1, 6)
    return 2 * np.abs(x_h + nl_h)[k], 2 * np.abs(np.fft.fft(f_d) / n)[k], f_d.min(), k_m


def test_sdof_perturbation_orders_against_closed_form_receptance():
    """Below resonance (300 rad/s) and at the order-2 resonance (397 rad/s, omega_n /
    (2 Z1)); damping 0.1, so contact holds (checked on the closed form). Tolerances: DTE
    1e-6 of its largest order (the integration's rtol 1e-7 on a continuous signal); mesh
    force 2e-4 of its largest order: F_D jumps with k_S and also kinks there, and the
    kinks are left to the DFT, whose aliasing error falls like N^-2 (measured at 397 rad/s,
    largest error over orders 1-5 / largest order: 2.3e-4, 4.9e-5, 7e-6 at 64, 128, 256
    samples per mesh period; 128 here, simulate's default). Measured with the independent
    inputs of _closed_form_orders: DTE 7.6e-7 / 1.9e-7, force 1.4e-4 / 4.9e-5 at 300 / 397
    rad/s (the same as with the model's own tables)."""
    model = TorsionalModel.build(Mesh.build(baud_velex_pair(False)), table1_relief("long"),
                                 formulation="perturbation", damping_ratio=0.1)
    assert model.nlte_terms
    speeds = np.array([300.0, 397.0])
    res = sweep(model, speeds)
    assert np.all(res.converged) and res.dte_orders_m.shape == (2, 5)
    for i, omega in enumerate(speeds):
        dte, force, f_min, k_m = _closed_form_orders(model, omega, 0.1)
        # the model's k_m (mean of its Hermite table) against the step-corrected sample mean:
        # measured 8e-13 relative (the plain sample mean is off by 2.3e-6)
        assert k_m == pytest.approx(float(model.mean_stiffness_N_per_m()), rel=1e-9)
        assert f_min > 0 and not res.contact_loss[i]  # the linear orbit is the model's
        np.testing.assert_allclose(res.dte_orders_m[i], dte, rtol=0, atol=1e-6 * dte.max())
        np.testing.assert_allclose(res.mesh_force_orders_N[i], force, rtol=0,
                                   atol=2e-4 * force.max())
    # the resonance of order 2 at 397 rad/s: order 2 dominates there, not at 300 rad/s
    assert np.argmax(res.dte_orders_m[1]) == 1 and np.argmax(res.dte_orders_m[0]) != 1
    assert np.all(np.isnan(res.accel_orders_m_s2))  # the sdof model has no acceleration


def test_pure_sine_te_file_orders_against_closed_form_receptance():
    """A TE file (Section 6.2) holding a pure sine TE_S = TE0 + a sin(z1 theta) and a
    constant mesh stiffness k0, no NLTE: Eq. (20) is then linear time-invariant, so mesh
    order 1 of the DTE is ``|H(z1 Omega)| k0 cos^2 b_b a`` with the closed-form receptance
    ``H(w) = 1 / (k0 cos^2 b_b - m_eq w^2 + i c w)``, mesh order 1 of the force is
    ``k0 cos b_b |X_1 - a|`` (Eq. (24)), and orders 2-5 vanish. Below (300 rad/s) and
    near (0.9 omega_n / z1) the tooth critical speed, damping 0.1 (contact holds).
    Tolerance 1e-6 of the DTE's order 1 (the integration's rtol 1e-7 and the file's cubic
    Hermite interpolation at 256 rows per mesh period, O(h^4), ~1e-9 here), carried
    through Eq. (24) for the force."""
    from gearjax.excitation.te_file import TETable

    mesh = Mesh.build(baud_velex_pair(False))
    base = TorsionalModel.build(mesh, table1_relief("short"), formulation="te", damping_ratio=0.1)
    z1, period = mesh.pair.z1, base.mesh_period_rad
    k0, a = float(base.mean_stiffness_N_per_m()), 1e-6
    theta = np.arange(256) * (period / 256)
    table = TETable.from_samples(theta, 12e-6 + a * np.sin(z1 * theta),
                                 stiffness_N_per_m=np.full(theta.size, k0),
                                 mesh_period_rad=period)
    model = base.with_te(table)
    assert not model.nlte_terms and float(model.mean_stiffness_N_per_m()) == pytest.approx(k0)
    m_eq, cb = float(model.equivalent_mass_kg), model.cos_bb
    stiff = k0 * cb**2
    c = 2 * 0.1 * math.sqrt(stiff * m_eq)
    speeds = np.array([300.0, 0.9 * math.sqrt(stiff / m_eq) / z1])
    res = sweep(model, speeds)
    assert np.all(res.converged) and not np.any(res.contact_loss)
    for i, omega in enumerate(speeds):
        w = z1 * omega
        x1 = stiff * a / (stiff - m_eq * w**2 + 1j * c * w)  # order 1 of x, phase of TE_S
        dte = np.array([abs(x1), 0, 0, 0, 0])
        force = np.array([k0 * cb * abs(x1 - a), 0, 0, 0, 0])
        np.testing.assert_allclose(res.dte_orders_m[i], dte, rtol=0, atol=1e-6 * dte[0])
        # F_D's order 1 is k0 cos b_b (X_1 - a): X_1's error (1e-6 |X_1|) carried through
        np.testing.assert_allclose(res.mesh_force_orders_N[i], force, rtol=0,
                                   atol=1e-6 * k0 * cb * abs(x1))
    assert res.dte_orders_m[1, 0] > 2 * a  # near resonance: amplified
