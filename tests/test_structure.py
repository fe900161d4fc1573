"""Tests of gearjax.structure against independent closed forms.

Every reference value below is computed in the test from a textbook formula written
next to it (never copied from the code's output). Notation: E Young's modulus, G shear
modulus, nu Poisson's ratio, rho density, A area, I second moment of area, J polar
second moment, k shear coefficient, L length.
"""

from __future__ import annotations

import math
import warnings

import gearjax  # noqa: F401  (enables float64)
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gearjax.structure import (
    ElementInputError,
    Material,
    RigidBodyModeWarning,
    Structure,
    StructureBuilder,
    StructureInputError,
    coupling_stiffness,
    disc_properties,
    modal_basis,
    modal_damping_matrix,
    reduced_model,
    shear_coefficient_hutchinson,
    timoshenko_element,
    torsional_coupling,
)
from gearjax.rigs.baud_velex import (
    BAUD_VELEX_BEARINGS,
    ENCODER_POSITIONS,
    GEAR_NODE,
    LOAD_NODE,
    MOTOR_NODE,
    PINION_NODE,
    baud_velex_structure,
    encoder_nodes,
    paper_node,
)

E, NU, RHO = 2.1e11, 0.3, 7800.0
G = E / (2 * (1 + NU))
STEEL = Material(E=E, nu=NU, rho=RHO)
U, V, W, PHI, PSI, THETA = range(6)


# ----------------------------------------------------------------------------- helpers
def section(do: float, di: float = 0.0) -> tuple[float, float, float]:
    """A = pi (D^2 - d^2)/4, I = pi (D^4 - d^4)/64, J = 2 I."""
    A = math.pi * (do**2 - di**2) / 4
    I = math.pi * (do**4 - di**4) / 64
    return A, I, 2 * I


def k_hutchinson_solid(nu: float) -> float:
    """Hutchinson (2001), solid circle: k = 6 (1 + nu)^2 / (7 + 12 nu + 4 nu^2)."""
    return 6 * (1 + nu) ** 2 / (7 + 12 * nu + 4 * nu**2)


def uniform_shaft(n_el: int, L: float, do: float, di: float = 0.0) -> Structure:
    z = np.linspace(0.0, L, n_el + 1)
    return (
        StructureBuilder(n_nodes=n_el + 1)
        .add_shaft(list(range(n_el + 1)), positions_m=z, outer_diameters_m=do,
                   inner_diameters_m=di, material=STEEL)
        .build()
    )  # fmt: skip


def solve_clamped(K: np.ndarray, fixed: list[int], F: np.ndarray) -> np.ndarray:
    """Static solution with the dofs in ``fixed`` held at zero (row/column deletion)."""
    n = K.shape[0]
    free = np.setdiff1d(np.arange(n), fixed)
    x = np.zeros(n)
    x[free] = np.linalg.solve(K[np.ix_(free, free)], F[free])
    return x


def plane_eigs(s: Structure, disp: int, rot: int, fixed_nodes: list[int]) -> np.ndarray:
    """Angular frequencies of one bending plane with disp = 0 at ``fixed_nodes``."""
    dofs = [6 * n + d for n in range(s.n_nodes) for d in (disp, rot)]
    dofs = [d for d in dofs if not (d % 6 == disp and d // 6 in fixed_nodes)]
    ix = np.ix_(dofs, dofs)
    Mp, Kp = s.M[ix], s.K[ix]
    Lc = np.linalg.cholesky(Mp)
    Li = np.linalg.inv(Lc)
    return np.sqrt(np.linalg.eigvalsh(Li @ Kp @ Li.T))


def rigid_body_vectors(s: Structure) -> np.ndarray:
    """Six rigid-body fields from kinematics: translation t and rotation omega about the
    origin give node translations t + omega x r and node rotations omega."""
    R = np.zeros((s.n_dof, 6))
    basis = np.eye(3)
    for j in range(6):
        t = basis[j] if j < 3 else np.zeros(3)
        om = basis[j - 3] if j >= 3 else np.zeros(3)
        for n in range(s.n_nodes):
            r = s.node_positions_m[n]
            R[s.translation_dofs_stz(n), j] = t + np.cross(om, r)
            R[s.rotation_dofs_stz(n), j] = om
    return R


# ----------------------------------------------------------------- element properties
@settings(max_examples=40, deadline=None)
@given(
    L=st.floats(0.005, 2.0),
    do=st.floats(0.005, 0.5),
    ratio=st.floats(0.0, 0.95),
    nu=st.floats(0.0, 0.49),
)
def test_element_symmetric_semidefinite(L: float, do: float, ratio: float, nu: float) -> None:
    Ke, Me = timoshenko_element(L, do, ratio * do, E=E, nu=nu, rho=RHO)
    assert np.allclose(Ke, Ke.T, rtol=0, atol=1e-14 * np.abs(Ke).max())
    assert np.allclose(Me, Me.T, rtol=0, atol=1e-14 * np.abs(Me).max())
    # Mass positive definite (Cholesky succeeds), stiffness PSD with 6 zero eigenvalues.
    np.linalg.cholesky(Me)
    # Scale rows/cols to comparable units before counting zero eigenvalues.
    d = np.diag(1.0 / np.sqrt(np.diag(Ke)))
    ev = np.linalg.eigvalsh(d @ Ke @ d)
    assert ev.min() > -1e-9
    assert int(np.sum(ev < 1e-9 * ev.max())) == 6


def test_shear_coefficient_limits() -> None:
    # Solid circle (Hutchinson 2001): 6 (1+nu)^2 / (7 + 12 nu + 4 nu^2).
    for nu in (0.0, 0.25, 0.3, 0.45):
        assert shear_coefficient_hutchinson(0.1, 0.0, nu) == pytest.approx(
            k_hutchinson_solid(nu), rel=1e-14
        )
    # Thin-walled tube (b -> a): (1 + nu) / (2 + nu).
    assert shear_coefficient_hutchinson(0.1, 0.1 * (1 - 1e-7), 0.3) == pytest.approx(
        1.3 / 2.3, rel=1e-6
    )


def test_disc_properties_closed_form() -> None:
    # Annulus R, r, width b: m = rho pi (R^2 - r^2) b; I_p = pi rho b (R^4 - r^4) / 2;
    # I_d = I_p / 2 + m b^2 / 12 (perpendicular-axis + slab thickness).
    Ro, ri, b = 0.3, 0.04, 0.05
    m, it, ip = disc_properties(2 * Ro, 2 * ri, b, RHO)
    m_ref = RHO * math.pi * (Ro**2 - ri**2) * b
    ip_ref = math.pi * RHO * b * (Ro**4 - ri**4) / 2
    assert m == pytest.approx(m_ref, rel=1e-14)
    assert ip == pytest.approx(ip_ref, rel=1e-14)
    assert it == pytest.approx(ip_ref / 2 + m_ref * b**2 / 12, rel=1e-14)


# ------------------------------------------------------------------------ statics
@pytest.mark.parametrize("n_el", [1, 3, 8])
def test_cantilever_tip_deflection_timoshenko(n_el: int) -> None:
    # Short solid beam (L/d = 2): shear flexibility is ~12 % of the total.
    L, d, P = 0.1, 0.05, 1e4
    A, I, _ = section(d)
    k = k_hutchinson_solid(NU)
    s = uniform_shaft(n_el, L, d)
    tip = n_el
    # Euler-Bernoulli + Timoshenko shear: delta = P L^3 / (3 E I) + P L / (k G A).
    delta = P * L**3 / (3 * E * I) + P * L / (k * G * A)
    # Slope of the bending part at the tip (shear adds no section rotation): P L^2/(2EI).
    slope = P * L**2 / (2 * E * I)
    assert P * L / (k * G * A) > 0.1 * delta  # the shear term matters here
    fixed = list(range(6))
    for disp, rot, sign in ((V, PSI, +1.0), (W, PHI, -1.0)):
        F = np.zeros(s.n_dof)
        F[6 * tip + disp] = P
        x = solve_clamped(s.K, fixed, F)
        assert x[6 * tip + disp] == pytest.approx(delta, rel=1e-10)
        # psi = +dv/dz, phi = -dw/dz (right-hand rule, see beams.py).
        assert x[6 * tip + rot] == pytest.approx(sign * slope, rel=1e-10)
        others = np.delete(x, [6 * n + dd for n in range(s.n_nodes) for dd in (disp, rot)])
        assert np.abs(others).max() == 0.0


def test_cantilever_tip_moment() -> None:
    # Pure tip moment: rotation M L / (E I), deflection M L^2 / (2 E I) (no shear force).
    L, do, di, Mt = 0.6, 0.06, 0.03, 500.0
    _, I, _ = section(do, di)
    s = uniform_shaft(6, L, do, di)
    F = np.zeros(s.n_dof)
    F[6 * 6 + PSI] = Mt  # moment about T bends the (z, S) plane
    x = solve_clamped(s.K, list(range(6)), F)
    assert x[6 * 6 + PSI] == pytest.approx(Mt * L / (E * I), rel=1e-10)
    assert x[6 * 6 + V] == pytest.approx(Mt * L**2 / (2 * E * I), rel=1e-10)


def test_simply_supported_midspan_deflection() -> None:
    # delta = P L^3 / (48 E I) + P L / (4 k G A); hollow shaft, k from Hutchinson's
    # hollow-circle formula written out here.
    L, do, di, P = 0.4, 0.08, 0.04, 2e4
    A, I, _ = section(do, di)
    a, b = do / 2, di / 2
    k = (6 * (a * a + b * b) ** 2 * (1 + NU) ** 2) / (
        7 * a**4 + 34 * a * a * b * b + 7 * b**4
        + NU * (12 * a**4 + 48 * a * a * b * b + 12 * b**4)
        + NU**2 * (4 * a**4 + 16 * a * a * b * b + 4 * b**4)
    )  # fmt: skip
    n_el = 10
    s = uniform_shaft(n_el, L, do, di)
    mid = n_el // 2
    delta = P * L**3 / (48 * E * I) + P * L / (4 * k * G * A)
    for disp in (V, W):
        F = np.zeros(s.n_dof)
        F[6 * mid + disp] = P
        # Pins: disp = 0 at both ends; also fix u and theta at node 0 (decoupled anyway)
        # and the other bending plane at the ends.
        other = W if disp == V else V
        fixed = [disp, other, U, THETA, 6 * n_el + disp, 6 * n_el + other]
        x = solve_clamped(s.K, fixed, F)
        assert x[6 * mid + disp] == pytest.approx(delta, rel=1e-10)


def test_torsion_and_axial_stiffness() -> None:
    # theta_tip = T L / (G J); u_tip = F L / (E A) for a hollow shaft.
    L, do, di = 0.75, 0.05, 0.02
    A, _, J = section(do, di)
    s = uniform_shaft(5, L, do, di)
    F = np.zeros(s.n_dof)
    F[6 * 5 + THETA] = 300.0
    F[6 * 5 + U] = 1e5
    x = solve_clamped(s.K, list(range(6)), F)
    assert x[6 * 5 + THETA] == pytest.approx(300.0 * L / (G * J), rel=1e-12)
    assert x[6 * 5 + U] == pytest.approx(1e5 * L / (E * A), rel=1e-12)
    # Linear variation along the shaft.
    zs = s.node_positions_m[:, 2]
    assert np.allclose(x[THETA::6], 300.0 * zs / (G * J), rtol=1e-12, atol=0)


def test_torsional_coupling_in_series() -> None:
    # Shaft (G J / L) in series with a coupling k: 1/k_eq = L/(G J) + 1/k.
    L, d, kc = 0.5, 0.04, 2e4
    _, _, J = section(d)
    s = (
        StructureBuilder(n_nodes=3)
        .add_shaft([0, 1], positions_m=[0.0, L], outer_diameters_m=d, material=STEEL)
        .add_torsional_coupling(1, 2, kc)
        .add_disc(2, mass_kg=1.0, transverse_inertia_kg_m2=1e-3, polar_inertia_kg_m2=1e-3)
        .build()
    )
    F = np.zeros(s.n_dof)
    F[6 * 2 + THETA] = 100.0
    fixed = list(range(6)) + [12, 13, 14, 15, 16]  # node 2 only keeps theta
    x = solve_clamped(s.K, fixed, F)
    assert x[6 * 2 + THETA] == pytest.approx(100.0 * (L / (G * J) + 1 / kc), rel=1e-12)
    Kc = torsional_coupling(kc)
    assert np.count_nonzero(Kc) == 4 and Kc[5, 11] == -kc
    assert np.allclose(coupling_stiffness(kc)[:, :], Kc)


# ------------------------------------------------------------------ mass and rigid body
def continuum_rigid_mass(positions: np.ndarray, do: float, di: float,
                         discs: list[tuple[int, float, float, float]]) -> np.ndarray:
    """6x6 kinetic inner products of the rigid fields (t, omega) of a shaft on z.

    Integrates rho A (t_a + w_a x r).(t_b + w_b x r) + rho (I w_aS w_bS + I w_aT w_bT +
    J w_az w_bz) along the axis with 3-point Gauss quadrature (exact: quadratic in z),
    plus discs m (..).(..) + I_d (w_S w_S + w_T w_T) + I_p w_z w_z.
    """
    A, I, J = section(do, di)
    gp, gw = np.polynomial.legendre.leggauss(3)
    basis = np.eye(3)

    def field(j: int, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        t = basis[j] if j < 3 else np.zeros(3)
        om = basis[j - 3] if j >= 3 else np.zeros(3)
        return t + np.cross(om, r), om

    Mrb = np.zeros((6, 6))
    for a in range(6):
        for b in range(6):
            tot = 0.0
            for z0, z1 in zip(positions[:-1], positions[1:]):
                for xi, wq in zip(gp, gw):
                    r = np.array([0.0, 0.0, 0.5 * (z0 + z1) + 0.5 * (z1 - z0) * xi])
                    ua, oa = field(a, r)
                    ub, ob = field(b, r)
                    dens = RHO * A * ua @ ub + RHO * (I * oa[0] * ob[0] + I * oa[1] * ob[1]
                                                      + J * oa[2] * ob[2])
                    tot += 0.5 * (z1 - z0) * wq * dens
            for node, m, it, ip in discs:
                r = np.array([0.0, 0.0, positions[node]])
                ua, oa = field(a, r)
                ub, ob = field(b, r)
                tot += m * ua @ ub + it * (oa[0] * ob[0] + oa[1] * ob[1]) + ip * oa[2] * ob[2]
            Mrb[a, b] = tot
    return Mrb


def test_mass_matrix_conserves_mass_and_inertia() -> None:
    z = np.array([0.1, 0.18, 0.3, 0.33, 0.5, 0.72])
    do, di = 0.07, 0.025
    discs = [(2, 12.0, 0.05, 0.09), (5, 3.0, 0.004, 0.007)]
    b = StructureBuilder(n_nodes=len(z)).add_shaft(
        list(range(len(z))), positions_m=z, outer_diameters_m=do, inner_diameters_m=di,
        material=STEEL)  # fmt: skip
    for node, m, it, ip in discs:
        b.add_disc(node, mass_kg=m, transverse_inertia_kg_m2=it, polar_inertia_kg_m2=ip)
    s = b.build()
    R = rigid_body_vectors(s)
    ref = continuum_rigid_mass(z, do, di, discs)
    got = R.T @ s.M @ R
    assert np.allclose(got, ref, rtol=1e-12, atol=1e-12 * np.abs(ref).max())
    # Total mass: rho A L + discs.
    A, _, _ = section(do, di)
    assert got[0, 0] == pytest.approx(RHO * A * (z[-1] - z[0]) + 15.0, rel=1e-12)
    assert np.allclose(s.M, s.M.T, rtol=0, atol=0)
    np.linalg.cholesky(s.M)


def test_free_free_shaft_has_six_rigid_body_modes() -> None:
    z = np.linspace(-0.3, 0.5, 9)
    s = (
        StructureBuilder()
        .add_shaft(list(range(9)), positions_m=z, outer_diameters_m=[0.05] * 4 + [0.07] * 4,
                   material=STEEL, axis_st_m=(0.2, -0.1))
        .add_disc(4, mass_kg=5.0, transverse_inertia_kg_m2=0.02, polar_inertia_kg_m2=0.03)
        .build()
    )  # fmt: skip
    R = rigid_body_vectors(s)
    # Kinematic rigid-body fields are strain-free: K R = 0 (validates the bending signs).
    assert np.abs(s.K @ R).max() < 1e-12 * np.abs(s.K).max()
    with pytest.warns(RigidBodyModeWarning, match="6 rigid-body"):
        mb = modal_basis(s.M, s.K)
    assert mb.n_rigid == 6
    assert np.all(mb.omegas_rad_s[:6] == 0.0) and mb.omegas_rad_s[6] > 0.0
    # The six zero modes span the rigid-body space.
    P = mb.modes[:, :6]
    coef, *_ = np.linalg.lstsq(P, R, rcond=None)
    assert np.allclose(P @ coef, R, atol=1e-9 * np.abs(R).max())
    assert np.allclose(mb.modes.T @ s.M @ mb.modes, np.eye(s.n_dof), atol=1e-9)


# ------------------------------------------------------------------------ frequencies
def test_pinned_pinned_slender_euler_bernoulli() -> None:
    # Slender (L/d = 100). Timoshenko closed form (timoshenko_pinned_frequency, below):
    # measured error of the 20 elements 6.0e-7 / 9.6e-6 / 4.8e-5 for modes 1-3, falling as
    # h^3 (7.5e-6 / 1.2e-4 / 5.9e-4 at 10 elements, 7e-8 / 1.1e-6 / 5.7e-6 at 40): rtol 1e-4.
    # Dropping shear and rotary inertia (the EB frequencies) is off by 1.2e-4 / 4.7e-4 /
    # 1.1e-3, which this catches.
    L, d, n_el = 2.0, 0.02, 20
    A, I, _ = section(d)
    s = uniform_shaft(n_el, L, d)
    tim = np.array([timoshenko_pinned_frequency(n, L, A, I, k_hutchinson_solid(NU))
                    for n in (1, 2, 3)])
    # Euler-Bernoulli slender limit w_n = (n pi / L)^2 sqrt(E I / (rho A)): shear and rotary
    # inertia lower it by about (n pi r_g / L)^2 (1 + E / (k G)) / 2 with r_g = d / 4, i.e.
    # 1.2e-4 / 4.7e-4 / 1.1e-3 (measured on the elements: 1.2e-4 / 4.6e-4 / 1.0e-3), so
    # below EB and within 1.5e-3 of it.
    eb = np.array([(n * math.pi / L) ** 2 * math.sqrt(E * I / (RHO * A)) for n in (1, 2, 3)])
    for disp, rot in ((V, PSI), (W, PHI)):
        w = plane_eigs(s, disp, rot, [0, n_el])[:3]
        assert np.allclose(w, tim, rtol=1e-4, atol=0)
        assert np.all(w < eb) and np.allclose(w, eb, rtol=1.5e-3, atol=0)


def test_pinned_pinned_euler_bernoulli_limit_converges() -> None:
    # With shear and rotary inertia switched off the element is Euler-Bernoulli; the
    # consistent-mass Ritz solution converges from above, error O(h^4).
    L, d, n_el = 1.0, 0.05, 12
    A, I, _ = section(d)
    Ks, Ms = np.zeros((6 * (n_el + 1),) * 2), np.zeros((6 * (n_el + 1),) * 2)
    for e in range(n_el):
        Ke, Me = timoshenko_element(L / n_el, d, E=E, nu=NU, rho=RHO, shear=False,
                                    rotary_inertia=False)  # fmt: skip
        ix = np.ix_(range(6 * e, 6 * e + 12), range(6 * e, 6 * e + 12))
        Ks[ix] += Ke
        Ms[ix] += Me
    dofs = [6 * n + dd for n in range(n_el + 1) for dd in (V, PSI)]
    dofs = [x for x in dofs if x not in (V, 6 * n_el + V)]
    ix = np.ix_(dofs, dofs)
    Lc = np.linalg.inv(np.linalg.cholesky(Ms[ix]))
    w = np.sqrt(np.linalg.eigvalsh(Lc @ Ks[ix] @ Lc.T))[:3]
    ref = np.array([(n * math.pi / L) ** 2 * math.sqrt(E * I / (RHO * A)) for n in (1, 2, 3)])
    assert np.all(w >= ref * (1 - 1e-12))
    assert np.allclose(w, ref, rtol=5e-4)


def timoshenko_pinned_frequency(n: int, L: float, A: float, I: float, k: float) -> float:
    """Lower root of the Timoshenko frequency equation for y = sin(a z), a = n pi / L:

    E I a^4 - w^2 [rho A + rho I a^2 (1 + E / (k G))] + w^4 rho^2 I / (k G) = 0.
    """
    a = n * math.pi / L
    c2 = RHO**2 * I / (k * G)
    c1 = -(RHO * A + RHO * I * a * a * (1 + E / (k * G)))
    c0 = E * I * a**4
    w2 = (-c1 - math.sqrt(c1 * c1 - 4 * c2 * c0)) / (2 * c2)
    return math.sqrt(w2)


def test_pinned_pinned_thick_timoshenko() -> None:
    # Thick (L/d = 4): shear and rotary inertia lower the frequencies markedly.
    L, d, n_el = 0.4, 0.1, 40
    A, I, _ = section(d)
    k = k_hutchinson_solid(NU)
    s = uniform_shaft(n_el, L, d)
    ref = np.array([timoshenko_pinned_frequency(n, L, A, I, k) for n in (1, 2, 3)])
    eb = np.array([(n * math.pi / L) ** 2 * math.sqrt(E * I / (RHO * A)) for n in (1, 2, 3)])
    assert np.all(eb / ref > 1.05)  # the correction is large: the test has teeth
    for disp, rot in ((V, PSI), (W, PHI)):
        w = plane_eigs(s, disp, rot, [0, n_el])[:3]
        assert np.allclose(w, ref, rtol=1e-3)


# --------------------------------------------------------------------- modal damping
def supported_shaft() -> Structure:
    z = np.linspace(0.0, 0.8, 9)
    return (
        StructureBuilder()
        .add_shaft(list(range(9)), positions_m=z, outer_diameters_m=0.05, material=STEEL)
        .add_bearing(1, 1e8, 2e8, 1e7)
        .add_bearing(7, 3e8, 1e8)
        .add_torsional_spring_to_ground(0, 5e3)
        .add_disc(4, mass_kg=8.0, transverse_inertia_kg_m2=0.03, polar_inertia_kg_m2=0.05)
        .build()
    )


@pytest.mark.parametrize("zeta", [0.03, 0.1])
def test_modal_damping_gives_ratio_zeta_on_each_mode(zeta: float) -> None:
    scipy_linalg = pytest.importorskip("scipy.linalg")
    s = supported_shaft()
    mb = modal_basis(s.M, s.K)
    assert mb.n_rigid == 0
    C = modal_damping_matrix(s.M, mb.modes, mb.omegas_rad_s, zeta)
    n = s.n_dof
    # State space of M x'' + C x' + K x = 0: eigenvalues -zeta w +- i w sqrt(1 - zeta^2).
    Minv = np.linalg.inv(s.M)
    Asys = np.block([[np.zeros((n, n)), np.eye(n)], [-Minv @ s.K, -Minv @ C]])
    lam = scipy_linalg.eigvals(Asys)
    lam = lam[lam.imag > 0]
    lam = lam[np.argsort(np.abs(lam))]
    assert np.allclose(-lam.real / np.abs(lam), zeta, rtol=1e-6)
    assert np.allclose(np.abs(lam), mb.omegas_rad_s, rtol=1e-6)
    Cm = mb.modes.T @ C @ mb.modes
    assert np.allclose(Cm, np.diag(2 * zeta * mb.omegas_rad_s), atol=1e-8 * Cm.max())


def test_modal_basis_truncation_options() -> None:
    s = supported_shaft()
    full = modal_basis(s.M, s.K)
    some = modal_basis(s.M, s.K, n_modes=5)
    low = modal_basis(s.M, s.K, max_frequency_hz=float(full.frequencies_hz[7]) * 1.0000001)
    assert some.n_modes == 5 and low.n_modes == 8
    assert np.allclose(some.omegas_rad_s, full.omegas_rad_s[:5])
    assert np.allclose(full.frequencies_hz, full.omegas_rad_s / (2 * math.pi))


# ------------------------------------------------------------------------ reduced model
def spur_structure_vector(s: Structure, a: float, z1: int, z2: int, alpha: float) -> np.ndarray:
    """Averaged structure vector of Eq. (A.1) for a spur pair: V = (n, O1M x n, -n,
    -O2M x n), M at the pitch point, n in the transverse plane at the pressure angle."""
    O1 = s.node_position(s.pinion_node)
    O2 = s.node_position(s.gear_node)
    e = (O2 - O1) / np.linalg.norm(O2 - O1)
    t = np.cross(np.array([0.0, 0.0, 1.0]), e)
    r1 = a * z1 / (z1 + z2)
    Mp = O1 + r1 * e
    n = math.sin(alpha) * e + math.cos(alpha) * t
    V = np.zeros(s.n_dof)
    V[s.translation_dofs_stz(s.pinion_node)] = n
    V[s.rotation_dofs_stz(s.pinion_node)] = np.cross(Mp - O1, n)
    V[s.translation_dofs_stz(s.gear_node)] = -n
    V[s.rotation_dofs_stz(s.gear_node)] = -np.cross(Mp - O2, n)
    return V


def test_reduced_model_static_correction_is_exact() -> None:
    s = baud_velex_structure()
    a, z1, z2, alpha = 0.366, 26, 157, math.radians(20)
    Vs = spur_structure_vector(s, a, z1, z2, alpha)
    # Torsional components are the base radii (Eq. (8b)): Rb = r cos(alpha).
    assert Vs[s.dof(PINION_NODE, "theta")] == pytest.approx(a * z1 / (z1 + z2) * math.cos(alpha))
    assert Vs[s.dof(GEAR_NODE, "theta")] == pytest.approx(a * z2 / (z1 + z2) * math.cos(alpha))
    km = 4e8
    F0 = np.zeros(s.n_dof)
    F0[s.dof(MOTOR_NODE, "theta")] = 254.8  # input torque of Section 6.1
    Kbar = s.K + km * np.outer(Vs, Vs)
    x_full = np.linalg.solve(Kbar, F0)
    sm = s.with_stiffness(km * np.outer(Vs, Vs), "mean mesh", (PINION_NODE, GEAR_NODE))
    assert np.array_equal(sm.K, Kbar) and sm.elements[-1].nodes == (PINION_NODE, GEAR_NODE)
    with pytest.raises(StructureInputError, match="K_extra must have shape"):
        s.with_stiffness(np.eye(3), "bad")

    # 1) The structure alone is singular (free pinion-line rotation): reduce it with the
    #    static loads {F0, V}, then add the mesh in reduced coordinates.
    with pytest.warns(RigidBodyModeWarning):
        modal_basis(s.M, s.K)
    rm = reduced_model(s.M, s.K, np.stack([F0, Vs], axis=1), max_frequency_hz=300.0)
    assert rm.n_static == 2 and rm.n_modes < 20
    assert np.allclose(rm.M, np.eye(rm.M.shape[0]), atol=1e-10)
    Vr = rm.project_force(Vs)
    q = np.linalg.solve(rm.K + km * np.outer(Vr, Vr), rm.project_force(F0))
    assert np.allclose(rm.expand(q), x_full, rtol=0, atol=1e-9 * np.abs(x_full).max())
    # Without the static correction the same truncation is visibly wrong.
    rm0 = reduced_model(s.M, s.K, None, max_frequency_hz=300.0)
    Vr0 = rm0.project_force(Vs)
    q0 = np.linalg.solve(rm0.K + km * np.outer(Vr0, Vr0), rm0.project_force(F0))
    assert np.abs(rm0.expand(q0) - x_full).max() > 1e-3 * np.abs(x_full).max()

    # 2) Reduce K + k_m V V^T directly: exact statics, exact kept frequencies.
    rb = reduced_model(s.M, Kbar, F0, max_frequency_hz=500.0, zeta=0.03)
    qb = np.linalg.solve(rb.K, rb.project_force(F0))
    assert np.allclose(rb.expand(qb), x_full, rtol=0, atol=1e-9 * np.abs(x_full).max())
    full = modal_basis(s.M, Kbar)
    assert full.n_rigid == 0  # the mesh removes the rigid-body mode
    nk = rb.n_modes
    assert np.allclose(rb.omegas_rad_s[:nk], full.omegas_rad_s[:nk], rtol=1e-9)
    assert np.all(full.frequencies_hz[:nk] <= 500.0) and full.frequencies_hz[nk] > 500.0
    # Kept modes carry the modal damping ratio exactly.
    assert np.allclose(np.diag(rb.C)[:nk], 2 * 0.03 * rb.omegas_rad_s[:nk], rtol=1e-8)
    # Harmonic response well below the cut-off: the reduced model is close to the full one.
    w = 2 * math.pi * 150.0
    xf = np.linalg.solve(Kbar - w * w * s.M, F0)
    xr = rb.expand(np.linalg.solve(rb.K - w * w * rb.M, rb.project_force(F0)))
    assert np.linalg.norm(xr - xf) < 1e-3 * np.linalg.norm(xf)


# ------------------------------------------------------------------------- Baud-Velex rig
def test_baud_velex_topology() -> None:
    s = baud_velex_structure()
    assert s.n_nodes == 43 and s.n_dof == 258 and s.M.shape == s.K.shape == (258, 258)
    # 39 shaft elements + the pinion-gear element = 40 elements (Section 6.1).
    assert len(s.elements_of_kind("shaft")) == 39
    assert (s.pinion_node, s.gear_node) == (PINION_NODE, GEAR_NODE) == (6, 34)
    assert np.allclose(s.K, s.K.T, rtol=0, atol=0) and np.allclose(s.M, s.M.T, rtol=0, atol=0)
    np.linalg.cholesky(s.M)
    # Pinion shaft first (paper nodes 1-21), gear line after (22-43).
    assert s.line_nodes("pinion") == tuple(range(21))
    assert s.line_nodes("gear") == tuple(range(21, 43))
    for pos in (1, 2, 3):
        i, ii = encoder_nodes(pos)
        assert s.node_lines[i] == "pinion" and s.node_lines[ii] == "gear"
    assert ENCODER_POSITIONS[1] == (PINION_NODE, GEAR_NODE)
    # Pinion and gear centres are a centre distance apart in the same transverse plane.
    d = s.node_position(GEAR_NODE) - s.node_position(PINION_NODE)
    assert np.linalg.norm(d) == pytest.approx(0.366) and d[2] == 0.0
    # Default frame of the pinion-gear element: S along the line of action, so
    # O1O2 = a (sin alpha_w S - cos alpha_w T) (tangent points T1 = O1 - Rb1 T,
    # T2 = O2 + Rb2 T, T1T2 = a sin alpha_w S).
    aw = math.radians(20.0)
    assert np.allclose(d, 0.366 * np.array([math.sin(aw), -math.cos(aw), 0.0]), atol=1e-15)
    s2 = baud_velex_structure(centre_distance_m=0.3895, centre_line_angle_rad=math.pi / 2)
    d2 = s2.node_position(GEAR_NODE) - s2.node_position(PINION_NODE)
    assert np.allclose(d2, [0.0, 0.3895, 0.0], atol=1e-15)


def test_baud_velex_bearings_match_table_2() -> None:
    s = baud_velex_structure()
    # A rigid translation of the whole rig strains only bearings (shafts and couplings
    # move rigidly), so K @ (rigid translation) lists the grounded stiffnesses per node.
    motor = MOTOR_NODE
    for comp, dof, col in (("S", V, 0), ("T", W, 1), ("z", U, 2)):
        x = np.zeros(s.n_dof)
        x[dof::6] = 1.0
        f = (s.K @ x).reshape(43, 6)
        expected = np.zeros((43, 6))
        for n_paper, ks in BAUD_VELEX_BEARINGS.items():
            expected[paper_node(n_paper), dof] = ks[col]
        got = f.copy()
        got[motor] = 0.0  # the motor's own (assumed) support, not in Table 2
        assert np.allclose(got, expected, rtol=1e-9, atol=1e-6), comp
    # Table 2 values themselves (paper, 1-based): independent transcription.
    table2 = {5: (1e9, 1e9, 0), 9: (1e9, 1e9, 0), 13: (0, 0, 3.5e7), 23: (7e7, 7e7, 0),
              25: (7e7, 7e7, 0), 33: (1e9, 1e9, 0), 37: (1e9, 1e9, 0), 41: (0, 0, 6e7)}
    assert BAUD_VELEX_BEARINGS == table2
    # Torsion: rotating the pinion line rigidly is free (the rigid-body mode removed by
    # the mesh); rotating the gear line loads only the resisting torsional spring.
    x = np.zeros(s.n_dof)
    x[[6 * n + THETA for n in s.line_nodes("pinion")]] = 1.0
    assert np.abs(s.K @ x).max() < 1e-9
    x = np.zeros(s.n_dof)
    x[[6 * n + THETA for n in s.line_nodes("gear")]] = 1.0
    f = s.K @ x
    assert np.count_nonzero(np.abs(f) > 1e-6) == 1 and f[6 * LOAD_NODE + THETA] > 0
    with pytest.warns(RigidBodyModeWarning, match="1 rigid-body"):
        mb = modal_basis(s.M, s.K, n_modes=12)
    assert mb.n_rigid == 1 and mb.omegas_rad_s[1] > 2 * math.pi * 5.0


def test_structure_is_a_pytree_and_converts_to_jax() -> None:
    import jax
    import jax.numpy as jnp

    s = uniform_shaft(2, 0.3, 0.04)
    leaves = jax.tree_util.tree_leaves(s)
    assert len(leaves) == 3
    sj = s.as_jax()
    assert isinstance(sj.K, jax.Array) and sj.K.dtype == jnp.float64
    assert sj.node_labels == s.node_labels


# ------------------------------------------------------------------------- validation
def test_validation_errors_name_field_and_value() -> None:
    assert issubclass(StructureInputError, ValueError)
    assert issubclass(ElementInputError, ValueError)
    b = StructureBuilder(n_nodes=3)
    with pytest.raises(StructureInputError, match=r"k_s.*-1"):
        b.add_bearing(0, -1.0, 1e8)
    with pytest.raises(StructureInputError, match=r"k_axial.*nan"):
        b.add_bearing(0, 1e8, 1e8, float("nan"))
    with pytest.raises(StructureInputError, match=r"node.*\[0, 2\].*5"):
        b.add_bearing(5, 1e8, 1e8)
    with pytest.raises(StructureInputError, match=r"nodes\[1\].*-1"):
        b.add_shaft([0, -1], lengths_m=[0.1], outer_diameters_m=0.05)
    with pytest.raises(StructureInputError, match=r"positions_m.*increasing.*element 1"):
        b.add_shaft([0, 1, 2], positions_m=[0.0, 0.2, 0.2], outer_diameters_m=0.05)
    with pytest.raises(StructureInputError, match=r"lengths_m\[1\].*-0.1"):
        b.add_shaft([0, 1, 2], lengths_m=[0.1, -0.1], outer_diameters_m=0.05)
    with pytest.raises(StructureInputError, match=r"inner_diameters_m\[0\].*0.06"):
        b.add_shaft([0, 1], lengths_m=[0.1], outer_diameters_m=0.05, inner_diameters_m=0.06)
    with pytest.raises(StructureInputError, match="exactly one of positions_m and lengths_m"):
        b.add_shaft([0, 1], outer_diameters_m=0.05)
    with pytest.raises(StructureInputError, match=r"k_torsion.*-5"):
        b.add_coupling(0, 1, k_torsion=-5.0)
    with pytest.raises(StructureInputError, match=r"n2 must differ"):
        b.add_torsional_coupling(1, 1, 1e3)
    with pytest.raises(ElementInputError, match=r"mass_kg.*-2"):
        b.add_disc(0, mass_kg=-2.0, transverse_inertia_kg_m2=0.0, polar_inertia_kg_m2=0.0)
    with pytest.raises(ElementInputError, match=r"length_m.*0"):
        timoshenko_element(0.0, 0.05)
    with pytest.raises(ElementInputError, match=r"inner_diameter_m.*0.05"):
        timoshenko_element(0.1, 0.05, 0.05)
    with pytest.raises(ElementInputError, match=r"Material.nu.*0.5"):
        Material(nu=0.5)
    # A node never used by an element.
    b.add_shaft([0, 1], lengths_m=[0.1], outer_diameters_m=0.05)
    with pytest.raises(StructureInputError, match=r"node\(s\) \[2\]"):
        b.build()
    b.add_bearing(2, 1.0, 1.0, name="b")
    with pytest.raises(StructureInputError, match="duplicate 'b'"):
        b.add_bearing(2, 1.0, 1.0, name="b")
    # Node 2 has a bearing but no mass: modal analysis refuses a singular M.
    s = b.build()
    with pytest.raises(StructureInputError, match="M must be symmetric positive definite"):
        modal_basis(s.M, s.K)
    with pytest.raises(StructureInputError, match=r"zeta.*-0.1"):
        modal_damping_matrix(np.eye(2), np.eye(2), np.ones(2), -0.1)
    with pytest.raises(StructureInputError, match="position must be one of"):
        encoder_nodes(4)
    with pytest.raises(StructureInputError, match=r"n must be a paper node.*44"):
        paper_node(44)
    with pytest.raises(StructureInputError, match=r"centre_distance_m.*-1"):
        baud_velex_structure(centre_distance_m=-1.0)


def test_no_warning_for_grounded_structure() -> None:
    s = supported_shaft()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        mb = modal_basis(s.M, s.K, n_modes=3)
    assert mb.n_rigid == 0


def test_rig_with_pinion_gear_element_satisfies_appendix_a() -> None:
    """Integration with the mesh core: the rig's node positions agree with the frame of
    the pinion-gear element (a rigid motion of the whole rig does not load the mesh,
    V^T R = 0), and Eqs. (33)-(35) hold: C_vv k_m = 1, C_wv k_m cos(beta_b) = 1 for every
    encoder position, w_x0 equal at positions 1 and 2 (no torque beyond the mesh on the
    free-end side) and different at position 3 (on the torque path)."""
    from gearjax.rigs.baud_velex import baud_velex_pair
    from gearjax.gears.mesh import Mesh
    from gearjax.structure.element import PinionGearElement

    pair = baud_velex_pair()
    s = baud_velex_structure(
        centre_distance_m=pair.centre_distance_m,
        working_pressure_angle_rad=pair.working_pressure_angle_rad,
    )
    mesh = Mesh.build(pair)
    el = PinionGearElement.at_nodes(mesh, s.n_dof, s.pinion_node, s.gear_node)
    V = np.asarray(el.mean_vector(n_positions=64))
    km = 8e8
    assert np.abs(V @ rigid_body_vectors(s)).max() < 1e-12
    Kbar = s.K + km * np.outer(V, V)
    Cv = np.linalg.solve(Kbar, V)
    assert V @ Cv * km == pytest.approx(1.0, rel=1e-9)
    F0 = np.zeros(s.n_dof)
    F0[s.dof(MOTOR_NODE, "theta")] = 254.8
    X0 = np.linalg.solve(Kbar, F0)
    rb1, rb2 = pair.base_radii_m
    w_x0 = {}
    for pos in (1, 2, 3):
        i, ii = encoder_nodes(pos)
        W = np.zeros(s.n_dof)
        W[s.dof(i, "theta")], W[s.dof(ii, "theta")] = rb1, rb2
        assert W @ Cv * km * math.cos(pair.base_helix_angle_rad) == pytest.approx(1.0, rel=1e-9)
        w_x0[pos] = W @ X0
    assert w_x0[2] == pytest.approx(w_x0[1], rel=1e-9)
    assert abs(w_x0[3] - w_x0[1]) > 0.1 * abs(w_x0[1])
