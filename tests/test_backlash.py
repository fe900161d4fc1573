"""Backlash (issue 49): the three-state mesh law, the back flanks' geometry, the models with
back flanks against an independent SciPy integration (Kahraman & Singh, 1991), and the
inputs.

What each test checks against:

* the three-state law: its closed form for a linear mesh, continuity at the switches;
* the back flanks' phase: explicit involute geometry in the transverse plane (the flank of
  a tooth centred on the line of centres meets the line of action where the mating flank
  does: tight mesh);
* the back-flank structure vectors: rigid-body motions whose effect on each flank's
  clearance is known (a rotation closes one and opens the other, moving the pinion towards
  the gear closes both, an axial shift of a helical pinion closes one and opens the other);
* the 3D reference formulation on a torsional structure: the sdof reference law;
* no backlash / a clearance never reached: the model of the paper, unchanged;
* Kahraman & Singh's gear pair through a TE file: the mesh-force extremes and the impact
  regime of orbits in each regime against ``scipy.integrate.solve_ivp`` with the contact
  switches located as events (``tests/oscillators.py``); the full up and down sweeps (jump
  speeds, regimes at every speed) are ``slow``;
* bad values: one-line errors from the model, the rig file and the command line.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from gearjax.errors import ModelError, RigError
from gearjax.gears.backlash import back_flank_angle_rad, cell_backlash_force
from gearjax.gears.contact import te_backlash_contact, te_contact, three_state_force
from gearjax.gears.geometry import GearPair, involute
from gearjax.gears.mesh import Mesh
from gearjax.gears.modifications import ToothModifications
from gearjax.rigs.baud_velex import baud_velex_pair, table1_relief
from gearjax.structure.element import PinionGearElement

from oscillators import (KS_LENGTH_M, KS_STIFFNESS_N_PER_M, KS_Z1, KahramanSingh, _settle_measure,
                         impact_regime, ks_gear_model, ks_gearjax_sweep, ks_speed_rad_s,
                         ks_state, ks_te_file)


# ------------------------------------------------------------------ the three-state law
def test_three_state_law_closed_form():
    k, b = 3.0e8, 1e-4
    delta = jnp.asarray([2e-5, 1e-12, 0.0, -5e-5, -b, -b - 1e-12, -3e-4])
    f = three_state_force(delta, b, lambda u: k * u)
    want = np.where(delta > 0, k * delta, np.where(delta < -b, k * (delta + b), 0.0))
    np.testing.assert_allclose(np.asarray(f), want, rtol=1e-14, atol=1e-9)
    # continuous at both switches, a back-flank load of the other sign
    assert abs(float(three_state_force(jnp.asarray(-b - 1e-15), b, lambda u: k * u))) < 1e-6
    assert float(f[-1]) < 0.0
    # a separate back-flank law
    fb = three_state_force(jnp.asarray(-2e-4), b, lambda u: k * u, lambda u: 2 * k * u)
    assert float(fb) == pytest.approx(2 * k * (-2e-4 + b))


def test_te_backlash_contact_is_te_contact_until_the_back_flanks():
    """In drive contact and in free flight the backlash law is the paper's contact law; on
    the back flanks the equation's force is ``k (delta + b)`` and the reported one reads the
    loaded stiffness (perturbation: ``k_m`` in the equation, ``k_S`` reported)."""
    k_eq, k_ld, b = 2.0e8, 2.4e8, 1e-5
    for f_eq, f_ld in ((3e3, 3.3e3), (-100.0, -120.0), (-2e3, -2.4e3), (-5e3, -6e3)):
        cut, f_d = te_backlash_contact(jnp.asarray(f_eq), jnp.asarray(f_ld), k_eq, k_ld, b)
        cut0, f_d0 = te_contact(jnp.asarray(f_eq), jnp.asarray(f_ld))
        delta = f_eq / k_eq
        if delta >= -b:
            np.testing.assert_allclose([float(cut), float(f_d)], [float(cut0), float(f_d0)],
                                       atol=1e-9)
        else:
            assert float(f_eq - cut) == pytest.approx(k_eq * (delta + b))
            assert float(f_d) == pytest.approx(min(0.0, f_ld + k_ld * b))
            assert float(f_d) < 0.0


# ------------------------------------------------------------------ back-flank geometry
def _line_point_of_flank(pair):
    """Transverse plane, O1 at the origin, O2 on +x, a pinion tooth centred on +x: where its
    upper flank meets the line of action tangent to the pinion base circle below the axis
    (roll distance xi from the tangent point), and the gear's flank through that point."""
    rb1, rb2 = pair.base_radii_m
    a_w = pair.centre_distance_m
    aw = math.acos((rb1 + rb2) / a_w)
    t1 = rb1 * np.array([math.cos(aw), -math.sin(aw)])
    s = np.array([math.sin(aw), math.cos(aw)])
    at, an = pair.transverse_pressure_angle_rad, pair.normal_pressure_angle_rad

    def half_base(z, x):  # half the base tooth angle, from the reference tooth thickness
        return (math.pi / 2 + 2 * x * math.tan(an)) / z + involute(at)

    def flank_angle(r, rb, z, x):  # polar angle of the flank at radius r from the tooth centre
        return half_base(z, x) - involute(math.acos(rb / r))

    # bisection on the roll xi: the line point's polar angle equals the flank's
    def gap(xi):
        m = t1 + xi * s
        r = float(np.hypot(*m))
        return math.atan2(m[1], m[0]) - flank_angle(r, rb1, pair.z1, pair.profile_shift1)

    lo, hi = 1e-9, pair.contact_limits_m[1] + pair.base_pitch_m
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if gap(lo) * gap(mid) > 0 else (lo, mid)
    xi = 0.5 * (lo + hi)
    m = t1 + xi * s
    # the gear, with a space centred on the line of centres (facing the pinion tooth): its
    # flank through M at the angle from O2 of the tooth beside the space
    rel = m - np.array([a_w, 0.0])
    r2 = float(np.hypot(*rel))
    ang = math.pi - math.atan2(rel[1], rel[0])  # measured from -x at O2
    tooth = math.pi / pair.z2 - flank_angle(r2, rb2, pair.z2, pair.profile_shift2)
    return xi, ang, tooth


@pytest.mark.parametrize("pair", [
    baud_velex_pair(False), baud_velex_pair(True),
    GearPair(normal_module_m=3e-3, z1=16, z2=32, profile_shift1=0.2, profile_shift2=-0.2),
    GearPair(normal_module_m=2e-3, z1=21, z2=47, profile_shift1=0.4, profile_shift2=0.1)],
    ids=["spur", "helical", "ks", "shifted"])
def test_back_flank_phase_from_involute_geometry(pair):
    xi_geo, ang, tooth = _line_point_of_flank(pair)
    # tight mesh: the gear's flank passes through the pinion flank's point on the line
    assert abs(abs(ang) - abs(tooth)) < 1e-9, (ang, tooth)
    # the pinion angle of that configuration, theta_s = phi0 / 2 (mod half a mesh period:
    # a tooth or a space centred), has a contact line at xi_geo at mid-face (Mesh.cells)
    phi0 = back_flank_angle_rad(pair)
    mesh = Mesh.build(pair, "uniform", cells_per_line=1 if pair.spur else 41)
    cells = mesh.cells(phi0 / 2)
    mid = np.abs(np.asarray(cells.eta_m) - 0.5 * pair.face_width_m) < 1e-12
    xs = np.asarray(cells.xi_m)[mid]
    half = pair.base_pitch_m / 2
    d = np.abs(np.mod(xs - xi_geo + half / 2, half) - half / 2)
    assert np.min(d) < 1e-9 * pair.base_pitch_m, (xs, xi_geo)


@pytest.mark.parametrize("helical", [False, True])
def test_back_vectors_rigid_body_motions(helical):
    """V'^T X of rigid motions of the pinion: a rotation about its axis closes the back
    flanks as it opens the drive flanks; moving it towards the gear along the line of
    centres closes both alike; an axial shift (helical) closes one and opens the other."""
    pair = baud_velex_pair(helical)
    mesh = Mesh.build(pair, "uniform", cells_per_line=3)
    el = PinionGearElement.at_nodes(mesh, 12, 0, 1)
    v = np.asarray(el.local_vectors(jnp.asarray([0.01, 0.02]), jnp.asarray([0.005, 0.03])))
    vb = np.asarray(el.back_vectors(v))
    r = el.half_turn()
    np.testing.assert_allclose(r @ r, np.eye(3), atol=1e-15)
    assert np.linalg.det(r) == pytest.approx(1.0)
    rb1 = pair.base_radii_m[0]
    cb, sb = math.cos(pair.base_helix_angle_rad), math.sin(abs(pair.base_helix_angle_rad))
    aw = pair.working_pressure_angle_rad
    rot = np.zeros(12)
    rot[5] = 1e-6  # pinion rotation (theta dof)
    np.testing.assert_allclose(v @ rot, rb1 * cb * 1e-6, rtol=1e-12)
    np.testing.assert_allclose(vb @ rot, -rb1 * cb * 1e-6, rtol=1e-12)
    # towards the gear along the line of centres (s, t) = (L, -(Rb1 + Rb2)) / a_w
    c = np.array([pair.line_of_action_length_m, -sum(pair.base_radii_m)]) / pair.centre_distance_m
    tr = np.zeros(12)
    tr[1], tr[2] = 1e-6 * c  # pinion translation dofs v (s), w (t)
    np.testing.assert_allclose(v @ tr, 1e-6 * math.sin(aw) * cb, rtol=1e-9)
    np.testing.assert_allclose(vb @ tr, v @ tr, rtol=1e-9)
    ax = np.zeros(12)
    ax[0] = 1e-6  # pinion axial dof u (z)
    np.testing.assert_allclose(v @ ax, 1e-6 * sb * np.sign(pair.helix_angle_rad or 1.0), atol=1e-20)
    np.testing.assert_allclose(vb @ ax, -(v @ ax), atol=1e-20)


def _torsional_3d(formulation, clearance, n_table=32, **kw):
    """A torsional-only 3D structure (two inertias, a soft resisting spring) with the long
    relief (gaps and NLTE on both flanks), and its mesh."""
    from gearjax.models.geared3d import Geared3DModel
    from gearjax.structure.assembly import StructureBuilder

    pair = baud_velex_pair(False)
    mesh = Mesh.build(pair, "iso6336", cells_per_line=2)
    mods = table1_relief("long")
    b = StructureBuilder(n_nodes=2)
    b.add_disc(0, mass_kg=1.0, transverse_inertia_kg_m2=1.0, polar_inertia_kg_m2=0.002)
    b.add_disc(1, mass_kg=1.0, transverse_inertia_kg_m2=1.0, polar_inertia_kg_m2=0.05)
    b.add_torsional_spring_to_ground(1, 100.0)
    b.set_node(0, line="pinion").set_node(1, line="gear")
    b.set_pinion_node(0).set_gear_node(1)
    fixed = [d for d in range(12) if d not in (5, 11)]
    m3 = Geared3DModel.build(b.build(), mesh, mods, fixed_dofs=fixed, n_table=n_table,
                             formulation=formulation, backlash_m=clearance, **kw)
    return m3, mesh, mods


def _state_at(m3, delta):
    """The scaled state of ``X = X_0 + s C_v`` with ``V^T X = delta`` (m), at rest."""
    s = (delta - float(m3.v_x0)) / float(m3.c_vv)
    return jnp.concatenate([s * m3.c_v_r / m3.scale_a, jnp.zeros(m3.n_reduced)])


DELTAS = (8e-6, 1e-7, -5e-6, -24e-6, -50e-6)  # drive, free flight, back (clearance 20 um)


@pytest.fixture(scope="module")
def torsional_3d_models():
    """The torsional-structure 3D models with a 20 um backlash (reference, te; perturbation
    shares te's build) and te's without."""
    ref, mesh, mods = _torsional_3d("reference", 20e-6)
    te, _, _ = _torsional_3d("te", 20e-6)
    te0, _, _ = _torsional_3d("te", None)
    return dict(reference=ref, te=te, perturbation=te.with_formulation("perturbation"),
                te0=te0, perturbation0=te0.with_formulation("perturbation"), mesh=mesh,
                mods=mods)


def test_3d_reference_back_flanks_are_the_sdof_law_in_torsion(torsional_3d_models):
    """On a torsional-only structure the 3D reference formulation's mesh force with
    back-flank cells (vectors ``H V``) equals the sdof per-cell law at the same approach, on
    both flanks and in free flight; the back cells' engagement angles are integrator jumps."""
    from gearjax.excitation.events import engagement_angles

    clearance = 20e-6
    m3, mesh, mods = (torsional_3d_models[k] for k in ("reference", "mesh", "mods"))
    p = mesh.pair.mesh_period_rad
    back = np.mod(back_flank_angle_rad(mesh.pair) - engagement_angles(mesh, p), p)
    jumps = np.asarray(m3.jump_thetas)
    assert all(np.min(np.abs(np.mod(jumps - t + p / 2, p) - p / 2)) < 1e-9 * p for t in back)
    for theta in np.linspace(0.0, mesh.pair.mesh_period_rad, 7)[:-1]:
        for delta in DELTAS:
            f3 = float(m3.outputs(jnp.asarray(theta), _state_at(m3, delta), 300.0).mesh_force_N)
            f1 = float(cell_backlash_force(mesh, mods, jnp.asarray(theta), delta, clearance))
            assert f3 == pytest.approx(f1, rel=1e-9, abs=1e-6), (theta, delta, f3, f1)


@pytest.mark.parametrize("formulation", ["te", "perturbation"])
def test_3d_te_back_flanks_are_the_sdof_law_in_torsion(torsional_3d_models, formulation):
    """The 3D te/perturbation formulations' back-flank law along ``H V`` is, in torsion, the
    sdof mesh-level law: back-flank contact ``b`` behind the drive flanks' no-load position,
    the equation's stiffness, the loaded one reported (a force, N, against
    :func:`gearjax.gears.contact.te_backlash_contact` on the 3D model's own excitation);
    before the back flanks, the paper's law."""
    clearance = 20e-6
    m3, m0, mesh = (torsional_3d_models[k] for k in (formulation, formulation + "0", "mesh"))
    f_s = float(m3.static_force_N)
    for theta in np.linspace(0.0, mesh.pair.mesh_period_rad, 5)[:-1]:
        d, k = (float(v) for v in m3.table(jnp.asarray(theta))[0][:2])
        k_eq = k if formulation == "te" else float(m3.k_m)
        v_xs = float(m3.v_x0) + m3.cos_bb * d
        for delta in DELTAS:  # here the approach beyond the drive flanks' no-load position
            v_q = delta + v_xs - f_s / k_eq
            y = _state_at(m3, v_q)
            f3 = float(m3.outputs(jnp.asarray(theta), y, 300.0).mesh_force_N)
            _, want = te_backlash_contact(f_s + k_eq * (v_q - v_xs), f_s + k * (v_q - v_xs),
                                          k_eq, k, clearance)
            assert f3 == pytest.approx(float(want), rel=1e-9, abs=1e-6), (theta, delta)
            f0 = float(m0.outputs(jnp.asarray(theta), y, 300.0).mesh_force_N)
            if delta > -clearance:  # the paper's law until the back flanks
                assert f3 == pytest.approx(f0, rel=1e-12, abs=1e-9)
            else:
                assert f3 < 0.0 == f0


@pytest.mark.slow
@pytest.mark.parametrize("formulation", ["reference", "te"])
def test_3d_torsional_structure_with_backlash_is_the_sdof_model(formulation):
    """Through double-sided impacts, the 3D model on a torsional-only structure (its NLTE''
    reaction on the pinion node: the sdof ``nlte_reaction="pinion"``) and the sdof model
    with the same backlash give the same steady response (tight tolerances; the two codes
    scale their states differently)."""
    from gearjax.dynamics.simulate import simulate
    from gearjax.models.torsional import TorsionalModel

    clearance = 5e-6
    mesh = Mesh.build(baud_velex_pair(False), "iso6336", cells_per_line=2)
    m1 = TorsionalModel.build(mesh, table1_relief("long"), inertias_kg_m2=(0.002, 0.05),
                              excitation="inline", nlte_reaction="pinion",
                              formulation=formulation, damping_ratio=0.02, backlash_m=clearance)
    m3, _, _ = _torsional_3d(formulation, clearance, n_table=64, damping_ratio=0.02,
                             mean_stiffness_N_per_m=float(m1.mean_stiffness_N_per_m()))
    omega = 1500.0  # above 1450 rad/s both models strike the back flanks (sdof sweep)
    run = lambda m: simulate(m, omega, n_transient_periods=300, n_measured_periods=2,  # noqa: E731
                             rtol=1e-9, atol=1e-11)
    r3, r1 = run(m3), run(m1)
    assert bool(r1.back_contact) and bool(r3.back_contact)
    # a fixed offset between the two codes (their states and tables differ), not integration
    # error; the bound is about four times the largest offset of the four extremes
    np.testing.assert_allclose(float(r3.max_mesh_force_N), float(r1.max_mesh_force_N), rtol=2e-5)
    np.testing.assert_allclose(float(r3.min_mesh_force_N), float(r1.min_mesh_force_N), rtol=2e-5)


# ------------------------------------------------------------------ without backlash
@pytest.mark.parametrize("formulation", ["reference", "te", "perturbation"])
def test_no_backlash_is_the_paper_model(formulation):
    """backlash_m None is the default model, leaf for leaf (the paper's model, bit for bit);
    a clearance the orbit never reaches (a module) leaves the vector field and the mesh force
    unchanged to round-off (the reference formulation's angle map then has the back flanks'
    engagement angles as extra fixed nodes; the linear ones compute ``k (f / k)``)."""
    from gearjax.models.torsional import TorsionalModel

    pair = baud_velex_pair(False)
    mesh = Mesh.build(pair, "iso6336")
    mods = table1_relief("long")
    m0 = TorsionalModel.build(mesh, mods, formulation=formulation)
    mn = TorsionalModel.build(mesh, mods, formulation=formulation, backlash_m=None)
    l0, t0 = jax.tree_util.tree_flatten(m0)
    ln, tn = jax.tree_util.tree_flatten(mn)
    assert t0 == tn and all(np.array_equal(a, b) for a, b in zip(l0, ln))
    mb = TorsionalModel.build(mesh, mods, formulation=formulation,
                              backlash_m=pair.normal_module_m)
    rng = np.random.default_rng(4)
    for theta in rng.uniform(0, pair.mesh_period_rad, 5):
        for y0 in (-3.0, -0.5, 0.4, 1.0, 2.5):  # separated ... well loaded
            y = jnp.asarray([y0, rng.normal()])
            f0 = np.asarray(m0.vector_field(jnp.asarray(theta), y, 400.0))
            fb = np.asarray(mb.vector_field(jnp.asarray(theta), y, 400.0))
            o0 = float(m0.outputs(jnp.asarray(theta), y, 400.0).mesh_force_N)
            ob = float(mb.outputs(jnp.asarray(theta), y, 400.0).mesh_force_N)
            np.testing.assert_allclose(fb, f0, rtol=1e-13, atol=1e-13)
            assert ob == pytest.approx(o0, rel=1e-13, abs=1e-9)


# ------------------------------------------------------------------ Kahraman & Singh
CASE_A = (0.01, 0.004, 0.002)  # the forcing: no-impact and single-sided regimes
CASE_B = (0.2, 0.08, 0.04)  # twenty times: the back flanks are reached


@pytest.fixture(scope="module")
def ks_models(tmp_path_factory):
    out = {}
    for name, f_te in (("A", CASE_A), ("B", CASE_B)):
        ks = KahramanSingh(f_te=f_te)
        path = tmp_path_factory.mktemp("ks") / f"ks{name}.csv"
        ks_te_file(path, ks)
        out[name] = (ks, ks_gear_model(ks, path))
    return out


def test_ks_model_is_the_dimensionless_equation(ks_models):
    """The TE file and the gear mapping give the case's k_m, omega_n and damping."""
    ks, m = ks_models["A"]
    assert float(m.k_m) == pytest.approx(KS_STIFFNESS_N_PER_M, rel=1e-9)
    assert float(m.omega_n) == pytest.approx(math.sqrt(KS_STIFFNESS_N_PER_M / 0.23), rel=1e-9)
    assert float(m.backlash_m) == KS_LENGTH_M and float(m.x_ref) == pytest.approx(
        ks.f_m * KS_LENGTH_M, rel=1e-9)


# (case, W): one periodic orbit per regime, each started on SciPy's orbit
KS_ORBITS = [("A", 1.5, "none"), ("A", 0.9, "single"), ("B", 0.6, "double")]
KS_FORCE_ATOL = 2e-5  # of k_m b: gearjax at its default tolerances (rtol 1e-7)


@pytest.mark.parametrize("case, w, regime", KS_ORBITS, ids=[f"{c}-{w}" for c, w, _ in KS_ORBITS])
def test_ks_orbit_against_scipy_events(ks_models, case, w, regime):
    ks, m = ks_models[case]
    y, _, _, _ = ks.integrate(w, np.array([0.1, 0.0]), 0.0,
                              3 * ks.transient_periods(w) * 2 * np.pi / w)
    ref = ks.measure(w, y)
    assert impact_regime(ref["regimes"]) == regime
    # one period of transient (the state is on the orbit), then gearjax's measurement
    _, r = _settle_measure(m, jnp.asarray(float(ks_speed_rad_s(m, w))),
                           jnp.asarray(ks_state(ks, m, y)), jnp.asarray(1.0))
    f = KS_STIFFNESS_N_PER_M * KS_LENGTH_M
    assert bool(r.converged)
    assert float(r.max_mesh_force_N) / f == pytest.approx(ref["f_max"], abs=KS_FORCE_ATOL)
    assert float(r.min_mesh_force_N) / f == pytest.approx(ref["f_min"], abs=KS_FORCE_ATOL)
    assert bool(r.contact_loss) == (regime != "none")
    assert bool(r.back_contact) == (regime == "double")


def _jumps(rows, key):
    return [(a["w"], b["w"]) for a, b in zip(rows[:-1], rows[1:])
            if a[key] != b[key] or abs(a["f_max"] - b["f_max"]) > 0.2 * min(a["f_max"], b["f_max"])]


@pytest.mark.slow
@pytest.mark.parametrize("case", ["A", "B"])
def test_ks_up_and_down_sweeps_against_scipy(ks_models, case):
    """Brute-force up and down transient sweeps (gearjax and SciPy alike, the same start
    and transients) and gearjax's continuation: the same jump speeds to the sweep's step
    and the same impact regime at every speed; the metrics to the orbit test's bound.
    Case B's continuation starts from the quasi-static state at 0.60 and may take the other
    coexisting branch there, so only its down sweep is compared."""
    from gearjax.dynamics.continuation import continuation_sweep

    ks, m = ks_models[case]
    ws = (np.round(np.arange(0.40, 1.6001, 0.05), 3) if case == "A"
          else np.round(np.arange(0.60, 1.1001, 0.05), 3))
    f = KS_STIFFNESS_N_PER_M * KS_LENGTH_M
    for direction in ("up", "down"):
        seq = ws if direction == "up" else ws[::-1]
        sp = ks.sweep(seq, [0.1, 0.0])
        for r in sp:
            r["regime"] = impact_regime(r["regimes"])
        gj = ks_gearjax_sweep(ks, m, seq, [0.1, 0.0])
        for r in gj:
            r["regime"] = {(False, False): "none", (True, False): "single",
                           (True, True): "double"}[(r["contact_loss"], r["back_contact"])]
        assert [r["regime"] for r in gj] == [r["regime"] for r in sp]
        assert _jumps(gj, "regime") == _jumps(sp, "regime")
        for a, b in zip(sp, gj):
            assert b["converged"]
            assert b["f_max"] == pytest.approx(a["f_max"], abs=KS_FORCE_ATOL)
            assert b["f_min"] == pytest.approx(a["f_min"], abs=KS_FORCE_ATOL)
        if case == "B" and direction == "up":
            continue
        co = continuation_sweep(m, ks_speed_rad_s(m, seq), direction)
        order = np.argsort(ks_speed_rad_s(m, seq))
        order = order if direction == "up" else order[::-1]
        rows = [dict(w=float(seq[j]), f_max=float(co.max_mesh_force_N[i]) / f,
                     regime={(False, False): "none", (True, False): "single",
                             (True, True): "double"}[(bool(co.contact_loss[i]),
                                                      bool(co.back_contact[i]))])
                for j, i in enumerate(order)]
        assert [r["regime"] for r in rows] == [r["regime"] for r in sp]
        assert _jumps(rows, "regime") == _jumps(sp, "regime")


@pytest.mark.slow
def test_ks_folds_are_where_brute_force_sweeps_jump(ks_models):
    """Case A traced by pseudo-arclength continuation (``trace_speed``) against SciPy's
    brute-force up and down transient sweeps (step 0.05 in W). Where the two sweeps' max
    forces differ by more than 20 % two stable orbits coexist (a hysteresis band); the up
    sweep leaves a band between its last speed and the next one, the down sweep between its
    first speed and the one below. For each such jump the trace has exactly one jump speed
    of that direction (a fold ending the branch the sweep was on) within the sweep's step of
    it, and no other. The branch exists where the sweep still was on it, so the fold lies
    beyond that speed; a sweep may leave a branch a step early, where its transient from
    the last orbit falls out of the shrinking basin near the fold (the down sweep at W 0.60,
    0.0018 above the fold), never late: up, ``lo < fold < hi + step``; down, ``lo - step <
    fold < hi``."""
    from gearjax.dynamics.arclength import trace_speed

    ks, m = ks_models["A"]
    ws = np.round(np.arange(0.40, 1.6001, 0.05), 3)
    traced = trace_speed(m, ks_speed_rad_s(m, ws))
    to_w = lambda om: om * KS_Z1 / float(m.omega_n)  # noqa: E731
    folds = {"up": [to_w(w) for w in traced.jump_up_rad_s()],
             "down": [to_w(w) for w in traced.jump_down_rad_s()]}
    up = {r["w"]: r["f_max"] for r in ks.sweep(ws, [0.1, 0.0])}
    down = {r["w"]: r["f_max"] for r in ks.sweep(ws[::-1], [0.1, 0.0])}
    band = [abs(up[w] - down[w]) > 0.2 * min(up[w], down[w]) for w in ws]
    leaves = {"up": [(ws[i], ws[i + 1]) for i in range(ws.size - 1) if band[i] and not band[i + 1]],
              "down": [(ws[i], ws[i + 1]) for i in range(ws.size - 1)
                       if not band[i] and band[i + 1]]}
    assert leaves["up"] and leaves["down"]
    step = 0.05
    for direction in ("up", "down"):
        assert len(leaves[direction]) == len(folds[direction]), (leaves, folds)
        for lo, hi in leaves[direction]:
            lo, hi = (lo, hi + step) if direction == "up" else (lo - step, hi)
            assert sum(lo < w < hi for w in folds[direction]) == 1, (lo, hi, folds)


# ------------------------------------------------------------------ bad values
@pytest.mark.parametrize("value, words", [(-1e-6, ">= 0"), (float("nan"), "finite"),
                                          (5e-3, "larger than the normal module")])
def test_bad_backlash_model(value, words):
    from gearjax.models.torsional import TorsionalModel

    mesh = Mesh.build(baud_velex_pair(False), "uniform", cells_per_line=1)
    with pytest.raises(ModelError, match="backlash_m=") as exc:
        TorsionalModel.build(mesh, backlash_m=value)
    assert words in str(exc.value) and "\n" not in str(exc.value)


def test_reference_backlash_refuses_pitch_errors():
    from gearjax.models.torsional import TorsionalModel

    pair = baud_velex_pair(False)
    mesh = Mesh.build(pair, "uniform", cells_per_line=1)
    mods = ToothModifications.none().with_pitch_errors(np.linspace(0, 5e-6, pair.z1),
                                                       np.zeros(pair.z2))
    with pytest.raises(ModelError, match="pitch errors or eccentricity"):
        TorsionalModel.build(mesh, mods, backlash_m=1e-4)


EXAMPLE = "examples/rigs/baud_velex_spur.toml"


@pytest.mark.parametrize("text, words", [
    ("backlash_m = -1e-5", "gear_pair.backlash_m=-1e-05: must be >= 0"),
    ("backlash_m = nan", "gear_pair.backlash_m=nan: must be a finite"),
    ("backlash_m = 0.01", "gear_pair.backlash_m=0.01: larger than the normal module"),
    ('backlash_m = "0.1 mm"', "gear_pair.backlash_m='0.1 mm': must be a number"),
])
def test_bad_backlash_rig_file(tmp_path, text, words):
    from pathlib import Path

    from gearjax.rigs.rigfile import load_rig

    src = (Path(__file__).resolve().parents[1] / EXAMPLE).read_text()
    p = tmp_path / "rig.toml"
    p.write_text(src.replace("[gear_pair]         # Table 1\n", f"[gear_pair]\n{text}\n"))
    with pytest.raises(RigError) as exc:
        load_rig(p)
    assert words in str(exc.value) and "\n" not in str(exc.value)


def test_rig_file_backlash(tmp_path):
    from pathlib import Path

    from gearjax.rigs.rigfile import load_rig

    src = (Path(__file__).resolve().parents[1] / EXAMPLE).read_text()
    p = tmp_path / "rig.toml"
    p.write_text(src.replace("[gear_pair]         # Table 1\n", "[gear_pair]\nbacklash_m = 1e-4\n"))
    assert load_rig(p).backlash_m == 1e-4
    assert load_rig(Path(__file__).resolve().parents[1] / EXAMPLE).backlash_m is None


@pytest.mark.parametrize("argv, words", [
    (["--backlash=-1e-4"], ["--backlash=-0.0001", ">= 0"]),
    (["--backlash", "nan"], ["--backlash=nan", "finite"]),
    (["--backlash", "0.01"], ["--backlash=0.01", "normal module"]),
])
def test_bad_backlash_command_line(capsys, tmp_path, argv, words):
    from gearjax.cli.main import main

    try:
        code = main(["sweep", "--model", "torsional", "--speeds", "300:300:1", "--out",
                     str(tmp_path / "o")] + argv)
    except SystemExit as exc:
        code = exc.code
    err = capsys.readouterr().err
    assert code == 2 and "Traceback" not in err
    line = [ln for ln in err.splitlines() if " error: " in ln]
    assert len(line) == 1, err
    for w in words:
        assert w in line[0], (w, line[0])
