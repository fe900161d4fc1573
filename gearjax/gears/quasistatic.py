"""Quasi-static solution with unilateral contact, TE_S and NLTE (Eqs. (7), (9), (10), (17)).

Torsional (sdof) model, Eq. (17): with ``y = x cos(beta_b)`` the normal approach, the
loaded cells satisfy ``sum_i k_i max(0, y - delta_e_i) = F_S`` with ``F_S = F_t / cos(beta_b)``
(equivalently ``(sum k_i)^S cos^2(beta_b) x_S = F_t + (sum k_i delta_e_i)^S cos(beta_b)``).

The root is found exactly by :func:`gearjax.gears.contact.solve_unilateral` (re-exported
here). The 3D model reuses it through the condensed compliance of the pinion-gear dofs.

Transmission errors are transverse distances on the base plane (m), Eq. (9):
``NLTE = min_i r(M_i) / cos(beta_b)`` (rigid approach to first contact, ``r`` the composite
removed material, see :mod:`.modifications`) and ``TE_S = x_S + NLTE``.
"""

from __future__ import annotations

import math

import equinox as eqx
import jax
import jax.numpy as jnp

from .contact import solve_unilateral
from .mesh import Mesh
from .modifications import ToothModifications

__all__ = ["QuasiStatic", "solve_unilateral", "contact_gaps", "quasi_static", "static_mesh_force"]


def static_mesh_force(pair, pinion_torque_Nm):
    """Static normal mesh force F_S = C_m0 / (Rb1 cos(beta_b)) (N) (Section 3, Eq. (23)).
    A float for a float torque; traceable (a model's torque is an array field)."""
    if isinstance(pinion_torque_Nm, (int, float)):
        pinion_torque_Nm = float(pinion_torque_Nm)
    return pinion_torque_Nm / (pair.base_radii_m[0] * math.cos(pair.base_helix_angle_rad))


def contact_gaps(mesh: Mesh, mods: ToothModifications, theta):
    """Cell stiffnesses, initial gaps and NLTE at pinion angle ``theta`` (Eq. (7)).

    Returns
    -------
    (cells, delta_e, nlte) : :class:`gearjax.gears.mesh.Cells`; ``delta_e_i = r_i - min r`` over the
    cells inside the path of contact (m, >= 0 there); NLTE (m, transverse, Eq. (9)).
    """
    # shapes are static: checked at trace time; flat relief bands are fine here (exact)
    mods.check_against(mesh.pair, dynamics=False)
    cells = mesh.cells(theta)
    r = mesh.removed_material(mods, cells, theta)
    r_min = jnp.min(jnp.where(cells.inside, r, jnp.inf))
    delta_e = jnp.where(cells.inside, r - r_min, 0.0)
    nlte = r_min / math.cos(mesh.pair.base_helix_angle_rad)
    return cells, delta_e, nlte


class QuasiStatic(eqx.Module):
    """Quasi-static solution of the torsional model at a set of pinion angles.

    Attributes (leading axis: angles)
    ----------
    theta_rad : pinion angles (rad).
    te_s_m : quasi-static transmission error under load TE_S (m, transverse, Eq. (10)).
    nlte_m : no-load transmission error NLTE (m, transverse).
    x_s_m : elastic approach x_S = TE_S - NLTE (m), Eq. (17).
    mesh_force_N : total normal mesh force (N) (equals F_S: a consistency check).
    loaded_stiffness_N_per_m : (sum k_i)^S over loaded cells (N/m), Eq. (17)-(19).
    cell_load_N : (angles, cells) loads per cell (N).
    pair_index : (angles, cells) global tooth-pair counter of each cell.
    static_force_N : F_S (N).
    """

    theta_rad: jax.Array
    te_s_m: jax.Array
    nlte_m: jax.Array
    x_s_m: jax.Array
    mesh_force_N: jax.Array
    loaded_stiffness_N_per_m: jax.Array
    cell_load_N: jax.Array
    pair_index: jax.Array
    static_force_N: jax.Array

    def pair_loads(self, n_slots: int):
        """Load per tooth-pair slot (angles, n_slots) (N) and the slot pair indices."""
        n = self.cell_load_N.shape[0]
        loads = self.cell_load_N.reshape(n, n_slots, -1).sum(-1)
        return loads, self.pair_index.reshape(n, n_slots, -1)[:, :, 0]


def _solve_one(mesh: Mesh, mods: ToothModifications, force, theta):
    cells, delta_e, nlte = contact_gaps(mesh, mods, theta)
    y, loads = solve_unilateral(cells.stiffness_N_per_m, delta_e, force)
    cos_bb = math.cos(mesh.pair.base_helix_angle_rad)
    x_s = y / cos_bb
    k_s = jnp.sum(jnp.where(loads > 0, cells.stiffness_N_per_m, 0.0))
    return x_s, nlte, jnp.sum(loads), k_s, loads, cells.pair_index


@eqx.filter_jit
def quasi_static(mesh: Mesh, mods: ToothModifications, theta, static_force_N) -> QuasiStatic:
    """Quasi-static TE_S, NLTE and load sharing of the torsional model at angles ``theta``.

    Parameters
    ----------
    mesh : :class:`gearjax.gears.mesh.Mesh`.
    mods : :class:`gearjax.gears.modifications.ToothModifications`.
    theta : (n,) pinion angles (rad), e.g. ``mesh.theta_grid(256)``.
    static_force_N : static normal mesh force F_S (N), see :func:`static_mesh_force`.
    """
    theta = jnp.atleast_1d(jnp.asarray(theta, dtype=float))
    force = jnp.asarray(static_force_N, dtype=float)
    x_s, nlte, f, k_s, loads, idx = jax.vmap(lambda t: _solve_one(mesh, mods, force, t))(theta)
    return QuasiStatic(
        theta_rad=theta,
        te_s_m=x_s + nlte,
        nlte_m=nlte,
        x_s_m=x_s,
        mesh_force_N=f,
        loaded_stiffness_N_per_m=k_s,
        cell_load_N=loads,
        pair_index=idx,
        static_force_N=force,
    )
