"""Bad and edge inputs of the command line (issue 16): every case ends with a clear one-line
error naming the option or field, the value and the reason, exit status 2, no traceback,
and (where it matters) before any computing; plus the behaviours that replaced silent wrong
results: rig-file modifications applied, labels from the values used, undamped stability
neutral, peaks over converged speeds only, no results deleted, Ctrl-C kept and resumed.

Kept fast: errors fire before computing, dynamic runs use the torsional model and a few
speeds; one subprocess for Ctrl-C.
"""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from gearjax.cli.main import main

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "rigs" / "baud_velex_spur.toml"
EXAMPLE_TEXT = EXAMPLE.read_text()


def _run(capsys, argv):
    try:
        code = main([str(a) for a in argv])
    except SystemExit as exc:  # argparse errors
        code = exc.code
    cap = capsys.readouterr()
    return code, cap.out, cap.err


def _rig(tmp_path, old=None, new=None, every=False, extra="", name="rig.toml"):
    text = EXAMPLE_TEXT
    if old is not None:
        assert old in text, old
        text = text.replace(old, new, -1 if every else 1)
    p = tmp_path / name
    p.write_text(text + extra)
    return p


# ------------------------------------------------------------------ clean one-line errors
# (argv with {tmp} for the test's folder, {file} for an existing plain file; words expected
# in the message)
CASES = [
    # unknown / malformed inputs that already gave clean errors
    (["info", "--rig", "nope"], ["rig='nope'", "unknown rig"]),
    (["info", "--rig", "{tmp}/missing.toml"], ["missing.toml", "cannot read"]),
    (["sweep", "--damping", "-0.1"], ["--damping=-0.1", "[0, 1)"]),
    (["sweep", "--damping", "nan"], ["--damping=nan", "[0, 1)"]),
    (["sweep", "--damping", "inf"], ["--damping=inf", "[0, 1)"]),
    (["sweep", "--rtol", "0.5"], ["--rtol=0.5", "[1e-13, 1e-2]"]),
    (["sweep", "--rtol", "nan"], ["--rtol=nan", "[1e-13, 1e-2]"]),
    (["sweep", "--rtol", "1e-9", "--direction", "up"], ["--rtol=1e-09", "independent sweeps"]),
    (["stability", "--damping", "1.5"], ["--damping=1.5"]),
    (["sweep", "--speeds", "900:20:5"], ["--speeds='900:20:5'"]),
    (["sweep", "--speeds", "abc"], ["--speeds='abc'", "A:B:N"]),
    (["sweep", "--speeds", "0:10:3"], ["--speeds='0:10:3'", "0 < A"]),
    (["sweep", "--speeds", "1:inf:3"], ["--speeds='1:inf:3'"]),
    (["sweep", "--speeds=-5:10:3"], ["--speeds='-5:10:3'"]),
    (["sweep", "--speeds", "-5:10:3"], ["--speeds", "expected one argument"]),  # argparse
    (["stability", "--speeds", "1:2"], ["--speeds='1:2'"]),
    (["stability", "--rtol", "0.5"], ["--rtol=0.5", "[1e-13, 1e-2]"]),
    (["optimise", "--rtol", "nan"], ["--rtol=nan", "[1e-13, 1e-2]"]),
    (["stability", "--method", "transient"], ["--method", "invalid choice"]),
    (["sweep", "--formulations", "reference,tee"], ["--formulations", "tee"]),
    (["sweep", "--signals", "100,abc"], ["--signals", "100,abc"]),
    (["sweep", "--signals", "-5"], ["--signals", "> 0"]),
    (["sweep", "--model", "torsional", "--encoders", "2"], ["--encoders", "3d only"]),
    (["sweep", "--max-frequency", "-1"], ["--max-frequency", ">= 0 Hz"]),
    (["stability", "--max-frequency", "nan"], ["--max-frequency", ">= 0 Hz"]),
    (["sweep", "--chunk", "0", "--model", "torsional"], ["--chunk=0"]),
    (["sweep", "--resume", "--overwrite", "--model", "torsional"], ["--resume", "--overwrite"]),
    (["sweep", "--resume", "--distributed"], ["--resume", "several processes"]),
    (["quasistatic", "--relief-extent", "1.5"], ["relief_extent"]),
    (["quasistatic", "--relief-amplitude=-1e-6"], ["relief_amplitude_m"]),
    (["quasistatic", "--positions", "2"], ["--positions=2"]),
    (["harris-map", "--speeds", "5:1:3"], ["--speeds='5:1:3'"]),
    (["harris-map", "--amplitudes", "0:1e-4:3"], ["--amplitudes='0:1e-4:3'", "<= 4e-05 (m)"]),
    (["harris-map", "--extents", "x"], ["--extents='x'", "A:B:N"]),
    (["harris-map", "--inertias", "1,-2"], ["--inertias='1,-2'"]),
    # issue 16: array sizes against memory, before computing
    (["quasistatic", "--positions", "100000000"], ["--positions=100000000", "GiB", "at most"]),
    # issue 16: output paths, checked first
    (["quasistatic", "--plot", "{tmp}"], ["--plot=", "is a folder"]),
    (["quasistatic", "--plot", "{tmp}/te"], ["--plot=", "figure file name", ".png"]),
    (["quasistatic", "--csv", "{tmp}"], ["--csv=", "is a folder"]),
    (["quasistatic", "--csv", "{file}/te.csv"], ["--csv=", "is a file, not a folder"]),
    (["quasistatic", "--csv", "/proc/gearjax-x/te.csv"], ["--csv=", "/proc"]),
    (["sweep", "--model", "torsional", "--out", "{file}"], ["--out=", "is a file"]),
    (["sweep", "--model", "torsional", "--out", "{file}/sub"], ["--out=", "is a file, not a folder"]),
    (["sweep", "--model", "torsional", "--out", "/proc/gearjax-x"], ["--out='/proc/gearjax-x'", "cannot"]),
    (["harris-map", "--out", "{file}/sub"], ["--out=", "is a file, not a folder"]),
    # issue 16: a 3D cut-off keeping no mode (checked from the rig's modes, before building)
    (["stability", "--max-frequency", "1", "--speeds", "100:100:1"],
     ["--max-frequency=1.0", "keeps no vibration mode", "lowest natural frequency"]),
    (["sweep", "--max-frequency", "1", "--speeds", "100:100:1", "--out", "{tmp}/mf"],
     ["--max-frequency=1.0", "keeps no vibration mode"]),
    # issue 15: the NLTE'' reaction at the pinion is a torsional-model option; the 3D model
    # puts it at its torque node (the drive), refused before anything is written
    (["sweep", "--nlte-reaction", "pinion", "--out", "{tmp}/nr"],
     ["--nlte-reaction='pinion'", "3D model", "torque node"]),
    (["stability", "--model", "3d", "--nlte-reaction", "pinion"],
     ["--nlte-reaction='pinion'", "3D model"]),
    (["harris-map", "--model", "3d", "--nlte-reaction", "pinion", "--out", "{tmp}/nr"],
     ["--nlte-reaction='pinion'", "3D model"]),
    (["sweep", "--model", "torsional", "--nlte-reaction", "motor"], ["--nlte-reaction", "motor"]),
]


@pytest.mark.parametrize("argv, words", CASES, ids=[" ".join(c[0])[:60] for c in CASES])
def test_bad_input_one_line_error(capsys, tmp_path, argv, words):
    plain = tmp_path / "plain.txt"
    plain.write_text("not a folder")
    argv = [a.format(tmp=tmp_path, file=plain) for a in argv]
    code, out, err = _run(capsys, argv)
    assert code == 2, (code, err)
    assert "Traceback" not in err + out
    line = [ln for ln in err.splitlines() if ln.startswith("gearjax") and " error: " in ln]
    assert len(line) == 1, err
    for w in words:
        assert w in line[0], (w, line[0])
    assert not Path(str(tmp_path) + ".png").exists()  # --plot DIR never writes DIR.png


def test_unwritable_output_folder(capsys, tmp_path):
    if os.geteuid() == 0:
        pytest.skip("root writes into read-only folders")
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        code, _, err = _run(capsys, ["quasistatic", "--csv", ro / "te.csv"])
        assert code == 2 and "cannot write" in err and "Traceback" not in err
        code, _, err = _run(capsys, ["sweep", "--model", "torsional", "--out", ro / "x"])
        assert code == 2 and "--out=" in err and "Traceback" not in err
    finally:
        ro.chmod(0o755)


# ----------------------------------------------------------------------- rig files
RIG_CASES = [
    # already clean: unknown keys, bad types, non-finite and negative values
    (("pinion_torque_Nm = 254.8", "pinion_torque_Nm = -5.0"), ["operating.pinion_torque_Nm=-5.0", "> 0"]),
    (("pinion_torque_Nm = 254.8", "pinion_torque_Nm = nan"), ["pinion_torque_Nm=nan", "finite"]),
    (("pinion_torque_Nm = 254.8", "pinion_torque_Nm = inf"), ["pinion_torque_Nm=inf", "finite"]),
    (("pinion_torque_Nm = 254.8", "pinion_torque_Nm = \"big\""), ["pinion_torque_Nm='big'", "number"]),
    (("pinion_torque_Nm = 254.8", "pinion_torq_Nm = 254.8"), ["pinion_torq_Nm", "did you mean"]),
    (("k_S_N_per_m = 1e9", "k_S_N_per_m = -1e9"), ["k_S_N_per_m=-1000000000.0", ">= 0"]),
    # issue 16: gear data ranges
    (("z1 = 26", "z1 = 1000000000"), ["gear_pair.z1=1000000000", "above 2000"]),
    # issue 16: values range-checked before the rigid-body analysis
    # issue 52: "rigid" supports (1e14 N/m) read (test_rigid_supports_are_accepted); the
    # limit is where float64 eigenvalues lose the soft modes, and the message states it
    (("k_S_N_per_m = 1e9", "k_S_N_per_m = 1e17"),
     ["bearing[0].k_S_N_per_m=1e+17", "physical range", "1e+16] N/m"]),
    # issue 52: face widths in millimetres typed as metres (k_m x 1000), pointed teeth
    (("face_width1_m = 0.050", "face_width1_m = 50"),
     ["gear_pair.face_width1_m=50", "millimetres typed as metres", "0.05"]),
    (("face_width2_m = 0.040", "face_width2_m = 25.0"),
     ["gear_pair.face_width2_m=25.0", "millimetres typed as metres", "0.025"]),
    (("profile_shift1 = 0.16\nprofile_shift2 = -0.16", "profile_shift1 = 1.2\nprofile_shift2 = 0.0"),
     ["gear_pair.profile_shift1=1.2", "pointed", "m_n"]),
    (("k_torsion_Nm_per_rad = 5e4", "k_torsion_Nm_per_rad = 1e300"),
     ["coupling[0].k_torsion_Nm_per_rad=1e+300", "physical range"]),
    (("outer_diameter_m = 0.060\naxis", "outer_diameter_m = 1e6\naxis"),
     ["outer_diameter_m=1000000.0", "physical range"]),
    (("z_m = [-1.100, -1.000", "z_m = [-1.100, -1.0999999999"), ["z_m[1]", "below 0.0001 m"]),
    # tilting stiffness of every Table 2 bearing: once read as "2 rigid-body modes ...
    # missing bearings?" (soft modes lost in round-off); now out of range, named
    (("[[bearing]]\n", "[[bearing]]\nk_phi_Nm_per_rad = 1e10\nk_psi_Nm_per_rad = 1e10\n", True),
     ["bearing[1].k_phi_Nm_per_rad=10000000000.0", "physical range"]),
]


@pytest.mark.parametrize("edit, words", RIG_CASES, ids=[c[0][1].strip()[:40] for c in RIG_CASES])
def test_bad_rig_file(capsys, tmp_path, edit, words):
    path = _rig(tmp_path, *edit)
    code, out, err = _run(capsys, ["info", "--model", "torsional", "--rig", path])
    assert code == 2, err
    assert "Traceback" not in err + out and "missing bearings" not in err
    for w in words:
        assert w in err, (w, err)


def test_rigid_supports_are_accepted(capsys, tmp_path):
    # every bearing at 1e14 N/m, as users write "rigid" (issue 52): once refused above 1e13
    # N/m; the soft modes (the resisting load's torsion near 9.8 Hz) stay resolved
    path = _rig(tmp_path, "k_S_N_per_m = 1e9\nk_T_N_per_m = 1e9",
                "k_S_N_per_m = 1e14\nk_T_N_per_m = 1e14", every=True)
    assert EXAMPLE_TEXT.count("k_S_N_per_m = 1e9\nk_T_N_per_m = 1e9") >= 2
    code, out, err = _run(capsys, ["info", "--rig", path, "--model", "3d", "--json"])
    assert code == 0, err
    stiff = json.loads(out)["natural_frequencies_hz"]
    code, out, _ = _run(capsys, ["info", "--rig", EXAMPLE, "--model", "3d", "--json"])
    soft = json.loads(out)["natural_frequencies_hz"]
    assert stiff[0] == pytest.approx(soft[0], rel=1e-3)  # the torsional mode, not zeroed
    assert stiff[0] > 1.0


def test_rig_file_with_byte_order_mark_reads(capsys, tmp_path):
    path = tmp_path / "bom.toml"
    path.write_bytes(b"\xef\xbb\xbf" + EXAMPLE_TEXT.encode())
    code, out, err = _run(capsys, ["info", "--rig", path, "--model", "torsional", "--json"])
    assert code == 0 and "Traceback" not in err, err
    assert json.loads(out)["tooth_numbers"] == [26, 157]


def test_node_on_two_shaft_lines_is_refused(capsys, tmp_path):
    bridge = ('\n[[shaft]]\nname = "bridge"\nline = "gear"\nnodes = [20, 28]\n'
              'z_m = [0.0, 0.1]\nouter_diameter_m = 0.05\naxis = "gear"\n')
    path = _rig(tmp_path, extra=bridge)
    code, _, err = _run(capsys, ["info", "--rig", path])
    assert code == 2 and "Traceback" not in err
    assert "shaft[3].nodes=20" in err and "'pinion'" in err and "'gear'" in err


# ------------------------------------------------- modifications, labels, summaries
def test_rig_file_modifications_are_applied_and_overridden(capsys, tmp_path):
    # the example's [modifications]: Table 1 short relief and pinion pitch errors; made
    # 20 um over 0.3 here so that they differ from the CLI default
    path = _rig(tmp_path, "relief_amplitude_m = 13.3e-6\nrelief_extent = 0.2",
                "relief_amplitude_m = 20e-6\nrelief_extent = 0.3", every=True)
    code, out, err = _run(capsys, ["quasistatic", "--rig", path, "--positions", "8", "--json"])
    assert code == 0, err
    s = json.loads(out)
    assert s["relief_source"] == "rig file [modifications]" and s["pitch_errors"]
    assert s["positions"] == 8 * 26  # pitch errors: a pinion revolution
    assert s["relief_amplitude_m"] == pytest.approx([20e-6, 20e-6])
    assert s["relief_extent"] == pytest.approx([0.3, 0.3])
    code, out, _ = _run(capsys, ["quasistatic", "--rig", path, "--positions", "8", "--json",
                                 "--relief-amplitude", "5e-6"])
    s = json.loads(out)
    assert "--relief-amplitude" in s["relief_source"] and "rig file" in s["relief_source"]
    assert s["relief_amplitude_m"] == pytest.approx([5e-6, 5e-6])
    assert s["relief_extent"] == pytest.approx([0.3, 0.3])  # the file's extent kept
    code, out, _ = _run(capsys, ["quasistatic", "--rig", path, "--positions", "8", "--json",
                                 "--relief", "long"])
    s = json.loads(out)
    assert s["relief_source"] == "--relief long" and s["relief_extent"] == pytest.approx([0.5, 0.5])


def test_labels_from_the_values_used(capsys, tmp_path):
    csv_path = tmp_path / "new" / "deeper" / "te.csv"  # missing folders are created
    code, out, _ = _run(capsys, ["quasistatic", "--positions", "64", "--json",
                                 "--relief-amplitude", "10e-6", "--csv", csv_path])
    s = json.loads(out)
    assert code == 0 and csv_path.exists()
    assert "short" not in s["relief_label"] and "10 um" in s["relief_label"]
    assert "--relief-amplitude" in s["relief_source"]


def test_undamped_stability_is_neutral_not_unstable(capsys):
    code, out, err = _run(capsys, ["stability", "--model", "torsional", "--damping", "0",
                                   "--speeds", "300:700:2"])
    assert code == 0 and "Traceback" not in err
    assert "UNSTABLE" not in out and "neutral" in out


def test_peak_dynamic_factor_over_converged_speeds_only():
    from gearjax.cli.results import summarise_rows

    def row(w, df, conv):
        return {"speed_rad_s": repr(w), "formulation": "te", "max_mesh_force_N": repr(df * 1e4),
                "dynamic_factor": repr(df), "contact_loss": "False", "converged": str(conv)}

    rows = [row(100.0, 1.2, True), row(200.0, 3.5e22, False), row(300.0, 1.6, True)]
    s = summarise_rows(rows, "te", np.array([100.0, 200.0, 300.0, 400.0]))
    assert s["peak_dynamic_factor"] == 1.6 and s["critical_speed_rad_s"] == 300.0
    assert s["unconverged_speeds"] == [200.0] and s["missing_speeds"] == [400.0]
    none = summarise_rows([row(200.0, 3.5e22, False)], "te", np.array([200.0]))
    assert math.isnan(none["peak_dynamic_factor"])


def test_version_help_and_rig_help(capsys):
    code, out, _ = _run(capsys, ["--version"])
    assert code == 0 and out.startswith("gearjax ")
    code, out, _ = _run(capsys, ["--help"])
    assert code == 0 and out.count("\n  gearjax ") >= 3
    code, out, _ = _run(capsys, ["sweep", "--help"])
    assert code == 0 and "FILE.toml" in out and "--resume" in out and "--overwrite" in out


# ----------------------------------------------------- no lost work: overwrite, Ctrl-C, resume
SWEEP = ["sweep", "--model", "torsional", "--formulations", "te"]


def test_rerun_refuses_then_overwrite(capsys, tmp_path):
    out = tmp_path / "sw"
    argv = SWEEP + ["--speeds", "300:500:2", "--out", out, "--json"]
    assert _run(capsys, argv)[0] == 0
    (out / "notes.txt").write_text("mine")
    before = (out / "results.csv").read_text()
    code, _, err = _run(capsys, argv)
    assert code == 2 and "earlier run" in err and "--overwrite" in err and "--resume" in err
    assert (out / "results.csv").read_text() == before  # nothing deleted
    code, _, _ = _run(capsys, argv + ["--overwrite"])
    assert code == 0 and (out / "notes.txt").read_text() == "mine"
    assert len((out / "results.csv").read_text().splitlines()) == 3
    # --resume of a finished run computes nothing; another case is refused
    code, _, err = _run(capsys, argv + ["--resume"])
    assert code == 0 and json.loads((out / "summary.json").read_text())["resumed"] == {"te": 2}
    code, _, err = _run(capsys, SWEEP + ["--speeds", "300:500:3", "--out", out, "--resume"])
    assert code == 2 and "another case" in err and "speeds_rad_s" in err
    # a results.csv of an earlier version (one column fewer, one speed still to run): refused
    # by --resume before computing (its rows are not read under the new columns, and the
    # new rows are not appended under the old header)
    lines = (out / "results.csv").read_text().splitlines()
    old = "".join(line.rsplit(",", 1)[0] + "\n" for line in lines[:2])
    (out / "results.csv").write_text(old)
    stamp = (out / "summary.json").stat().st_mtime_ns
    code, _, err = _run(capsys, argv + ["--resume"])
    assert code == 2 and "--resume" in err and "results.csv" in err and "earlier version" in err
    assert (out / "summary.json").stat().st_mtime_ns == stamp  # nothing run, nothing written
    assert (out / "results.csv").read_text() == old  # its rows kept as they were


def test_ctrl_c_keeps_results_and_resume_finishes(tmp_path):
    out = tmp_path / "int"
    # a process started in the background by a non-interactive shell (CI scripts, `cmd &`)
    # inherits SIGINT ignored, and Python then installs no KeyboardInterrupt handler: the
    # CLI gets the handler of an interactive terminal (set in the child, not by a
    # preexec_fn, which would run Python between fork and exec of a multithreaded parent)
    argv = [sys.executable, "-c", "import runpy, signal; signal.signal(signal.SIGINT, "
            "signal.default_int_handler); runpy.run_module('gearjax.cli.main', "
            "run_name='__main__')"] + SWEEP + [
        "--speeds", "100:900:40", "--chunk", "1", "--out", str(out)]
    # and the command line's persistent compilation cache in $XDG_CACHE_HOME/gearjax/jax
    env = {k: v for k, v in os.environ.items() if k != "JAX_COMPILATION_CACHE_DIR"}
    env.update(PYTHONUNBUFFERED="1", XDG_CACHE_HOME=str(tmp_path / "xdg"))
    p = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    csv_path = out / "results.csv"
    t0 = time.monotonic()
    while time.monotonic() - t0 < 240 and p.poll() is None:
        if csv_path.exists() and len(csv_path.read_text().splitlines()) >= 3:
            break
        time.sleep(0.1)
    assert p.poll() is None, p.communicate()
    p.send_signal(signal.SIGINT)
    stdout, stderr = p.communicate(timeout=240)
    assert p.returncode == 130, stderr
    assert "Traceback" not in stderr and "KeyboardInterrupt" not in stderr
    msg = [ln for ln in stderr.splitlines() if ln.startswith("gearjax: interrupted")]
    assert len(msg) == 1 and "--resume" in msg[0]
    summary = json.loads((out / "summary.json").read_text())
    done = summary["formulations"]["te"]["speeds_done"]
    assert summary["interrupted"] and 2 <= done < 40
    assert (out / "response_curves.png").exists()
    rows = len(csv_path.read_text().splitlines()) - 1
    assert rows == done
    cache = tmp_path / "xdg" / "gearjax" / "jax"
    assert cache.is_dir() and any(cache.iterdir())  # the resume loads what it can
    # resume: only the missing speeds are computed, every speed once
    r = subprocess.run(argv[:-2] + ["--chunk", "20", "--out", str(out), "--resume"],
                       capture_output=True, text=True, timeout=600, env=env)
    assert r.returncode == 0, r.stderr
    assert f"{40 - done} left to compute" in r.stderr
    import csv

    got = [float(x["speed_rad_s"]) for x in csv.DictReader(open(csv_path))]
    assert sorted(got) == pytest.approx(np.linspace(100, 900, 40))
    summary = json.loads((out / "summary.json").read_text())
    assert "interrupted" not in summary and summary["formulations"]["te"]["speeds_done"] == 40


@pytest.mark.slow
def test_ctrl_c_of_ten_million_speeds_exits_within_seconds(tmp_path):
    """Issue 52: --speeds 20:900:10000000 wrote a 231 MB case.json before computing, and
    the first Ctrl-C then hung for minutes in the summary (quadratic in the speeds). Now
    the case records the speed specification, the run is announced with its estimate, and
    Ctrl-C ends with a summary of what finished within seconds."""
    out = tmp_path / "big"
    argv = [sys.executable, "-c", "import runpy, signal; signal.signal(signal.SIGINT, "
            "signal.default_int_handler); runpy.run_module('gearjax.cli.main', "
            "run_name='__main__')"] + SWEEP + ["--speeds", "20:900:10000000", "--out", str(out)]
    env = {k: v for k, v in os.environ.items() if k != "JAX_COMPILATION_CACHE_DIR"}
    env.update(PYTHONUNBUFFERED="1", XDG_CACHE_HOME=str(tmp_path / "xdg"))
    p = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    csv_path = out / "results.csv"
    t0 = time.monotonic()
    while time.monotonic() - t0 < 300 and p.poll() is None:
        if csv_path.exists() and len(csv_path.read_text().splitlines()) >= 3:
            break
        time.sleep(0.2)
    assert p.poll() is None, p.communicate()
    assert (out / "case.json").stat().st_size < 10_000
    p.send_signal(signal.SIGINT)
    t1 = time.monotonic()
    _, stderr = p.communicate(timeout=120)
    assert time.monotonic() - t1 < 30.0  # measured under load: 4.8 s
    assert p.returncode == 130 and "Traceback" not in stderr
    assert "10,000,000 speeds" in stderr and " h of computing" in stderr
    summary = json.loads((out / "summary.json").read_text())
    te = summary["formulations"]["te"]
    assert summary["interrupted"] and te["missing_speeds_count"] == 10_000_000 - te["speeds_done"]
