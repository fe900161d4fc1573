"""ISO 6336-1 figures of a gear pair: single stiffness c', mesh stiffness c_gamma_alpha, the
resonance speed n_E1 and the method-B internal dynamic factor K_v over speed.

These are the standard's design figures, set beside gearjax's dynamic simulation (Velex &
Ajmi): the simulation's dynamic factor ``max F / F_S`` (``dynamic_factor`` of a sweep) and
ISO's K_v both divide a dynamic tooth load by a static one, so their curves are comparable.
The static loads differ in where they are taken, which matters wherever a user compares
forces rather than ratios:

* ISO 6336-1's nominal tangential load ``F_t = 2 T1 / d1`` is taken at the **reference
  (pitch) circle** in the transverse plane (:func:`reference_tangential_force`); it enters
  K_v only through the line load ``F_t K_A / b``.
* Velex & Ajmi's static mesh force ``F_S = C_m0 / (Rb1 cos beta_b)`` (Eq. (23)) is the
  **normal** force on the **base** plane (:func:`gearjax.gears.quasistatic.static_mesh_force`).

Method B as implemented (ISO 6336-1:2006, 6.5; clause numbers of that edition)
------------------------------------------------------------------------------
* ``c'`` (:func:`single_stiffness`): ``c'_th C_M C_R C_B cos(beta)`` of
  :func:`gearjax.gears.mesh.iso6336_single_stiffness` (Eq. (98) coefficients, ``C_M = 0.8``,
  ``C_R = 1``, solid blanks), times ``((F_t K_A / b) / (100 N/mm))^0.25`` when the line load
  is below 100 N/mm (clause 9). ``c_gamma_alpha = c' (0.75 eps_alpha + 0.25)``.
* Resonance speed (Eq. (6)): ``n_E1 = 30000 / (pi z1) sqrt(c_gamma_alpha / m_red)``
  (1/min), solid gears, ``m_red = m1* m2* / (m1* + m2*)``, ``m_i* = pi rho d_mi^4 /
  (8 d_bi^2)`` per unit face width, ``d_m`` the mean of tip and root diameters; here in
  rad/s, ``Omega_E1 = sqrt(c_gamma_alpha / m_red) / z1`` (:func:`resonance_speed`).
* Resonance ratio ``N = Omega1 / Omega_E1`` (Eq. (9)); lower limit of the main resonance range
  ``N_S = 0.85`` for ``F_t K_A / b >= 100 N/mm``, else ``0.5 + 0.35 sqrt((F_t K_A / b) / 100)``
  (Eqs. (11), (12)).
* ``B_p = c' f_pb,eff / (F_t K_A / b)``, ``B_f = c' f_falpha,eff / (F_t K_A / b)``,
  ``B_k = |1 - c' C_a / (F_t K_A / b)|`` (Eqs. (15)-(17)); ``f_pb,eff = f_pb - y_p``, ``f_falpha,eff =
  f_falpha - y_f``; gearjax takes ``y_p = y_f = y_alpha`` with ``y_alpha = 0.075 f_pb``
  (at most 3 um: case-hardened or nitrided steel).
* ``K_v``: subcritical ``N <= N_S``: ``N (C_v1 B_p + C_v2 B_f + C_v3 B_k) + 1`` (6.5.4, Eqs.
  (13), (14)); main resonance ``N_S < N <= 1.15``: ``C_v1 B_p + C_v2 B_f + C_v4 B_k + 1``
  (6.5.5, Eq. (20)); supercritical ``N >= 1.5``: ``C_v5 B_p + C_v6 B_f + C_v7`` (6.5.6,
  Eq. (21)); linear between 1.15 and 1.5 (6.5.7, Eq. (22)). ``C_v1..C_v7``
  from the total contact ratio ``eps_gamma`` (Table 8).

Accuracy data and defaults (:class:`AccuracyData`)
--------------------------------------------------
* ``f_pb`` and ``f_falpha``: given, or ISO 1328-1:1995's grade-5 formulas ``f_pt =
  0.3 (m_n + 0.4 sqrt(d)) + 4`` and ``f_falpha = 2.5 sqrt(m_n) + 0.17 sqrt(d) + 0.5`` (um,
  with m_n and d in mm) scaled by ``2^((Q - 5)/2)`` for grade Q, at the exact m_n and
  reference diameter of the wheel (the larger values; no class means, no rounding), and
  ``f_pb = f_pt cos(alpha_t)``. Default grade Q = 5.
* ``C_a``: given (a rig file's ``[iso6336] tip_relief_m``, ``--iso-tip-relief``), else the
  larger tip relief amplitude of the scenario's modifications, else (no relief) the
  running-in amount ``C_ay = (1/18) (sigma_Hlim / 97 - 18.45)^2 + 1.5`` um with ``sigma_Hlim``
  in N/mm^2 (default 1500 N/mm^2, case-hardened steel).
* ``K_A = 1`` (application factor), steel density 7800 kg/m^3.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..errors import GeometryError
from .geometry import STEEL_DENSITY_KG_M3, GearPair
from .mesh import iso6336_single_stiffness

__all__ = ["AccuracyData", "DynamicFactorB", "single_stiffness", "mesh_stiffness",
           "reference_tangential_force", "reduced_mass_per_width", "resonance_speed",
           "iso1328_deviations", "running_in_tip_relief", "dynamic_factor",
           "DEFAULT_ACCURACY_GRADE", "DEFAULT_SIGMA_HLIM_PA"]

DEFAULT_ACCURACY_GRADE = 5
DEFAULT_SIGMA_HLIM_PA = 1500e6  # case-hardened steel
_UM = 1e-6
_N_PER_MM = 1e3  # 1 N/mm in N/m
_LOW_LOAD_N_PER_M = 100.0 * _N_PER_MM  # 100 N/mm: the line load below which c' and N_S change


@dataclasses.dataclass(frozen=True)
class AccuracyData:
    """Accuracy data of a gear pair for ISO 6336-1 method B (SI units).

    Attributes
    ----------
    accuracy_grade : ISO 1328-1 grade Q (1-12) giving ``f_pb`` and ``f_falpha`` when they are
        not given (module docstring).
    base_pitch_deviation_m : f_pb (m) or None.
    profile_form_deviation_m : f_falpha (m) or None.
    tip_relief_m : C_a (m) or None (then the scenario's tip relief, else C_ay).
    application_factor : K_A (default 1).
    sigma_hlim_Pa : allowable contact stress number sigma_Hlim (Pa), for C_ay only.
    rated_speed_rad_s : pinion speed at which ``gearjax info`` reports K_v, or None.

    Raises
    ------
    GeometryError
        a grade outside 1-12, a negative deviation or relief, a non-positive K_A,
        sigma_Hlim or rated speed.
    """

    accuracy_grade: int = DEFAULT_ACCURACY_GRADE
    base_pitch_deviation_m: float | None = None
    profile_form_deviation_m: float | None = None
    tip_relief_m: float | None = None
    application_factor: float = 1.0
    sigma_hlim_Pa: float = DEFAULT_SIGMA_HLIM_PA
    rated_speed_rad_s: float | None = None

    def __post_init__(self):
        q = self.accuracy_grade
        if int(q) != q or not 1 <= q <= 12:
            raise GeometryError("accuracy_grade", q, "ISO 1328-1 grades are whole numbers 1-12")
        for name in ("base_pitch_deviation_m", "profile_form_deviation_m", "tip_relief_m"):
            v = getattr(self, name)
            if v is not None and not (math.isfinite(v) and 0.0 <= v < 1e-3):
                raise GeometryError(name, v, "must lie in [0, 1e-3) m (a deviation in metres)")
        for name in ("application_factor", "sigma_hlim_Pa"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0.0):
                raise GeometryError(name, v, "must be a finite positive number")
        if self.rated_speed_rad_s is not None and not (
                math.isfinite(self.rated_speed_rad_s) and self.rated_speed_rad_s > 0.0):
            raise GeometryError("rated_speed_rad_s", self.rated_speed_rad_s,
                                "must be a finite positive speed in rad/s")


def reference_tangential_force(pair: GearPair, pinion_torque_Nm: float) -> float:
    """ISO 6336-1 nominal tangential load ``F_t = 2 T1 / d1`` (N): transverse, at the
    **reference circle** (``d1 = z1 m_n / cos(beta)``). Not the paper's static mesh force
    (normal, base plane, Eq. (23)): ``F_S = F_t r1 / (Rb1 cos beta_b) = F_t / (cos(alpha_t)
    cos(beta_b))``."""
    return float(pinion_torque_Nm) / pair.pitch_radii_m[0]


def single_stiffness(pair: GearPair, line_load_N_per_m: float | None = None) -> float:
    """ISO 6336-1 single stiffness c' (N/m^2, i.e. N/(m m); 1 N/(mm um) = 1e9 N/m^2), with the
    low-load correction ``((F_t K_A / b) / 100 N/mm)^0.25`` below 100 N/mm when
    ``line_load_N_per_m`` (``F_t K_A / b``, N/m) is given."""
    c = iso6336_single_stiffness(pair)
    if line_load_N_per_m is not None and line_load_N_per_m < _LOW_LOAD_N_PER_M:
        c *= (line_load_N_per_m / _LOW_LOAD_N_PER_M) ** 0.25
    return c


def mesh_stiffness(pair: GearPair, line_load_N_per_m: float | None = None) -> float:
    """ISO 6336-1 mesh stiffness ``c_gamma_alpha = c' (0.75 eps_alpha + 0.25)`` (N/m^2);
    ``c_gamma_alpha b`` is the ISO mean mesh stiffness (N/m)."""
    return single_stiffness(pair, line_load_N_per_m) * (0.75 * pair.transverse_contact_ratio + 0.25)


def reduced_mass_per_width(pair: GearPair, density_kg_m3: float = STEEL_DENSITY_KG_M3) -> float:
    """ISO 6336-1 (6.5.9, Eq. (30), solid gears) reduced mass per unit face width (kg/m):
    ``m_red = m1* m2* / (m1* + m2*)``, ``m_i* = pi rho d_mi^4 / (8 d_bi^2)``, ``d_m`` the mean
    of tip and root diameters, ``d_b`` the base diameter."""
    m_star = []
    for ra, rf, rb in zip(pair.tip_radii_m, pair.root_radii_m, pair.base_radii_m):
        dm, db = ra + rf, 2.0 * rb
        m_star.append(math.pi * density_kg_m3 * dm**4 / (8.0 * db**2))
    return m_star[0] * m_star[1] / (m_star[0] + m_star[1])


def resonance_speed(pair: GearPair, c_gamma_alpha_N_per_m2: float,
                    density_kg_m3: float = STEEL_DENSITY_KG_M3) -> float:
    """ISO 6336-1 (Eq. (6)) pinion resonance speed in rad/s: ``Omega_E1 =
    sqrt(c_gamma_alpha / m_red) / z1`` (``n_E1 = 30 Omega_E1 / pi`` in 1/min) with
    :func:`reduced_mass_per_width`; ``c_gamma_alpha`` in N/m^2 (mesh stiffness per unit
    face width)."""
    return math.sqrt(c_gamma_alpha_N_per_m2 / reduced_mass_per_width(pair, density_kg_m3)) / pair.z1


def iso1328_deviations(pair: GearPair, grade: int = DEFAULT_ACCURACY_GRADE) -> tuple[float, float]:
    """``(f_pb, f_falpha)`` in m for ISO 1328-1:1995 grade ``grade`` at the wheel (the larger
    reference diameter): ``f_pt = 0.3 (m_n + 0.4 sqrt(d)) + 4`` and ``f_falpha = 2.5 sqrt(m_n)
    + 0.17 sqrt(d) + 0.5`` (um, m_n and d in mm) for grade 5, times ``2^((Q - 5)/2)``;
    ``f_pb = f_pt cos(alpha_t)``. Exact m_n and d (no class means, no rounding)."""
    mn = pair.normal_module_m * 1e3
    d = 2.0 * max(pair.pitch_radii_m) * 1e3
    step = 2.0 ** ((grade - 5) / 2.0)
    f_pt = (0.3 * (mn + 0.4 * math.sqrt(d)) + 4.0) * step
    f_fa = (2.5 * math.sqrt(mn) + 0.17 * math.sqrt(d) + 0.5) * step
    return f_pt * math.cos(pair.transverse_pressure_angle_rad) * _UM, f_fa * _UM


def running_in_tip_relief(sigma_hlim_Pa: float = DEFAULT_SIGMA_HLIM_PA) -> float:
    """ISO 6336-1 running-in amount ``C_ay = (1/18) (sigma_Hlim / 97 - 18.45)^2 + 1.5`` um
    (sigma_Hlim in N/mm^2), in m: the C_a of a pair without tip relief."""
    s = sigma_hlim_Pa / 1e6
    return ((s / 97.0 - 18.45) ** 2 / 18.0 + 1.5) * _UM


def _coefficients(eps_gamma: float) -> tuple[float, ...]:
    """C_v1..C_v7 of ISO 6336-1 method B (Table 8) for the total contact ratio eps_gamma."""
    if eps_gamma <= 2.0:
        cv2, cv3, cv4, cv6 = 0.34, 0.23, 0.90, 0.47
    else:
        cv2 = 0.57 / (eps_gamma - 0.3)
        cv3 = 0.096 / (eps_gamma - 1.56)
        cv4 = (0.57 - 0.05 * eps_gamma) / (eps_gamma - 1.44)
        cv6 = 0.12 / (eps_gamma - 1.74)
    if eps_gamma <= 1.5:
        cv7 = 0.75
    elif eps_gamma <= 2.5:
        cv7 = 0.125 * math.sin(math.pi * (eps_gamma - 2.0)) + 0.875
    else:
        cv7 = 1.0
    return 0.32, cv2, cv3, cv4, 0.47, cv6, cv7


@dataclasses.dataclass(frozen=True)
class DynamicFactorB:
    """ISO 6336-1 method-B dynamic factor of a pair at a torque, over pinion speeds.

    ``kv`` and ``resonance_ratio`` have the shape of ``speeds_rad_s``; stiffnesses in N/m^2
    (per unit face width), forces in N, line load in N/m, deviations in m; ``sources`` says
    where ``f_pb``, ``f_falpha`` and ``C_a`` came from.
    """

    speeds_rad_s: np.ndarray
    kv: np.ndarray
    resonance_ratio: np.ndarray
    resonance_speed_rad_s: float
    single_stiffness_N_per_m2: float
    mesh_stiffness_N_per_m2: float
    reference_tangential_force_N: float
    line_load_N_per_m: float
    base_pitch_deviation_m: float
    profile_form_deviation_m: float
    tip_relief_m: float
    running_in_allowance_m: float
    application_factor: float
    total_contact_ratio: float
    n_s: float
    b_p: float
    b_f: float
    b_k: float
    sources: dict

    def summary(self) -> dict:
        """Plain numbers for JSON: SI, plus c' and c_gamma_alpha in ISO's N/(mm um)."""
        return {
            "iso6336_single_stiffness_N_per_m2": self.single_stiffness_N_per_m2,
            "iso6336_mesh_stiffness_N_per_m2": self.mesh_stiffness_N_per_m2,
            "iso6336_c_prime_N_per_mm_um": self.single_stiffness_N_per_m2 / 1e9,
            "iso6336_c_gamma_alpha_N_per_mm_um": self.mesh_stiffness_N_per_m2 / 1e9,
            "iso6336_resonance_speed_rad_s": self.resonance_speed_rad_s,
            "iso6336_resonance_speed_rpm": self.resonance_speed_rad_s * 30.0 / math.pi,
            "iso6336_reference_tangential_force_N": self.reference_tangential_force_N,
            "iso6336_line_load_N_per_m": self.line_load_N_per_m,
            "iso6336_f_pb_m": self.base_pitch_deviation_m,
            "iso6336_f_falpha_m": self.profile_form_deviation_m,
            "iso6336_C_a_m": self.tip_relief_m,
            "iso6336_y_alpha_m": self.running_in_allowance_m,
            "iso6336_K_A": self.application_factor,
            "iso6336_eps_gamma": self.total_contact_ratio,
            "iso6336_N_S": self.n_s,
            "iso6336_B_p": self.b_p, "iso6336_B_f": self.b_f, "iso6336_B_k": self.b_k,
            "iso6336_sources": dict(self.sources),
        }


def dynamic_factor(pair: GearPair, pinion_torque_Nm: float, speeds_rad_s,
                   accuracy: AccuracyData | None = None, scenario_tip_relief_m: float = 0.0,
                   density_kg_m3: float = STEEL_DENSITY_KG_M3) -> DynamicFactorB:
    """ISO 6336-1 method-B internal dynamic factor K_v at pinion speeds ``speeds_rad_s``
    (rad/s) for ``pinion_torque_Nm`` (N m) (module docstring for the clauses and defaults).

    ``scenario_tip_relief_m`` is the tip relief of the modifications in use (m), taken as
    C_a when ``accuracy.tip_relief_m`` is None; zero means no relief (C_a = C_ay).

    Raises
    ------
    GeometryError
        a non-positive torque, negative speeds, or a total contact ratio <= 1.
    """
    acc = accuracy or AccuracyData()
    if not (math.isfinite(pinion_torque_Nm) and pinion_torque_Nm > 0):
        raise GeometryError("pinion_torque_Nm", pinion_torque_Nm, "must be a finite positive torque")
    speeds = np.atleast_1d(np.asarray(speeds_rad_s, dtype=np.float64))
    if not np.all(np.isfinite(speeds) & (speeds >= 0)):
        raise GeometryError("speeds_rad_s", speeds_rad_s, "speeds must be finite and >= 0 rad/s")
    eps_gamma = pair.total_contact_ratio
    if eps_gamma <= 1.0:
        raise GeometryError("total_contact_ratio", eps_gamma, "method B needs eps_gamma > 1")
    f_t = reference_tangential_force(pair, pinion_torque_Nm)
    w = f_t * acc.application_factor / pair.face_width_m
    c_p = single_stiffness(pair, w)
    c_ga = c_p * (0.75 * pair.transverse_contact_ratio + 0.25)
    omega_e = resonance_speed(pair, c_ga, density_kg_m3)
    grade_pb, grade_fa = iso1328_deviations(pair, acc.accuracy_grade)
    sources = {}
    if acc.base_pitch_deviation_m is not None:
        f_pb, sources["f_pb"] = acc.base_pitch_deviation_m, "given"
    else:
        f_pb, sources["f_pb"] = grade_pb, f"ISO 1328-1 grade {acc.accuracy_grade}"
    if acc.profile_form_deviation_m is not None:
        f_fa, sources["f_falpha"] = acc.profile_form_deviation_m, "given"
    else:
        f_fa, sources["f_falpha"] = grade_fa, f"ISO 1328-1 grade {acc.accuracy_grade}"
    if acc.tip_relief_m is not None:
        c_a, sources["C_a"] = acc.tip_relief_m, "given"
    elif scenario_tip_relief_m > 0.0:
        c_a, sources["C_a"] = float(scenario_tip_relief_m), "tip relief of the modifications"
    else:
        c_a = running_in_tip_relief(acc.sigma_hlim_Pa)
        sources["C_a"] = f"C_ay (no tip relief; sigma_Hlim {acc.sigma_hlim_Pa / 1e6:g} N/mm^2)"
    y_alpha = min(0.075 * f_pb, 3.0 * _UM)
    b_p = c_p * max(f_pb - y_alpha, 0.0) / w
    b_f = c_p * max(f_fa - y_alpha, 0.0) / w
    b_k = abs(1.0 - c_p * c_a / w)
    n_s = 0.85 if w >= _LOW_LOAD_N_PER_M else 0.5 + 0.35 * math.sqrt(w / _LOW_LOAD_N_PER_M)
    cv1, cv2, cv3, cv4, cv5, cv6, cv7 = _coefficients(eps_gamma)
    ratio = speeds / omega_e
    sub = ratio * (cv1 * b_p + cv2 * b_f + cv3 * b_k) + 1.0
    main = cv1 * b_p + cv2 * b_f + cv4 * b_k + 1.0
    sup = cv5 * b_p + cv6 * b_f + cv7
    inter = sup + (main - sup) * (1.5 - ratio) / 0.35
    kv = np.where(ratio <= n_s, sub, np.where(ratio <= 1.15, main, np.where(ratio < 1.5, inter, sup)))
    return DynamicFactorB(
        speeds_rad_s=speeds, kv=kv, resonance_ratio=ratio, resonance_speed_rad_s=omega_e,
        single_stiffness_N_per_m2=c_p, mesh_stiffness_N_per_m2=c_ga,
        reference_tangential_force_N=f_t, line_load_N_per_m=w, base_pitch_deviation_m=f_pb,
        profile_form_deviation_m=f_fa, tip_relief_m=c_a, running_in_allowance_m=y_alpha,
        application_factor=acc.application_factor, total_contact_ratio=eps_gamma, n_s=n_s,
        b_p=b_p, b_f=b_f, b_k=b_k, sources=sources)
