"""Involute geometry of an external spur or helical gear pair (ISO 21771 conventions).

Everything here is plain Python/NumPy evaluated once, outside ``jit``: a :class:`GearPair`
is configuration (its fields are static), and the mesh model reads its derived numbers.

Conventions (SI units: m, rad)
------------------------------
* Subscript 1 is the pinion (driving), 2 the gear.
* The *base plane* is the plane tangent to both base cylinders. Positions on it are
  ``xi`` along the transverse line of action, measured from T1 (tangency point on the
  pinion base circle, so ``xi`` equals the pinion involute's radius of curvature), and
  ``eta`` across the face width (``0 <= eta <= b``).
* Contact starts at ``xi_start`` (gear tip circle, point A) and ends at ``xi_end``
  (pinion tip circle, point E); these are the paper's limits T'1, T'2 of the meshing area
  on the base plane (Fig. 1). The path of contact is ``g_alpha = xi_end - xi_start``.
* Contact lines on the base plane are inclined by the base helix angle ``beta_b``.
"""

from __future__ import annotations

import dataclasses
import math

from ..errors import GeometryError

__all__ = ["GearPair", "GeometryError", "involute", "inverse_involute", "solid_cylinder_inertias",
           "MAX_FACE_WIDTH_MODULES", "MIN_TIP_THICKNESS_MODULES", "UNDERCUT_TOLERANCE",
           "STEEL_DENSITY_KG_M3"]


MAX_TEETH = 2000  # tooth-number range checked by GearPair
# A face width above this many normal modules is no real gear (wide turbo gears reach
# about 100 m_n): most likely millimetres typed as metres, which multiplies k_m by 1000.
MAX_FACE_WIDTH_MODULES = 200.0
# Minimum tip thickness as a fraction of the normal module: below it the tooth is
# (nearly) pointed, its tip breaks off under load (usual design rule s_a >= 0.2-0.4 m_n).
MIN_TIP_THICKNESS_MODULES = 0.2
# Undercut by the generating rack (ISO 53 profile A: addendum h_f* of the gear, tip radius
# 0.38 m_n): refused when the profile shift lies more than this below the undercut limit,
# i.e. beyond the slight undercut accepted in practice (14 instead of 17 teeth for x = 0).
UNDERCUT_RACK_TIP_RADIUS = 0.38
UNDERCUT_TOLERANCE = 0.17


def involute(alpha: float) -> float:
    """inv(alpha) = tan(alpha) - alpha."""
    return math.tan(alpha) - alpha


def inverse_involute(value: float) -> float:
    """Solve inv(alpha) = value for alpha in [0, pi/2) by Newton's method."""
    if value < 0:
        raise ValueError(f"inverse_involute: value={value!r} must be >= 0")
    alpha = (3.0 * value) ** (1.0 / 3.0)  # inv(a) ~ a^3/3 for small a
    for _ in range(60):
        f = involute(alpha) - value
        step = f / math.tan(alpha) ** 2  # d inv / d alpha = tan^2
        alpha -= step
        if abs(step) < 1e-15:
            break
    return alpha


def _positive(field: str, value: float) -> float:
    value = float(value)
    if not math.isfinite(value) or value <= 0.0:
        raise GeometryError(field, value, "must be a finite positive number")
    return value


@dataclasses.dataclass(frozen=True)
class GearPair:
    """An external involute gear pair; derived quantities follow ISO 21771.

    Parameters
    ----------
    normal_module_m : normal module m_n (m).
    z1, z2 : tooth numbers of pinion and gear.
    normal_pressure_angle_rad : alpha_n (rad).
    helix_angle_rad : beta (rad); 0 for spur gears.
    profile_shift1, profile_shift2 : profile shift coefficients x1, x2.
    addendum_coeff1, addendum_coeff2 : h_a* (tip height / m_n before shift).
    dedendum_coeff1, dedendum_coeff2 : h_f* (root depth / m_n before shift).
    face_width1_m, face_width2_m : face widths b1, b2 (m). The common face width
        ``b = min(b1, b2)`` carries the load.

    Raises
    ------
    GeometryError
        non-positive module or width, a face width above :data:`MAX_FACE_WIDTH_MODULES`
        normal modules (a unit slip: millimetres typed as metres), fewer than 5 teeth,
        undercut/interference at the start of contact, undercut by the generating rack
        beyond :data:`UNDERCUT_TOLERANCE` (:meth:`undercut_limit`), pointed tips (tip
        thickness below :data:`MIN_TIP_THICKNESS_MODULES` normal modules), negative tip clearance from
        inconsistent shifts, transverse contact ratio below 1.
    """

    normal_module_m: float
    z1: int
    z2: int
    normal_pressure_angle_rad: float = math.radians(20.0)
    helix_angle_rad: float = 0.0
    profile_shift1: float = 0.0
    profile_shift2: float = 0.0
    addendum_coeff1: float = 1.0
    addendum_coeff2: float = 1.0
    dedendum_coeff1: float = 1.25
    dedendum_coeff2: float = 1.25
    face_width1_m: float = 0.02
    face_width2_m: float = 0.02

    def __post_init__(self):
        _positive("normal_module_m", self.normal_module_m)
        if self.normal_module_m > 0.1:
            raise GeometryError("normal_module_m", self.normal_module_m,
                                "above 0.1 m (100 mm): beyond any real gear; the module is in metres")
        _positive("face_width1_m", self.face_width1_m)
        _positive("face_width2_m", self.face_width2_m)
        mn = float(self.normal_module_m)
        for k in (1, 2):
            b = float(getattr(self, f"face_width{k}_m"))
            if b > MAX_FACE_WIDTH_MODULES * mn:
                raise GeometryError(
                    f"face_width{k}_m", b,
                    f"{b / mn:.0f} normal modules wide (m_n = {mn * 1e3:g} mm), above "
                    f"{MAX_FACE_WIDTH_MODULES:g}: millimetres typed as metres? Widths are in "
                    f"metres ({b:g} mm is {b * 1e-3:g})")
        for name in ("z1", "z2"):
            z = getattr(self, name)
            if int(z) != z or z < 5:
                raise GeometryError(name, z, "tooth number must be an integer >= 5")
            if z > MAX_TEETH:
                raise GeometryError(name, z, f"tooth number above {MAX_TEETH}: beyond any real "
                                             "gear (the mesh and quasi-static grids grow with z)")
        an = float(self.normal_pressure_angle_rad)
        if not (math.radians(5.0) <= an <= math.radians(40.0)):
            raise GeometryError(
                "normal_pressure_angle_rad", an, "must lie between 5 and 40 degrees (in radians)"
            )
        if not (0.0 <= abs(self.helix_angle_rad) < math.radians(50.0)):
            raise GeometryError("helix_angle_rad", self.helix_angle_rad, "|beta| must be < 50 degrees")
        for name in ("addendum_coeff1", "addendum_coeff2", "dedendum_coeff1", "dedendum_coeff2"):
            _positive(name, getattr(self, name))
        for k in (1, 2):
            x = getattr(self, f"profile_shift{k}")
            if not math.isfinite(x) or abs(x) > 2.0:
                raise GeometryError(f"profile_shift{k}", x, "must be finite with |x| <= 2")
        self._check_consistency()

    # ------------------------------------------------------------------ transverse data
    @property
    def spur(self) -> bool:
        return self.helix_angle_rad == 0.0

    @property
    def transverse_pressure_angle_rad(self) -> float:
        """alpha_t = atan(tan alpha_n / cos beta)."""
        return math.atan(math.tan(self.normal_pressure_angle_rad) / math.cos(self.helix_angle_rad))

    @property
    def transverse_module_m(self) -> float:
        return self.normal_module_m / math.cos(self.helix_angle_rad)

    @property
    def pitch_radii_m(self) -> tuple[float, float]:
        mt = self.transverse_module_m
        return 0.5 * self.z1 * mt, 0.5 * self.z2 * mt

    @property
    def base_radii_m(self) -> tuple[float, float]:
        """Rb_k = r_k cos alpha_t."""
        c = math.cos(self.transverse_pressure_angle_rad)
        r1, r2 = self.pitch_radii_m
        return r1 * c, r2 * c

    @property
    def base_helix_angle_rad(self) -> float:
        """beta_b = atan(tan beta cos alpha_t)."""
        return math.atan(math.tan(self.helix_angle_rad) * math.cos(self.transverse_pressure_angle_rad))

    @property
    def working_pressure_angle_rad(self) -> float:
        """alpha_wt from inv(alpha_wt) = inv(alpha_t) + 2 tan(alpha_n)(x1+x2)/(z1+z2)."""
        inv = involute(self.transverse_pressure_angle_rad) + 2.0 * math.tan(
            self.normal_pressure_angle_rad
        ) * (self.profile_shift1 + self.profile_shift2) / (self.z1 + self.z2)
        return inverse_involute(inv)

    @property
    def centre_distance_m(self) -> float:
        """Working centre distance a_w = (r1 + r2) cos alpha_t / cos alpha_wt."""
        r1, r2 = self.pitch_radii_m
        return (r1 + r2) * math.cos(self.transverse_pressure_angle_rad) / math.cos(
            self.working_pressure_angle_rad
        )

    @property
    def tip_radii_m(self) -> tuple[float, float]:
        """r_a = r + m_n (h_a* + x) (no tip shortening)."""
        r1, r2 = self.pitch_radii_m
        mn = self.normal_module_m
        return (
            r1 + mn * (self.addendum_coeff1 + self.profile_shift1),
            r2 + mn * (self.addendum_coeff2 + self.profile_shift2),
        )

    @property
    def root_radii_m(self) -> tuple[float, float]:
        """r_f = r - m_n (h_f* - x)."""
        r1, r2 = self.pitch_radii_m
        mn = self.normal_module_m
        return (
            r1 - mn * (self.dedendum_coeff1 - self.profile_shift1),
            r2 - mn * (self.dedendum_coeff2 - self.profile_shift2),
        )

    # ------------------------------------------------------------------ base plane
    @property
    def line_of_action_length_m(self) -> float:
        """T1T2 = a_w sin alpha_wt (distance between the base-circle tangency points)."""
        return self.centre_distance_m * math.sin(self.working_pressure_angle_rad)

    @property
    def contact_limits_m(self) -> tuple[float, float]:
        """(xi_start, xi_end): T'1 and T'2 measured from T1 on the line of action (m)."""
        ra1, ra2 = self.tip_radii_m
        rb1, rb2 = self.base_radii_m
        xi_end = math.sqrt(ra1**2 - rb1**2)
        xi_start = self.line_of_action_length_m - math.sqrt(ra2**2 - rb2**2)
        return xi_start, xi_end

    @property
    def path_of_contact_m(self) -> float:
        """g_alpha, length of the transverse path of contact (m)."""
        a, e = self.contact_limits_m
        return e - a

    @property
    def base_pitch_m(self) -> float:
        """Transverse base pitch p_bt = 2 pi Rb1 / z1 (m)."""
        return 2.0 * math.pi * self.base_radii_m[0] / self.z1

    @property
    def face_width_m(self) -> float:
        """Common (load-carrying) face width b = min(b1, b2) (m)."""
        return min(self.face_width1_m, self.face_width2_m)

    @property
    def transverse_contact_ratio(self) -> float:
        """epsilon_alpha = g_alpha / p_bt."""
        return self.path_of_contact_m / self.base_pitch_m

    @property
    def overlap_ratio(self) -> float:
        """epsilon_beta = b sin|beta| / (pi m_n)."""
        return self.face_width_m * math.sin(abs(self.helix_angle_rad)) / (math.pi * self.normal_module_m)

    @property
    def total_contact_ratio(self) -> float:
        return self.transverse_contact_ratio + self.overlap_ratio

    @property
    def contact_line_shift_m(self) -> float:
        """b tan(beta_b): shift along the line of action between the two face ends (m)."""
        return self.face_width_m * math.tan(abs(self.base_helix_angle_rad))

    @property
    def mesh_period_rad(self) -> float:
        """Mesh period in the pinion angle theta = Omega1 t: 2 pi / z1 (rad)."""
        return 2.0 * math.pi / self.z1

    @property
    def gear_ratio(self) -> float:
        """z2 / z1 = Rb2 / Rb1."""
        return self.z2 / self.z1

    def tip_thickness_m(self, k: int) -> float:
        """Transverse tooth thickness on the tip circle of gear k (1 or 2) (m)."""
        z = (self.z1, self.z2)[k - 1]
        x = (self.profile_shift1, self.profile_shift2)[k - 1]
        ra = self.tip_radii_m[k - 1]
        rb = self.base_radii_m[k - 1]
        at = self.transverse_pressure_angle_rad
        aat = math.acos(min(1.0, rb / ra))
        half = (math.pi / 2.0 + 2.0 * x * math.tan(self.normal_pressure_angle_rad)) / z
        return 2.0 * ra * (half + involute(at) - involute(aat))

    def undercut_limit(self, k: int) -> float:
        """Profile shift below which gear k (1 or 2) is undercut when generated by the
        basic rack of ISO 53 profile A (addendum ``h_f*`` of the gear, tip radius
        ``0.38 m_n``): ``x_min = h_f* - 0.38 (1 - sin alpha_n) - z sin^2(alpha_t) /
        (2 cos beta)`` (ISO 21771)."""
        z = (self.z1, self.z2)[k - 1]
        hf = (self.dedendum_coeff1, self.dedendum_coeff2)[k - 1]
        an, at = self.normal_pressure_angle_rad, self.transverse_pressure_angle_rad
        straight = hf - UNDERCUT_RACK_TIP_RADIUS * (1.0 - math.sin(an))
        return straight - z * math.sin(at) ** 2 / (2.0 * math.cos(self.helix_angle_rad))

    # ------------------------------------------------------------------ validation
    def _check_consistency(self):
        rb1, rb2 = self.base_radii_m
        ra1, ra2 = self.tip_radii_m
        rf1, rf2 = self.root_radii_m
        for k, (ra, rb) in enumerate(((ra1, rb1), (ra2, rb2)), start=1):
            if ra <= rb:
                raise GeometryError(
                    f"addendum_coeff{k}", getattr(self, f"addendum_coeff{k}"),
                    f"tip circle (r_a={ra:.6g} m) lies inside the base circle (r_b={rb:.6g} m)",
                )
        aw = self.centre_distance_m
        for k, (ra, rf_other) in enumerate(((ra1, rf2), (ra2, rf1)), start=1):
            clearance = aw - ra - rf_other
            if clearance < 0.0:
                raise GeometryError(
                    f"profile_shift{k}", getattr(self, f"profile_shift{k}"),
                    f"inconsistent profile shifts: tip of gear {k} reaches {-clearance:.3g} m into "
                    "the root of its mate (negative tip clearance)",
                )
        xi_start, xi_end = self.contact_limits_m
        if xi_start <= 0.0:
            raise GeometryError(
                "z1", self.z1,
                "interference: the gear tip meets the pinion below its base circle "
                f"(start of contact {xi_start:.4g} m before T1); add pinion profile shift or teeth",
            )
        if xi_end >= self.line_of_action_length_m:
            raise GeometryError(
                "z2", self.z2,
                "interference: the pinion tip meets the gear below its base circle; "
                "add gear profile shift or teeth",
            )
        for k in (1, 2):
            x, x_min = getattr(self, f"profile_shift{k}"), self.undercut_limit(k)
            if x < x_min - UNDERCUT_TOLERANCE:
                raise GeometryError(
                    f"profile_shift{k}", x,
                    f"undercut teeth on gear {k} (z = {(self.z1, self.z2)[k - 1]}): the "
                    f"generating rack cuts the root below x = {x_min:.3f}, beyond the slight "
                    f"undercut accepted in practice ({x_min - UNDERCUT_TOLERANCE:.3f}); add "
                    "profile shift or teeth")
        mn = self.normal_module_m
        for k in (1, 2):
            sa = self.tip_thickness_m(k)
            if sa <= 0.0:
                raise GeometryError(
                    f"addendum_coeff{k}", getattr(self, f"addendum_coeff{k}"),
                    f"pointed tip on gear {k} (tip thickness {sa:.3g} m <= 0)",
                )
            if sa < MIN_TIP_THICKNESS_MODULES * mn:
                x = getattr(self, f"profile_shift{k}")
                field, value = ((f"profile_shift{k}", x) if x > 0.0
                                else (f"addendum_coeff{k}", getattr(self, f"addendum_coeff{k}")))
                raise GeometryError(
                    field, value,
                    f"(nearly) pointed teeth on gear {k}: tip thickness {sa * 1e3:.3g} mm = "
                    f"{sa / mn:.3f} m_n, below {MIN_TIP_THICKNESS_MODULES:g} m_n; reduce the "
                    "profile shift or the addendum",
                )
        if self.transverse_contact_ratio < 1.0:
            raise GeometryError(
                "addendum_coeff1", self.addendum_coeff1,
                f"transverse contact ratio epsilon_alpha={self.transverse_contact_ratio:.4f} < 1: "
                "the pair cannot transmit motion continuously",
            )

    def summary(self) -> dict:
        """Plain-number summary (SI units) for reports and JSON output."""
        return {
            "normal_module_m": self.normal_module_m,
            "tooth_numbers": [self.z1, self.z2],
            "helix_angle_rad": self.helix_angle_rad,
            "transverse_pressure_angle_rad": self.transverse_pressure_angle_rad,
            "working_pressure_angle_rad": self.working_pressure_angle_rad,
            "centre_distance_m": self.centre_distance_m,
            "pitch_radii_m": list(self.pitch_radii_m),
            "base_radii_m": list(self.base_radii_m),
            "tip_radii_m": list(self.tip_radii_m),
            "root_radii_m": list(self.root_radii_m),
            "base_helix_angle_rad": self.base_helix_angle_rad,
            "base_pitch_m": self.base_pitch_m,
            "path_of_contact_m": self.path_of_contact_m,
            "contact_limits_m": list(self.contact_limits_m),
            "face_width_m": self.face_width_m,
            "contact_ratio": self.transverse_contact_ratio,
            "overlap_ratio": self.overlap_ratio,
            "total_contact_ratio": self.total_contact_ratio,
            "mesh_period_rad": self.mesh_period_rad,
        }


STEEL_DENSITY_KG_M3 = 7800.0


def solid_cylinder_inertias(pair: GearPair, density_kg_m3: float = STEEL_DENSITY_KG_M3):
    """Polar inertias (kg m^2) of solid cylinders at the pitch radii with the face widths.

    ``J_k = rho pi b_k r_k^4 / 2``: the default pinion and gear shaft-line inertias of the
    sdof model when nothing better is known (steel, rho = 7800 kg/m^3).
    """
    r1, r2 = pair.pitch_radii_m
    return (
        density_kg_m3 * math.pi * pair.face_width1_m * r1**4 / 2.0,
        density_kg_m3 * math.pi * pair.face_width2_m * r2**4 / 2.0,
    )
