"""Rig files in TOML (gearjax.rigs.rigfile): the shipped Baud-Velex file equals the built-in rig,
a small custom rig equals the same structure assembled by hand, malformed files raise a
RigError naming the field, the value and the reason."""

from pathlib import Path

import numpy as np
import pytest

from gearjax.rigs.baud_velex import fig5_pitch_errors
from gearjax.rigs import build_model
from gearjax.rigs.rigfile import load_rig
from gearjax.rigs.registry import RigError, get_rig
from gearjax.structure import StructureBuilder, disc_properties

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "rigs" / "baud_velex_spur.toml"


def _rel(a, b):
    a, b = np.asarray(a), np.asarray(b)
    return np.abs(a - b).max() / np.abs(b).max()


# ------------------------------------------------------------------ the shipped rig file
@pytest.fixture(scope="module")
def example_rig():
    return load_rig(EXAMPLE)


def test_example_file_equals_builtin_structure(example_rig):
    builtin = get_rig("baud-velex-spur")
    s, b = example_rig.structure(), builtin.structure()
    assert s.n_dof == b.n_dof == 258
    assert _rel(s.M, b.M) < 1e-12
    assert _rel(s.K, b.K) < 1e-12
    np.testing.assert_array_equal(np.isnan(s.node_positions_m), np.isnan(b.node_positions_m))
    np.testing.assert_allclose(s.node_positions_m, b.node_positions_m, rtol=0, atol=1e-15)
    assert s.node_lines == b.node_lines
    assert (s.pinion_node, s.gear_node) == (b.pinion_node, b.gear_node)
    assert example_rig.pair == builtin.pair
    assert example_rig.pinion_torque_Nm == builtin.pinion_torque_Nm
    assert example_rig.torque_node == builtin.torque_node
    for pos in (1, 2, 3):
        assert example_rig.encoder_nodes(pos) == builtin.encoder_nodes(pos)
    with pytest.raises(RigError, match="encoders=4"):
        example_rig.encoder_nodes(4)


def test_example_file_modifications_are_table1_short_and_fig5(example_rig):
    mods = example_rig.modifications_default
    np.testing.assert_array_equal(np.asarray(mods.relief_amplitude_m), [13.3e-6, 13.3e-6])
    np.testing.assert_array_equal(np.asarray(mods.relief_extent), [0.2, 0.2])
    assert mods.relief_shape == "linear"
    np.testing.assert_array_equal(np.asarray(mods.pitch_errors_m[0]), fig5_pitch_errors(26))
    np.testing.assert_array_equal(np.asarray(mods.pitch_errors_m[1]), np.zeros(157))
    np.testing.assert_array_equal(example_rig.pinion_pitch_errors_m, fig5_pitch_errors(26))
    # the CLI's scenario builder gives the same modifications as for the built-in rig
    a = example_rig.modifications("long", pitch_errors=True)
    b = get_rig("baud-velex-spur").modifications("long", pitch_errors=True)
    for x, y in zip(np.asarray(a.pitch_errors_m[0]), np.asarray(b.pitch_errors_m[0])):
        assert x == y


def test_get_rig_loads_toml_paths(example_rig):
    rig = get_rig(str(EXAMPLE))
    assert rig.name == "baud-velex-spur-file"
    with pytest.raises(RigError, match="cannot read"):
        get_rig("no/such/rig.toml")
    with pytest.raises(RigError, match="unknown rig"):
        get_rig("baud-velex-sprue")


@pytest.mark.slow
def test_example_file_3d_model_same_natural_frequencies(example_rig):
    """build_model on the file and on the built-in rig: same modes of (M, K_bar),
    same static transmission-error constants at encoder position 3 (wiring of the motor
    node, torque and encoders)."""

    kw = dict(max_frequency_hz=10_000.0, n_table=32, encoder_position=3)
    m_file = build_model(example_rig, **kw)
    m_ref = build_model(get_rig("baud-velex-spur"), **kw)
    assert m_file.n_modes == m_ref.n_modes > 50
    f_file = np.asarray(m_file.omega_r[: m_file.n_modes]) / (2 * np.pi)
    f_ref = np.asarray(m_ref.omega_r[: m_ref.n_modes]) / (2 * np.pi)
    np.testing.assert_allclose(f_file, f_ref, rtol=1e-10)
    assert float(m_file.w_x0) == pytest.approx(float(m_ref.w_x0), rel=1e-10)
    assert float(m_file.v_x0) == pytest.approx(float(m_ref.v_x0), rel=1e-10)


# --------------------------------------------------------------------- a small custom rig
SMALL = """
name = "two-shafts"
pinion_node = 0
gear_node = 4
motor_node = 2

[gear_pair]
normal_module_m = 3e-3
z1 = 20
z2 = 40
face_width1_m = 0.03
face_width2_m = 0.03

[operating]
pinion_torque_Nm = 100.0

[materials.alloy]
E_Pa = 2.0e11
nu = 0.29
rho_kg_per_m3 = 7850.0

[[shaft]]
line = "pinion"
nodes = [0, 1, 2]
lengths_m = [0.1, 0.15]
outer_diameter_m = [0.04, 0.035]
inner_diameter_m = 0.01
material = "alloy"

[[shaft]]
line = "gear"
nodes = [3, 4, 5]
z_m = [-0.1, 0.0, 0.12]
outer_diameter_m = 0.05
axis = "gear"

[[disc]]
node = 0
mass_kg = 1.5
transverse_inertia_kg_m2 = 1e-3
polar_inertia_kg_m2 = 2e-3

[[disc]]
node = 4
outer_diameter_m = 0.12
inner_diameter_m = 0.05
width_m = 0.03

[[bearing]]
node = 1
k_S_N_per_m = 5e8
k_T_N_per_m = 4e8
k_axial_N_per_m = 1e8

[[bearing]]
node = 0
k_S_N_per_m = 5e8
k_T_N_per_m = 5e8
k_phi_Nm_per_rad = 1e5

[[bearing]]
node = 3
k_S_N_per_m = 3e8
k_T_N_per_m = 3e8
k_axial_N_per_m = 1e8

[[bearing]]
node = 5
k_S_N_per_m = 3e8
k_T_N_per_m = 3e8

[[torsional_spring]]
node = 5
k_Nm_per_rad = 2e4
"""


def _write(tmp_path, text, name="rig.toml"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_small_custom_rig_equals_hand_assembly(tmp_path):
    rig = load_rig(_write(tmp_path, SMALL))
    s = rig.structure()
    from gearjax.structure import Material

    alloy = Material(E=2.0e11, nu=0.29, rho=7850.0)
    m, it, ip = disc_properties(0.12, 0.05, 0.03)  # steel by default
    ref = (StructureBuilder(n_nodes=6)
           .add_shaft([0, 1, 2], lengths_m=[0.1, 0.15], outer_diameters_m=[0.04, 0.035],
                      inner_diameters_m=0.01, material=alloy)
           .add_shaft([3, 4, 5], positions_m=[-0.1, 0.0, 0.12], outer_diameters_m=0.05)
           .add_disc(0, mass_kg=1.5, transverse_inertia_kg_m2=1e-3, polar_inertia_kg_m2=2e-3)
           .add_disc(4, mass_kg=m, transverse_inertia_kg_m2=it, polar_inertia_kg_m2=ip)
           .add_bearing(1, 5e8, 4e8, 1e8)
           .add_bearing(0, 5e8, 5e8, 0.0, k_phi=1e5)
           .add_bearing(3, 3e8, 3e8, 1e8)
           .add_bearing(5, 3e8, 3e8)
           .add_torsional_spring_to_ground(5, 2e4)
           .build())
    assert s.n_dof == 36
    assert _rel(s.M, ref.M) < 1e-12 and _rel(s.K, ref.K) < 1e-12
    assert (s.pinion_node, s.gear_node, rig.torque_node) == (0, 4, 2)
    assert rig.encoder_nodes(1) == (0, 4)  # default: pinion and gear centres
    assert rig.name == "two-shafts" and rig.modifications_default is None
    np.testing.assert_array_equal(rig.pinion_pitch_errors_m, np.zeros(20))
    # gear axis at the centre distance m (z1 + z2) / 2 = 90 mm, pinion axis at the origin
    np.testing.assert_allclose(np.hypot(*s.node_position(4)[:2]), 0.09, rtol=1e-12)
    np.testing.assert_array_equal(s.node_position(1), [0.0, 0.0, 0.1])


@pytest.mark.slow
def test_small_rig_3d_figures_satisfy_appendix_a(tmp_path):
    """The Appendix A relations (Eqs. (33)-(35)) hold on the rig-file structure too."""
    from gearjax.rigs.figures import three_d_figures

    out = three_d_figures(load_rig(_write(tmp_path, SMALL)), n_frequencies=5)
    assert out["n_dof"] == 36
    for key in ("C_vv_times_km", "C_wv_times_km_cos_beta_b", "v_x0_times_km_over_FS"):
        assert out[key] == pytest.approx(1.0, rel=1e-9)
    assert out["natural_frequencies_hz"][0] > 0


# ------------------------------------------------------------------------ malformed files
def _edit(old, new, count=1):
    assert SMALL.count(old) >= count, old
    return SMALL.replace(old, new, count)


def _nth(text, old, new, n):
    """Replace the n-th (0-based) occurrence of ``old``."""
    parts = text.split(old)
    assert len(parts) > n + 1, old
    return old.join(parts[: n + 1]) + new + old.join(parts[n + 1:])


MALFORMED = {
    "missing field": (
        _nth(SMALL, "k_T_N_per_m = 3e8\n", "", 1),
        ["bearing[3].k_T_N_per_m", "missing"]),
    "wrong type": (
        _edit("z1 = 20", 'z1 = "20"'),
        ["gear_pair.z1", "'20'", "integer"]),
    "wrong type in a list": (
        _edit("outer_diameter_m = [0.04, 0.035]", 'outer_diameter_m = [0.04, "35 mm"]'),
        ["shaft[0].outer_diameter_m[1]", "'35 mm'", "number"]),
    "negative stiffness": (
        _nth(SMALL, "k_S_N_per_m = 3e8", "k_S_N_per_m = -3e8", 0),
        ["bearing[2].k_S_N_per_m", "-300000000.0", ">= 0"]),
    "unknown node": (
        _edit("[[disc]]\nnode = 4", "[[disc]]\nnode = 9"),
        ["disc[1].node", "9", "unknown node", "0..5"]),
    "unknown node in a coupling": (
        SMALL + "\n[[coupling]]\nnodes = [2, 7]\nk_torsion_Nm_per_rad = 1e4\n",
        ["coupling[0].nodes[1]", "7", "unknown node"]),
    "typo in a key": (
        _nth(SMALL, "k_S_N_per_m = 3e8", "k_s_N_per_m = 3e8", 1),
        ["bearing[3].k_s_N_per_m", "unknown key", "did you mean 'k_S_N_per_m'"]),
    "typo in a table name": (
        SMALL + "\n[[bearings]]\nnode = 2\n",
        ["bearings", "unknown key", "did you mean 'bearing'"]),
    "missing table": (
        _edit("[operating]\npinion_torque_Nm = 100.0\n", ""),
        ["operating", "missing"]),
    "invalid gear geometry": (
        _edit("z1 = 20", "z1 = 3"),
        ["gear_pair.z1", "3", "tooth number"]),
    "negative torque": (
        _edit("pinion_torque_Nm = 100.0", "pinion_torque_Nm = -100.0"),
        ["operating.pinion_torque_Nm", "-100.0", "> 0"]),
    "node gap": (
        _edit("nodes = [3, 4, 5]", "nodes = [3, 4, 6]").replace("node = 5", "node = 6"),
        ["nodes", "node 5 is never declared"]),
    "bore larger than the shaft": (
        _edit("inner_diameter_m = 0.01", "inner_diameter_m = 0.037"),
        ["shaft[0].inner_diameter_m", "0.037", "smaller than the outer diameter 0.035"]),
    "positions not increasing": (
        _edit("z_m = [-0.1, 0.0, 0.12]", "z_m = [-0.1, 0.0, -0.05]"),
        ["shaft[1].z_m[2]", "-0.05", "increase strictly"]),
    "unknown material": (
        _edit('material = "alloy"', 'material = "aloy"'),
        ["shaft[0].material", "'aloy'", "unknown material"]),
    "pitch errors of the wrong length": (
        SMALL + "\n[modifications.pinion]\npitch_errors_m = [0.0, 1e-6]\n",
        ["modifications.pinion.pitch_errors_m", "must list 20 values"]),
    "relief in micrometres": (
        SMALL + "\n[modifications.gear]\nrelief_amplitude_m = 13.3\n",
        ["modifications.gear.relief_amplitude_m", "13.3", "metres"]),
    "free structure": (
        _nth(_nth(SMALL, "k_S_N_per_m = 3e8", "k_S_N_per_m = 0.0", 0),
             "k_S_N_per_m = 3e8", "k_S_N_per_m = 0.0", 0),
        ["structure", "3 rigid-body modes", "line 'gear' v", "line 'pinion' theta"]),
    "pinion and gear on one line": (
        _edit('line = "gear"', 'line = "pinion"'),
        ["gear_node", "4", "shaft line 'pinion'"]),
    "encoder on an unknown node": (
        SMALL + "\n[encoders]\n1 = [0, 4]\n2 = [2, 8]\n",
        ["encoders.2[1]", "8", "unknown node"]),
    "angle given twice": (
        _edit("z1 = 20", "z1 = 20\nhelix_angle_deg = 10.0\nhelix_angle_rad = 0.17"),
        ["gear_pair.helix_angle_deg", "either"]),
    "massless node": (
        SMALL + "\n[[node]]\nnode = 6\n\n[[coupling]]\nnodes = [2, 6]\nk_torsion_Nm_per_rad = 1e3\n"
                "\n[[disc]]\nnode = 6\nmass_kg = 1.0\ntransverse_inertia_kg_m2 = 0.0\n"
                "polar_inertia_kg_m2 = 1e-3\n",
        ["node 6", "no mass"]),
}


@pytest.mark.parametrize("case", sorted(MALFORMED))
def test_malformed_file_names_the_field(tmp_path, case):
    text, expected = MALFORMED[case]
    with pytest.raises(RigError) as info:
        load_rig(_write(tmp_path, text))
    msg = str(info.value)
    for piece in expected:
        assert piece in msg, (piece, msg)
    assert "rig.toml" in msg  # the file is named


def test_toml_syntax_error(tmp_path):
    with pytest.raises(RigError, match=r"not valid TOML.*line 2"):
        load_rig(_write(tmp_path, 'name = "x"\nz1 = = 3\n'))


def test_first_node_one_reports_file_numbers(tmp_path):
    """With first_node = 1 the file uses 1-based numbers; messages quote them."""
    import re

    def shift(match):
        return str(int(match.group(0)) + 1)

    text = re.sub(r"(?m)^((?:node|pinion_node|gear_node|motor_node) = )(\d+)$",
                  lambda m: m.group(1) + str(int(m.group(2)) + 1), SMALL)
    text = re.sub(r"(?m)^nodes = \[[\d, ]+\]$", lambda m: re.sub(r"\d+", shift, m.group(0)), text)
    text = "first_node = 1\n" + text
    rig = load_rig(_write(tmp_path, text))
    ref = load_rig(_write(tmp_path, SMALL, "ref.toml"))
    assert _rel(rig.structure().K, ref.structure().K) == 0.0
    assert rig.torque_node == ref.torque_node == 2
    with pytest.raises(RigError, match=r"disc\[0\].node=0: unknown node; the declared nodes are 1..6"):
        load_rig(_write(tmp_path, text.replace("[[disc]]\nnode = 1", "[[disc]]\nnode = 0")))
