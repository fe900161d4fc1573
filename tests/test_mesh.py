"""Mesh stiffness against closed forms: square wave (uniform law) and ISO 6336-1 c_gamma_alpha b."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from gearjax.rigs.baud_velex import baud_velex_pair
from gearjax.gears.mesh import Mesh


def _pairs_in_contact(pair, theta):
    """Number of spur tooth pairs inside the path of contact, from the base-plane kinematics:
    pair n sits at s = Rb1 theta - n p_bt along the path, in contact when 0 <= s <= g_alpha."""
    s0 = (pair.base_radii_m[0] * theta) % pair.base_pitch_m
    g = pair.path_of_contact_m
    return sum(1 for j in range(4) if 0.0 <= s0 + j * pair.base_pitch_m <= g)


def test_uniform_spur_stiffness_is_exact_square_wave():
    pair = baud_velex_pair(False)
    k_l = 1.7e10  # N/m per m of contact line
    mesh = Mesh.build(pair, "uniform", cells_per_line=5, stiffness_per_length_N_per_m2=k_l)
    theta = np.arange(600) * (3 * pair.mesh_period_rad / 600)  # three whole periods
    k = np.asarray(jax.vmap(mesh.stiffness)(jnp.asarray(theta)))
    expected = np.array([_pairs_in_contact(pair, t) for t in theta]) * k_l * pair.face_width_m
    np.testing.assert_allclose(k, expected, rtol=1e-12)
    # duty cycle: the two-pair zone lasts (eps_alpha - 1) of a mesh period; sampling
    # misplaces each of the 6 zone boundaries by at most one sample
    two = np.mean(k > 1.5 * k_l * pair.face_width_m)
    assert two == pytest.approx(pair.transverse_contact_ratio - 1.0, abs=6.0 / len(theta))


def _iso_c_gamma_alpha(z1, z2, x1, x2, beta, beta_b, alpha_n_deg, hf, eps_alpha):
    """ISO 6336-1:2006 Eqs. (98)-(101) by hand, N/(mm um)."""
    zn1 = z1 / (math.cos(beta_b) ** 2 * math.cos(beta))
    zn2 = z2 / (math.cos(beta_b) ** 2 * math.cos(beta))
    q = (0.04723 + 0.15551 / zn1 + 0.25791 / zn2 - 0.00635 * x1 - 0.11654 * x1 / zn1
         - 0.00193 * x2 - 0.24188 * x2 / zn2 + 0.00529 * x1**2 + 0.00182 * x2**2)
    c_b = (1 + 0.5 * (1.2 - hf)) * (1 - 0.02 * (20 - alpha_n_deg))
    c_prime = (1 / q) * 0.8 * 1.0 * c_b * math.cos(beta)
    return c_prime * (0.75 * eps_alpha + 0.25)


@pytest.mark.parametrize("helical", [False, True])
def test_iso_law_mean_stiffness_matches_iso6336(helical):
    pair = baud_velex_pair(helical)
    mesh = Mesh.build(pair, "iso6336")
    c_ga = _iso_c_gamma_alpha(26, 157, 0.16, -0.16, pair.helix_angle_rad, pair.base_helix_angle_rad,
                              20.0, 1.46, pair.transverse_contact_ratio)
    expected = c_ga * 1e9 * pair.face_width_m  # N/(mm um) -> N/m^2, times b
    # tolerance: midpoint quadrature over 2048 angles and 40 cells across the helical face
    assert float(mesh.mean_stiffness()) == pytest.approx(expected, rel=2e-3)


def test_iso_law_single_pair_stiffness_is_c_prime():
    """Spur: at mid-profile in the single-contact zone the pair stiffness is ISO's c' b."""
    pair = baud_velex_pair(False)
    mesh = Mesh.build(pair, "iso6336", cells_per_line=4)
    c_ga = _iso_c_gamma_alpha(26, 157, 0.16, -0.16, 0.0, 0.0, 20.0, 1.46,
                              pair.transverse_contact_ratio)
    c_prime = c_ga / (0.75 * pair.transverse_contact_ratio + 0.25) * 1e9
    xi_a, xi_e = pair.contact_limits_m
    theta_mid = (0.5 * (xi_e - xi_a)) / pair.base_radii_m[0]  # pair 0 at mid-profile
    assert _pairs_in_contact(pair, theta_mid) == 1
    assert float(mesh.stiffness(theta_mid)) == pytest.approx(c_prime * pair.face_width_m, rel=1e-12)


def test_helical_stiffness_fluctuates_less_and_has_unit_shape_function():
    spur, hel = (Mesh.build(baud_velex_pair(h), "uniform") for h in (False, True))
    th = spur.theta_grid(512)
    k_m_s, a_s, g_s = spur.stiffness_variation(th)
    k_m_h, a_h, g_h = hel.stiffness_variation(th)
    assert float(jnp.max(jnp.abs(g_s))) == pytest.approx(1.0)
    assert abs(float(jnp.mean(g_s))) < 1e-12  # zero-mean shape function of Eq. (19)
    # uniform law, continuous limit: k_m = k_l * (total contact length) = k_l eps_alpha b / cos beta_b
    for mesh, k_m in ((spur, k_m_s), (hel, k_m_h)):
        p = mesh.pair
        expect = mesh.stiffness_peak_N_per_m2 * p.transverse_contact_ratio * p.face_width_m / math.cos(
            p.base_helix_angle_rad)
        assert float(k_m) == pytest.approx(expect, rel=3e-3)
    assert float(a_h) < 0.25 * float(a_s)


def test_cells_jit_and_vmap_shapes():
    mesh = Mesh.build(baud_velex_pair(True), "iso6336", cells_per_line=12)
    th = mesh.theta_grid(16)
    cells = jax.jit(jax.vmap(mesh.cells))(th)
    assert cells.stiffness_N_per_m.shape == (16, mesh.n_cells)
    assert bool(jnp.all(cells.stiffness_N_per_m[~cells.inside] == 0))
    # roll distances on both profiles add up to T1T2
    np.testing.assert_allclose(cells.roll1_m + cells.roll2_m, mesh.pair.line_of_action_length_m)


def test_bad_mesh_options():
    pair = baud_velex_pair(False)
    with pytest.raises(ValueError, match="law='hertz'"):
        Mesh.build(pair, "hertz")
    with pytest.raises(ValueError, match="cells_per_line=0"):
        Mesh.build(pair, "uniform", cells_per_line=0)
    with pytest.raises(ValueError, match="only for law='uniform'"):
        Mesh.build(pair, "iso6336", stiffness_per_length_N_per_m2=1e10)
