"""The per-cell contact law of the TE-based formulations, the other reading of Section 6.2
(:func:`gearjax.gears.contact.te_cell_contact`, ``TEContactLaw.CELLS``).

Independent checks:

* the law against Eq. (37) with each cell's unilateral law written here, ``sum_i k_i
  max(0, a_i + r v_xD)``, with ``F_S`` and ``k(theta)`` formed from the loaded cells;
* the limit (assumption (18a) holds): while every cell keeps its quasi-static state (states
  within each angle's smallest cell approach, from the quasi-static solve) the vector field
  is the mesh-level model's bit for bit, and with perfect teeth (every gap zero: no cell can
  switch alone) the steady orbits are the same;
* contact lost: on the sdof model Eq. (20) with the per-cell law is Eq. (16) again, so its
  mesh force and vector field equal the reference formulation's at the same state, in
  contact, partly and wholly separated, and the force is never negative; on the 3D model
  with the averaged structure vector (``mesh_vectors="mean"``) it is the reference Eq. (14)
  with that vector;
* refusals: a TE file, the frequency-domain solver.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from gearjax import Mesh, ToothModifications, baud_velex_pair, quasi_static, table1_relief
from gearjax.dynamics.sweep import sweep
from gearjax.errors import ModelError, SimulationError
from gearjax.gears.contact import TEContactLaw, te_cell_contact
from gearjax.gears.quasistatic import contact_gaps
from gearjax.models.torsional import TorsionalModel

CELLS = TEContactLaw.CELLS


def test_law_is_eq37_cell_by_cell():
    """Random cells: loaded (a > 0), open (a < 0) and outside the path (k = 0). The
    equation's force is sum k max(0, a + r v) for te (r = 1) and perturbation (r = k_m/k),
    the reported one the same with r = 1; both exactly the linear forces while no cell
    switches, zero when every cell is open."""
    rng = np.random.default_rng(0)
    for _ in range(20):
        n = 12
        k = rng.uniform(1e7, 5e7, n) * (rng.uniform(size=n) > 0.2)
        a = rng.uniform(-4e-6, 6e-6, n)
        load = (k > 0) & (a > 0)
        if not load.any():
            continue
        f_s, k_s = float(np.sum(k[load] * a[load])), float(np.sum(k[load]))
        k_m = 0.8 * k_s
        for v in rng.uniform(-8e-6, 3e-6, 8):
            for k_eq in (k_s, k_m):
                r = k_eq / k_s
                cut, f_d = te_cell_contact(jnp.asarray(f_s + k_eq * v), jnp.asarray(f_s + k_s * v),
                                           jnp.asarray(k), jnp.asarray(a), jnp.asarray(v),
                                           jnp.asarray(r))
                eq = np.sum(k * np.maximum(0.0, a + r * v))
                rep = np.sum(k * np.maximum(0.0, a + v)) if eq > 0 else 0.0
                assert abs(float(f_s + k_eq * v - cut) - eq) <= 1e-9 * f_s
                assert abs(float(f_d) - rep) <= 1e-9 * f_s and float(f_d) >= 0.0
        # no cell switches: |v| below every |a|: exactly the linear forces
        v = 0.9 * float(np.min(np.abs(a[k > 0]))) * rng.choice([-1.0, 1.0])
        cut, f_d = te_cell_contact(jnp.asarray(f_s + k_s * v), jnp.asarray(f_s + k_s * v),
                                   jnp.asarray(k), jnp.asarray(a), jnp.asarray(v), 1.0)
        assert float(cut) == 0.0 and float(f_d) == f_s + k_s * v
    # every cell open: zero, not a round-off residue of F_S - sum k a
    cut, f_d = te_cell_contact(jnp.asarray(-5.0), jnp.asarray(-5.0), jnp.ones(3) * 1e8,
                               jnp.asarray([1e-6, 2e-6, 3e-6]), jnp.asarray(-4e-6), 1.0)
    assert float(f_d) == 0.0 and float(-5.0 - cut) == 0.0


@pytest.fixture(scope="module")
def spur():
    return Mesh.build(baud_velex_pair(False))


@pytest.fixture(scope="module")
def sdof_short(spur):
    """Short relief (NLTE = 0): reference, te (mesh level) and te (per cell)."""
    kw = dict(damping_ratio=0.05)
    return {name: TorsionalModel.build(spur, table1_relief("short"), formulation=f, contact_law=law,
                                       **kw)
            for name, f, law in (("reference", "reference", TEContactLaw.MESH),
                                 ("te", "te", TEContactLaw.MESH), ("cells", "te", CELLS),
                                 ("pert", "perturbation", TEContactLaw.MESH),
                                 ("pert-cells", "perturbation", CELLS))}


@pytest.mark.parametrize("mesh_law, cell_law", [("te", "cells"), ("pert", "pert-cells")])
def test_sdof_limit_every_cell_keeps_its_state(sdof_short, mesh_law, cell_law):
    """States whose dynamic approach stays below each angle's smallest |a_i| (quasi-static
    solve of the gears alone, not the model): the per-cell vector field and force are the
    mesh-level ones bit for bit (Eqs. (20), (47a) as printed)."""
    m, c = sdof_short[mesh_law], sdof_short[cell_law]
    omega, n = 500.0, 96
    rng = np.random.default_rng(2)
    th = np.sort(rng.uniform(0, m.period_rad, n))
    qs = quasi_static(m.mesh, m.mods, jnp.asarray(th), m.static_force_N)
    cos_bb = math.cos(m.mesh.pair.base_helix_angle_rad)
    margin = []
    for t, x_s in zip(th, np.asarray(qs.x_s_m)):
        cells, de, _ = contact_gaps(m.mesh, m.mods, jnp.asarray(t))
        on = np.asarray(cells.stiffness_N_per_m) > 0
        margin.append(np.min(np.abs(x_s * cos_bb - np.asarray(de)[on])))
    margin = np.asarray(margin)
    # perturbation: the equation's cells see r v_xD, r = k_m / k(theta) (te_cell_contact)
    r_max = 1.0 if mesh_law == "te" else float(m.k_m) / float(
        np.min(np.asarray(qs.loaded_stiffness_N_per_m)))
    x_d = 0.5 * margin / max(r_max, 1.0) * rng.uniform(-1, 1, n) / cos_bb  # transverse (m)
    y_s = jax.vmap(lambda t: m.initial_state(omega, t))(jnp.asarray(th))
    y = y_s + jnp.stack([jnp.asarray(x_d) / float(m.x_ref), jnp.asarray(rng.normal(size=n))], 1)
    th = jnp.asarray(th)
    for f in (lambda mm, t, yy: mm.vector_field(t, yy, omega),
              lambda mm, t, yy: mm.outputs(t, yy, omega).mesh_force_N):
        fa = jax.vmap(lambda t, yy: f(m, t, yy))(th, y)
        fb = jax.vmap(lambda t, yy: f(c, t, yy))(th, y)
        np.testing.assert_array_equal(np.asarray(fa), np.asarray(fb))


@pytest.mark.parametrize("relief", ["short", "long"])
def test_sdof_cell_law_is_the_reference(spur, sdof_short, relief):
    """Eq. (20) cell by cell is Eq. (16): at random states (in contact, partly and wholly
    separated; long relief: NLTE and NLTE'' in both) the per-cell te force and vector field
    equal the reference's (measured 1.2e-11 F_S and 7e-12 relative: the table's
    interpolation of x_S), the force is never negative and zero exactly where the
    reference's is; the mesh-level law differs by up to 40 % of F_S there."""
    if relief == "short":
        ref, cells, mesh_law = sdof_short["reference"], sdof_short["cells"], sdof_short["te"]
    else:
        kw = dict(damping_ratio=0.05)
        ref = TorsionalModel.build(spur, table1_relief("long"), formulation="reference", **kw)
        cells = TorsionalModel.build(spur, table1_relief("long"), formulation="te",
                                     contact_law=CELLS, **kw)
        mesh_law = None
    omega, n = 500.0, 200
    rng = np.random.default_rng(0)
    th = jnp.asarray(rng.uniform(0, cells.period_rad, n))
    y_s = jax.vmap(lambda t: cells.initial_state(omega, t))(th)
    y = y_s + jnp.asarray(rng.uniform(-1.5, 0.5, (n, 2)))
    f_s = float(cells.static_force_N)
    force = lambda m: np.asarray(jax.vmap(lambda t, yy: m.outputs(t, yy, omega).mesh_force_N)(th, y))  # noqa: E731
    fr, fc = force(ref), force(cells)
    assert np.sum(fr == 0.0) >= 10 and np.sum(fr > 0.0) >= 100  # both sides exercised
    np.testing.assert_array_equal(fc == 0.0, fr == 0.0)
    assert np.all(fc >= 0.0)
    np.testing.assert_allclose(fc, fr, rtol=0, atol=1e-9 * f_s)
    vr = np.asarray(jax.vmap(lambda t, yy: ref.vector_field(t, yy, omega))(th, y))
    vc = np.asarray(jax.vmap(lambda t, yy: cells.vector_field(t, yy, omega))(th, y))
    assert np.max(np.abs(vc - vr)) <= 1e-9 * np.max(np.abs(vr))
    if mesh_law is not None:  # the mesh-level law is another force where cells open
        assert np.max(np.abs(force(mesh_law) - fr)) > 0.1 * f_s


@pytest.mark.slow
def test_sdof_perfect_teeth_orbits_are_the_mesh_level_ones(spur):
    """Perfect teeth: every gap is zero, so every loaded cell has the same approach and
    the cells open together; below the critical speed (contact kept) the per-cell te and
    perturbation vector fields are today's bit for bit (previous test), so their orbits
    agree to the transient's tolerance (rtol 1e-7 of the state: the two compiled programs
    round differently and take other steps; measured 7e-10 F_S)."""
    speeds = np.array([300.0, 520.0])
    for f in ("te", "perturbation"):
        res = [sweep(TorsionalModel.build(spur, ToothModifications.none(), formulation=f,
                                          damping_ratio=0.05, contact_law=law), speeds)
               for law in (TEContactLaw.MESH, CELLS)]
        assert not np.any(res[0].contact_loss)
        f_s = float(res[0].max_mesh_force_N[0] / res[0].dynamic_factor[0])
        for name in ("max_mesh_force_N", "min_mesh_force_N"):
            np.testing.assert_allclose(getattr(res[1], name), getattr(res[0], name), rtol=0,
                                       atol=1e-7 * f_s)
        np.testing.assert_allclose(res[1].dte_ptp_m, res[0].dte_ptp_m, rtol=1e-7)


def test_refusals(spur, sdof_short, tmp_path):
    """A TE file gives TE_S, not the cells' gaps: the per-cell law is refused (model and
    command line); the frequency-domain solver checks contact on the mesh force only."""
    from gearjax.dynamics.harmonic_sweep import harmonic_sweep
    from gearjax.excitation.te_file import read_te_csv

    path = tmp_path / "te.csv"
    rows = ["mesh_cycle_fraction,te_s_m"] + [f"{i / 16},{1e-6 * math.cos(2 * math.pi * i / 16)}"
                                            for i in range(16)]
    path.write_text("\n".join(rows) + "\n")
    te = read_te_csv(str(path), spur.pair.mesh_period_rad)
    sdof_short["te"].with_te(te)  # the mesh-level model takes the file
    with pytest.raises(ModelError, match="contact_law"):
        sdof_short["cells"].with_te(te)
    with pytest.raises(ModelError, match="contact_law"):
        TorsionalModel.build(spur, table1_relief("short"), formulation="te", contact_law="cells")
    with pytest.raises(SimulationError, match="per-cell"):
        harmonic_sweep(sdof_short["cells"], np.array([400.0]))


@pytest.fixture(scope="module")
def rig3d_mean():
    """3D Baud-Velex spur rig, short relief, the averaged structure vector for every cell
    (Eq. (27)): reference, te (mesh level) and te (per cell)."""
    from gearjax.rigs import baud_velex_rig, build_model

    common = dict(cells_per_line=2, mesh_vectors="mean", max_frequency_hz=5000.0, n_table=32)
    return {name: build_model(baud_velex_rig(False), table1_relief("short"), formulation=f,
                              contact_law=law, **common)
            for name, f, law in (("reference", "reference", TEContactLaw.MESH),
                                 ("te", "te", TEContactLaw.MESH), ("cells", "te", CELLS))}


@pytest.mark.slow
def test_3d_mean_vector_cell_law_is_the_reference(rig3d_mean):
    """With V for every cell, Eq. (42) cell by cell is Eq. (14): at states around the
    quasi-static one and far on the separated side the per-cell te force and vector field
    equal the reference's (the te table interpolates X_S: measured 4.4e-8 F_S and 1.3e-8
    relative), zero exactly where the reference's is; the mesh-level law differs there."""
    ref, te = rig3d_mean["reference"], rig3d_mean["cells"]
    omega, n = 600.0, 48
    rng = np.random.default_rng(1)
    th = jnp.asarray(rng.uniform(0, te.period_rad, n))
    y_s = jax.vmap(lambda t: te.initial_state(omega, t))(th)
    r = te.state_size // 2
    cv = jnp.concatenate([te.c_v_r / te.scale_a, jnp.zeros(r)]) * float(te.static_force_N)
    y = (y_s + jnp.asarray(rng.uniform(-3.0, 1.0, n))[:, None] * cv[None, :]
         + 0.05 * jnp.asarray(rng.normal(size=(n, 2 * r))))
    out = lambda m: np.asarray(jax.vmap(lambda t, yy: m.outputs(t, yy, omega).mesh_force_N)(th, y))  # noqa: E731
    fr, fc, fm = out(ref), out(te), out(rig3d_mean["te"])
    f_s = float(te.static_force_N)
    assert np.sum(fr == 0.0) >= 5 and np.sum(fr > 0.0) >= 5
    np.testing.assert_array_equal(fc == 0.0, fr == 0.0)
    np.testing.assert_allclose(fc, fr, rtol=0, atol=2e-7 * f_s)
    vr = np.asarray(jax.vmap(lambda t, yy: ref.vector_field(t, yy, omega))(th, y))
    vc = np.asarray(jax.vmap(lambda t, yy: te.vector_field(t, yy, omega))(th, y))
    assert np.max(np.abs(vc - vr)) <= 1e-7 * np.max(np.abs(vr))
    assert np.max(np.abs(fm - fr)) > 0.1 * f_s


@pytest.mark.slow
def test_3d_limit_every_cell_keeps_its_state(rig3d_mean):
    """States displaced along C_v = K_bar^-1 V by less than each angle's smallest cell
    approach |V^T x_S - de_i| (the model's quasi-static solve, Eq. (25)): the per-cell
    te vector field and force are the mesh-level ones to round-off (1e-12 relative: the law
    adds exactly 0, but the two compiled 3D programs may split their modal dot products
    differently; measured 0 alone, 2.8e-14 under a loaded machine)."""
    m, c = rig3d_mean["te"], rig3d_mean["cells"]
    omega, n = 600.0, 32
    rng = np.random.default_rng(3)
    th = np.sort(rng.uniform(0, m.period_rad, n))
    margin = []
    for t in th:
        x = np.asarray(c.quasi_static(jnp.asarray(t)).x_local)
        cells, de, _ = contact_gaps(c.mesh, c.mods, jnp.asarray(t))
        on = np.asarray(cells.stiffness_N_per_m) > 0
        margin.append(np.min(np.abs(np.asarray(c.v_local) @ x - np.asarray(de)[on])))
    v_d = 0.5 * np.asarray(margin) * rng.uniform(-1, 1, n)  # V^T X_D (m)
    r = m.state_size // 2
    y_s = jax.vmap(lambda t: m.initial_state(omega, t))(jnp.asarray(th))
    dq = (jnp.asarray(v_d / float(m.c_vv))[:, None] * m.c_v_r[None, :]) / m.scale_a
    y = y_s + jnp.concatenate([dq, 0.05 * jnp.asarray(rng.normal(size=(n, r)))], axis=1)
    th = jnp.asarray(th)
    for f in (lambda mm, t, yy: mm.vector_field(t, yy, omega),
              lambda mm, t, yy: mm.outputs(t, yy, omega).mesh_force_N):
        fa = np.asarray(jax.vmap(lambda t, yy: f(m, t, yy))(th, y))
        fb = np.asarray(jax.vmap(lambda t, yy: f(c, t, yy))(th, y))
        assert np.max(np.abs(fb - fa)) <= 1e-12 * np.max(np.abs(fa))
