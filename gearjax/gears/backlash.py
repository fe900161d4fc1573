"""Backlash: the clearance between the back flanks and where the back flanks mesh.

The backlash ``b`` (m) is the normal backlash ``j_bn`` of ISO 21771: the clearance between
the back (non-working) flanks when the drive flanks of the perfect (unmodified) teeth
touch, measured along the line of action, normal to the flanks -- the same direction as
the cell approaches ``delta_i = V(M_i)^T X`` (``x cos(b_b)`` in the sdof model). The mesh
force of a pair with backlash is :func:`gearjax.gears.contact.three_state_force`.

Where the back flanks mesh
--------------------------
The back flanks mesh on the second base plane, tangent to both base circles on the other
side of the line of centres. An involute pair (tight mesh: the tooth thicknesses of the
profile shifts, ``inv a_wt = inv a_t + 2 tan a_n (x1 + x2) / (z1 + z2)``) is symmetric
under the half-turn ``H`` about the line of centres ``O1O2`` in the face mid-plane at the
pinion angle ``theta_s`` where a pinion tooth is centred on that line; ``H`` maps the
drive flanks onto the back flanks and a pinion rotation ``+a`` onto ``-a``, so the back
contact pattern at ``theta`` is the image under ``H`` of the drive pattern at ``phi0 -
theta``, ``phi0 = 2 theta_s`` (:func:`back_flank_angle_rad`): the same cells
(:meth:`gearjax.gears.mesh.Mesh.cells`) at the mirror angle, travelling the back line of
action the other way, with structure vectors ``V'(M_i) = H V(M_i)``
(:meth:`gearjax.structure.element.PinionGearElement.back_vectors`; in torsion ``V'^T X =
-V^T X``). A pinion tooth is centred on the line of centres when the drive contact line
of its pair crosses the mid-plane at ``xi_s = Rb1 (a_wt + psi_b / 2)`` from T1 (the pitch
point ``Rb1 tan a_wt`` plus the roll from the flank to the tooth's centre, ``Rb1 (psi_b / 2
- inv a_wt)``), with ``psi_b = (pi + 4 x1 tan a_n) / z1 + 2 inv a_t`` the pinion's base
tooth angle. The contact positions are those of the rigid-body angle, as for the drive
flanks (small displacements: the clearance is small beside the base pitch).

Back-flank gaps (:func:`back_flank_gaps`): the drive flanks' modifications at the mirror
angle (tip relief and crowning are the same on both flanks). With the drive flanks' first
contact at ``delta = 0`` (:func:`gearjax.gears.quasistatic.contact_gaps`: gaps relative to
the least removed material ``r_min = NLTE cos(b_b)``), the back flanks' first contact is at
``delta = -(b + r_min + r'_min)``. Tooth position errors (pitch errors, eccentricity)
shift a tooth's back flank the other way from its drive flank; those gaps are not
modelled (:func:`check_backlash_mods`).
"""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np

from ..errors import ModelError
from .contact import three_state_force
from .geometry import GearPair, involute
from .mesh import Mesh
from .modifications import ToothModifications
from .quasistatic import contact_gaps

__all__ = ["MAX_BACKLASH_MODULES", "backlash_problem", "check_backlash", "check_model_backlash", "back_flank_angle_rad",
           "back_flank_gaps", "check_backlash_mods", "cell_backlash_force"]

MAX_BACKLASH_MODULES = 1.0  # a larger clearance is almost surely a unit slip (mm for m)


def backlash_problem(value, pair: GearPair) -> str | None:
    """Why ``value`` is not a backlash (m) of ``pair``, or None: it must be a finite
    number in ``[0, m_n]`` (a clearance of more than a normal module is a unit slip, and
    the back-flank contact positions assume it small beside the base pitch)."""
    try:
        b = float(value)
    except (TypeError, ValueError):
        return "not a number (the clearance between the back flanks, m)"
    if not math.isfinite(b):
        return "must be a finite clearance (m)"
    if b < 0.0:
        return "must be >= 0 (the clearance between the back flanks, m)"
    limit = MAX_BACKLASH_MODULES * pair.normal_module_m
    if b > limit:
        return (f"larger than the normal module ({limit:g} m): the backlash is in metres "
                "along the line of action (0.1 mm is 1e-4)")
    return None


def check_backlash(field: str, value, pair: GearPair, error=ModelError) -> float | None:
    """``value`` as a backlash (m) of ``pair``, None for None; else ``error(field, value,
    reason)`` (:func:`backlash_problem`)."""
    if value is None:
        return None
    why = backlash_problem(value, pair)
    if why is not None:
        raise error(field, value, why)
    return float(value)


def check_backlash_mods(backlash_m: float, mods: ToothModifications, pair: GearPair) -> None:
    """Refuse (:class:`~gearjax.errors.ModelError` on ``backlash_m``) backlash with tooth
    position errors in a per-cell formulation: a pitch error or an eccentricity moves a
    tooth's back flank the other way from its drive flank, and those back-flank gaps are
    not modelled (module docstring)."""
    if mods.excitation_period_rad(pair) > pair.mesh_period_rad * (1 + 1e-9):
        raise ModelError("backlash_m", backlash_m, "not with pitch errors or eccentricity in "
                         "the reference formulation (the back-flank gaps of tooth position "
                         "errors are not modelled); use the te or perturbation formulation")


def check_model_backlash(backlash_m, mods: ToothModifications, pair: GearPair, *,
                         reference: bool, cell_contact: bool) -> float | None:
    """The backlash (m) a model builder takes, None for none: :func:`check_backlash`, then
    refused (:class:`~gearjax.errors.ModelError`) with the per-cell te/perturbation contact
    law (``cell_contact``: it has no back flanks) and, for the ``reference`` formulation,
    with tooth position errors (:func:`check_backlash_mods`)."""
    backlash = check_backlash("backlash_m", backlash_m, pair)
    if backlash is not None and cell_contact:
        raise ModelError("contact_law", "cells", "the per-cell te/perturbation contact law has "
                         "no back flanks; with backlash_m use the mesh-level law "
                         "(TEContactLaw.MESH)")
    if backlash is not None and reference:
        check_backlash_mods(backlash, mods, pair)
    return backlash


def back_flank_angle_rad(pair: GearPair) -> float:
    """``phi0`` (rad, in ``[0, 2 pi / z1)``): the back contact pattern at the pinion angle
    ``theta`` is the drive pattern at ``phi0 - theta`` (module docstring)."""
    rb1 = pair.base_radii_m[0]
    a_t, a_n = pair.transverse_pressure_angle_rad, pair.normal_pressure_angle_rad
    psi_b = (math.pi + 4.0 * pair.profile_shift1 * math.tan(a_n)) / pair.z1 + 2.0 * involute(a_t)
    xi_s = rb1 * (pair.working_pressure_angle_rad + 0.5 * psi_b)
    xi_start = pair.contact_limits_m[0]
    mid = 0.5 * pair.face_width_m * math.tan(abs(pair.base_helix_angle_rad))
    # xi_start + Rb1 theta_s - mid = xi_s  (mod p_bt), see Mesh.cells
    theta_s = (xi_s - xi_start + mid) / rb1
    return float(np.mod(2.0 * theta_s, pair.mesh_period_rad))


def back_flank_gaps(mesh: Mesh, mods: ToothModifications, theta, phi0: float):
    """The back-flank cells at the pinion angle ``theta`` (rad): ``(cells, gaps (m), offset
    (m))`` with the cells and gaps (``r'_i - r'_min``) of the drive flanks at ``phi0 -
    theta`` and ``offset = r'_min`` (m, the back flanks' least removed material, normal)."""
    cells, gaps, nlte = contact_gaps(mesh, mods, phi0 - theta)
    return cells, gaps, nlte * math.cos(mesh.pair.base_helix_angle_rad)


def cell_backlash_force(mesh: Mesh, mods: ToothModifications, theta, delta, backlash_m):
    """The sdof mesh force of Eq. (22) with back flanks (N, signed): at the normal approach
    ``delta = x cos b_b`` (m) of the drive flanks beyond their first contact,
    :func:`gearjax.gears.contact.three_state_force` with ``k(u) = sum_i k_i max(0, u -
    delta_e_i)`` over the drive cells at ``theta`` (rad), ``k_b`` the same over the back
    cells (:func:`back_flank_gaps`) and the clearance between first contacts ``b + r_min +
    r'_min`` (module docstring). ``backlash_m`` is b (m)."""
    cells, gaps, nlte = contact_gaps(mesh, mods, theta)
    b_cells, b_gaps, b_min = back_flank_gaps(mesh, mods, theta, back_flank_angle_rad(mesh.pair))
    k, kb = cells.stiffness_N_per_m, b_cells.stiffness_N_per_m
    clearance = backlash_m + nlte * math.cos(mesh.pair.base_helix_angle_rad) + b_min
    return three_state_force(delta, clearance, lambda u: jnp.sum(k * jnp.maximum(u - gaps, 0.0)),
                             lambda u: jnp.sum(kb * jnp.maximum(u - b_gaps, 0.0)))
