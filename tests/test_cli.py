"""The `gearjax` command line: JSON keys, CSV columns, plots, clear errors."""

import json
import os

import numpy as np
import pytest

from gearjax.cli.main import main
from gearjax.rigs.baud_velex import baud_velex_pair


def _json(capsys, argv):
    assert main(argv) == 0
    return json.loads(capsys.readouterr().out)


@pytest.mark.parametrize("rig, helical", [("baud-velex-spur", False), ("baud-velex-helical", True)])
def test_info_json_keys_and_values(capsys, rig, helical):
    out = _json(capsys, ["info", "--rig", rig, "--model", "torsional", "--json"])
    pair = baud_velex_pair(helical)
    for key in ("contact_ratio", "overlap_ratio", "base_radii_m", "base_helix_angle_rad",
                "base_pitch_m", "mean_mesh_stiffness_N_per_m", "stiffness_variation_alpha",
                "static_mesh_force_N"):
        assert key in out
    assert out["contact_ratio"] == pytest.approx(pair.transverse_contact_ratio)
    # F_S = C_m0 / (Rb1 cos beta_b)
    assert out["static_mesh_force_N"] == pytest.approx(
        254.8 / (pair.base_radii_m[0] * np.cos(pair.base_helix_angle_rad)))
    assert 0 < out["stiffness_variation_alpha"] < 1


def test_info_human_readable(capsys):
    assert main(["info"]) == 0
    text = capsys.readouterr().out
    assert "contact ratio" in text and "N/um" in text


def test_quasistatic_json_csv_plot(capsys, tmp_path):
    csv, png = tmp_path / "qs.csv", tmp_path / "qs.png"
    out = _json(capsys, ["quasistatic", "--relief", "long", "--positions", "64", "--json",
                         "--csv", str(csv), "--plot", str(png)])
    for key in ("te_s_mean_m", "te_s_ptp_m", "nlte_ptp_m"):
        assert key in out
    assert out["nlte_ptp_m"] > 1e-6  # long relief: NLTE != 0 (Section 6.3.2)
    data = np.genfromtxt(csv, delimiter=",", names=True)
    assert data.dtype.names == ("theta_rad", "te_s_m", "nlte_m", "mesh_force_N",
                                "mesh_stiffness_N_per_m")
    # the 64 positions + two rows (left, right) at every jump angle (a --te-file)
    th = data["theta_rad"]
    assert np.all(np.diff(th) >= 0) and len(np.unique(th)) >= 64 - 6 and len(th) > 64
    assert np.all(data["mesh_stiffness_N_per_m"] > 0)
    np.testing.assert_allclose(data["mesh_force_N"], out["static_mesh_force_N"], rtol=1e-9)
    assert png.stat().st_size > 10_000


def test_quasistatic_pitch_errors_span_a_revolution(capsys):
    out = _json(capsys, ["quasistatic", "--pitch-errors", "--positions", "8", "--json"])
    assert out["positions"] == 8 * 26
    assert out["span_rad"] == pytest.approx(2 * np.pi)
    assert out["nlte_ptp_m"] > 1e-6


@pytest.mark.parametrize(
    "argv, words",
    [
        (["info", "--rig", "nope"], "rig='nope'"),
        (["quasistatic", "--relief-extent", "1.5"], "relief_extent"),
        (["quasistatic", "--relief-amplitude=-1e-6"], "relief_amplitude_m"),
        (["quasistatic", "--positions", "2"], "--positions=2"),
    ],
)
def test_bad_input_is_a_clear_error(capsys, argv, words):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert words in err and "Traceback" not in err


@pytest.mark.parametrize("encoders", [1, 3])
def test_info_3d_reports_appendix_a_relations(capsys, encoders):
    out = _json(capsys, ["info", "--model", "3d", "--encoders", str(encoders), "--json"])
    assert out["n_dof"] == 258  # Section 6.1: 43 nodes x 6 dof
    # Eqs. (33)-(35) hold whatever the encoder position (Appendix A)
    for key in ("C_vv_times_km", "C_wv_times_km_cos_beta_b", "v_x0_times_km_over_FS"):
        assert out[key] == pytest.approx(1.0, abs=1e-9)
    f = np.asarray(out["natural_frequencies_hz"])
    assert f[0] > 0 and np.all(np.diff(f) >= 0)  # K_bar invertible: no rigid-body mode left


@pytest.mark.xdist_group("torsional_cli_sweep")  # one worker runs the shared sweep
def test_sweep_writes_csv_json_and_figure(torsional_cli_sweep):
    # `gearjax sweep --model torsional --speeds 40:700:3 --formulations te,reference ...`,
    # shared with tests/test_cli_dynamics.py (tests/conftest.py)
    summary, out_dir = torsional_cli_sweep
    data = np.genfromtxt(out_dir / "results.csv", delimiter=",", names=True, dtype=None,
                         encoding="utf-8")
    assert data.dtype.names == ("speed_rad_s", "formulation", "max_mesh_force_N", "dynamic_factor",
                                "dte_ptp_m", "accel_ptp_m_s2", "min_mesh_force_N", "contact_loss",
                                "back_contact", "converged", "convergence", "period_multiple")
    assert len(data) == 6 and set(data["formulation"]) == {"reference", "te"}
    # Eq. (24): max F_D / F_S is the dynamic factor
    f_s = 254.8 / baud_velex_pair(False).base_radii_m[0]
    np.testing.assert_allclose(data["max_mesh_force_N"] / data["dynamic_factor"], f_s, rtol=1e-9)
    assert set(summary["formulations"]) == {"reference", "te"}
    assert json.loads((out_dir / "summary.json").read_text())["rig"] == "baud-velex-spur"
    assert (out_dir / "response_curves.png").stat().st_size > 10_000


def test_sweep_bad_speeds(capsys):
    assert main(["sweep", "--speeds", "900:20:5"]) == 2
    assert "--speeds='900:20:5'" in capsys.readouterr().err


def test_compile_bound_sweeps_take_xla_legacy_emitters(monkeypatch):
    """The README main job, other compile-bound sweeps and the torsional optimiser ask XLA
    for its legacy CPU emitters (gearjax.cli.main, measured there); a long 3D sweep, a long
    excitation period, the 3D optimiser, other commands, a caller's own choice and
    GEARJAX_XLA_DEFAULTS=0 keep XLA's default.
    The flag must be one this jaxlib knows: XLA aborts the process on an unknown flag."""
    import importlib
    import subprocess
    import sys

    cli = importlib.import_module("gearjax.cli.main")
    parse = cli._parser().parse_args
    bound = {("sweep",): True, ("sweep", "--model", "torsional", "--speeds", "1:2:9000"): True,
             ("sweep", "--speeds", "20:900:300"): True,
             ("sweep", "--speeds", "20:900:301"): False, ("sweep", "--pitch-errors"): False,
             ("sweep", "--eccentricity", "1e-5"): False, ("sweep", "--damping", "0.03"): False,
             ("sweep", "--model", "torsional", "--damping", "0.03"): True, ("paper",): False,
             ("optimise",): True, ("optimise", "--model", "3d"): False,
             ("harris-map",): False}
    for argv, want in bound.items():
        assert cli.compile_bound(parse(list(argv))) is want, argv
    xla = importlib.import_module("gearjax.runtime.xla")
    monkeypatch.delenv("GEARJAX_XLA_DEFAULTS", raising=False)
    monkeypatch.setenv("GEARJAX_COMPILATION_CACHE", "0")  # the flags alone
    monkeypatch.setattr(xla, "jaxlib_minor", lambda: xla.FUSION_FLAG_JAXLIB)
    workarounds = " ".join(xla.CPU_WORKAROUND_FLAGS)
    for flags, argv, want in (
            ("--xla_cpu_foo=1", ["sweep"],
             f"--xla_cpu_foo=1 {workarounds} --xla_cpu_use_fusion_emitters=false"),
            ("", ["sweep", "--speeds", "20:900:1000"], workarounds),
            ("--xla_cpu_use_fusion_emitters=true", ["sweep"],
             f"--xla_cpu_use_fusion_emitters=true {workarounds}")):
        monkeypatch.setenv("XLA_FLAGS", flags)
        cli.configure_process(parse(argv), own_process=True)
        assert os.environ["XLA_FLAGS"] == want
    # a caller's process (main(argv) in-process) never gets the emitters
    monkeypatch.setenv("XLA_FLAGS", "")
    cli.configure_process(parse(["sweep"]), own_process=False)
    assert os.environ["XLA_FLAGS"] == workarounds
    monkeypatch.setenv("XLA_FLAGS", "")
    monkeypatch.setenv("GEARJAX_XLA_DEFAULTS", "0")
    cli.configure_process(parse(["sweep"]), own_process=True)
    assert os.environ["XLA_FLAGS"] == ""
    monkeypatch.delenv("GEARJAX_XLA_DEFAULTS")
    monkeypatch.setattr(xla, "jaxlib_minor", lambda: (0, 11))  # not measured there
    assert xla.use_legacy_emitters() == []
    assert os.environ["XLA_FLAGS"] == ""
    if importlib.import_module("importlib.metadata").version("jaxlib").startswith("0.10."):
        env = dict(os.environ, XLA_FLAGS=f"{xla.FUSION_FLAG}=false", JAX_PLATFORMS="cpu")
        run = subprocess.run([sys.executable, "-c", "import jax.numpy as j; print(j.ones(2).sum())"],
                             env=env, capture_output=True, text=True, timeout=120)
        assert run.returncode == 0 and "2.0" in run.stdout, run.stderr[-500:]


def test_sweep_programs_reach_the_persistent_compilation_cache(tmp_path):
    """The command line's sweep program has no host callback (equinox's checks as NaN,
    gearjax.runtime.use_cacheable_checks), so JAX stores it in the persistent cache and
    a second run loads it instead of compiling (README main job: 29 -> 18 s). With
    ``EQX_ON_ERROR=raise`` (equinox's default) nothing of it is stored."""
    import subprocess
    import sys

    env = {k: v for k, v in os.environ.items() if k != "EQX_ON_ERROR"}
    env.update(JAX_COMPILATION_CACHE_DIR=str(tmp_path / "cache"),
               JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS="0")
    argv = [sys.executable, "-c", "import sys; from gearjax.cli import main; sys.exit(main())",
            "sweep", "--model", "torsional", "--formulations", "te", "--speeds", "100:200:2",
            "--json", "--out", str(tmp_path / "out")]
    run = subprocess.run(argv, env=env, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-800:]
    stored = sorted(p.name for p in (tmp_path / "cache").iterdir())
    # the sweep's program: _batched (sdof) on one CPU device (tests/conftest.py), run sharded
    assert any(n.startswith(("jit__batched-", "jit_run-")) for n in stored), stored


def test_one_cpu_device_per_core_unless_told(monkeypatch):
    """The sweeping commands ask XLA for one CPU device per usable core (a transient sweep
    shares its speeds over them), the others do not; GEARJAX_HOST_DEVICES is honoured and
    a device count already in XLA_FLAGS never overridden (it must act before JAX starts
    its CPU backend)."""
    import os

    import importlib

    cli = importlib.import_module("gearjax.cli.main")  # the package exports main()
    xla = importlib.import_module("gearjax.runtime.xla")
    parse = cli._parser().parse_args
    workarounds = " ".join(xla.CPU_WORKAROUND_FLAGS)

    monkeypatch.delenv("GEARJAX_HOST_DEVICES", raising=False)
    monkeypatch.delenv("GEARJAX_XLA_DEFAULTS", raising=False)
    monkeypatch.setenv("GEARJAX_COMPILATION_CACHE", "0")  # the flags alone
    monkeypatch.setenv("XLA_FLAGS", "--xla_cpu_foo=1")
    cores = len(os.sched_getaffinity(0))
    assert xla.host_device_count() == cores
    cli.configure_process(parse(["optimise"]), own_process=False)  # no sweep to shard
    assert os.environ["XLA_FLAGS"] == f"--xla_cpu_foo=1 {workarounds}"
    monkeypatch.setenv("XLA_FLAGS", "--xla_cpu_foo=1")
    cli.configure_process(parse(["sweep"]), own_process=False)
    expected = f"--xla_cpu_foo=1 {workarounds}" + (
        f" --xla_force_host_platform_device_count={cores}" if cores > 1 else "")
    assert os.environ["XLA_FLAGS"] == expected
    monkeypatch.setenv("GEARJAX_HOST_DEVICES", "3")
    monkeypatch.setenv("XLA_FLAGS", f"--xla_force_host_platform_device_count=5 {workarounds}")
    assert xla.host_device_count() == 3
    cli.configure_process(parse(["paper"]), own_process=False)  # an explicit count stays
    assert os.environ["XLA_FLAGS"] == f"--xla_force_host_platform_device_count=5 {workarounds}"
    monkeypatch.setenv("XLA_FLAGS", workarounds)
    cli.configure_process(parse(["sweep"]), own_process=False)
    assert os.environ["XLA_FLAGS"] == f"{workarounds} --xla_force_host_platform_device_count=3"
    for bad in ("two", "0", "-1"):  # a clear error naming the variable, not a silent 1
        monkeypatch.setenv("GEARJAX_HOST_DEVICES", bad)
        with pytest.raises(ValueError, match="GEARJAX_HOST_DEVICES"):
            xla.host_device_count()
        assert main(["sweep", "--speeds", "100:200:2"]) == 2  # one line, exit 2
    # a jaxlib whose XLA:CPU crashed compiling the sharded 3D sweep: one device unless asked
    monkeypatch.setattr(xla, "jaxlib_minor", lambda: (0, 11))
    monkeypatch.delenv("GEARJAX_HOST_DEVICES")
    assert xla.host_device_count() == 1
    monkeypatch.setenv("GEARJAX_HOST_DEVICES", "4")
    assert xla.host_device_count() == 4


def test_compile_ahead_only_where_a_linear_3d_sweep_follows_the_reference(monkeypatch):
    """gearjax.cli.ahead: the te/perturbation program compiles during the reference sweep
    only for a 3D independent transient sweep with a linear formulation after the
    reference one (a torsional sweep compiles in seconds; the continuation and the other
    methods run other programs); GEARJAX_COMPILE_AHEAD=0 turns it off."""
    from argparse import Namespace

    from gearjax.cli.ahead import worth_compiling_ahead

    def pick(forms, form="reference", **kw):
        args = Namespace(**{**dict(model="3d", direction="independent", method="auto"), **kw})
        return worth_compiling_ahead(args, forms, form, None)

    main_job = ["reference", "te", "perturbation"]
    assert pick(main_job) == "te"
    assert pick(["reference", "perturbation"], method="transient") == "perturbation"
    assert pick(main_job, form="te") is None  # the te sweep itself
    assert pick(["te", "reference"]) is None  # nothing linear left after the reference
    assert pick(main_job, model="torsional") is None
    assert pick(main_job, direction="up") is None
    assert pick(main_job, method="harmonic") is None
    monkeypatch.setenv("GEARJAX_COMPILE_AHEAD", "0")
    assert pick(main_job) is None


def test_reference_program_compiles_while_the_te_model_is_built(monkeypatch):
    """gearjax.cli.ahead: the reference program is traced and set compiling before the te
    model is built (the build's Python then runs beside XLA's compile), the te program
    after it; each sweep waits for its own program only, and the reference's tracing
    counts as its time."""
    from argparse import Namespace

    from gearjax.cli import ahead as ahead_mod

    order = []

    class Thread:  # stands for a compiling thread: records what waited on it
        def __init__(self, name):
            self.name = name

        def join(self):
            order.append(("join", self.name))

    def compile_ahead(model, speeds, **kw):
        order.append(("compile", model))
        return Thread(model)

    def build(form):
        order.append(("build", form))
        return form

    monkeypatch.setattr(ahead_mod, "compile_ahead", compile_ahead)
    args = Namespace(model="3d", direction="independent", method="auto")
    forms = ["reference", "te", "perturbation"]
    early = {}
    got = ahead_mod.build_and_compile_ahead(args, forms, "reference", "reference", build,
                                            lambda f: np.ones(3), lambda m: {}, early)
    assert order == [("compile", "reference"), ("build", "te"), ("compile", "te")]
    assert got.own.name == "reference" and got.nxt.name == "te" and got.own_trace_s >= 0.0
    assert early["te"][0] == "te"
    del order[:]
    got.join(mine=True, linear=False)  # the reference sweep
    got.join(mine=False, linear=True)  # te, then perturbation (a no-op join again)
    assert order == [("join", "reference"), ("join", "te")]
    # nothing ahead: an empty Ahead, whose join waits for nothing
    none = ahead_mod.build_and_compile_ahead(Namespace(**{**vars(args), "model": "torsional"}),
                                             forms, "reference", "reference", build,
                                             lambda f: np.ones(3), lambda m: {}, {})
    assert none == ahead_mod.Ahead()
    none.join(mine=True, linear=True)
    assert order == [("join", "reference"), ("join", "te")]
