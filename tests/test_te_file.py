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


def test_te_file_refuses_reference_and_3d(tmp_path, capsys):
    path = _write(tmp_path / "ok.csv", ["mesh_cycle_fraction", "te_s_m"],
                  [(i / 8, 1e-5) for i in range(8)])
    for extra in (["--model", "torsional", "--formulations", "reference,te"], []):
        code = main(["sweep", "--te-file", path, "--speeds", "100:200:2",
                     "--out", str(tmp_path / "o"), *extra])
        err = capsys.readouterr().err.strip()
        assert code == 2 and len(err.splitlines()) == 1
        assert ("reference formulation" in err) if extra else ("--model torsional" in err)
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
    assert fed.nlte_terms and fed.formulation == "te"
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
