"""Contact lines on the base plane, discretised in cells with mesh stiffness (Fig. 1, Eq. (7)).

At pinion angle ``theta`` the potential contact lines of all tooth pairs that can be in
mesh are laid on the base plane. Tooth pair ``n`` (a global counter; pinion tooth
``n mod z1`` against gear tooth ``n mod z2``) enters contact at the face end ``eta = 0`` when
``Rb1 theta = n p_bt`` and its contact line sits at

    xi_n(theta, eta) = xi_start + Rb1 theta - n p_bt - eta tan(beta_b)

(``xi`` from T1 along the transverse line of action, see :mod:`gearjax.gears.geometry`). Each
line is cut into ``cells_per_line`` cells across the face width; a cell is active when
``xi_start <= xi <= xi_end``. Shapes are fixed (``n_slots`` tooth-pair slots x cells), with
masks, so everything jits and vmaps over ``theta``.

Stiffness laws (per unit length of contact line, N/m^2), selected by a static string:

* ``"uniform"``: constant ``k_l``. The spur mesh stiffness is then the exact 1-pair/2-pair
  square wave. Default ``k_l = c' cos(beta_b)`` (ISO single stiffness per unit face width,
  spread over a contact line of length ``b / cos(beta_b)``).
* ``"iso6336"``: a symmetric parabola along the profile, ``k_l(xi) = k_peak (1 - c s^2)``
  with ``s in [-1, 1]`` across the path of contact, ``c = 0.75 (1 - 1/eps_alpha)`` and
  ``k_peak = c_gamma_alpha cos(beta_b) / (eps_alpha (1 - c/3))``, so that the mean mesh
  stiffness is exactly ISO 6336-1's ``c_gamma_alpha b`` (``c_gamma_alpha = c' (0.75
  eps_alpha + 0.25)``) while the mid-profile single-pair stiffness of a spur pair is ``c' b``
  times ``(0.75 eps_alpha + 0.25) / (eps_alpha (1 - c/3)) = 1`` -- both ISO figures hold.
* ``"weber"``: the paper's law (Section 6.1): the tooth-pair compliance of Weber &
  Banaschek's beam integrals, the O'Donnell-form foundation and Weber's Hertzian approach,
  computed at build along the path (:mod:`.weber`) and stored as a degree-10 polynomial in
  the same ``s``; not calibrated on ISO (its k_m is the model's own).

The cell stiffness is ``k_i = k_l(xi_i) * dl`` with ``dl = (b / cells_per_line) / cos(beta_b)``.
Mesh stiffness ``k(theta) = sum_i k_i`` (normal direction), ``k_m`` its mean, and
``k(theta) = k_m (1 + alpha g(theta))`` with ``max |g| = 1`` (Eq. (19)).
"""

from __future__ import annotations

import math
from typing import Literal

import equinox as eqx
import jax
import jax.numpy as jnp

from .geometry import GearPair
from .modifications import ToothModifications
from . import weber

__all__ = [
    "Mesh",
    "Cells",
    "StiffnessLaw",
    "iso6336_single_stiffness",
    "iso6336_mesh_stiffness",
    "STIFFNESS_LAWS",
]

StiffnessLaw = Literal["uniform", "iso6336", "weber"]
STIFFNESS_LAWS = ("uniform", "iso6336", "weber")

# ISO 6336-1:2006 Eq. (98) coefficients for q' (mm um / N)
_ISO_C = (0.04723, 0.15551, 0.25791, -0.00635, -0.11654, -0.00193, -0.24188, 0.00529, 0.00182)
_N_PER_MM_UM = 1e9  # 1 N/(mm um) in N/m^2


def iso6336_single_stiffness(pair: GearPair) -> float:
    """ISO 6336-1 single stiffness c' per unit face width (N/m^2).

    ``c' = c'_th C_M C_R C_B cos(beta)`` with ``c'_th = 1/q'`` (Eq. (98), virtual tooth
    numbers ``z_n = z / (cos^2 beta_b cos beta)``), ``C_M = 0.8``, ``C_R = 1`` (solid
    blanks) and ``C_B = [1 + 0.5 (1.2 - h_f*)][1 - 0.02 (20 deg - alpha_n)]`` averaged over
    pinion and gear. No load correction (valid for F_t/b >= 100 N/mm).
    """
    c1, c2, c3, c4, c5, c6, c7, c8, c9 = _ISO_C
    beta, beta_b = pair.helix_angle_rad, pair.base_helix_angle_rad
    zn1 = pair.z1 / (math.cos(beta_b) ** 2 * math.cos(beta))
    zn2 = pair.z2 / (math.cos(beta_b) ** 2 * math.cos(beta))
    x1, x2 = pair.profile_shift1, pair.profile_shift2
    q = c1 + c2 / zn1 + c3 / zn2 + c4 * x1 + c5 * x1 / zn1 + c6 * x2 + c7 * x2 / zn2 + c8 * x1**2 + c9 * x2**2
    c_th = 1.0 / q
    alpha_n_deg = math.degrees(pair.normal_pressure_angle_rad)
    cb = [
        (1 + 0.5 * (1.2 - hf)) * (1 - 0.02 * (20.0 - alpha_n_deg))
        for hf in (pair.dedendum_coeff1, pair.dedendum_coeff2)
    ]
    c_b = 0.5 * (cb[0] + cb[1])
    return c_th * 0.8 * 1.0 * c_b * math.cos(beta) * _N_PER_MM_UM


def iso6336_mesh_stiffness(pair: GearPair) -> float:
    """ISO 6336-1 mesh stiffness per unit face width ``c_gamma_alpha = c'(0.75 eps_alpha +
    0.25)`` (N/m^2); ``c_gamma_alpha * b`` is the mean mesh stiffness k_m (N/m)."""
    return iso6336_single_stiffness(pair) * (0.75 * pair.transverse_contact_ratio + 0.25)


class Cells(eqx.Module):
    """Potential contact cells at one angle; arrays of shape ``(n_slots * cells_per_line,)``.

    Attributes
    ----------
    xi_m : position along the transverse line of action from T1 (m) = pinion roll distance
        (radius of curvature of the pinion involute at the contact point).
    eta_m : position across the face width (m).
    roll1_m, roll2_m : roll distances (radii of curvature) on pinion and gear profiles (m).
    pinion_tooth, gear_tooth : tooth indices (int).
    pair_index : global tooth-pair counter n (int).
    inside : bool, the cell lies inside the path of contact.
    stiffness_N_per_m : cell stiffness k_i (N/m), zero outside the path of contact.
    """

    xi_m: jax.Array
    eta_m: jax.Array
    roll1_m: jax.Array
    roll2_m: jax.Array
    pinion_tooth: jax.Array
    gear_tooth: jax.Array
    pair_index: jax.Array
    inside: jax.Array
    stiffness_N_per_m: jax.Array


class Mesh(eqx.Module):
    """Mesh model of a gear pair: discretisation and stiffness law (all static).

    Build with :meth:`Mesh.build`; evaluate with :meth:`cells`, :meth:`stiffness`,
    :meth:`gaps`.
    """

    pair: GearPair = eqx.field(static=True)
    law: str = eqx.field(static=True)
    cells_per_line: int = eqx.field(static=True)
    n_slots: int = eqx.field(static=True)
    stiffness_peak_N_per_m2: float = eqx.field(static=True)
    profile_curvature: float = eqx.field(static=True)
    profile_coefficients: tuple = eqx.field(static=True, default=())

    @classmethod
    def build(
        cls,
        pair: GearPair,
        law: StiffnessLaw = "iso6336",
        cells_per_line: int | None = None,
        stiffness_per_length_N_per_m2: float | None = None,
        pinion_torque_Nm: float | None = None,
    ) -> "Mesh":
        """Build a mesh model.

        Parameters
        ----------
        pair : the gear pair.
        law : ``"uniform"``, ``"iso6336"`` or ``"weber"`` (see module docstring).
        cells_per_line : cells across the face width; default 10 (spur) or 40 (helical).
        stiffness_per_length_N_per_m2 : overrides the peak stiffness per unit contact
            length (uniform law only).
        pinion_torque_Nm : weber law only: the torque setting the line load of its Hertzian
            term (:func:`.weber.static_line_load`); None: 300 N/mm. Ignored by the others.
        """
        if law not in STIFFNESS_LAWS:
            raise ValueError(f"law={law!r}: stiffness law must be one of {STIFFNESS_LAWS}")
        if cells_per_line is None:
            cells_per_line = 10 if pair.spur else 40
        if int(cells_per_line) != cells_per_line or cells_per_line < 1:
            raise ValueError(f"cells_per_line={cells_per_line!r}: must be a positive integer")
        cos_bb = math.cos(pair.base_helix_angle_rad)
        eps = pair.transverse_contact_ratio
        if law == "uniform":
            curvature = 0.0
            peak = iso6336_single_stiffness(pair) * cos_bb
            if stiffness_per_length_N_per_m2 is not None:
                peak = float(stiffness_per_length_N_per_m2)
                if not (math.isfinite(peak) and peak > 0):
                    raise ValueError(
                        f"stiffness_per_length_N_per_m2={peak!r}: must be finite and > 0"
                    )
        elif stiffness_per_length_N_per_m2 is not None:
            raise ValueError(
                f"stiffness_per_length_N_per_m2 is only for law='uniform'; the {law} law "
                "computes its own"
            )
        coefficients = ()
        if law == "weber":
            load = (weber.REFERENCE_LINE_LOAD_N_PER_M if pinion_torque_Nm is None
                    else weber.static_line_load(pair, pinion_torque_Nm))
            coefficients = weber.stiffness_profile(pair, load)
            s = [-1.0 + 2.0 * j / 200 for j in range(201)]
            curvature = 0.0
            peak = max(sum(c * x**j for j, c in enumerate(coefficients)) for x in s)
        elif law == "iso6336":
            curvature = 0.75 * (1.0 - 1.0 / eps)
            peak = iso6336_mesh_stiffness(pair) * cos_bb / (eps * (1.0 - curvature / 3.0))
        span = pair.path_of_contact_m + pair.contact_line_shift_m
        n_slots = int(math.ceil(span / pair.base_pitch_m)) + 1
        return cls(pair, law, int(cells_per_line), n_slots, float(peak), float(curvature),
                   coefficients)

    # ------------------------------------------------------------------ geometry of cells
    @property
    def n_cells(self) -> int:
        return self.n_slots * self.cells_per_line

    @property
    def cell_length_m(self) -> float:
        """Length of contact line per cell, (b / cells_per_line) / cos(beta_b) (m)."""
        return self.pair.face_width_m / self.cells_per_line / math.cos(self.pair.base_helix_angle_rad)

    def stiffness_per_length(self, xi):
        """Stiffness per unit contact length k_l(xi) (N/m^2) of the selected law."""
        xi_a, xi_e = self.pair.contact_limits_m
        s = (2.0 * xi - xi_a - xi_e) / (xi_e - xi_a)
        if self.profile_coefficients:  # weber: Horner in s
            k = jnp.zeros_like(s) + self.profile_coefficients[-1]
            for c in self.profile_coefficients[-2::-1]:
                k = k * s + c
            return k
        return self.stiffness_peak_N_per_m2 * (1.0 - self.profile_curvature * s * s)

    def cells(self, theta) -> Cells:
        """The potential contact cells at pinion angle ``theta`` (rad); see :class:`Cells`."""
        p = self.pair
        xi_a, xi_e = p.contact_limits_m
        u = jnp.asarray(theta) / p.mesh_period_rad  # mesh cycles (Rb1 theta / p_bt)
        n_top = jnp.floor(u)
        slot = jnp.arange(self.n_slots)
        pair_index = (n_top - slot).astype(jnp.int32)  # (slots,)
        s = (u - n_top + slot) * p.base_pitch_m  # Rb1 theta - n p_bt
        eta = (jnp.arange(self.cells_per_line) + 0.5) * (p.face_width_m / self.cells_per_line)
        xi = xi_a + s[:, None] - eta[None, :] * math.tan(abs(p.base_helix_angle_rad))
        inside = (xi >= xi_a) & (xi <= xi_e)
        k = jnp.where(inside, self.stiffness_per_length(xi) * self.cell_length_m, 0.0)
        shape = xi.shape
        pair_b = jnp.broadcast_to(pair_index[:, None], shape)
        return Cells(
            xi_m=xi.ravel(),
            eta_m=jnp.broadcast_to(eta[None, :], shape).ravel(),
            roll1_m=xi.ravel(),
            roll2_m=(p.line_of_action_length_m - xi).ravel(),
            pinion_tooth=jnp.mod(pair_b, p.z1).ravel(),
            gear_tooth=jnp.mod(pair_b, p.z2).ravel(),
            pair_index=pair_b.ravel(),
            inside=inside.ravel(),
            stiffness_N_per_m=k.ravel(),
        )

    def stiffness(self, theta):
        """Geometric mesh stiffness k(theta) = sum of k_i over the path of contact (N/m)."""
        return jnp.sum(self.cells(theta).stiffness_N_per_m)

    def removed_material(self, mods: ToothModifications, cells: Cells, theta):
        """Composite removed material r(M_i) at the cells (m); see :mod:`.modifications`."""
        return mods.removed_material(
            self.pair, cells.xi_m, cells.eta_m, cells.pinion_tooth, cells.gear_tooth, theta
        )

    def theta_grid(self, n_positions: int, n_periods: int = 1):
        """``n_positions`` pinion angles per mesh period, uniformly spaced over ``n_periods``
        mesh periods, starting at 0 (rad)."""
        n = n_positions * n_periods
        return jnp.arange(n) * (self.pair.mesh_period_rad / n_positions)

    def mean_stiffness(self, n_positions: int = 2048):
        """Mean mesh stiffness k_m over one mesh period (N/m), midpoint rule in theta."""
        th = (jnp.arange(n_positions) + 0.5) * (self.pair.mesh_period_rad / n_positions)
        return jnp.mean(jax.vmap(self.stiffness)(th))

    def stiffness_variation(self, theta):
        """(k_m, alpha, g(theta)) of Eq. (19) for the geometric stiffness sampled at
        ``theta`` covering whole mesh periods: ``k = k_m (1 + alpha g)``, ``max |g| = 1``."""
        k = jax.vmap(self.stiffness)(theta)
        return stiffness_shape(k)


def stiffness_shape(k):
    """Split stiffness samples over whole periods into (k_m, alpha, g) of Eq. (19)."""
    k_m = jnp.mean(k)
    dev = k / k_m - 1.0
    alpha = jnp.max(jnp.abs(dev))
    g = dev / jnp.where(alpha > 0, alpha, 1.0)
    return k_m, alpha, g
