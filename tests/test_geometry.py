"""Involute geometry against ISO 21771 formulas written out here, and input validation."""

import math

import pytest

from gearjax.gears.geometry import GearPair, GeometryError, inverse_involute
from gearjax.rigs.baud_velex import baud_velex_pair


def _iso21771(mn, z1, z2, an_deg, beta_deg, x1, x2, ha, b):
    """Hand-written ISO 21771 relations for an external pair (no tip shortening)."""
    an, beta = math.radians(an_deg), math.radians(beta_deg)
    at = math.atan(math.tan(an) / math.cos(beta))
    mt = mn / math.cos(beta)
    d1, d2 = z1 * mt, z2 * mt
    db1, db2 = d1 * math.cos(at), d2 * math.cos(at)
    inv = lambda a: math.tan(a) - a  # noqa: E731
    target = inv(at) + 2 * math.tan(an) * (x1 + x2) / (z1 + z2)
    lo, hi = 0.0, 1.5  # bisection, independent of the library's Newton solver
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if inv(mid) < target else (lo, mid)
    awt = 0.5 * (lo + hi)
    aw = (d1 + d2) / 2 * math.cos(at) / math.cos(awt)
    da1, da2 = d1 + 2 * mn * (ha + x1), d2 + 2 * mn * (ha + x2)
    g_alpha = 0.5 * (math.sqrt(da1**2 - db1**2) + math.sqrt(da2**2 - db2**2)) - aw * math.sin(awt)
    p_bt = math.pi * mt * math.cos(at)
    return {
        "rb": (db1 / 2, db2 / 2),
        "beta_b": math.asin(math.sin(beta) * math.cos(an)),
        "eps_alpha": g_alpha / p_bt,
        "eps_beta": b * math.sin(beta) / (math.pi * mn),
        "aw": aw,
        "p_bt": p_bt,
    }


@pytest.mark.parametrize("helical", [False, True])
def test_table1_pair_matches_iso21771(helical):
    pair = baud_velex_pair(helical)
    ref = _iso21771(4e-3, 26, 157, 20.0, 20.0 if helical else 0.0, 0.16, -0.16, 1.0, 0.040)
    assert pair.base_radii_m == pytest.approx(ref["rb"], rel=1e-12)
    assert pair.base_helix_angle_rad == pytest.approx(ref["beta_b"], rel=1e-12, abs=1e-15)
    assert pair.transverse_contact_ratio == pytest.approx(ref["eps_alpha"], rel=1e-10)
    assert pair.overlap_ratio == pytest.approx(ref["eps_beta"], rel=1e-12, abs=1e-15)
    assert pair.centre_distance_m == pytest.approx(ref["aw"], rel=1e-10)
    assert pair.base_pitch_m == pytest.approx(ref["p_bt"], rel=1e-12)
    # x1 + x2 = 0: working centre distance equals the reference one (z1+z2) m_t / 2
    assert pair.centre_distance_m == pytest.approx(183 * pair.transverse_module_m / 2, rel=1e-12)


def test_shifted_pair_working_pressure_angle():
    pair = GearPair(3e-3, 17, 40, profile_shift1=0.4, profile_shift2=0.2, face_width1_m=0.02,
                    face_width2_m=0.02)
    ref = _iso21771(3e-3, 17, 40, 20.0, 0.0, 0.4, 0.2, 1.0, 0.02)
    assert pair.centre_distance_m == pytest.approx(ref["aw"], rel=1e-10)
    assert pair.transverse_contact_ratio == pytest.approx(ref["eps_alpha"], rel=1e-9)


def test_inverse_involute_roundtrip():
    for a in (0.05, 0.3, 0.6, 1.0):
        assert inverse_involute(math.tan(a) - a) == pytest.approx(a, rel=1e-13)


@pytest.mark.parametrize(
    "kwargs, field, words",
    [
        ({"normal_module_m": -1e-3}, "normal_module_m", "positive"),
        ({"face_width2_m": 0.0}, "face_width2_m", "positive"),
        ({"z1": 3}, "z1", ">= 5"),
        ({"z1": 12.5}, "z1", "integer"),
        ({"addendum_coeff1": 0.3, "addendum_coeff2": 0.3}, "addendum_coeff1", "contact ratio"),
        ({"z1": 8, "profile_shift1": -0.3, "profile_shift2": 0.3}, "z1", "interference"),
        ({"profile_shift1": 1.5, "profile_shift2": 1.5, "dedendum_coeff1": 2.0,
          "dedendum_coeff2": 2.0}, "addendum_coeff1", "pointed"),
        ({"z1": 10, "profile_shift1": 1.2, "addendum_coeff1": 1.4}, "profile_shift1", "inconsistent"),
        ({"normal_pressure_angle_rad": 20.0}, "normal_pressure_angle_rad", "degrees"),
        # issue 52: 25 mm typed as 25 (m): k_m x 1000 without a word before
        ({"normal_module_m": 3e-3, "z1": 20, "z2": 45, "face_width1_m": 25.0,
          "face_width2_m": 25.0}, "face_width1_m", "millimetres typed as metres"),
        # issue 52: x1 = 1.2 on z1 = 20: tip thickness 0.05 mm (0.017 m_n), once accepted
        ({"normal_module_m": 3e-3, "z1": 20, "z2": 45, "profile_shift1": 1.2},
         "profile_shift1", "pointed"),
        # undercut by the generating rack with the start of contact still above the base
        # circle (a short-addendum gear): no interference, yet the root is cut away
        ({"z1": 30, "z2": 200, "profile_shift1": -1.0, "addendum_coeff2": 0.6},
         "profile_shift1", "undercut"),
    ],
)
def test_bad_geometry_names_field_and_reason(kwargs, field, words):
    base = dict(normal_module_m=4e-3, z1=26, z2=57, face_width1_m=0.02, face_width2_m=0.02)
    base.update(kwargs)
    with pytest.raises(GeometryError) as exc:
        GearPair(**base)
    assert field in str(exc.value)
    assert words in str(exc.value)


def test_undercut_limit_is_the_classic_17_teeth():
    """x_min = h_a0 - z sin^2(alpha) / 2 with the rack's straight flank h_a0 (ISO 53 A):
    a standard spur pinion (x = 0, h_f* = 1.25, rho 0.38 m_n, alpha 20 deg) is free of
    undercut from z = 2 h_a0 / sin^2(alpha), ~17 teeth for h_a0 = 1."""
    import math

    pair = GearPair(3e-3, 17, 60)
    h_a0 = 1.25 - 0.38 * (1 - math.sin(math.radians(20.0)))
    assert pair.undercut_limit(1) == pytest.approx(h_a0 - 17 * math.sin(math.radians(20.0)) ** 2 / 2,
                                                   rel=1e-12)
    z_free = 2 * h_a0 / math.sin(math.radians(20.0)) ** 2
    assert 17.0 < z_free < 18.0

