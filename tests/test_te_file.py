"""TE from a file (paper Section 6.2): reading and checking, the interpolant against closed
forms, the round trip quasi-static TE -> file -> model, and the CLI's one-line errors."""

import csv
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from gearjax.cli.main import main
from gearjax.errors import GearjaxError
from gearjax.excitation.te_file import TETable, read_te_csv, with_jump_rows
from gearjax.gears.mesh import Mesh
from gearjax.gears.quasistatic import quasi_static, static_mesh_force
from gearjax.rigs.baud_velex import table1_relief
from gearjax.rigs.factory import build_model
from gearjax.rigs.registry import get_rig

Z1 = 26  # Baud-Velex spur pinion
MESH = 2 * math.pi / Z1


def _write(path, header, rows):
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        w.writerows(rows)
    return str(path)


def test_sine_te_is_interpolated_to_fourth_order_and_units_agree(tmp_path):
    """A pure sine TE over one mesh period: the periodic Hermite interpolant of 64 rows
    reproduces sin and its derivative (O(h^4), O(h^3)); the same data as
    mesh_cycle_fraction with the closing row and as pinion_angle_rad without it agree."""
    n, amp = 64, 2e-6
    f = np.arange(n + 1) / n
    te = 1e-5 + amp * np.sin(2 * np.pi * f)
    a = read_te_csv(_write(tmp_path / "a.csv", ["mesh_cycle_fraction", "te_s_m"],
                           zip(f, te)), MESH)
    b = read_te_csv(_write(tmp_path / "b.csv", ["pinion_angle_rad", "te_s_m", "nlte_m"],
                           zip(f[:-1] * MESH, te[:-1], np.zeros(n))), MESH)
    th = np.random.default_rng(1).uniform(-MESH, 2 * MESH, 500)
    exact = 1e-5 + amp * np.sin(2 * np.pi * th / MESH)
    slope = amp * 2 * np.pi / MESH * np.cos(2 * np.pi * th / MESH)
    for t in (a, b):
        assert t.period_rad == pytest.approx(MESH, rel=1e-12) and not t.jump_thetas
        v, d = t(th)
        h = 2 * np.pi / n
        assert np.max(np.abs(v[:, 0] - exact)) < 0.05 * amp * h**4
        assert np.max(np.abs(d[:, 0] - slope)) < 0.05 * amp * h**3 * 2 * np.pi / MESH
    assert not a.has_nlte and b.has_nlte and not a.has_stiffness


def test_jumps_and_piecewise_linear_data_are_exact(tmp_path):
    """Two rows at one angle are a jump: a saw-tooth TE (jump at every mesh period) with a
    stiffness step at 0.4 of the period (an LTCA export), given over two mesh periods
    without the closing row, is reproduced exactly on both sides of every jump."""
    saw = lambda x: 1e-5 + 1e-6 * np.mod(x, 1.0)  # noqa: E731
    stiff = lambda x: np.where(np.mod(x, 1.0) < 0.4, 6e8, 9e8)  # noqa: E731
    rows = []
    for f in np.round(np.arange(20) * 0.1, 12):
        if np.mod(f, 1.0) == 0:  # left value (end of the previous period) first
            rows.append((f, 1.1e-5, 9e8))
        elif np.isclose(np.mod(f, 1.0), 0.4):
            rows.append((f, saw(f), 6e8))
        rows.append((f, saw(f), stiff(f + 1e-12)))
    t = read_te_csv(_write(tmp_path / "j.csv", ["mesh_cycle_fraction", "te_s_m",
                                                "mesh_stiffness_N_per_m"], rows), MESH)
    assert t.n_mesh_periods == 2 and len(t.jump_thetas) == 4
    x = np.random.default_rng(2).uniform(0, 2, 400)
    v, d = t(x * MESH)
    np.testing.assert_allclose(v[:, 0], saw(x), rtol=1e-12)
    np.testing.assert_allclose(d[:, 0], 1e-6 / MESH, rtol=1e-9)
    np.testing.assert_allclose(v[:, 2], stiff(x), rtol=1e-12)


BAD = [  # (header, rows as text, words the one-line message must hold)
    ("pinion_angle_rad,nlte_m", ["0,0", "0.1,0"], ["missing column te_s_m"]),
    ("theta_rad,te_s_m", ["0,1e-5", "0.1,1e-5", "0.05,1e-5", "0.2,1e-5", "0.24,1e-5"],
     ["theta_rad=", "row 4", "must increase"]),
    ("mesh_cycle_fraction,te_s_m", ["0,1e-5", "0.25,nan", "0.5,1e-5", "0.75,1e-5"],
     ["te_s_m=", "row 3", "finite"]),
    ("mesh_cycle_fraction,te_s_m", ["0,1e-5", "0.25,abc", "0.5,1e-5", "0.75,1e-5"],
     ["te_s_m='abc'", "row 3", "not a number"]),
    ("mesh_cycle_fraction,te_s_m", ["0,12.0", "0.25,13.1", "0.5,11.0", "0.75,12.5"],
     ["te_s_m=13.1", "row 3", "micrometres given as metres"]),
    ("mesh_cycle_fraction,te_s_m,mesh_stiffness_N_per_m",
     ["0,1e-5,6e8", "0.25,1e-5,-6e8", "0.5,1e-5,6e8", "0.75,1e-5,6e8"],
     ["mesh_stiffness_N_per_m=-6", "row 3", "> 0"]),
    ("mesh_cycle_fraction,te_s_m", ["0,1e-5", "0.2,1.1e-5", "0.4,1e-5", "0.6,1.2e-5"],
     ["mesh_cycle_fraction=0.6", "row 5", "whole mesh periods"]),
    ("mesh_cycle_fraction,te_s_m", ["0,1e-5", "0.25,1.1e-5", "0.5,1e-5", "0.75,1.2e-5", "1,2e-5"],
     ["te_s_m=2e-05", "row 6", "not periodic"]),
    ("mesh_cycle_fraction,te_s_m", ["0,1e-5", "0.5,1e-5", "0.5,1e-5", "0.5,1e-5", "0.75,1e-5"],
     ["row 5", "third row at one angle"]),
    # issue 52: a mesh period exported in degrees under pinion_angle_rad (360/26 deg read
    # as 57 mesh periods, K_v 1.29 instead of 2.28): questioned, with and without the
    # closing row
    ("pinion_angle_rad,te_s_m",
     [f"{360 / 26 * i / 16!r},{1e-5 * (1 + math.sin(2 * math.pi * i / 16))!r}" for i in range(17)],
     ["pinion_angle_rad=13.84", "row 18", "degrees", "1 whole mesh period"]),
    ("pinion_angle_rad,te_s_m",
     [f"{360 / 26 * i / 16!r},{1e-5 * (1 + math.sin(2 * math.pi * i / 16))!r}" for i in range(16)],
     ["pinion_angle_rad=12.98", "row 17", "degrees"]),
]


@pytest.mark.parametrize("header,rows,words", BAD)
def test_bad_te_file_is_one_line_naming_column_and_row(tmp_path, capsys, header, rows, words):
    path = tmp_path / "bad.csv"
    path.write_text("\n".join([header, *rows]) + "\n")
    code = main(["stability", "--model", "torsional", "--te-file", str(path), "--speeds", "100:200:2"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and "Traceback" not in err
    for w in words:
        assert w in err, (w, err)


def test_te_file_refuses_the_reference_formulation(tmp_path, capsys):
    path = _write(tmp_path / "ok.csv", ["mesh_cycle_fraction", "te_s_m"],
                  [(i / 8, 1e-5) for i in range(8)])
    for model in ("torsional", "3d"):
        code = main(["sweep", "--te-file", path, "--speeds", "100:200:2", "--model", model,
                     "--formulations", "reference,te", "--out", str(tmp_path / "o")])
        err = capsys.readouterr().err.strip()
        assert code == 2 and len(err.splitlines()) == 1 and "reference formulation" in err
    with pytest.raises(GearjaxError, match="micrometres"):
        TETable.from_samples([0, 1, 2, 3], [1e-2] * 4, mesh_period_rad=4.0)


@pytest.fixture(scope="module")
def long_relief_te():
    """Table 1 long relief (NLTE, kinks and stiffness jumps), torsional te model, and the
    rows `gearjax quasistatic --csv` writes for it (grid + both sides of every jump)."""
    rig = get_rig("baud-velex-spur")
    mods = table1_relief("long")
    model = build_model(rig, mods, model="torsional", formulation="te")
    mesh = Mesh.build(rig.pair, "iso6336")
    th = np.asarray(mesh.theta_grid(256))  # the CLI default --positions
    qs = quasi_static(mesh, mods, th, static_mesh_force(rig.pair, rig.pinion_torque_Nm))
    grid = np.column_stack([qs.te_s_m, qs.nlte_m, qs.loaded_stiffness_N_per_m])
    t, rows = with_jump_rows(th, grid, model.table, model.table_side, model.jump_thetas, MESH)
    return model, t, rows


def test_quasistatic_rows_fed_back_reproduce_the_model_excitation(tmp_path, long_relief_te):
    """Round trip: the quasi-static TE_S, NLTE and loaded stiffness written as a file (11
    digits, as the CLI writes them) and read back drive the te model with the excitation
    of the model's own quasi-static table: values to the 11-digit print, k_m, and the same
    integrator jumps; without the stiffness column the model's own stiffness is used."""
    model, t, rows = long_relief_te
    path = tmp_path / "qs.csv"
    np.savetxt(path, np.column_stack([t, rows]), delimiter=",", fmt="%.10e", comments="",
               header="theta_rad,te_s_m,nlte_m,mesh_stiffness_N_per_m")
    fed = model.with_te(read_te_csv(path, MESH))
    assert fed.nlte_terms and fed.formulation.name == "te"
    np.testing.assert_allclose(fed.jump_thetas, model.jump_thetas, rtol=0, atol=1e-10)
    assert float(fed.k_m) == pytest.approx(float(model.k_m), rel=1e-10)
    x = jnp.asarray(np.random.default_rng(3).uniform(0, 2 * MESH, 1000))
    a = np.asarray(jax.vmap(model.excitations)(x)[0])
    b = np.asarray(jax.vmap(fed.excitations)(x)[0])
    err = np.max(np.abs(b - a), axis=0) / np.max(np.abs(a), axis=0)
    assert np.all(err <= 1e-9), err
    no_k = TETable.from_samples(t, rows[:, 0], rows[:, 1], mesh_period_rad=MESH)
    c = np.asarray(jax.vmap(model.with_te(no_k).excitations)(x)[0])
    assert np.all(np.abs(c - a) <= 1e-9 * np.max(np.abs(a), axis=0))


@pytest.mark.slow
def test_quasistatic_csv_as_te_file_gives_the_same_sweep(tmp_path, capsys):
    """The issue's round trip from the command line: `gearjax quasistatic --csv` fed back
    as `--te-file` gives the same te sweep (torsional, long relief, 3 speeds) to 1e-9.
    The frequency-domain solver is used: its orbit is a continuous function of the
    excitation; the transient's step and stopping decisions alone move the peaks by up to
    ~4e-7 between two models whose excitations agree to 1e-11."""
    qs = tmp_path / "qs.csv"
    assert main(["quasistatic", "--relief", "long", "--csv", str(qs), "--json"]) == 0
    common = ["sweep", "--model", "torsional", "--relief", "long", "--formulations", "te",
              "--speeds", "300:900:3", "--damping", "0.03", "--method", "harmonic", "--json"]
    assert main([*common, "--out", str(tmp_path / "a")]) == 0
    assert main([*common, "--out", str(tmp_path / "b"), "--te-file", str(qs)]) == 0
    capsys.readouterr()
    res = [list(csv.DictReader(open(tmp_path / d / "results.csv"))) for d in "ab"]
    for ra, rb in zip(*res):
        for key in ("max_mesh_force_N", "min_mesh_force_N", "dte_ptp_m"):
            assert float(rb[key]) == pytest.approx(float(ra[key]), rel=1e-9), key


@pytest.mark.slow  # 40 s (a long-relief 3D te table twice); the sine test below is the default's
def test_3d_model_driven_by_its_own_te_as_a_file_is_the_same_model():
    """3D round trip (Eqs. (42) and (36)-(41)): the te model's own TE_S at its encoders
    (``d + NLTE + w_x0``), NLTE and loaded stiffness written as file rows (both sides of
    every jump) and read back drive a model with the same excitation ``d, k, NLTE`` and the
    same vector field (same k_m given: the modal basis depends on it); by default k_m is
    the exact mean of the file's stiffness, which the trapezoidal mean of a dense sample
    of the file's rows approaches. Tooth modifications cannot change a file's excitation."""
    import equinox as eqx

    from gearjax.models.geared3d_excitation import file_mean_stiffness

    rig = get_rig("baud-velex-spur")
    mods = table1_relief("long")
    own = build_model(rig, mods, model="3d", formulation="te", max_frequency_hz=3000.0)
    v = np.asarray(own.table.values)
    at_encoders = eqx.tree_at(lambda t: t.values, own.table, jnp.asarray(
        np.column_stack([v[:, 0] + float(own.w_x0), v[:, 1], v[:, 2]])))  # (TE_S - NLTE, k, NLTE)
    th = np.arange(256) * (MESH / 256)
    s = np.asarray(jax.vmap(at_encoders)(jnp.asarray(th))[0])
    grid = np.column_stack([s[:, 0] + s[:, 2], s[:, 2], s[:, 1]])  # TE_S, NLTE, k
    t, rows = with_jump_rows(th, grid, at_encoders, own.table_side, own.jump_thetas, MESH)
    te = TETable.from_samples(t, rows[:, 0], rows[:, 1], rows[:, 2], mesh_period_rad=MESH)
    fed = build_model(rig, mods, model="3d", formulation="te", max_frequency_hz=3000.0,
                      te_table=te, mean_stiffness_N_per_m=float(own.k_m))
    assert fed.nlte_terms and fed.te_source == "arrays" and fed.angle_map is None
    x = jnp.asarray(np.random.default_rng(3).uniform(0, 2 * MESH, 1000))
    a = np.asarray(jax.vmap(own.table)(x)[0])
    b = np.asarray(jax.vmap(fed.table)(x)[0])
    assert np.all(np.max(np.abs(b - a), axis=0) <= 1e-10 * np.max(np.abs(a), axis=0))
    rng = np.random.default_rng(1)
    y = jnp.asarray(0.1 * rng.normal(size=(50, own.state_size)))
    sim = jnp.asarray(rng.uniform(0, MESH, 50))
    f_own = jax.vmap(lambda s, y: own.vector_field(s, y, 500.0))(sim, y)
    f_fed = jax.vmap(lambda s, y: fed.vector_field(s, y, 500.0))(sim, y)
    assert float(jnp.max(jnp.abs(f_fed - f_own))) <= 1e-10 * float(jnp.max(jnp.abs(f_own)))
    def wrapped(t):  # angles in [0, MESH), the period's end as its start
        t = np.mod(np.asarray(t), MESH)
        return np.sort(np.where(t > MESH - 1e-12, 0.0, t))

    np.testing.assert_allclose(wrapped(fed.jump_thetas), wrapped(own.jump_thetas), rtol=0, atol=1e-12)
    dense = np.linspace(0, MESH, 200001)  # the default k_m: the file's exact mean
    k_dense = np.asarray(te(dense)[0])[:, 2]
    assert file_mean_stiffness(te) == pytest.approx(np.trapezoid(k_dense, dense) / MESH, rel=1e-6)
    with pytest.raises(GearjaxError, match="TE file"):
        fed.with_modifications(mods)


def _sine_file(k0=7.7e8, a=1e-6, n=256):
    theta = np.arange(n) * (MESH / n)
    return TETable.from_samples(theta, 12e-6 + a * np.sin(Z1 * theta),
                                stiffness_N_per_m=np.full(theta.size, k0), mesh_period_rad=MESH)


def _modal_order1(model, omega, k0, a):
    """(DTE, force) order-1 amplitudes of Eq. (48a) under a sine TE_S (closed form)."""
    kr, cr = np.asarray(model.kbar_r), np.asarray(model.c_r)
    vr, wr, cb = np.asarray(model.v_r), np.asarray(model.w_r), model.cos_bb
    w = Z1 * omega
    q1 = np.linalg.solve(kr - w**2 * np.eye(len(vr)) + 1j * w * cr, vr * k0 * cb * a)
    return abs(wr @ q1), k0 * abs(vr @ q1 - cb * a)


def test_3d_pure_sine_te_file_against_the_closed_form_modal_receptance():
    """A pure sine TE_S = a sin(z1 theta) with a constant stiffness k0 makes Eq. (48a) of
    the 3D model linear time-invariant: ``Omega^2 X'' + Omega C X' + K_bar X = F_0 +
    k0 cos b_b (TE_S - w_x0) V``, so in the modal basis (``M_r = I``) the order-1 response
    is ``q_1 = (K_r - (z1 Omega)^2 I + i z1 Omega C_r)^-1 v_r k0 cos b_b a``, DTE order 1
    ``|w_r^T q_1|`` and force order 1 ``k0 |v_r^T q_1 - cos b_b a|`` (Eq. (41)); orders 2-5
    vanish. In the quasi-static limit the DTE is the file's TE_S (C_wv k0 cos b_b = 1,
    Eq. (35)). Below and at the tooth critical speed, damping 0.1 (contact holds); the file's
    Hermite interpolation (256 rows) is O(h^4) ~ 1e-9, the transient's rtol ~1e-6 sets the
    tolerance."""
    from gearjax.dynamics.sweep import sweep

    rig = get_rig("baud-velex-spur")
    k0, a = 7.7e8, 1e-6
    model = build_model(rig, None, model="3d", formulation="perturbation", damping_ratio=0.1,
                        max_frequency_hz=3000.0, te_table=_sine_file(k0, a))
    assert not model.nlte_terms and float(model.k_m) == pytest.approx(k0, rel=1e-12)
    assert float(model.c_wv) * k0 * model.cos_bb == pytest.approx(1.0, rel=1e-9)  # Eq. (35)
    speeds = np.array([300.0, 860.0])  # 860 rad/s: the main job's tooth critical speed
    res = sweep(model, speeds)
    assert np.all(res.converged) and not np.any(res.contact_loss)
    for i, omega in enumerate(speeds):
        dte, force = _modal_order1(model, omega, k0, a)
        np.testing.assert_allclose(res.dte_orders_m[i], [dte, 0, 0, 0, 0], rtol=0, atol=1e-5 * dte)
        np.testing.assert_allclose(res.mesh_force_orders_N[i], [force, 0, 0, 0, 0], rtol=0,
                                   atol=1e-5 * k0 * model.cos_bb * dte)
    assert res.dte_orders_m[1, 0] > 1.5 * a  # at the critical speed: amplified


@pytest.mark.slow
def test_3d_sweep_with_te_file_from_the_command_line(tmp_path, capsys):
    """`gearjax sweep --model 3d --te-file`: the sine file of the closed-form test through
    the command line (perturbation, 2 speeds) writes the closed-form order-1 DTE to
    orders.csv and records the file in summary.json."""
    import json

    k0, a = 7.7e8, 1e-6
    te = _sine_file(k0, a)
    path = _write(tmp_path / "sine.csv", ["pinion_angle_rad", "te_s_m", "mesh_stiffness_N_per_m"],
                  [(float(t), float(v[0]), float(v[2])) for t, v in zip(te.knots[:-1], te.values[:-1])])
    out = tmp_path / "o"
    assert main(["sweep", "--model", "3d", "--te-file", path, "--formulations", "perturbation",
                 "--speeds", "300:860:2", "--max-frequency", "3000", "--out", str(out),
                 "--json"]) == 0
    capsys.readouterr()
    model = build_model(get_rig("baud-velex-spur"), None, model="3d", formulation="perturbation",
                        damping_ratio=0.1, max_frequency_hz=3000.0, te_table=read_te_csv(path, MESH))
    rows = list(csv.DictReader(open(out / "orders.csv")))
    assert len(rows) == 2
    for row in rows:
        dte, _ = _modal_order1(model, float(row["speed_rad_s"]), k0, a)
        assert float(row["order1_dte_m"]) == pytest.approx(dte, rel=1e-5)
    assert json.load(open(out / "summary.json"))["te_file"].endswith("sine.csv")
