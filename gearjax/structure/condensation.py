"""Static condensation of the structure onto the pinion-gear element and the 3D
quasi-static solution with unilateral contact (paper Eqs. (25), (29)-(36)).

The structure's ``K X = F_0 - f_mesh`` (``F_0`` the motor torque, ``f_mesh`` the mesh
forces acting on the 12 dofs of the pinion and gear nodes only) is condensed onto those 12
dofs (:class:`Condensation`; the internal block is invertible once they are held). The
quasi-static solution (:func:`quasi_static_3d`) then solves, on the condensed system,
``[K_cc + sum_A k_i V_i V_i^T] x = f_c + sum_A k_i de_i V_i`` with the unilateral active
set ``A = {i : V_i^T x > de_i}`` (:func:`gearjax.gears.contact.active_set_solve`), with
either the position-dependent cell vectors ``V(M_i)`` (Eq. (25)) or the averaged ``V`` for
every cell (Eq. (27)). ``TE_S = W^T X_S + NLTE`` (Eq. (10)) comes from the condensation at
the encoder dofs. Units: SI (m, rad, N, N m).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..errors import ModelError
from ..gears.contact import active_set_solve, unilateral_solve_pairwise
from ..gears.modifications import ToothModifications
from ..gears.quasistatic import contact_gaps
from .element import PinionGearElement

__all__ = ["Condensation", "QuasiStatic3D", "quasi_static_3d"]


class Condensation(eqx.Module):
    """Static condensation of ``K X = F_0 - f_mesh`` onto the 12 pinion-gear dofs.

    With ``l`` the 12 element dofs and ``i`` the others, ``K_cc = K_ll - K_li K_ii^-1 K_il``
    and ``f_c = F_l - K_li K_ii^-1 F_i``; the encoder observation ``W^T X = c_w + g_w^T x``
    (x the 12 element dofs). ``K_cc`` is singular by one (the free pinion-line rotation)
    until the mesh is added.

    Attributes
    ----------
    k_cc : (12, 12) condensed stiffness (N/m, N m/rad).
    f_c : (12,) condensed load (N, N m).
    c_w : W^T X for x = 0 (m).
    g_w : (12,) gradient of W^T X with respect to x.
    x0_local : (12,) element dofs of X_0 = K_bar^-1 F_0 from the same condensation, so
        that ``TE_S - NLTE - w_x0 = g_w^T (x - x0_local)`` is formed without cancelling the
        large static wind-up of the shafts.
    """

    k_cc: jax.Array
    f_c: jax.Array
    c_w: jax.Array
    g_w: jax.Array
    x0_local: jax.Array

    @classmethod
    def build(cls, K, F0, W, element_dofs, free12=None, k_m=None, v_local=None) -> "Condensation":
        """Condense ``K`` (n, n), ``F0`` and ``W`` (n,) on the 12 ``element_dofs`` (indices
        into K, -1 for a clamped element dof, whose component then stays zero; ``free12``
        overrides which of the 12 are free). Clamped element dofs get an identity row so
        that they stay at zero.

        With ``k_m`` (N/m) and ``v_local`` (12,) also fills ``x0_local`` (element dofs of
        ``K_bar^-1 F_0``, ``K_bar = K + k_m V V^T``, Eq. (27)); otherwise it is zero.

        Raises
        ------
        ModelError
            when the internal block is singular (a shaft line is not supported).
        """
        K, F0, W = np.asarray(K, float), np.asarray(F0, float), np.asarray(W, float)
        pos = np.asarray(element_dofs, dtype=int)
        keep12 = pos >= 0 if free12 is None else np.asarray(free12, dtype=bool)
        loc_free = pos[keep12]
        n = K.shape[0]
        inner = np.setdiff1d(np.arange(n), loc_free)
        m = loc_free.size
        perm = np.r_[loc_free, inner]
        Kp, Fp, Wp = K[np.ix_(perm, perm)], F0[perm], W[perm]
        kll, kli, kii = Kp[:m, :m], Kp[:m, m:], Kp[m:, m:]
        if inner.size:
            try:
                sol = np.linalg.solve(kii, np.concatenate([Kp[m:, :m], Fp[m:, None]], axis=1))
            except np.linalg.LinAlgError as exc:
                raise ModelError("structure.K", "internal block", "singular once the pinion and "
                                 "gear node dofs are held: a shaft line is not supported") from exc
            rr, xf = sol[:, :m], sol[:, m]
        else:
            rr, xf = np.zeros((0, m)), np.zeros(0)
        k_cc = kll - kli @ rr
        f_c = Fp[:m] - kli @ xf
        c_w = Wp[m:] @ xf
        g_w = Wp[:m] - Wp[m:] @ rr
        K12 = np.eye(12) * (np.abs(k_cc).max() if k_cc.size else 1.0)
        idx = np.flatnonzero(keep12)
        K12[np.ix_(idx, idx)] = k_cc
        f12 = np.zeros(12)
        f12[idx] = f_c
        g12 = np.zeros(12)
        g12[idx] = g_w
        K12 = 0.5 * (K12 + K12.T)
        x0 = np.zeros(12)
        if k_m is not None:
            v = np.asarray(v_local, float) * keep12
            x0 = np.linalg.solve(K12 + k_m * np.outer(v, v), f12)
        return cls(jnp.asarray(K12), jnp.asarray(f12), jnp.asarray(c_w), jnp.asarray(g12),
                   jnp.asarray(x0))


class QuasiStatic3D(eqx.Module):
    """Quasi-static 3D solution at one angle (a leading axis after vmap).

    Attributes
    ----------
    x_local : (12,) pinion-gear dofs of X_S (m, rad).
    te_s_m : TE_S = W^T X_S + NLTE (m), Eq. (10).
    nlte_m : NLTE (m).
    v_xs_m : V^T X_S with the averaged V (m), Eq. (36).
    mesh_force_N : total normal mesh force (N) (= F_S when the pinion line is free).
    loaded_stiffness_N_per_m : stiffness of the loaded cells k(theta) (N/m).
    cell_load_N : (cells,) loads per cell (N).
    iterations : active-set iterations used.
    converged : the active set is consistent (no tensile load, no penetration).
    """

    x_local: jax.Array
    te_s_m: jax.Array
    nlte_m: jax.Array
    v_xs_m: jax.Array
    mesh_force_N: jax.Array
    loaded_stiffness_N_per_m: jax.Array
    cell_load_N: jax.Array
    iterations: jax.Array
    converged: jax.Array


def quasi_static_3d(
    cond: Condensation,
    element: PinionGearElement,
    mods: ToothModifications,
    theta,
    static_force_N,
    v_mean_local,
    mesh_vectors: str = "cells",
    max_iter: int = 30,
    free_mask=None,
) -> QuasiStatic3D:
    """Quasi-static 3D solution with unilateral contact at pinion angle ``theta`` (Eq. (25)).

    The active-set iteration starts from the torsional root (Eq. (17)) and is exact at
    convergence; with ``"mean"`` vectors the first set is already the solution (the pinion
    line is torsionally free, so the total mesh force is ``F_S``).

    Parameters
    ----------
    cond : :class:`Condensation` of the structure (K, F_0, W) on the element dofs.
    element : the pinion-gear element (mesh and dof indices).
    mods : tooth modifications.
    theta : pinion angle (rad), scalar (vmap for several).
    static_force_N : F_S (N), used for the warm start (the torsional root).
    v_mean_local : (12,) averaged structure vector V (Eq. (A.1)).
    mesh_vectors : ``"cells"`` (V(M_i), Eq. (25)) or ``"mean"`` (V for every cell, Eq. (27)).
    max_iter : maximum active-set iterations.
    free_mask : (12,) 1 for free element dofs, 0 for clamped ones (default all free).
    """
    cells, de, nlte = contact_gaps(element.mesh, mods, theta)
    k = cells.stiffness_N_per_m
    y, _ = unilateral_solve_pairwise(k, de, static_force_N)
    active0 = (k > 0) & (de < y)
    if mesh_vectors == "cells":
        vecs = element.cell_vectors(cells)
        if free_mask is not None:
            vecs = vecs * free_mask[None, :]
    else:
        vecs = jnp.broadcast_to(v_mean_local, (k.shape[0], 12))
    x, active, it, ok = active_set_solve(cond.k_cc, cond.f_c, vecs, k, de, active0, max_iter)
    loads = jnp.where(active, k * (vecs @ x - de), 0.0)
    return QuasiStatic3D(
        x_local=x,
        te_s_m=cond.c_w + cond.g_w @ x + nlte,
        nlte_m=nlte,
        v_xs_m=v_mean_local @ x,
        mesh_force_N=jnp.sum(loads),
        loaded_stiffness_N_per_m=jnp.sum(jnp.where(active, k, 0.0)),
        cell_load_N=loads,
        iterations=it,
        converged=ok,
    )
