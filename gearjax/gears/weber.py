"""Tooth-pair compliance along the path of contact: Weber's beam integrals, the tooth
foundation and Weber's Hertzian approach (the ``"weber"`` stiffness law of :mod:`.mesh`).

Velex & Ajmi, Section 6.1: "The tooth mesh model is based on the analytical formulae of
Weber and Banaschek [17] and O'Donnell [18]." This module evaluates those formulae once, in
NumPy, at build time; :class:`gearjax.gears.mesh.Mesh` stores the result as a polynomial in
the normalised profile coordinate so that ``k_l(xi)`` stays a pure jnp function.

Per unit face width, a load ``w`` (N/m) on the pair at the point of roll distance ``xi``
(pinion roll ``rho1 = xi``, gear roll ``rho2 = T1T2 - xi``) deflects the pair along the
line of action by ``q(xi) w`` with the compliance (m^2/N)

    q = q_t1 + q_f1 + q_t2 + q_f2 + q_H,

and the stiffness per unit length of contact line is ``k_l = cos(beta_b) / q`` (N/m^2), the
conversion used by the other laws (:mod:`.mesh`).

Tooth (Weber & Banaschek 1953, energy method, plane strain for bending and compression)
-------------------------------------------------------------------------------------
The tooth is a cantilever of variable thickness ``2 y(x)`` along its centre line ``x``
(from the root circle ``r_f`` to the tip), the transverse profile being the involute down to
the base circle and a radial line below it (``r_f < r_b``); the trochoidal fillet is not
modelled. The load acts along the line of action at the contact point ``(x_c, y_c)`` (radius
``r_c = sqrt(r_b^2 + rho^2)``), at the load angle ``alpha_F = alpha_c - psi_c`` to the normal
of the centre line (``alpha_c`` the profile pressure angle at ``r_c``, ``psi_c`` the half
tooth-thickness angle there); its line crosses the centre line at ``x_L = x_c - y_c tan
alpha_F``. With ``E' = E / (1 - nu^2)``, ``G = E / (2 (1 + nu))`` and Timoshenko's shear
factor 1.2:

    q_t = 12 cos^2(alpha_F) / E' * int_{x_f}^{x_c} (x_L - x)^2 / (2y)^3 dx      (bending)
        + 1.2 cos^2(alpha_F) / G  * int_{x_f}^{x_c} dx / (2y)                  (shear)
        +     sin^2(alpha_F) / E' * int_{x_f}^{x_c} dx / (2y)                  (compression)

i.e. Weber's ``cos^2 alpha_F / E [10.92 int (x_L - x)^2/(2y)^3 dx + 3.12 (1 + 0.292
tan^2 alpha_F) int dx/(2y)]`` for nu = 0.3.

Foundation (the tooth's built-in end; Weber-O'Donnell form, Sainsot et al. 2004 coefficients)
-----------------------------------------------------------------------------------------
O'Donnell (1960, 1963) gave the extra deflection of a cantilever from the elasticity of its
support in the form

    q_f = cos^2(alpha_F) / E * [L (u_f/S_f)^2 + M (u_f/S_f) + P (1 + Q tan^2 alpha_F)]

with ``u_f = x_L - r_f`` and ``S_f = 2 r_f theta_f`` the root thickness (``theta_f`` the half
angle of the tooth on the root circle). For a semi-infinite support his bending-rotation
coefficient is ``L = 16.67 (1 - nu^2) / pi`` (the energy of the linear root stress on an
elastic half-plane gives 18 (1 - nu^2)/pi, the same physics), but the translation terms of a
half-plane diverge logarithmically and need a reference point. We therefore use the
coefficients that Sainsot, Velex & Duverger (2004) fitted on finite-element gear bodies with
the same formula (Velex's group's successor of the Weber-O'Donnell term): each of L, M, P, Q
is ``A/theta_f^2 + B h_f^2 + C h_f/theta_f + D/theta_f + E h_f + F`` with ``h_f = r_f /
r_int`` (``r_int`` the bore radius) and the table :data:`SAINSOT_COEFFICIENTS`, valid for
1.4 <= h_f <= 7 and 0.01 <= theta_f <= 0.12 rad (we clip ``h_f`` into that range and refuse
``theta_f`` outside it). Their displacement is measured relative to the bore, so q_f grows
with the body (``P`` ~ h_f^2: the plane torsion of the web). The paper's mesh model has
O'Donnell's foundation only (no gear body), and its structure carries the bodies, so the
default is the smallest body of the formula's range, ``h_f = 1.4`` (``bore_radius_m=None``);
a bore radius adds the body's share (Baud-Velex spur, bores 60 and 80 mm: h_f = 1.56 and
7.7 -> 7, mid-profile stiffness 7.1 instead of 10.2 N/(mm um) at 254.8 N m).

Contact (Weber's Hertzian approach of two cylinders, plane strain)
-----------------------------------------------------------------
    q_H = 2 (1 - nu^2) / (pi E) * [ln(2 h_1 / a) + ln(2 h_2 / a) - nu / (1 - nu)]

with ``h_k = y_ck / cos(alpha_Fk)`` the distance from the contact point to the centre line of
tooth k along the line of action, the Hertz half width ``a^2 = 8 w (1 - nu^2) R / (pi E)`` and
``R = rho1 rho2 / (rho1 + rho2)``. It depends weakly (logarithmically) on the line load
``w``; the law uses the static load per unit contact length ``F_S / (b eps_alpha /
cos(beta_b))`` at the rig's torque (:func:`static_line_load`), or
:data:`REFERENCE_LINE_LOAD_N_PER_M` when no torque is given.

Helical pairs are treated slice by slice in the transverse section (the thin-slice
approximation); the ISO 6336 laws use virtual spur gears instead.

References
----------
* H. Weber, K. Banaschek, Formänderung und Profilrücknahme bei gerad- und
  schrägverzahnten Rädern, Schriftenreihe Antriebstechnik 11, Vieweg, Braunschweig, 1953
  (paper ref. [17]).
* P.J. O'Donnell, The additional deflection of a cantilever due to the elasticity of the
  support, J. Appl. Mech. 27 (1960) 461-464; Stresses and deflections in built-in beams,
  J. Eng. Ind. 85 (1963) 265-273 (paper ref. [18]).
* P. Sainsot, P. Velex, O. Duverger, Contribution of gear body to tooth deflections - a new
  bidimensional analytical formula, J. Mech. Des. 126 (2004) 748-752.
* K.L. Johnson, Contact Mechanics, CUP 1985, Section 5.6 (approach of two cylinders).
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import GeometryError
from .geometry import GearPair, involute

__all__ = [
    "YOUNG_MODULUS_PA",
    "POISSON_RATIO",
    "REFERENCE_LINE_LOAD_N_PER_M",
    "SAINSOT_COEFFICIENTS",
    "static_line_load",
    "tooth_compliance",
    "foundation_compliance",
    "hertz_compliance",
    "pair_compliance",
]

YOUNG_MODULUS_PA = 210e9  # steel, as the rig's shafts (gearjax.rigs.baud_velex)
POISSON_RATIO = 0.3
REFERENCE_LINE_LOAD_N_PER_M = 3.0e5  # 300 N/mm: ISO 6336-1's c' holds for F_t/b >= 100 N/mm

# Sainsot, Velex & Duverger (2004), Table 1: rows L, M, P, Q; columns A..F of
# X = A/theta_f^2 + B h_f^2 + C h_f/theta_f + D/theta_f + E h_f + F
SAINSOT_COEFFICIENTS = (
    (-5.574e-5, -1.9986e-3, -2.3015e-4, 4.7702e-3, 0.0271, 6.8045),
    (60.111e-5, 28.100e-3, -83.431e-4, -9.9256e-3, 0.1624, 0.9086),
    (-50.952e-5, 185.50e-3, 0.0538e-4, 53.300e-3, 0.2895, 0.9236),
    (-6.2042e-5, 9.0889e-3, -4.0964e-4, 7.8297e-3, -0.1472, 0.6904),
)
H_F_RANGE = (1.4, 7.0)
THETA_F_RANGE = (0.01, 0.12)

_GAUSS = np.polynomial.legendre.leggauss(48)


def static_line_load(pair: GearPair, pinion_torque_Nm: float) -> float:
    """Static load per unit contact length ``F_S cos(beta_b) / (b eps_alpha)`` (N/m), with
    ``F_S = C_m0 / (Rb1 cos beta_b)`` (Eq. (23)): the mean line load over the contact lines."""
    torque = float(pinion_torque_Nm)
    if not (math.isfinite(torque) and torque > 0):
        raise GeometryError("pinion_torque_Nm", torque, "must be finite and > 0")
    cos_bb = math.cos(pair.base_helix_angle_rad)
    f_s = torque / (pair.base_radii_m[0] * cos_bb)
    return f_s * cos_bb / (pair.face_width_m * pair.transverse_contact_ratio)


def _tooth_data(pair: GearPair, k: int):
    """(r_b, r_f, half-angle function psi(r), half-angle at the base circle) of gear k."""
    z = (pair.z1, pair.z2)[k - 1]
    x = (pair.profile_shift1, pair.profile_shift2)[k - 1]
    rb = pair.base_radii_m[k - 1]
    rf = pair.root_radii_m[k - 1]
    half0 = (math.pi / 2.0 + 2.0 * x * math.tan(pair.normal_pressure_angle_rad)) / z
    half0 += involute(pair.transverse_pressure_angle_rad)

    def psi(r):
        r = np.asarray(r, dtype=float)
        a = np.arccos(np.minimum(1.0, rb / r))
        return half0 - (np.tan(a) - a)

    return rb, rf, psi, half0


def _segments(r_lo, r_hi, rb):
    """Gauss nodes/weights in r on [r_lo, r_hi] split at the base circle (the kink of the
    flank); arrays of shape (n_loads, n_nodes)."""
    x, w = _GAUSS
    parts = []
    split = np.clip(rb, r_lo, r_hi)
    for a, b in ((r_lo, split), (split, r_hi)):
        h = 0.5 * (b - a)
        parts.append((0.5 * (a + b)[:, None] + h[:, None] * x[None, :], h[:, None] * w[None, :]))
    r = np.concatenate([p[0] for p in parts], axis=1)
    wr = np.concatenate([p[1] for p in parts], axis=1)
    return r, wr


def _load_point(pair: GearPair, k: int, rho):
    """Contact point of roll distance ``rho`` on gear k: (r_c, x_c, y_c, alpha_F, x_L)."""
    rb, _, psi, _ = _tooth_data(pair, k)
    rho = np.asarray(rho, dtype=float)
    rc = np.hypot(rb, rho)
    alpha_c = np.arctan2(rho, rb)
    psi_c = psi(rc)
    xc, yc = rc * np.cos(psi_c), rc * np.sin(psi_c)
    alpha_f = alpha_c - psi_c
    return rc, xc, yc, alpha_f, xc - yc * np.tan(alpha_f)


def _root_half_angle(pair: GearPair, k: int) -> float:
    rb, rf, psi, _ = _tooth_data(pair, k)
    return float(psi(max(rf, rb)))  # radial flank below the base circle keeps psi(r_b)


def tooth_compliance(pair: GearPair, k: int, rho, young_Pa: float = YOUNG_MODULUS_PA,
                     poisson: float = POISSON_RATIO):
    """Weber's bending + shear + compression compliance of tooth k (1 pinion, 2 gear) per
    unit face width (m^2/N), loaded at roll distance ``rho`` (m, array) along the line of
    action (module docstring)."""
    rb, rf, psi, _ = _tooth_data(pair, k)
    rc, _, _, alpha_f, x_l = _load_point(pair, k, rho)
    r, wr = _segments(np.full_like(rc, rf), rc, rb)
    p = psi(r)
    alpha_r = np.arccos(np.minimum(1.0, rb / r))
    x = r * np.cos(p)
    y = r * np.sin(p)
    dxdr = np.cos(p) + np.sin(p) * np.tan(alpha_r)  # d psi/dr = -tan(alpha_r)/r
    e_plane = young_Pa / (1.0 - poisson**2)
    shear_g = young_Pa / (2.0 * (1.0 + poisson))
    bend = np.sum(wr * dxdr * (x_l[:, None] - x) ** 2 / (2.0 * y) ** 3, axis=1)
    axial = np.sum(wr * dxdr / (2.0 * y), axis=1)
    c2, s2 = np.cos(alpha_f) ** 2, np.sin(alpha_f) ** 2
    return 12.0 * c2 * bend / e_plane + (1.2 * c2 / shear_g + s2 / e_plane) * axial


def foundation_compliance(pair: GearPair, k: int, rho, bore_radius_m: float | None = None,
                          young_Pa: float = YOUNG_MODULUS_PA):
    """Foundation (and gear-body) compliance of tooth k per unit face width (m^2/N):
    O'Donnell's form with Sainsot et al.'s coefficients (module docstring).
    ``bore_radius_m`` None: ``h_f = 1.4`` (no gear body, see the module docstring)."""
    rf = pair.root_radii_m[k - 1]
    if bore_radius_m is None:
        h_f = H_F_RANGE[0]
    else:
        r_int = float(bore_radius_m)
        if not (math.isfinite(r_int) and 0.0 < r_int < rf):
            raise GeometryError(f"bore_radius{k}_m", r_int, f"must lie in (0, r_f={rf:.6g} m)")
        h_f = min(max(rf / r_int, H_F_RANGE[0]), H_F_RANGE[1])
    theta_f = _root_half_angle(pair, k)
    if not (THETA_F_RANGE[0] <= theta_f <= THETA_F_RANGE[1]):
        raise GeometryError(
            f"z{k}", (pair.z1, pair.z2)[k - 1],
            f"root half-angle theta_f={theta_f:.4g} rad outside the range "
            f"{THETA_F_RANGE} of the foundation formula (Sainsot et al. 2004)")
    terms = np.array([1.0 / theta_f**2, h_f**2, h_f / theta_f, 1.0 / theta_f, h_f, 1.0])
    big_l, big_m, big_p, big_q = (float(np.dot(c, terms)) for c in SAINSOT_COEFFICIENTS)
    _, _, _, alpha_f, x_l = _load_point(pair, k, rho)
    ratio = (x_l - rf) / (2.0 * rf * theta_f)
    return np.cos(alpha_f) ** 2 / young_Pa * (
        big_l * ratio**2 + big_m * ratio + big_p * (1.0 + big_q * np.tan(alpha_f) ** 2))


def hertz_compliance(pair: GearPair, xi, line_load_N_per_m: float,
                     young_Pa: float = YOUNG_MODULUS_PA, poisson: float = POISSON_RATIO):
    """Weber's Hertzian approach per unit length (m^2/N) at the base-plane point ``xi``
    (m, array) under the line load ``line_load_N_per_m`` (module docstring)."""
    xi = np.asarray(xi, dtype=float)
    rho1, rho2 = xi, pair.line_of_action_length_m - xi
    radius = rho1 * rho2 / (rho1 + rho2)
    a = np.sqrt(8.0 * line_load_N_per_m * (1.0 - poisson**2) * radius / (math.pi * young_Pa))
    h = []
    for k, rho in ((1, rho1), (2, rho2)):
        _, _, yc, alpha_f, _ = _load_point(pair, k, rho)
        h.append(yc / np.cos(alpha_f))
    return 2.0 * (1.0 - poisson**2) / (math.pi * young_Pa) * (
        np.log(2.0 * h[0] / a) + np.log(2.0 * h[1] / a) - poisson / (1.0 - poisson))


def pair_compliance(pair: GearPair, xi, line_load_N_per_m: float = REFERENCE_LINE_LOAD_N_PER_M,
                    bore_radii_m=(None, None), young_Pa: float = YOUNG_MODULUS_PA,
                    poisson: float = POISSON_RATIO) -> dict:
    """Compliances per unit face width (m^2/N) of the tooth pair in contact at ``xi`` (m from
    T1 on the line of action, array): ``tooth1``, ``foundation1``, ``tooth2``,
    ``foundation2``, ``hertz`` and their sum ``total``."""
    if not (math.isfinite(line_load_N_per_m) and line_load_N_per_m > 0):
        raise GeometryError("line_load_N_per_m", line_load_N_per_m, "must be finite and > 0")
    xi = np.atleast_1d(np.asarray(xi, dtype=float))
    rho = (xi, pair.line_of_action_length_m - xi)
    out = {}
    for k in (1, 2):
        out[f"tooth{k}"] = tooth_compliance(pair, k, rho[k - 1], young_Pa, poisson)
        out[f"foundation{k}"] = foundation_compliance(pair, k, rho[k - 1], bore_radii_m[k - 1],
                                                      young_Pa)
    out["hertz"] = hertz_compliance(pair, xi, line_load_N_per_m, young_Pa, poisson)
    out["total"] = sum(out.values())
    return out


PROFILE_DEGREE = 10  # polynomial degree of k_l(s) stored in the Mesh
_FIT_RTOL = 1e-4


def stiffness_profile(pair: GearPair, line_load_N_per_m: float = REFERENCE_LINE_LOAD_N_PER_M,
                      bore_radii_m=(None, None)) -> tuple[float, ...]:
    """Power-series coefficients ``(c_0, ..., c_n)`` (N/m^2) of the stiffness per unit contact
    length ``k_l(s) = cos(beta_b) / q = sum_j c_j s^j`` over the normalised profile coordinate
    ``s = (2 xi - xi_start - xi_end) / g_alpha`` in [-1, 1] (the coordinate of the other laws).

    Fitted at Chebyshev points (degree :data:`PROFILE_DEGREE`); a fit worse than 1e-4
    relative on a dense check grid raises (it would mean a non-smooth profile)."""
    xa, xe = pair.contact_limits_m
    n = PROFILE_DEGREE
    nodes = np.cos(np.pi * (np.arange(4 * n) + 0.5) / (4 * n))
    k_l = lambda s: math.cos(pair.base_helix_angle_rad) / pair_compliance(
        pair, 0.5 * (xa + xe) + 0.5 * (xe - xa) * s, line_load_N_per_m, bore_radii_m)["total"]
    cheb = np.polynomial.chebyshev.Chebyshev.fit(nodes, k_l(nodes), n, domain=[-1.0, 1.0])
    coeffs = np.polynomial.chebyshev.cheb2poly(cheb.coef)
    check = np.linspace(-1.0, 1.0, 201)
    exact = k_l(check)
    err = np.max(np.abs(np.polynomial.polynomial.polyval(check, coeffs) - exact) / exact)
    if not err < _FIT_RTOL:
        raise GeometryError("z1", pair.z1, f"Weber stiffness profile not smooth enough for a "
                                           f"degree-{n} fit (relative error {err:.2e})")
    return tuple(float(c) for c in coeffs)
