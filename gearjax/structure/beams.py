"""Element matrices for the shaft-line structure: Timoshenko shafts, discs, bearings, couplings.

Everything here is plain NumPy (float64). The matrices are built once, outside ``jit``;
:mod:`gearjax.structure.assembly` places them in the global ``M`` and ``K`` of
Eqs. (12)-(14) of Velex & Ajmi (the constant stiffness matrix ``K`` "which accounts for
everything except the pinion and the gear" and the total mass matrix ``M``).

Degrees of freedom
------------------
Each node carries 6 dof, always in this order (paper Nomenclature and Fig. 3)::

    index  name   meaning                                   unit
    0      u      translation along z (axial)               m
    1      v      translation along S (radial)              m
    2      w      translation along T (radial)              m
    3      phi    rotation about S                          rad
    4      psi    rotation about T                          rad
    5      theta  rotation about z (torsion)                rad

The global index of dof ``d`` of node ``n`` is ``6 * n + d``. ``(S, T, z)`` is a
right-handed frame (``S x T = z``) and every shaft axis is parallel to ``z``.

Sign of the bending couplings
-----------------------------
A small rotation vector ``omega`` turns the cross-section normal ``e_z`` into
``e_z + omega x e_z``. With ``T x z = S`` and ``S x z = -T``:

* plane (z, S): the section rotation ``psi`` (about T) tilts the normal towards ``+S``,
  so in the Euler-Bernoulli limit ``psi = +dv/dz``;
* plane (z, T): the section rotation ``phi`` (about S) tilts the normal towards ``-T``,
  so in the Euler-Bernoulli limit ``phi = -dw/dz``.

The (v, psi) plane therefore uses the textbook planar element with ``theta_std = psi``
and the (w, phi) plane uses the same element with ``theta_std = -phi``: the
translation-rotation terms change sign, the translation-translation and
rotation-rotation terms do not. A rigid rotation ``omega`` of a shaft about any axis
(``translations = omega x r``, ``rotations = omega``) is strain-free with this
convention, which the tests check for free-free shafts.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from numpy.typing import NDArray
from ..errors import ElementInputError

__all__ = [
    "DOF_NAMES",
    "DOFS_PER_NODE",
    "STEEL",
    "Material",
    "ElementInputError",
    "bearing_stiffness",
    "coupling_stiffness",
    "disc_properties",
    "hollow_section",
    "rigid_disc",
    "shear_coefficient_hutchinson",
    "timoshenko_element",
    "torsional_coupling",
    "torsional_spring_to_ground",
]

DOFS_PER_NODE: int = 6
DOF_NAMES: tuple[str, ...] = ("u", "v", "w", "phi", "psi", "theta")

# Local indices inside one node.
_U, _V, _W, _PHI, _PSI, _THETA = range(6)


def _check_positive(name: str, value: float, *, allow_zero: bool = False) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError) as exc:
        raise ElementInputError(f"{name} must be a real number, got {value!r}") from exc
    if not math.isfinite(x):
        raise ElementInputError(f"{name} must be finite, got {value!r}")
    if allow_zero:
        if x < 0.0:
            raise ElementInputError(f"{name} must be >= 0, got {value!r}")
    elif x <= 0.0:
        raise ElementInputError(f"{name} must be > 0, got {value!r}")
    return x


@dataclasses.dataclass(frozen=True)
class Material:
    """Linear isotropic material.

    Parameters
    ----------
    E : float
        Young's modulus (Pa).
    nu : float
        Poisson's ratio (-), in (-1, 0.5).
    rho : float
        Density (kg/m^3).
    name : str
        Free label.
    """

    E: float = 2.1e11
    nu: float = 0.3
    rho: float = 7800.0
    name: str = "steel"

    def __post_init__(self) -> None:
        _check_positive("Material.E", self.E)
        _check_positive("Material.rho", self.rho)
        nu = float(self.nu)
        if not (-1.0 < nu < 0.5):
            raise ElementInputError(f"Material.nu must lie in (-1, 0.5), got {self.nu!r}")

    @property
    def G(self) -> float:
        """Shear modulus ``E / (2 (1 + nu))`` (Pa)."""
        return self.E / (2.0 * (1.0 + self.nu))


STEEL = Material()
"""Steel used throughout the paper's test rig model: E = 210 GPa, nu = 0.3, 7800 kg/m^3."""


def hollow_section(
    outer_diameter_m: float, inner_diameter_m: float = 0.0
) -> tuple[float, float, float]:
    """Area and second moments of a circular (hollow) section.

    Returns
    -------
    A : float
        Area ``pi (D^2 - d^2) / 4`` (m^2).
    I : float
        Second moment about a diameter ``pi (D^4 - d^4) / 64`` (m^4).
    J : float
        Polar second moment ``2 I`` (m^4), also the torsion constant of a circular tube.
    """
    do = _check_positive("outer_diameter_m", outer_diameter_m)
    di = _check_positive("inner_diameter_m", inner_diameter_m, allow_zero=True)
    if di >= do:
        raise ElementInputError(
            f"inner_diameter_m must be < outer_diameter_m ({do!r}), got {inner_diameter_m!r}"
        )
    area = math.pi * (do**2 - di**2) / 4.0
    inertia = math.pi * (do**4 - di**4) / 64.0
    return area, inertia, 2.0 * inertia


def shear_coefficient_hutchinson(
    outer_diameter_m: float, inner_diameter_m: float = 0.0, nu: float = 0.3
) -> float:
    """Timoshenko shear coefficient of a hollow circular section (Hutchinson 2001).

    .. math::

        k = \\frac{6 (a^2 + b^2)^2 (1 + \\nu)^2}
                  {7a^4 + 34a^2b^2 + 7b^4 + \\nu (12a^4 + 48a^2b^2 + 12b^4)
                   + \\nu^2 (4a^4 + 16a^2b^2 + 4b^4)}

    with ``a``, ``b`` the outer and inner radii (J. R. Hutchinson, "Shear coefficients for
    Timoshenko beam theory", J. Appl. Mech. 68 (2001) 87-92). Limits: solid section
    ``6 (1+nu)^2 / (7 + 12 nu + 4 nu^2)`` (0.925 for nu = 0.3), thin tube
    ``(1 + nu) / (2 + nu)``. Hutchinson's value was chosen over Cowper's (1966) because it
    comes from the exact elasticity solution of the cantilever; the two differ by about 4 %
    for a solid steel shaft, which changes the shear flexibility only.
    """
    a = _check_positive("outer_diameter_m", outer_diameter_m) / 2.0
    b = _check_positive("inner_diameter_m", inner_diameter_m, allow_zero=True) / 2.0
    if b >= a:
        raise ElementInputError(
            f"inner_diameter_m must be < outer_diameter_m ({2 * a!r}), got {inner_diameter_m!r}"
        )
    a2, b2 = a * a, b * b
    a4, b4 = a2 * a2, b2 * b2
    num = 6.0 * (a2 + b2) ** 2 * (1.0 + nu) ** 2
    den = (
        7.0 * a4
        + 34.0 * a2 * b2
        + 7.0 * b4
        + nu * (12.0 * a4 + 48.0 * a2 * b2 + 12.0 * b4)
        + nu**2 * (4.0 * a4 + 16.0 * a2 * b2 + 4.0 * b4)
    )
    return num / den


def _planar_bending(
    length: float, EI: float, rhoA: float, rhoI: float, phi: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Planar Timoshenko element on (y1, t1, y2, t2) with t = dy/dx in the EB limit.

    Stiffness: Przemieniecki (1968) exact two-node Timoshenko stiffness. Mass: consistent
    matrix of Friedman & Kosmatka (1993) built from the same (interdependent) shape
    functions, translational (rho A) plus rotary (rho I) parts.
    """
    L = length
    f = 1.0 + phi
    k = EI / (f * L**3)
    K = k * np.array(
        [
            [12.0, 6.0 * L, -12.0, 6.0 * L],
            [6.0 * L, (4.0 + phi) * L**2, -6.0 * L, (2.0 - phi) * L**2],
            [-12.0, -6.0 * L, 12.0, -6.0 * L],
            [6.0 * L, (2.0 - phi) * L**2, -6.0 * L, (4.0 + phi) * L**2],
        ]
    )

    p, p2 = phi, phi * phi
    m11 = 13.0 / 35.0 + 7.0 / 10.0 * p + 1.0 / 3.0 * p2
    m12 = (11.0 / 210.0 + 11.0 / 120.0 * p + 1.0 / 24.0 * p2) * L
    m13 = 9.0 / 70.0 + 3.0 / 10.0 * p + 1.0 / 6.0 * p2
    m14 = -(13.0 / 420.0 + 3.0 / 40.0 * p + 1.0 / 24.0 * p2) * L
    m22 = (1.0 / 105.0 + 1.0 / 60.0 * p + 1.0 / 120.0 * p2) * L**2
    m24 = -(1.0 / 140.0 + 1.0 / 60.0 * p + 1.0 / 120.0 * p2) * L**2
    Mt = (rhoA * L / f**2) * np.array(
        [
            [m11, m12, m13, m14],
            [m12, m22, -m14, m24],
            [m13, -m14, m11, -m12],
            [m14, m24, -m12, m22],
        ]
    )

    r11 = 6.0 / 5.0
    r12 = (1.0 / 10.0 - 1.0 / 2.0 * p) * L
    r22 = (2.0 / 15.0 + 1.0 / 6.0 * p + 1.0 / 3.0 * p2) * L**2
    r24 = (-1.0 / 30.0 - 1.0 / 6.0 * p + 1.0 / 6.0 * p2) * L**2
    Mr = (rhoI / (f**2 * L)) * np.array(
        [
            [r11, r12, -r11, r12],
            [r12, r22, -r12, r24],
            [-r11, -r12, r11, -r12],
            [r12, r24, -r12, r22],
        ]
    )
    return K, Mt + Mr


def timoshenko_element(
    length_m: float,
    outer_diameter_m: float,
    inner_diameter_m: float = 0.0,
    E: float = 2.1e11,
    G: float | None = None,
    nu: float = 0.3,
    rho: float = 7800.0,
    shear_coeff: float | None = None,
    *,
    shear: bool = True,
    rotary_inertia: bool = True,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Stiffness and consistent mass of a 2-node, 12-dof Timoshenko shaft element.

    The element lies along ``z`` from node 1 (local dof 0-5) to node 2 (local dof 6-11),
    each node in the order ``(u, v, w, phi, psi, theta)`` of the module docstring. It
    superposes four uncoupled parts:

    * axial bar on ``u``: ``EA/L [[1, -1], [-1, 1]]``, mass ``rho A L / 6 [[2, 1], [1, 2]]``;
    * torsion bar on ``theta``: ``G J/L [[1, -1], [-1, 1]]``, mass
      ``rho J L / 6 [[2, 1], [1, 2]]`` (``J`` polar second moment of area);
    * bending in plane (z, S) on ``(v, psi)`` with ``psi = +dv/dz`` (Euler-Bernoulli
      limit) and in plane (z, T) on ``(w, phi)`` with ``phi = -dw/dz``: the exact
      Timoshenko stiffness (Przemieniecki) and the consistent mass with rotary inertia of
      Friedman & Kosmatka (1993), both written with the shear parameter
      ``Phi = 12 E I / (k G A L^2)``.

    Parameters
    ----------
    length_m : float
        Element length ``L`` (m), > 0.
    outer_diameter_m, inner_diameter_m : float
        Section diameters (m); ``0 <= inner < outer``.
    E : float
        Young's modulus (Pa).
    G : float, optional
        Shear modulus (Pa). Default ``E / (2 (1 + nu))``.
    nu : float
        Poisson's ratio, used for ``G`` and the shear coefficient.
    rho : float
        Density (kg/m^3).
    shear_coeff : float, optional
        Shear coefficient ``k``. Default: Hutchinson's value for a hollow circle,
        :func:`shear_coefficient_hutchinson`.
    shear : bool
        If False, ``Phi = 0`` (no shear deformation: Rayleigh / Euler-Bernoulli element).
    rotary_inertia : bool
        If False, the rotary-inertia (``rho I``) part of the bending mass is dropped.

    Returns
    -------
    Ke, Me : ndarray, shape (12, 12)
        Symmetric stiffness (N/m, N, N m/rad in the respective blocks) and mass (kg,
        kg m, kg m^2) matrices. ``Ke`` is positive semi-definite with exactly the six
        rigid-body motions in its null space; ``Me`` is positive definite.
    """
    L = _check_positive("length_m", length_m)
    _check_positive("E", E)
    _check_positive("rho", rho)
    if not (-1.0 < float(nu) < 0.5):
        raise ElementInputError(f"nu must lie in (-1, 0.5), got {nu!r}")
    Gv = E / (2.0 * (1.0 + nu)) if G is None else _check_positive("G", G)
    A, I, J = hollow_section(outer_diameter_m, inner_diameter_m)
    if shear:
        k = (
            shear_coefficient_hutchinson(outer_diameter_m, inner_diameter_m, nu)
            if shear_coeff is None
            else _check_positive("shear_coeff", shear_coeff)
        )
        phi = 12.0 * E * I / (k * Gv * A * L**2)
    else:
        phi = 0.0

    Ke = np.zeros((12, 12))
    Me = np.zeros((12, 12))

    def put(idx: list[int], kb: NDArray[np.float64], mb: NDArray[np.float64]) -> None:
        ix = np.ix_(idx, idx)
        Ke[ix] += kb
        Me[ix] += mb

    bar = np.array([[1.0, -1.0], [-1.0, 1.0]])
    cons = np.array([[2.0, 1.0], [1.0, 2.0]]) / 6.0
    put([_U, 6 + _U], E * A / L * bar, rho * A * L * cons)
    put([_THETA, 6 + _THETA], Gv * J / L * bar, rho * J * L * cons)

    Kb, Mb = _planar_bending(L, E * I, rho * A, rho * I if rotary_inertia else 0.0, phi)
    # Plane (z, S): (v, psi) with psi = +dv/dz.
    put([_V, _PSI, 6 + _V, 6 + _PSI], Kb, Mb)
    # Plane (z, T): (w, phi) with phi = -dw/dz -> flip the sign of the rotation dofs.
    s = np.array([1.0, -1.0, 1.0, -1.0])
    put([_W, _PHI, 6 + _W, 6 + _PHI], s[:, None] * Kb * s[None, :], s[:, None] * Mb * s[None, :])
    return Ke, Me


def disc_properties(
    outer_diameter_m: float, inner_diameter_m: float, width_m: float, rho: float = 7800.0
) -> tuple[float, float, float]:
    """Mass and centroidal inertias of a solid annulus (gear blank, coupling hub, rotor).

    Returns
    -------
    mass_kg : float
        ``m = rho pi (D^2 - d^2) b / 4``.
    transverse_inertia_kg_m2 : float
        About a diameter through the centroid: ``m (3 (R^2 + r^2) + b^2) / 12``.
    polar_inertia_kg_m2 : float
        About the axis: ``m (R^2 + r^2) / 2``.
    """
    do = _check_positive("outer_diameter_m", outer_diameter_m)
    di = _check_positive("inner_diameter_m", inner_diameter_m, allow_zero=True)
    b = _check_positive("width_m", width_m)
    rho = _check_positive("rho", rho)
    if di >= do:
        raise ElementInputError(
            f"inner_diameter_m must be < outer_diameter_m ({do!r}), got {inner_diameter_m!r}"
        )
    R2, r2 = (do / 2.0) ** 2, (di / 2.0) ** 2
    m = rho * math.pi * (do**2 - di**2) * b / 4.0
    return m, m * (3.0 * (R2 + r2) + b * b) / 12.0, m * (R2 + r2) / 2.0


def rigid_disc(
    mass_kg: float, transverse_inertia_kg_m2: float, polar_inertia_kg_m2: float
) -> NDArray[np.float64]:
    """6x6 lumped mass of a rigid disc centred on its node (kinetic energy of Eq. (13)).

    ``diag(m, m, m, I, I, I_p)`` in the dof order ``(u, v, w, phi, psi, theta)``. The
    gyroscopic terms are neglected, as in Eq. (13) of the paper.
    """
    m = _check_positive("mass_kg", mass_kg, allow_zero=True)
    it = _check_positive("transverse_inertia_kg_m2", transverse_inertia_kg_m2, allow_zero=True)
    ip = _check_positive("polar_inertia_kg_m2", polar_inertia_kg_m2, allow_zero=True)
    return np.diag([m, m, m, it, it, ip])


def bearing_stiffness(
    k_s: float,
    k_t: float,
    k_axial: float = 0.0,
    k_phi: float = 0.0,
    k_psi: float = 0.0,
) -> NDArray[np.float64]:
    """6x6 stiffness of a bearing linking a node to the (rigid) housing.

    ``diag(k_axial, k_s, k_t, k_phi, k_psi, 0)``: radial stiffnesses along S and T
    (N/m), axial stiffness along z (N/m), optional tilting stiffnesses about S and T
    (N m/rad). Bearings never restrain torsion. Table 2 of the paper gives
    ``k_s``, ``k_t`` and ``k_axial`` for the test rig; the tilting terms are zero there.
    """
    vals = [
        _check_positive("k_axial", k_axial, allow_zero=True),
        _check_positive("k_s", k_s, allow_zero=True),
        _check_positive("k_t", k_t, allow_zero=True),
        _check_positive("k_phi", k_phi, allow_zero=True),
        _check_positive("k_psi", k_psi, allow_zero=True),
        0.0,
    ]
    return np.diag(vals)


def torsional_spring_to_ground(k_theta: float) -> NDArray[np.float64]:
    """6x6 stiffness of a torsional spring (N m/rad) between a node's ``theta`` and ground.

    Used for the resisting load of the test rig: "the resisting load is given by a
    torsional stiffness at one free end of the gear shaft" (Section 6.1).
    """
    K = np.zeros((6, 6))
    K[_THETA, _THETA] = _check_positive("k_theta", k_theta, allow_zero=True)
    return K


def coupling_stiffness(
    k_torsion: float,
    k_radial: float = 0.0,
    k_axial: float = 0.0,
    k_tilt: float = 0.0,
) -> NDArray[np.float64]:
    """12x12 stiffness of a zero-length flexible coupling between two nodes.

    Each dof of node 2 is tied to the same dof of node 1 by a spring:
    ``D = diag(k_axial, k_radial, k_radial, k_tilt, k_tilt, k_torsion)`` and
    ``K = [[D, -D], [-D, D]]``. Because the springs act on relative displacements at a
    single point, the two nodes should sit at the same position (a point connection).

    Parameters
    ----------
    k_torsion : float
        Torsional stiffness (N m/rad).
    k_radial : float
        Radial (S and T) stiffness (N/m).
    k_axial : float
        Axial stiffness (N/m).
    k_tilt : float
        Angular-misalignment stiffness about S and T (N m/rad).
    """
    d = np.diag(
        [
            _check_positive("k_axial", k_axial, allow_zero=True),
            _check_positive("k_radial", k_radial, allow_zero=True),
            _check_positive("k_radial", k_radial, allow_zero=True),
            _check_positive("k_tilt", k_tilt, allow_zero=True),
            _check_positive("k_tilt", k_tilt, allow_zero=True),
            _check_positive("k_torsion", k_torsion, allow_zero=True),
        ]
    )
    return np.block([[d, -d], [-d, d]])


def torsional_coupling(k_theta: float) -> NDArray[np.float64]:
    """12x12 stiffness of a torsion spring between the ``theta`` dofs of two nodes.

    ``k [[1, -1], [-1, 1]]`` on local dofs 5 and 11, zero elsewhere (N m/rad). This is
    :func:`coupling_stiffness` with only the torsional term.
    """
    return coupling_stiffness(k_torsion=k_theta)
