"""Quasi-static TE_S / NLTE with unilateral contact against closed forms and root finding."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import brentq

from gearjax.rigs.baud_velex import baud_velex_pair
from gearjax.gears.mesh import Mesh
from gearjax.gears.modifications import ModificationError, ToothModifications
from gearjax.rigs.baud_velex import table1_relief
from gearjax.gears.quasistatic import quasi_static, solve_unilateral, static_mesh_force

TORQUE = 254.8


def _setup(helical=False, law="iso6336", **kw):
    pair = baud_velex_pair(helical)
    return pair, Mesh.build(pair, law, **kw), static_mesh_force(pair, TORQUE)


@given(
    k=st.lists(st.floats(1e6, 1e9), min_size=1, max_size=12),
    seed=st.integers(0, 2**31 - 1),
    force=st.floats(1.0, 1e5),
)
@settings(max_examples=60, deadline=None)
def test_solve_unilateral_matches_root_finding(k, seed, force):
    """The sorted closed form equals a bracketed root of sum k max(0, y - gap) = F."""
    rng = np.random.default_rng(seed)
    k = np.asarray(k)
    gap = rng.uniform(0, 2e-5, k.size)
    gap[rng.integers(k.size)] = 0.0
    f = lambda y: np.sum(k * np.maximum(0.0, y - gap)) - force  # noqa: E731
    y_ref = brentq(f, 0.0, gap.max() + force / k.min() + 1.0, xtol=1e-16, rtol=1e-14)
    y, loads = solve_unilateral(jnp.asarray(k), jnp.asarray(gap), force)
    assert float(y) == pytest.approx(y_ref, rel=1e-10)
    assert float(jnp.sum(loads)) == pytest.approx(force, rel=1e-12)
    assert bool(jnp.all(loads >= 0))


@pytest.mark.parametrize("helical", [False, True])
def test_perfect_gears_zero_nlte_and_load_balance(helical):
    pair, mesh, f_s = _setup(helical)
    res = quasi_static(mesh, ToothModifications.none(), mesh.theta_grid(64, 2), f_s)
    assert float(jnp.max(jnp.abs(res.nlte_m))) == 0.0
    np.testing.assert_allclose(res.mesh_force_N, f_s, rtol=1e-12)
    np.testing.assert_allclose(res.cell_load_N.sum(axis=1), f_s, rtol=1e-12)
    # no gaps: every cell inside the path is loaded, so (sum k)^S is the geometric stiffness
    k_geo = jax.vmap(mesh.stiffness)(res.theta_rad)
    np.testing.assert_allclose(res.loaded_stiffness_N_per_m, k_geo, rtol=1e-12)
    np.testing.assert_allclose(res.te_s_m, f_s / k_geo / math.cos(pair.base_helix_angle_rad),
                               rtol=1e-12)


def test_uniform_spur_te_closed_form():
    """Uniform law, spur, no modification: TE_S = F_S / (n_pairs k_l b), a square wave."""
    pair, mesh, f_s = _setup(False, "uniform", cells_per_line=3, stiffness_per_length_N_per_m2=1.5e10)
    theta = mesh.theta_grid(200, 2)
    res = quasi_static(mesh, ToothModifications.none(), theta, f_s)
    s0 = np.mod(pair.base_radii_m[0] * np.asarray(theta), pair.base_pitch_m)
    n_pairs = sum(((s0 + j * pair.base_pitch_m) <= pair.path_of_contact_m).astype(int) for j in range(3))
    expected = f_s / (n_pairs * 1.5e10 * pair.face_width_m)
    np.testing.assert_allclose(res.te_s_m, expected, rtol=1e-12)
    assert set(np.unique(n_pairs)) == {1, 2}


def test_table1_short_relief_has_no_nlte_long_relief_does():
    """Section 6.3: short relief keeps an unrelieved pair in contact (NLTE = 0); long does not.
    For long linear relief on both gears the composite relief is P_c |xi - xi_mid| / (g/2), so
    NLTE = min over pairs in the path of that V-shape, written out here."""
    pair, mesh, f_s = _setup(False)
    theta = mesh.theta_grid(128)
    short = quasi_static(mesh, table1_relief("short"), theta, f_s)
    assert float(jnp.max(jnp.abs(short.nlte_m))) == 0.0
    long_ = quasi_static(mesh, table1_relief("long"), theta, f_s)
    xi_a, xi_e = pair.contact_limits_m
    g, mid = xi_e - xi_a, 0.5 * (xi_a + xi_e)
    s0 = np.mod(pair.base_radii_m[0] * np.asarray(theta), pair.base_pitch_m)
    xi = xi_a + s0[:, None] + pair.base_pitch_m * np.arange(3)[None, :]
    v = np.where(xi <= xi_e, 13.3e-6 * np.abs(xi - mid) / (0.5 * g), np.inf)
    np.testing.assert_allclose(long_.nlte_m, v.min(axis=1), rtol=1e-9, atol=1e-15)
    assert float(jnp.ptp(long_.nlte_m)) > 5e-6
    # TE_S - NLTE is the elastic approach, positive under load
    assert bool(jnp.all(long_.x_s_m > 0))


@pytest.mark.parametrize("helical", [False, True])
def test_pitch_error_shows_in_nlte_only_over_its_meshing_window(helical):
    pair, mesh, f_s = _setup(helical, cells_per_line=8)
    tooth, f = 5, 8e-6  # pinion tooth 5 stands 8 um ahead (material excess)
    f1 = np.zeros(pair.z1)
    f1[tooth] = f
    mods = ToothModifications.none().with_pitch_errors(f1, np.zeros(pair.z2))
    step = pair.mesh_period_rad / 48
    theta = mesh.theta_grid(48, pair.z1) + 0.37 * step  # no sample exactly on an engagement
    res = quasi_static(mesh, mods, theta, f_s)
    # pair n = tooth (first revolution): its cell at face position eta lies on the path of
    # contact when 0 <= Rb1 theta - n p_bt - eta tan(beta_b) <= g_alpha; cells sit at the
    # centres of 8 face slices, so the tooth is on the base plane for
    # eta_first tan(beta_b) <= s <= g_alpha + eta_last tan(beta_b)
    tan_bb = math.tan(pair.base_helix_angle_rad)
    eta_first, eta_last = (np.array([0.5, 7.5]) / 8) * pair.face_width_m
    s = pair.base_radii_m[0] * np.asarray(theta) - tooth * pair.base_pitch_m
    in_window = (s >= eta_first * tan_bb) & (s <= pair.path_of_contact_m + eta_last * tan_bb)
    nlte = np.asarray(res.nlte_m)
    np.testing.assert_allclose(nlte[in_window], -f, rtol=1e-12)
    np.testing.assert_allclose(nlte[~in_window], 0.0, atol=1e-18)
    assert in_window.sum() > 0 and (~in_window).sum() > 0


def test_pinion_eccentricity_nlte_is_sinusoid():
    pair, mesh, f_s = _setup(False, cells_per_line=2)
    mods = ToothModifications.none().with_eccentricity([20e-6, 0.0], [0.3, 0.0])
    theta = mesh.theta_grid(8, pair.z1)
    res = quasi_static(mesh, mods, theta, f_s)
    np.testing.assert_allclose(res.nlte_m, -20e-6 * np.sin(np.asarray(theta) - 0.3), atol=1e-18)


def _te_ptp(mesh, theta, f_s, amp, ext):
    mods = ToothModifications.tip_relief(amp, ext, "parabolic")
    te = quasi_static(mesh, mods, theta, f_s).te_s_m
    return jnp.max(te) - jnp.min(te)


def test_te_ptp_gradients_match_central_differences():
    pair, mesh, f_s = _setup(False, cells_per_line=2)
    theta = mesh.theta_grid(97)
    amp, ext = 9e-6, 0.31  # a smooth point: fixed argmax/argmin positions and active sets
    g_amp, g_ext = jax.grad(_te_ptp, argnums=(3, 4))(mesh, theta, f_s, amp, ext)
    fun = lambda a, e: float(_te_ptp(mesh, theta, f_s, a, e))  # noqa: E731
    h_a, h_e = 1e-3 * amp, 1e-3 * ext
    fd_amp = (fun(amp + h_a, ext) - fun(amp - h_a, ext)) / (2 * h_a)
    fd_ext = (fun(amp, ext + h_e) - fun(amp, ext - h_e)) / (2 * h_e)
    assert float(g_amp) == pytest.approx(fd_amp, rel=1e-4)
    assert float(g_ext) == pytest.approx(fd_ext, rel=1e-4)
    assert abs(fd_amp) > 1e-3 and abs(fd_ext) > 1e-8  # the check is not vacuous


def test_vmap_over_relief_designs_equals_loop():
    pair, mesh, f_s = _setup(True, cells_per_line=10)
    theta = mesh.theta_grid(32)
    amps = jnp.array([0.0, 5e-6, 13.3e-6, 20e-6])
    batched = jax.vmap(lambda a: _te_ptp(mesh, theta, f_s, a, 0.4))(amps)
    looped = jnp.stack([_te_ptp(mesh, theta, f_s, a, 0.4) for a in amps])
    np.testing.assert_allclose(batched, looped, rtol=1e-12)


@pytest.mark.parametrize(
    "make, words",
    [
        (lambda: ToothModifications.tip_relief(-1e-6, 0.2), "must be >= 0"),
        (lambda: ToothModifications.tip_relief(13.3, 0.2), "metres"),
        (lambda: ToothModifications.tip_relief(1e-5, 0.0), "(0, 1]"),
        (lambda: ToothModifications.tip_relief(1e-5, 0.2, "cubic"), "relief_shape"),
        (lambda: table1_relief("medium"), "relief='medium'"),
    ],
)
def test_bad_modifications_raise_clear_errors(make, words):
    with pytest.raises(ModificationError) as exc:
        make()
    assert words in str(exc.value)


def test_pitch_error_length_checked():
    pair = baud_velex_pair(False)
    mods = ToothModifications.none().with_pitch_errors(np.zeros(25), np.zeros(pair.z2))
    with pytest.raises(ModificationError, match="expected \\(26,\\)"):
        mods.check_against(pair)
    # and inside the jitted solve (JAX gathers would otherwise clamp the index silently)
    mesh = Mesh.build(pair, "uniform", cells_per_line=1)
    with pytest.raises(ModificationError, match="gear 1 has 26 teeth"):
        quasi_static(mesh, mods, mesh.theta_grid(4), 1000.0)
