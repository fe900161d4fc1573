"""The contact algorithm of the TE-based formulations (paper Section 6.2, Eqs. (20), (42),
(47a), (48a); :func:`gearjax.gears.contact.te_contact`).

Independent checks:

* the law itself: compressive linear force kept bit for bit, tensile force cut to zero;
* where contact holds the equations are today's linear ones, bit for bit (vector fields on
  states around the quasi-static solution, and one integration);
* energy balance through an impact: perfect spur teeth, uniform cell stiffness, no damping:
  between two stiffness jumps the te equation is conservative with the potential of a
  one-sided spring, ``E = m_eq Omega^2 x'^2 / 2 + k max(0, x)^2 / 2 - F_t x``, written here
  from the mesh stiffness and the inertias, and E must survive a separation and the impact
  that ends it;
* the Section 6.3.1 sdof case through the main critical speed (zeta 0.03, short relief): no
  tensile force in any formulation; peaks close to the reference, te closer than the
  perturbation one (paper Section 6.3); the issue's criterion was within 2x (they were
  14x: 52.6 against 3.6, a parametrically unstable linear equation).
"""

from __future__ import annotations

import diffrax
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from gearjax import Mesh, ToothModifications, baud_velex_pair, quasi_static, table1_relief
from gearjax.dynamics.sweep import sweep
from gearjax.gears.contact import te_contact
from gearjax.models.torsional import TorsionalModel


def test_law_keeps_compression_and_cuts_tension():
    f_eq = jnp.asarray([5.0, 1e-300, 0.0, -3.0])
    f_loaded = jnp.asarray([6.0, -1.0, 2.0, 4.0])
    cut, f_d = te_contact(f_eq, f_loaded)
    np.testing.assert_array_equal(np.asarray(cut), [0.0, 0.0, 0.0, -3.0])
    np.testing.assert_array_equal(np.asarray(f_d), [6.0, 0.0, 0.0, 0.0])


@pytest.fixture(scope="module")
def spur():
    return Mesh.build(baud_velex_pair(False))


@pytest.mark.parametrize("formulation", ["te", "perturbation"])
def test_linear_equations_unchanged_where_contact_holds(spur, formulation):
    """States within half the mean static approach of the quasi-static one keep the mesh
    compressive: the vector field is the linear one bit for bit, and an integration agrees
    to 1e-9; far below it the teeth separate and the mesh force is zero."""
    m = TorsionalModel.build(spur, table1_relief("short"), formulation=formulation,
                             damping_ratio=0.05)
    omega = 500.0
    rng = np.random.default_rng(0)
    th = jnp.asarray(rng.uniform(0, m.period_rad, 64))
    y_s = jax.vmap(lambda t: m.initial_state(omega, t))(th)
    dy = jnp.asarray(rng.uniform(-0.4, 0.4, (64, 2)))
    for sign, keep in ((1.0, True), (-1.0, False)):
        y = y_s + dy if keep else y_s - jnp.abs(dy) - 2.0  # 2 x_ref below: separated
        f_c = jax.vmap(lambda t, yy: m.vector_field(t, yy, omega))(th, y)
        f_l = jax.vmap(lambda t, yy: m.vector_field(t, yy, omega, contact=False))(th, y)
        force = jax.vmap(lambda t, yy: m.outputs(t, yy, omega).mesh_force_N)(th, y)
        if keep:
            np.testing.assert_array_equal(np.asarray(f_c), np.asarray(f_l))
            assert np.all(np.asarray(force) > 0)
        else:
            assert np.all(np.asarray(f_c[:, 1]) != np.asarray(f_l[:, 1]))
            np.testing.assert_array_equal(np.asarray(force), 0.0)
    # one integration over 4 mesh periods from the quasi-static start at a speed well
    # below the critical one (no separation on the way): identical
    omega = 250.0
    term = lambda field: diffrax.ODETerm(field)  # noqa: E731
    ts = jnp.linspace(0.0, 4 * m.mesh_period_rad, 9)

    # the jumps of every one of the 4 periods (steps that cross a jump by error control
    # alone amplify the programs' round-off into different step sequences)
    jumps = np.sort((np.asarray(m.jump_thetas)[None, :]
                     + m.period_rad * np.arange(4)[:, None]).ravel())

    def run(contact):
        sol = diffrax.diffeqsolve(
            term(lambda t, y, a: m.vector_field(t, y, a, contact=contact)), diffrax.Tsit5(),
            0.0, ts[-1], None, m.initial_state(omega), args=omega,
            saveat=diffrax.SaveAt(ts=ts), max_steps=100_000,
            stepsize_controller=diffrax.PIDController(rtol=1e-12, atol=1e-14,
                                                      jump_ts=jnp.asarray(jumps)))
        return np.asarray(sol.ys)

    # (XLA may fuse the two programs' arithmetic differently: round-off, then the step
    # sequences differ at the integration tolerance)
    ys = run(True)
    np.testing.assert_allclose(ys, run(False), rtol=1e-9, atol=1e-12)
    assert np.all(np.asarray(jax.vmap(lambda t, y: m.outputs(t, y, omega).mesh_force_N)(ts, ys)) > 0)


def test_energy_balance_through_an_impact():
    """Perfect spur teeth, uniform stiffness, zeta = 0, te: within the longest interval of
    constant stiffness the mesh is the one-sided spring ``F = k max(0, x)`` (the static
    approach ``x_S = F_S / k`` makes ``F_S + k (x - x_S) = k x``). Started with a
    velocity that throws the teeth apart, the energy is conserved through the separation
    and the impact that ends it."""
    pair = baud_velex_pair(False)
    mesh = Mesh.build(pair, "uniform")
    torque = 254.8
    m = TorsionalModel.build(mesh, ToothModifications.none(), formulation="te",
                             damping_ratio=0.0, pinion_torque_Nm=torque)
    jumps = np.sort(np.asarray(m.jump_thetas))
    edges = np.concatenate([jumps, [jumps[0] + m.period_rad]])
    j = int(np.argmax(np.diff(edges)))
    a, b = edges[j] + 1e-9, edges[j + 1] - 1e-9
    # independent data: stiffness of the interval, equivalent mass, tangential load
    k = float(quasi_static(mesh, ToothModifications.none(), jnp.asarray([0.5 * (a + b)]),
                           torque / pair.base_radii_m[0]).loaded_stiffness_N_per_m[0])
    j1, j2 = np.asarray(m.inertias_kg_m2)
    rb1, rb2 = pair.base_radii_m
    m_eq = j1 * j2 / (j1 * rb2**2 + j2 * rb1**2)
    f_t = torque / rb1
    omega = 40.0
    r = float(m.omega_n) / omega  # state scaling of the model (module docstring)
    x_ref = float(m.x_ref)
    y0 = jnp.asarray([f_t / k / x_ref, -3.0])  # at x_S, moving apart at 3 x_ref per 1/r rad
    ts = jnp.linspace(a, b, 4001)
    sol = diffrax.diffeqsolve(
        diffrax.ODETerm(lambda t, y, w: m.vector_field(t, y, w)), diffrax.Dopri8(), a, b,
        None, y0, args=omega, saveat=diffrax.SaveAt(ts=ts), max_steps=200_000,
        stepsize_controller=diffrax.PIDController(rtol=1e-12, atol=1e-14))
    x = np.asarray(sol.ys[:, 0]) * x_ref
    xp = np.asarray(sol.ys[:, 1]) * r * x_ref  # dx/dtheta
    energy = 0.5 * m_eq * omega**2 * xp**2 + 0.5 * k * np.maximum(x, 0.0) ** 2 - f_t * x
    scale = 0.5 * k * np.max(np.abs(x)) ** 2
    separated = x < 0
    assert separated.any() and (~separated).any()
    assert np.sum(np.diff(separated.astype(int)) == -1) >= 1  # at least one impact
    assert np.max(np.abs(energy - energy[0])) < 1e-8 * scale
    # during the free flight the mesh force is zero: x'' = F_t / (m_eq Omega^2)
    forces = jax.vmap(lambda t, y: m.outputs(t, y, omega).mesh_force_N)(ts, sol.ys)
    np.testing.assert_array_equal(np.asarray(forces)[separated], 0.0)


def test_section_631_sdof_no_tension_and_te_close_to_reference(spur):
    """Sdof, short relief, zeta 0.03, 600-1000 rad/s through the main critical speed: no
    tensile mesh force in any formulation (min >= -1e-6 F_S), contact loss reported by all,
    and the TE-based peak dynamic factors close to the reference (the issue asked for 2x).
    Paper Section 6.3: the TE-based formulation stays close to the reference, the
    perturbation one at the main order is less accurate near the critical speeds."""
    speeds = np.arange(600.0, 1001.0, 80.0)
    peaks = {}
    for f in ("reference", "te", "perturbation"):
        m = TorsionalModel.build(spur, table1_relief("short"), formulation=f, damping_ratio=0.03)
        res = sweep(m, speeds)
        f_s = float(m.static_force_N)
        assert np.all(np.asarray(res.solver_ok)), f
        assert np.min(res.min_mesh_force_N) >= -1e-6 * f_s, f
        assert np.any(res.contact_loss), f
        peaks[f] = float(np.max(res.max_mesh_force_N)) / f_s
    # measured peak / F_S (all at 680 rad/s): reference 3.466, te 3.515 (+1.4 %),
    # perturbation 3.686 (+6.3 %). Bands ~2x / 1.6x the measured deviations: te within 3 %
    # (te run at zeta 0.027, a 10 % damping error, reads +3.1 %; the perturbation
    # formulation in its place reads +6.3 %), perturbation within 10 %, and te the closer.
    dev = {f: peaks[f] / peaks["reference"] - 1.0 for f in ("te", "perturbation")}
    assert abs(dev["te"]) < 0.03, peaks
    assert abs(dev["perturbation"]) < 0.10, peaks
    assert abs(dev["te"]) < abs(dev["perturbation"]), peaks


def test_3d_te_contact_law_is_the_cell_law_for_perfect_teeth():
    """3D, perfect spur teeth (all gaps zero) and the averaged structure vector: the
    reference's cell-by-cell law sum_i k_i max(0, V^T X) V and the te mesh-level contact law
    are the same force, in contact and separated. Checked on the two models' vector fields
    (same modal basis) at states around the quasi-static one and far on the separated
    side, where the te mesh force is zero."""
    from gearjax.rigs import baud_velex_rig, build_model

    common = dict(cells_per_line=2, mesh_vectors="mean", max_frequency_hz=5000.0, n_table=32)
    ref = build_model(baud_velex_rig(False), ToothModifications.none(), formulation="reference",
                      **common)
    # NLTE = 0 (perfect teeth): the reference builds without NLTE terms; the te model keeps
    # them for every design by default, which adds E to its modal basis: drop them here so
    # that both models share one basis
    te = build_model(baud_velex_rig(False), ToothModifications.none(), formulation="te",
                     nlte_terms=False, **common)
    omega = 600.0
    rng = np.random.default_rng(1)
    n = te.state_size
    th = jnp.asarray(rng.uniform(0, te.period_rad, 24))
    y_s = jax.vmap(lambda t: te.initial_state(omega, t))(th)
    # along the mesh direction: the modal coordinates of C_v scaled to -3 .. +1 static approaches
    cv = jnp.concatenate([te.c_v_r / te.scale_a, jnp.zeros(n // 2)]) * float(te.static_force_N)
    amp = jnp.asarray(rng.uniform(-3.0, 1.0, 24))
    y = y_s + amp[:, None] * cv[None, :] + 0.05 * jnp.asarray(rng.normal(size=(24, n)))
    f_ref = jax.vmap(lambda t, yy: ref.vector_field(t, yy, omega))(th, y)
    f_te = jax.vmap(lambda t, yy: te.vector_field(t, yy, omega))(th, y)
    force = np.asarray(jax.vmap(lambda t, yy: te.outputs(t, yy, omega).mesh_force_N)(th, y))
    force_ref = np.asarray(jax.vmap(lambda t, yy: ref.outputs(t, yy, omega).mesh_force_N)(th, y))
    assert np.sum(force == 0.0) >= 5 and np.sum(force > 0.0) >= 5  # both sides exercised
    # te reads X_S from its excitation table (32 knots per mesh period, O(h^4)): agreement
    # to the table's interpolation error times the mesh stiffness, an absolute error on the
    # scale of F_S (measured 1.1e-4 N = 2e-8 F_S), not of the sampled force, which can lie
    # near 0 (the modal coordinates' signs, hence the sampled states, follow the eigensolver)
    np.testing.assert_array_equal(force == 0.0, force_ref == 0.0)
    np.testing.assert_allclose(force, force_ref, rtol=0, atol=1e-7 * float(te.static_force_N))
    err = np.max(np.abs(np.asarray(f_te) - np.asarray(f_ref))) / np.max(np.abs(np.asarray(f_ref)))
    print("relative vector-field difference", err)
    assert err < 1e-7
