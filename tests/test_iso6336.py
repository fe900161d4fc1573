"""ISO 6336-1 figures against the published ISO/TR 6336-30:2017 example 1 (m_n 8 mm, z 17/103,
b 100 mm, x 0.145/0, beta 15.8 deg, a_w 500 mm, h_fP = 1.4 m_n, T1 9 kN m, n1 360 1/min,
C_a 70 um): c' = 12.3705 and c_gamma_alpha = 17.4648 N/(mm um), K_v = 1.003; and method B's
own structure (continuity at the range limits, the subcritical line through 1 at N = 0)."""

import json
import math
from pathlib import Path

import numpy as np
import pytest

from gearjax.cli.main import main
from gearjax.errors import GeometryError, RigError
from gearjax.gears.geometry import GearPair
from gearjax.gears.iso6336 import AccuracyData, dynamic_factor, iso1328_deviations

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "rigs" / "iso_tr_6336_30_example1.toml"

# ISO/TR 6336-30:2017, example 1 (published values)
C_PRIME = 12.3705  # N/(mm um)
C_GAMMA_ALPHA = 17.4648  # N/(mm um)
KV_360_RPM = 1.003


def _pair():
    return GearPair(8e-3, 17, 103, math.radians(20.0), math.radians(15.8), 0.145, 0.0,
                    1.0, 1.0, 1.4, 1.4, 0.1, 0.1)


def test_info_json_of_the_iso_tr_6336_30_pair_matches_the_published_example(capsys):
    assert main(["info", "--rig", str(EXAMPLE), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["centre_distance_m"] == pytest.approx(0.500, rel=1e-5)  # a_w 500 mm
    assert out["iso6336_c_prime_N_per_mm_um"] == pytest.approx(C_PRIME, rel=5e-3)
    assert out["iso6336_c_gamma_alpha_N_per_mm_um"] == pytest.approx(C_GAMMA_ALPHA, rel=5e-3)
    assert out["iso6336_rated_speed_rad_s"] == pytest.approx(360 * math.pi / 30)
    assert out["iso6336_kv_at_rated_speed"] == pytest.approx(KV_360_RPM, rel=1e-2)
    # the example runs far below resonance: F_t at the reference circle, 1273 N/mm
    assert out["iso6336_reference_tangential_force_N"] == pytest.approx(
        2 * 9000.0 / (17 * 8e-3 / math.cos(math.radians(15.8))), rel=1e-12)
    assert out["iso6336_resonance_ratio_at_rated_speed"] < out["iso6336_N_S"]
    assert out["iso6336_sources"]["C_a"] == "given"


def test_cli_options_replace_the_rig_file_accuracy_data(capsys):
    argv = ["info", "--rig", str(EXAMPLE), "--json", "--model", "torsional"]
    assert main(argv + ["--iso-grade", "8", "--iso-speed", "600"]) == 0
    out = json.loads(capsys.readouterr().out)
    f_pb, f_fa = iso1328_deviations(_pair(), 8)
    assert out["iso6336_f_pb_m"] == pytest.approx(f_pb, rel=1e-12)
    assert out["iso6336_f_falpha_m"] == pytest.approx(f_fa, rel=1e-12)
    assert out["iso6336_rated_speed_rad_s"] == 600.0
    # grade 8 deviations are 2^1.5 times grade 5's: a larger K_v at the same speed
    assert out["iso6336_kv_at_rated_speed"] > dynamic_factor(
        _pair(), 9000.0, 600.0, AccuracyData(tip_relief_m=70e-6)).kv[0]


def test_method_b_ranges_join_and_the_subcritical_line_starts_at_one():
    pair = _pair()
    r0 = dynamic_factor(pair, 9000.0, [0.0], AccuracyData(tip_relief_m=70e-6))
    w_e = r0.resonance_speed_rad_s
    assert r0.kv[0] == pytest.approx(1.0, abs=1e-15)
    n = np.array([1.15, 1.15 + 1e-12, 1.5 - 1e-12, 1.5])
    r = dynamic_factor(pair, 9000.0, n * w_e, AccuracyData(tip_relief_m=70e-6))
    assert r.kv[0] == pytest.approx(r.kv[1], rel=1e-9)  # main resonance -> intermediate
    assert r.kv[2] == pytest.approx(r.kv[3], rel=1e-9)  # intermediate -> supercritical
    # B_k vanishes when C_a equals the line load's deflection F_t K_A / (b c')
    w = r.line_load_N_per_m
    exact = dynamic_factor(pair, 9000.0, [w_e], AccuracyData(tip_relief_m=w / r.single_stiffness_N_per_m2))
    assert exact.b_k == pytest.approx(0.0, abs=1e-12)


def test_low_line_load_corrects_c_prime_and_n_s():
    pair = _pair()
    light = dynamic_factor(pair, 9000.0 * 0.05, [100.0])  # 64 N/mm < 100 N/mm
    w_mm = light.line_load_N_per_m / 1e3
    assert w_mm < 100.0
    full = dynamic_factor(pair, 9000.0, [100.0])
    assert light.single_stiffness_N_per_m2 == pytest.approx(
        full.single_stiffness_N_per_m2 * (w_mm / 100.0) ** 0.25, rel=1e-12)
    assert light.n_s == pytest.approx(0.5 + 0.35 * math.sqrt(w_mm / 100.0), rel=1e-12)
    assert light.sources["C_a"].startswith("C_ay")  # no relief given or in use


def test_bad_accuracy_data_is_named():
    with pytest.raises(GeometryError, match="accuracy_grade=13"):
        AccuracyData(accuracy_grade=13)
    with pytest.raises(GeometryError, match="tip_relief_m"):
        AccuracyData(tip_relief_m=0.07)  # 70 mm: micrometres written as millimetres


def test_rig_file_iso6336_table_errors_name_the_key(tmp_path):
    from gearjax.rigs.rigfile import load_rig

    bad = tmp_path / "bad.toml"
    bad.write_text(EXAMPLE.read_text().replace("accuracy_grade = 5", "accuracy_grade = 0"))
    with pytest.raises(RigError, match=r"iso6336\.accuracy_grade=0"):
        load_rig(str(bad))


def test_sweep_summary_and_figure_carry_the_iso_dynamic_factor(capsys, tmp_path):
    """The default sweep figure and summary.json: ISO's K_v at every speed (C_a = the
    scenario's Table 1 short relief, 13.3 um) and n_E1; below N_S the curve is ISO's
    straight line K_v = 1 + N K through 1 at rest."""
    from gearjax.rigs.registry import get_rig

    out = tmp_path / "sw"
    assert main(["sweep", "--model", "torsional", "--formulations", "te", "--speeds",
                 "100:1000:4", "--out", str(out), "--json"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert (out / "response_curves.png").stat().st_size > 0
    rig = get_rig("baud-velex-spur")
    speeds = np.linspace(100.0, 1000.0, 4)
    ref = dynamic_factor(rig.pair, rig.pinion_torque_Nm, speeds, AccuracyData(tip_relief_m=13.3e-6))
    assert summary["iso6336_kv"] == pytest.approx(list(ref.kv), rel=1e-12)
    assert summary["iso6336_resonance_speed_rad_s"] == pytest.approx(ref.resonance_speed_rad_s, rel=1e-12)
    assert summary["iso6336"]["iso6336_sources"]["C_a"] == "tip relief of the modifications"
    # the same run records the model's own critical speeds (gearjax campbell's rows) and k_m
    crit = summary["critical_speeds"]
    assert [r["mesh_order"] for r in crit] == [5, 4, 3, 2, 1]
    assert crit[-1]["crossing_speed_rad_s"] == pytest.approx(
        summary["predicted"]["critical_speed_rad_s"], rel=1e-12)
    assert summary["loaded_mean_mesh_stiffness_N_per_m"] > 0
    sub = ref.resonance_ratio <= ref.n_s
    assert sub.sum() >= 2
    slope = (ref.kv[sub] - 1.0) / ref.resonance_ratio[sub]
    assert slope == pytest.approx(np.full(sub.sum(), slope[0]), rel=1e-12)
