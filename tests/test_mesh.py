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


def _contact_length_fluctuation(eps_a, eps_b):
    """alpha = max|L - L_m| / L_m of the total contact length L, by hand (1 < eps_a < 2).

    Spur: one pair, then two for a fraction a = eps_a - 1 of the mesh period, L_m = eps_a b.
    Helical, continuous face: the section at eta is the spur pair shifted by
    eta tan(beta_b) / p_bt = eps_beta eta / b periods, so L(u) is b / cos(beta_b) times the
    mean of the spur pair count over a window of eps_beta periods: m whole periods
    (m eps_a) plus a fraction r whose overlap with the two-pair zone ranges over
    [max(0, r + a - 1), min(r, a)] about its mean r a."""
    a = eps_a - 1.0
    if eps_b == 0.0:
        return max(1.0 - 1.0 / eps_a, 2.0 / eps_a - 1.0)
    r = eps_b - math.floor(eps_b)
    return max(min(r, a) - r * a, r * a - max(0.0, r + a - 1.0)) / (eps_b * eps_a)


@pytest.mark.parametrize("helical", [False, True])
def test_uniform_law_fluctuation_is_the_contact_length_closed_form(helical):
    """Uniform law: k = k_l x (total contact length), so Eq. (19)'s k_m = k_l eps_alpha b /
    cos(beta_b) and alpha is the contact length's fluctuation (_contact_length_fluctuation).
    eps_alpha, eps_beta, beta_b are the pair's, checked against ISO 21771 by hand in
    test_geometry. The helical closed form is the continuous face: it is checked on a
    4000-cell face (the default 40 cells read alpha = 0.0456 against 0.0296: one cell of
    the eps_alpha N = 63 in contact is 1.6e-2)."""
    pair = baud_velex_pair(helical)
    cells = 4000 if helical else None
    mesh = Mesh.build(pair, "uniform", cells_per_line=cells)
    k_m, alpha, g = mesh.stiffness_variation(mesh.theta_grid(512))
    k_m_exact = (mesh.stiffness_peak_N_per_m2 * pair.transverse_contact_ratio
                 * pair.face_width_m / math.cos(pair.base_helix_angle_rad))
    # 512 samples per period read the two-pair duty cycle to a fraction of a sample: the
    # spur's (eps_alpha - 1) 512 = 368.93 samples counted as 369 put k_m 7.5e-5 high and
    # alpha 1.0e-4 (measured); helical (4000 cells) measured 4.0e-7 in k_m. Bound 3e-4.
    assert float(k_m) == pytest.approx(k_m_exact, rel=3e-4)
    alpha_exact = _contact_length_fluctuation(pair.transverse_contact_ratio, pair.overlap_ratio)
    if helical:
        # a discrete face of N cells is off by up to about one cell of the eps_alpha N in
        # contact, 1/(eps_alpha N) = 1.6e-4 here; measured |alpha - closed form| 1.0e-4
        # (and 1.6e-2, 3.1e-3, 1.5e-3, 5.8e-4 at N = 40, 100, 400, 1000: the same 1/N)
        assert float(alpha) == pytest.approx(alpha_exact,
                                             abs=1.0 / (pair.transverse_contact_ratio * cells))
    else:
        assert float(alpha) == pytest.approx(alpha_exact, rel=3e-4)
    # API contract of Eq. (19) (holds by construction in stiffness_shape): max |g| = 1
    assert float(jnp.max(jnp.abs(g))) == pytest.approx(1.0, rel=1e-12)


def test_cells_jit_and_vmap_shapes():
    mesh = Mesh.build(baud_velex_pair(True), "iso6336", cells_per_line=12)
    th = mesh.theta_grid(16)
    cells = jax.jit(jax.vmap(mesh.cells))(th)
    assert cells.stiffness_N_per_m.shape == (16, mesh.n_cells)
    assert bool(jnp.all(cells.stiffness_N_per_m[~cells.inside] == 0))
    # The roll distances are the involutes' radii of curvature at the contact point, so the
    # point sits at radius sqrt(rb^2 + roll^2) on each gear, and a cell is in contact exactly
    # when that lies within both tip circles (written here from the Table 1 data, ISO 21771:
    # r_a = z m_n / (2 cos beta) + m_n (h_a + x)); rolls add up to the base tangent
    # T1T2 = sqrt(a_w^2 - (rb1 + rb2)^2) of the triangle O1 O2 T.
    p = mesh.pair
    mn, beta = 4e-3, math.radians(20.0)
    ra = [z * mn / (2 * math.cos(beta)) + mn * (1.0 + x) for z, x in ((26, 0.16), (157, -0.16))]
    rb1, rb2 = p.base_radii_m
    r1 = np.sqrt(rb1**2 + np.asarray(cells.roll1_m) ** 2)
    r2 = np.sqrt(rb2**2 + np.asarray(cells.roll2_m) ** 2)
    np.testing.assert_array_equal((r1 <= ra[0]) & (r2 <= ra[1]), np.asarray(cells.inside))
    t1t2 = math.sqrt(p.centre_distance_m**2 - (rb1 + rb2) ** 2)
    np.testing.assert_allclose(cells.roll1_m + cells.roll2_m, t1t2, rtol=1e-12)


def test_bad_mesh_options():
    pair = baud_velex_pair(False)
    with pytest.raises(ValueError, match="law='hertz'"):
        Mesh.build(pair, "hertz")
    with pytest.raises(ValueError, match="cells_per_line=0"):
        Mesh.build(pair, "uniform", cells_per_line=0)
    with pytest.raises(ValueError, match="only for law='uniform'"):
        Mesh.build(pair, "iso6336", stiffness_per_length_N_per_m2=1e10)
