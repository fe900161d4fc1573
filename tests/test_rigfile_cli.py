"""`--rig FILE.toml` in the command line: the shipped Baud-Velex rig file gives the same
`gearjax info --model 3d` figures as the built-in rig; a malformed file is a clean error."""

import json
from pathlib import Path

import pytest

from gearjax.cli.main import main

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "rigs" / "baud_velex_spur.toml"


def _json(capsys, argv):
    assert main(argv) == 0
    return json.loads(capsys.readouterr().out)


def test_info_3d_json_from_rig_file_matches_builtin(capsys):
    argv = ["info", "--model", "3d", "--encoders", "3", "--json", "--rig"]
    out = _json(capsys, argv + [str(EXAMPLE)])
    ref = _json(capsys, argv + ["baud-velex-spur"])
    assert out["rig"] == "baud-velex-spur-file"
    assert out["n_dof"] == ref["n_dof"] == 258
    for key in ("C_vv_times_km", "C_wv_times_km_cos_beta_b", "v_x0_times_km_over_FS", "w_x0_m",
                "mean_mesh_stiffness_N_per_m", "static_mesh_force_N", "contact_ratio"):
        assert out[key] == pytest.approx(ref[key], rel=1e-12), key
    assert out["natural_frequencies_hz"] == pytest.approx(ref["natural_frequencies_hz"], rel=1e-10)


def test_malformed_rig_file_is_a_clean_cli_error(capsys, tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text(EXAMPLE.read_text().replace("k_S_N_per_m = 7e7", "k_S_N_per_m = -7e7", 1))
    assert main(["info", "--rig", str(bad), "--model", "3d"]) == 2
    err = capsys.readouterr().err
    assert "bearing[4].k_S_N_per_m=-70000000.0: must be >= 0" in err
    assert "Traceback" not in err
