"""Quasi-static state codes and switching functions of the sdof (torsional) mesh.

The torsional quasi-static solution at an angle theta (rad) is the unilateral root of
Eq. (17) over the mesh cells (:func:`gearjax.gears.contact.solve_unilateral`) under the
static mesh force ``F_S`` (N). :func:`sdof_signature` gives its discrete state (the layout
that :func:`gearjax.excitation.events.code` turns into an integer row), used at build time
to bracket the switching events and in the assembly to check that the structure of the
solution is the build one; :func:`sdof_switch` is the switching function whose root is a
design-dependent event angle (:func:`gearjax.excitation.events.switch_value`). The 3D
counterparts are the methods of :class:`gearjax.excitation.mesh3d.QuasiStaticMesh3D`.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp

from ..gears.contact import solve_unilateral
from ..gears.quasistatic import contact_gaps
from .events import switch_value

__all__ = ["sdof_signature", "sdof_signature_fn", "sdof_switch"]


def sdof_signature(mesh, mods, force, theta):
    """Discrete state of the quasi-static solution at one angle theta: loaded cells, the
    cell realising NLTE, and, per cell, inside/outside the path of contact and
    inside/outside each tip-relief zone (where the gaps, hence TE_S and NLTE, have kinks;
    the zones follow :mod:`gearjax.gears.modifications`), plus NLTE (m) and the
    quasi-static approach ``x_S`` (m). Traceable in ``mods``."""
    p = mesh.pair
    cos_bb = math.cos(p.base_helix_angle_rad)
    xi_a, xi_e = p.contact_limits_m
    ext = mods.relief_extent * p.path_of_contact_m
    cells, delta_e, nlte = contact_gaps(mesh, mods, theta)
    k = cells.stiffness_N_per_m
    y, _ = solve_unilateral(k, delta_e, force)
    r = mesh.removed_material(mods, cells, theta)
    amp = mods.relief_amplitude_m
    zone = (jnp.where(amp[0] > 0, cells.xi_m > xi_e - ext[0], False).astype(jnp.int32)
            + 2 * jnp.where(amp[1] > 0, cells.xi_m < xi_a + ext[1], False).astype(jnp.int32))
    return {
        "loaded": (k > 0) & (delta_e < y),
        "nlte_arg": jnp.argmin(jnp.where(cells.inside, r, jnp.inf)),
        "inside": cells.inside,
        "zone": jnp.where(cells.inside, zone, -1),
        "nlte": nlte,
        "x_s": y / cos_bb,
    }


def sdof_signature_fn(mesh, mods, force):
    """Jitted, vmapped :func:`sdof_signature` over angles theta (build time)."""

    @jax.jit
    @jax.vmap
    def sig(theta):
        return sdof_signature(mesh, mods, force, theta)

    return sig


def sdof_switch(mesh, mods, force, kind, a, b, theta):
    """Switching function g (m) of an event of ``kind`` (cells a, b) at theta for the
    torsional quasi-static solution under the force ``force`` (N): the approach minus the
    gap of cell a enters :func:`gearjax.excitation.events.switch_value`."""
    cells, delta_e, _ = contact_gaps(mesh, mods, theta)
    y, _ = solve_unilateral(cells.stiffness_N_per_m, delta_e, force)
    return switch_value(mesh, mods, cells, theta, y - delta_e[a], kind, a, b)
