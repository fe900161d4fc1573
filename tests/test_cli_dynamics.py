"""`gearjax sweep` (torsional and 3D, signals) and `gearjax stability`, `gearjax info`'s
torsional figures: schema, closed forms and clear errors."""

import json
import math

import numpy as np
import pytest

from gearjax.cli.main import main
from gearjax.rigs import build_model
from gearjax.rigs.baud_velex import baud_velex_pair
from gearjax.gears.mesh import Mesh
from gearjax.models.torsional import TorsionalModel
from gearjax.rigs.registry import get_rig

CSV_COLUMNS = ("speed_rad_s", "formulation", "max_mesh_force_N", "dynamic_factor", "dte_ptp_m",
               "accel_ptp_m_s2", "min_mesh_force_N", "contact_loss", "back_contact", "converged",
               "convergence",
               "period_multiple")


def _json(capsys, argv):
    assert main(argv) == 0
    return json.loads(capsys.readouterr().out)


def _csv(path):
    return np.genfromtxt(path, delimiter=",", names=True, dtype=None, encoding="utf-8")


def test_info_torsional_figures_closed_form(capsys):
    out = _json(capsys, ["info", "--model", "torsional", "--json"])
    pair = baud_velex_pair(False)
    # solid steel cylinders at the pitch radii with the face widths (the sdof defaults)
    rho = 7800.0
    (r1, r2), (b1, b2) = pair.pitch_radii_m, (pair.face_width1_m, pair.face_width2_m)
    j1, j2 = rho * math.pi * b1 * r1**4 / 2, rho * math.pi * b2 * r2**4 / 2
    rb1, rb2 = pair.base_radii_m
    m_eq = 1.0 / (rb1**2 / j1 + rb2**2 / j2)  # Eq. (16): 1/m_eq = Rb1^2/J1 + Rb2^2/J2
    assert out["equivalent_mass_kg"] == pytest.approx(m_eq, rel=1e-12)
    w = math.sqrt(out["mean_mesh_stiffness_N_per_m"] / m_eq)  # spur: cos(beta_b) = 1
    assert out["torsional_natural_frequency_rad_s"] == pytest.approx(w, rel=1e-12)
    assert out["torsional_critical_speed_rad_s"] == pytest.approx(w / 26, rel=1e-12)
    # ISO 6336-1 uses mean diameters and the common face width: same order, not equal
    assert 0.8 < out["iso6336_resonance_speed_rad_s"] / (w / 26) < 1.3


@pytest.mark.xdist_group("torsional_cli_sweep")  # one worker runs the shared sweep
def test_torsional_sweep_with_signals(torsional_cli_sweep):
    # `gearjax sweep --model torsional --speeds 40:700:3 --formulations te,reference
    # --signals 300 --json` (tests/conftest.py; its CSV/JSON/figure: tests/test_cli.py)
    summary, out_dir = torsional_cli_sweep
    data = _csv(out_dir / "results.csv")
    assert data.dtype.names == CSV_COLUMNS
    assert len(data) == 6
    import csv

    rows = list(csv.DictReader(open(out_dir / "results.csv")))
    assert all(r["accel_ptp_m_s2"] == "" for r in rows)  # no acceleration in the sdof model
    assert summary["agreement_with_reference"]["te"]["max_rel_diff_max_mesh_force"] >= 0
    sig = _csv(out_dir / "signals.csv")
    assert set(sig["formulation"]) == {"te", "reference"} and set(sig["speed_rad_s"]) == {300.0}
    # one mesh period of samples per formulation, t/T_m in [0, 1)
    assert np.sum(sig["formulation"] == "te") == 128
    assert 0 <= sig["t_over_mesh_period"].min() and sig["t_over_mesh_period"].max() < 1
    # the plotted maximum is the sweep's maximum at that speed (same simulation settings
    # differ only in the number of measured periods: equal at steady state)
    r = TorsionalModel.build(Mesh.build(baud_velex_pair(False), "iso6336"), get_rig(
        "baud-velex-spur").modifications("short"), damping_ratio=0.1, formulation="te")
    import equinox as eqx

    from gearjax.dynamics.simulate import simulate

    one = eqx.filter_jit(simulate)(r, 300.0)  # compiled: op by op costs 2.5x the compilation
    f_te = sig["mesh_force_N"][sig["formulation"] == "te"]
    assert f_te.max() == pytest.approx(float(one.max_mesh_force_N), rel=1e-4)
    assert (out_dir / "mesh_force_signals.png").stat().st_size > 10_000



@pytest.mark.xdist_group("torsional_cli_sweep")  # one worker runs the shared sweep
def test_torsional_sweep_writes_mesh_orders(torsional_cli_sweep):
    """orders.csv (one row per results.csv row, DTE/force orders 1-5, no acceleration in
    the sdof model) and order_tracks.png of the shared sweep. A signal within [min, max]
    has single-sided amplitudes of at most 2 (max - min) / pi (the square wave's first
    harmonic): each order is bounded by the peak-to-peak of results.csv."""
    import csv

    from gearjax.dynamics.results import ORDER_COLUMNS

    summary, out_dir = torsional_cli_sweep
    rows = list(csv.DictReader(open(out_dir / "orders.csv")))
    assert tuple(rows[0]) == ORDER_COLUMNS and "order5_dte_m" in ORDER_COLUMNS
    res = {(r["formulation"], r["speed_rad_s"]): r for r in csv.DictReader(open(out_dir / "results.csv"))}
    assert sorted(res) == sorted((r["formulation"], r["speed_rad_s"]) for r in rows)
    for r in rows:
        m = res[(r["formulation"], r["speed_rad_s"])]
        dte = np.array([float(r[f"order{k}_dte_m"]) for k in range(1, 6)])
        force = np.array([float(r[f"order{k}_force_N"]) for k in range(1, 6)])
        assert np.all(dte > 0) and np.all(force > 0)
        assert np.all(dte <= 2 / np.pi * float(m["dte_ptp_m"]) * (1 + 1e-9))
        f_ptp = float(m["max_mesh_force_N"]) - float(m["min_mesh_force_N"])
        assert np.all(force <= 2 / np.pi * f_ptp * (1 + 1e-9))
        assert all(r[f"order{k}_accel_m_s2"] == "" for k in range(1, 6))
    assert summary["orders_csv"].endswith("orders.csv")
    assert (out_dir / "order_tracks.png").stat().st_size > 10_000


def test_default_case_name_and_out_dir(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    # the te sweep of the shared torsional CLI run (tests/conftest.py: same speeds, so the
    # same compiled chunk; the damping is model data, not compiled in)
    assert main(["sweep", "--model", "torsional", "--speeds", "40:700:3", "--formulations",
                 "te", "--damping", "0.03"]) == 0
    text = capsys.readouterr().out
    case = tmp_path / "gearjax-out" / "baud-velex-spur-torsional-short-zeta0.03"
    assert (case / "results.csv").exists() and (case / "summary.json").exists()
    assert "predicted main tooth critical speed" in text and "peak K_v" in text


@pytest.mark.parametrize("argv, words", [
    (["sweep", "--formulations", "reference,tee"], ["--formulations", "tee"]),
    (["sweep", "--signals", "100,abc"], ["--signals", "100,abc"]),
    (["sweep", "--signals", "-5"], ["--signals", "> 0"]),
    (["sweep", "--damping", "1.5"], ["--damping", "1.5", "[0, 1)"]),
    (["sweep", "--model", "torsional", "--encoders", "2"], ["--encoders", "3d only"]),
    (["stability", "--speeds", "0:10:3"], ["--speeds", "0 < A"]),
    (["sweep", "--coordinator", "127.0.0.1:1234"], ["--coordinator", "--num-processes"]),
    (["sweep", "--coordinator", "h:1", "--num-processes", "2", "--process-id", "2"],
     ["--process-id=2", "0..1"]),
    (["sweep", "--max-frequency", "-1"], ["--max-frequency", ">= 0 Hz"]),
    (["stability", "--max-frequency", "nan"], ["--max-frequency", ">= 0 Hz"]),
])
def test_dynamics_bad_input(capsys, argv, words):
    assert main(argv) == 2
    err = capsys.readouterr().err
    for w in words:
        assert w in err


def test_stability_perturbation_closed_form(capsys):
    """Eq. (47a) has constant coefficients: every Floquet multiplier has modulus
    exp(-zeta omega_n T) over the excitation period T = (2 pi / z1) / Omega."""
    out = _json(capsys, ["stability", "--model", "torsional", "--formulation", "perturbation",
                         "--damping", "0.05", "--speeds", "200:800:3", "--json"])
    m = TorsionalModel.build(Mesh.build(baud_velex_pair(False), "iso6336"),
                             get_rig("baud-velex-spur").modifications("short"),
                             damping_ratio=0.05, formulation="perturbation")
    w_n = float(m.natural_frequency_rad_s())
    for row in out["results"]:
        t = (2 * math.pi / 26) / row["speed_rad_s"]
        assert row["spectral_radius"] == pytest.approx(math.exp(-0.05 * w_n * t), rel=1e-6)
    assert out["unstable_speeds_rad_s"] == []


def test_stability_finds_the_principal_zone(capsys):
    """te with a square-ish stiffness and little damping: unstable where the mesh frequency
    is near twice the natural frequency (Omega1 ~ 2 omega_n / z1), stable far below."""
    m = TorsionalModel.build(Mesh.build(baud_velex_pair(False), "uniform"),
                             get_rig("baud-velex-spur").modifications("none"),
                             damping_ratio=0.005, formulation="te")
    principal = 2 * float(m.natural_frequency_rad_s()) / 26
    out = _json(capsys, ["stability", "--model", "torsional", "--stiffness", "uniform",
                         "--relief", "none", "--damping", "0.005", "--speeds",
                         f"{0.3 * principal}:{principal}:2", "--json"])
    rho = [r["spectral_radius"] for r in out["results"]]
    assert rho[0] < 1.0 < rho[1]


def test_stability_small_gain_proof_agrees_with_the_monodromy(capsys):
    """``stability --method harmonic`` proves stability by the small-gain bound without
    a monodromy where the bound is below 0.95, and integrates the monodromy elsewhere;
    ``--method steady`` integrates it everywhere. sdof te at damping 0.3: the bound (~0.5)
    proves both speeds, and the monodromy's radius confirms it; at 0.1 the bound (~1.44)
    cannot decide, so the radii are the monodromy's, equal under both methods; sdof
    perturbation (no parametric term): bound 0 (to round-off), proven. ``auto`` is the
    monodromy for the sdof model, the bound for the 3D one (te, modes < 3 kHz, damping
    0.1: bound ~0.83, no monodromy; the monodromy there gives ~0.995, the slow rig mode)."""
    sdof = ["stability", "--model", "torsional", "--speeds", "300:700:2", "--json"]
    proof = _json(capsys, sdof + ["--damping", "0.3", "--method", "harmonic"])
    radii = _json(capsys, sdof + ["--damping", "0.3", "--method", "steady"])
    assert proof["monodromies"] == 0 and radii["monodromies"] == 2
    for a, b in zip(proof["results"], radii["results"]):
        assert a["small_gain_bound"] < 0.95 and a["spectral_radius"] is None
        assert a["state"] == b["state"] == "stable" and b["spectral_radius"] < 1.0
    hb = _json(capsys, sdof + ["--method", "harmonic"])
    auto = _json(capsys, sdof)
    assert auto["method"] == "steady" and hb["monodromies"] == 2
    for a, b in zip(hb["results"], auto["results"]):
        assert a["small_gain_bound"] > 1.0  # undecided: the monodromy's radius
        assert a["spectral_radius"] == b["spectral_radius"] < 1.0
    pert = _json(capsys, sdof + ["--formulation", "perturbation", "--method", "harmonic"])
    assert pert["monodromies"] == 0
    assert all(r["small_gain_bound"] < 1e-10 and r["state"] == "stable" for r in pert["results"])
    rig3d = _json(capsys, ["stability", "--model", "3d", "--max-frequency", "3000",
                           "--speeds", "300:800:2", "--json"])
    assert rig3d["method"] == "harmonic" and rig3d["monodromies"] == 0
    assert all(r["small_gain_bound"] < 0.95 and r["state"] == "stable" for r in rig3d["results"])


def test_stability_rtol_sets_the_monodromy_tolerance(monkeypatch, capsys):
    """``stability --rtol R`` integrates the monodromy at rtol R, atol R/100."""
    import gearjax.dynamics.stability as stab

    seen = {}
    real = stab.spectral_radius

    def spy(model, speeds, **kw):
        seen.update(kw)
        return real(model, speeds, **kw)

    monkeypatch.setattr(stab, "spectral_radius", spy)
    out = _json(capsys, ["stability", "--model", "torsional", "--speeds", "500:500:1",
                         "--rtol", "1e-8", "--json"])
    assert seen == dict(rtol=1e-8, atol=1e-10) and out["rtol"] == 1e-8


# ---------------------------------------------------------------------- 3D modal cut-off
@pytest.mark.parametrize("z1, max_speed", [(26, 20.0), (26, 300.0), (26, 900.0), (26, 1500.0),
                                           (17, 2500.0), (40, 700.0)])
def test_default_cutoff_covers_the_mesh_harmonics(z1, max_speed):
    """The default cut-off keeps every mode up to 3 mesh harmonics of the highest speed
    with a 1.5 margin: the mesh period of a z1-tooth pinion at Omega is (2 pi / z1) / Omega
    seconds, its h-th harmonic h / T_m Hz; never below the former fixed 6 kHz."""
    from gearjax.models.geared3d import default_max_frequency_hz

    t_mesh_s = (2 * math.pi / z1) / max_speed
    f3 = 3 / t_mesh_s
    fc = default_max_frequency_hz(max_speed, z1)
    assert fc >= 1.5 * f3 * (1 - 1e-12) and fc >= 6000.0
    assert fc == pytest.approx(max(6000.0, 1.5 * f3), rel=1e-12)  # no more than needed
    # the Baud-Velex pinion: its angular pitch gives the same mesh period
    if z1 == 26:
        pitch_rad = baud_velex_pair(False).mesh_period_rad
        assert pitch_rad / max_speed == pytest.approx(t_mesh_s, rel=1e-12)


class _Built(Exception):
    pass


@pytest.mark.parametrize("argv, expected", [
    # default: 3 x 1.5 mesh harmonics of the highest speed (sweep range, signals included)
    (["sweep", "--speeds", "20:900:3", "--formulations", "te"], ("rule", 900.0)),
    (["sweep", "--speeds", "20:900:3", "--formulations", "te", "--signals", "1200"],
     ("rule", 1200.0)),
    (["stability", "--speeds", "100:1500:3"], ("rule", 1500.0)),
    (["sweep", "--speeds", "20:200:3", "--formulations", "te"], ("hz", 6000.0)),  # floor
    # an explicit cut-off wins, even below the rule; 0 keeps all modes
    (["sweep", "--speeds", "20:900:3", "--formulations", "te", "--max-frequency", "7000"],
     ("hz", 7000.0)),
    (["stability", "--speeds", "100:1500:3", "--max-frequency", "0"], ("hz", None)),
])
def test_cli_passes_the_cutoff_to_the_3d_model(monkeypatch, tmp_path, argv, expected):
    """The cut-off the 3D model is built with (the build is stopped right there)."""
    import gearjax.cli.case as cd

    monkeypatch.chdir(tmp_path)

    seen = {}

    def fake_build(rig, mods, **kw):
        seen.update(kw)
        raise _Built

    monkeypatch.setattr(cd, "build_model", fake_build)
    with pytest.raises(_Built):
        main(argv + ["--model", "3d", "--json"])
    kind, value = expected
    if kind == "rule":
        f_mesh = 26 * value / (2 * math.pi)
        assert seen["max_frequency_hz"] == pytest.approx(4.5 * f_mesh, rel=1e-12)
    else:
        assert seen["max_frequency_hz"] == value


@pytest.mark.parametrize("argv, top_speed, warned", [
    # the mesh frequency of the spur rig's 26-tooth pinion at 900 rad/s: 3724 Hz
    (["sweep", "--speeds", "20:900:3", "--max-frequency", "3000"], 900.0, True),
    (["sweep", "--speeds", "20:900:3", "--max-frequency", "3800"], 900.0, False),
    (["sweep", "--speeds", "20:900:3"], 900.0, False),  # the default rule
    (["sweep", "--speeds", "20:900:3", "--max-frequency", "0"], 900.0, False),  # all modes
    (["stability", "--speeds", "100:800:2", "--max-frequency", "3000"], 800.0, True),  # 3310 Hz
    (["stability", "--speeds", "100:700:2", "--max-frequency", "3000"], 700.0, False),  # 2897 Hz
])
def test_a_cutoff_below_the_mesh_frequency_is_warned(monkeypatch, tmp_path, capsys, argv,
                                                     top_speed, warned):
    """A 3D ``--max-frequency`` below the mesh frequency of the highest speed makes the
    modes the mesh excites answer quasi-statically: the command says so before it
    builds anything, naming that frequency and the default cut-off."""
    import gearjax.cli.case as cd

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(cd, "build_model", lambda *a, **k: (_ for _ in ()).throw(_Built()))
    with pytest.raises(_Built):
        main(argv + ["--model", "3d", "--json"])
    err = capsys.readouterr().err
    f_mesh = 26 * top_speed / (2 * math.pi)
    assert ("below the mesh frequency" in err) == warned
    if warned:
        assert f"({f_mesh:.0f} Hz)" in err and f"{4.5 * f_mesh:.0f} Hz" in err


@pytest.mark.slow
def test_3d_sweep_reports_its_cutoff(capsys, tmp_path):
    """A one-speed 3D sweep (te, 400 rad/s: 4.5 f_m = 7.45 kHz) reports its cut-off in the
    summary, and keeps exactly the modes of the full model (all 258 modes of (M, K_bar))
    at or below it. ~1 min on 2 shared cores."""

    summary = _json(capsys, ["sweep", "--model", "3d", "--formulations", "te", "--speeds",
                             "400:400:1", "--out", str(tmp_path), "--json"])
    fc = summary["max_frequency_hz"]
    assert fc == pytest.approx(4.5 * 26 * 400 / (2 * math.pi), rel=1e-12)
    assert summary["max_frequency_source"].startswith("default")
    full = build_model(get_rig("baud-velex-spur"),
                                  get_rig("baud-velex-spur").modifications("short"),
                                  formulation="te", damping_ratio=0.1, max_frequency_hz=None)
    f_full = np.asarray(full.omega_r) / (2 * math.pi)
    assert summary["n_modes"] == int(np.sum(f_full <= fc))
    assert json.load(open(tmp_path / "summary.json"))["max_frequency_hz"] == fc


# ---------------------------------------------------------------- NLTE'' reaction (issue 15)
def _stopped_at_build(monkeypatch, module, name, argv, real=None):
    """Run ``argv`` until ``module.name`` (the model or objective factory) is called; return
    its keyword arguments (and the model ``real`` builds, if given), the stop read as
    Ctrl-C (exit 130)."""
    seen = {}

    def fake(*a, **kw):
        seen.update(kw)
        if real is not None:
            seen["_model"] = real(*a, **kw)
        raise KeyboardInterrupt

    monkeypatch.setattr(module, name, fake)
    assert main(argv) == 130
    return seen


def _stopped_at_sweep(monkeypatch, argv):
    """Run a ``gearjax sweep`` ``argv`` with its real model build until the sweep starts;
    return the build's keyword arguments and model (``_model``). The sweep records its case
    once the model is built and reads the stop as Ctrl-C (exit 130, summary.json
    written)."""
    import gearjax.cli.case as cc
    import gearjax.dynamics.sweep as ds

    seen = {}

    def build(*a, **kw):
        seen.update(kw)
        seen["_model"] = build_model(*a, **kw)
        return seen["_model"]

    def stop(*a, **kw):
        raise KeyboardInterrupt

    monkeypatch.setattr(cc, "build_model", build)
    monkeypatch.setattr(ds, "sweep", stop)
    assert main(argv) == 130
    return seen


def test_every_command_defaults_to_the_drive_reaction(monkeypatch, tmp_path, capsys):
    """One convention: sweep, stability and optimise build their models with the NLTE''
    reaction at the drive unless told otherwise, and sweep records it in case.json and
    summary.json (the optimiser's optimum.json records the same key, see test_design)."""
    import inspect

    import gearjax.cli.case as cd
    import gearjax.design as design

    out = tmp_path / "sw"
    sw = _stopped_at_sweep(monkeypatch, [
        "sweep", "--model", "torsional", "--speeds", "300:400:2", "--formulations", "te",
        "--out", str(out), "--json"])
    st = _stopped_at_build(monkeypatch, cd, "build_model", [
        "stability", "--model", "torsional", "--speeds", "300:400:2", "--json"])
    opt = _stopped_at_build(monkeypatch, design, "make_objective", [
        "optimise", "--speeds", "300:400:2", "--out", str(tmp_path / "opt"), "--json"])
    assert sw["nlte_reaction"] == st["nlte_reaction"] == opt["nlte_reaction"] == "drive"
    assert json.loads((out / "case.json").read_text())["nlte_reaction"] == "drive"
    assert json.loads((out / "summary.json").read_text())["nlte_reaction"] == "drive"
    # ... which is also the library's default, so the CLI and a plain build agree
    default = inspect.signature(TorsionalModel.build).parameters["nlte_reaction"].default
    assert default == "drive"
    assert inspect.signature(build_model).parameters["nlte_reaction"].default == "drive"


def test_pinion_reaction_kappa_and_resume_check(monkeypatch, tmp_path, capsys):
    """``--nlte-reaction pinion`` on the torsional model: kappa = J2 / (Rb2^2 m_eq) = 1 +
    J2 Rb1^2 / (J1 Rb2^2) (Eq. (16)), from the default inertias (solid steel cylinders at
    the pitch radii) and the base radii computed here; 1 at the drive (the default). The
    case records the convention, so a resume with the other one is refused."""

    pair = baud_velex_pair(False)
    (r1, r2), (b1, b2) = pair.pitch_radii_m, (pair.face_width1_m, pair.face_width2_m)
    j1, j2 = 7800.0 * math.pi * b1 * r1**4 / 2, 7800.0 * math.pi * b2 * r2**4 / 2
    rb1, rb2 = pair.base_radii_m
    kappa = 1.0 + j2 * rb1**2 / (j1 * rb2**2)
    assert 25 < kappa < 35  # "about 30" for the Baud-Velex bodies
    out = tmp_path / "sw"
    base = ["sweep", "--model", "torsional", "--speeds", "300:400:2", "--formulations",
            "perturbation", "--out", str(out), "--json"]
    seen = _stopped_at_sweep(monkeypatch, base + ["--nlte-reaction", "pinion"])
    model = seen["_model"]
    assert model.nlte_reaction == "pinion"
    assert float(model.nlte_inertia_ratio) == pytest.approx(kappa, rel=1e-12)
    assert json.loads((out / "case.json").read_text())["nlte_reaction"] == "pinion"
    import dataclasses

    drive = dataclasses.replace(model, nlte_reaction="drive")
    assert float(drive.nlte_inertia_ratio) == 1.0
    monkeypatch.undo()
    assert main(base + ["--resume"]) == 2
    err = capsys.readouterr().err
    assert "another case" in err and "nlte" in err
    # the default folder name tells the conventions apart
    monkeypatch.chdir(tmp_path)
    seen = _stopped_at_sweep(monkeypatch, base[:-3] + ["--nlte-reaction", "pinion"])
    assert (tmp_path / "gearjax-out" / "baud-velex-spur-torsional-short-zeta0.1-nlte-pinion"
            / "case.json").exists()


def test_sweep_names_sub_harmonic_speeds(capsys, tmp_path):
    """te, short relief, zeta 0.03 at 1490 and 1510 rad/s settles on a period-2 orbit
    (tests/test_dynamics_sdof.py checks it against a long transient): the CLI lists those
    speeds as sub-harmonic, with their period, not as "not converged", and results.csv and
    summary.json say so."""
    out = tmp_path / "sub"
    assert main(["sweep", "--model", "torsional", "--formulations", "te", "--damping", "0.03",
                 "--speeds", "1490:1510:2", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "sub-harmonic" in text and "1490 (2P), 1510 (2P)" in text
    assert "not converged to steady state" not in text
    data = _csv(out / "results.csv")
    np.testing.assert_array_equal(data["period_multiple"], [2, 2])
    assert not any(data["converged"])
    summary = json.load(open(out / "summary.json"))
    assert summary["formulations"]["te"]["subharmonic_speeds"] == {"1490.0": 2, "1510.0": 2}
