"""3D geared-system model: shafts + bearings + pinion-gear element (paper Section 4).

The structure (``M``, ``K``: shafts, discs, bearings, couplings, the resisting torsional
spring; :mod:`gearjax.structure`) is coupled to the mesh cells of :mod:`gearjax.gears.mesh`
through the structure vectors ``V(M_i)`` of the pinion-gear element (Eq. (8a),
:class:`gearjax.structure.element.PinionGearElement`). Three formulations, a static choice so
that each compiles only its own terms (``' = d/dtheta``, ``theta = Omega1 t``):

``"reference"`` -- Eq. (14), instantaneous unilateral contact on every cell::

    Omega^2 M X'' + Omega C X' + K X + sum_i k_i max(0, V(M_i)^T X - de_i) V(M_i)
        = F_0 - Omega^2 [NLTE'' E + NLTE' F + G]

``"te"`` -- transmission-error based Eq. (42)::

    Omega^2 M X'' + Omega C X' + [K_bar + alpha k_m g V V^T] X
        = F_0 + [k(theta) cos b_b (TE_S - NLTE - w_x0) + alpha F_S g] V
          - Omega^2 [NLTE'' E + NLTE' F + G]

  with ``K_bar = K + k_m V V^T`` (Eq. (27)), ``k(theta) = k_m (1 + alpha g)`` the *loaded*
  quasi-static stiffness (stiffness of the cells loaded in the quasi-static solution) and
  ``k_m`` its mean over one excitation period, so that ``alpha k_m g = k(theta) - k_m`` and
  ``alpha F_S g = (k(theta) - k_m) F_S / k_m``.

``"perturbation"`` -- main-order perturbation Eq. (48a)::

    Omega^2 M X'' + Omega C X' + K_bar X
        = F_0 + k_m cos b_b (TE_S - NLTE - w_x0) V - Omega^2 [NLTE'' E + NLTE' F + G]

``V`` is the averaged structure vector (Eq. (A.1), :meth:`PinionGearElement.mean_vector`),
``W`` the TE projection vector (Rb1, Rb2 at the encoder torsional dofs, Eq. (10)),
``X_0 = K_bar^-1 F_0``, ``w_x0 = W^T X_0`` and ``v_x0 = V^T X_0``.

Quasi-static solution (Eq. (25))
--------------------------------
``TE_S``, ``NLTE`` and ``k(theta)`` come from the exact unilateral quasi-static solution
(tabulated once per call on a jump-aware periodic Hermite table, see below), with either the
position-dependent cell vectors (``mesh_vectors="cells"``, the paper's Section 6.2: TE_S
from Eq. (14) at very low speed) or the averaged ``V`` for every cell (``"mean"``, Eq. (27),
the simplification of Section 4.2). The structure is condensed statically onto the 12
pinion-gear dofs (the internal block is invertible), then an active-set iteration on the
cells solves ``[K_cc + sum_A k_i V_i V_i^T] x = f_c + sum_A k_i de_i V_i`` until the set
``A = {i : V_i^T x > de_i}`` is stable (exact at convergence; warm-started from the torsional
solution; fixed maximum number of iterations inside ``lax.while_loop``; the returned
solution is a final solve with the converged set, hence differentiable almost everywhere).
With ``"mean"`` vectors the approach ``V^T X_S`` is exactly the torsional root (the pinion
line is torsionally free, so the total mesh force is ``F_S``) and no iteration is needed.
``TE_S = W^T X_S + NLTE`` is recovered from the condensation at the encoder dofs.

For te/perturbation the excitations ``(TE_S - NLTE - w_x0, k(theta), NLTE)`` do not depend
on speed: :meth:`Geared3DModel.prepare` evaluates them (inside ``jit``, so they stay
differentiable in the modifications) at the knots of a
:class:`gearjax.models.torsional.PeriodicHermiteTable` -- ``n_table`` uniform knots per mesh
period plus the two adjacent floats bracketing every change of the quasi-static active set,
of the cells inside the path, of the cell realising NLTE and of the cells inside each relief
zone (found by bisection at build time; several changes inside one scan interval, as the
cells of a 3D contact line loading one after the other, are all found) -- with exact slopes
by forward-mode AD. Hermite interpolation is then exact at the jumps of ``k(theta)`` and
the kinks of ``TE_S`` and NLTE (measured on the spur rig, short relief: ``k`` to 5e-13,
``TE_S`` to 3e-11 of its peak-to-peak). A lookup costs a few flops, against an active-set
solve over the cells at every right-hand side (``excitation="inline"``, kept to check the
table): a 16-speed te sweep of the reduced spur rig took 237 s inline and 65 s with the
table (the latter with other jobs loading the 2 cores about 3x; the default solver choice,
:func:`gearjax.dynamics.simulate.jump_density`, matters as much).

Derivatives with respect to the design (moving events)
------------------------------------------------------
The angles where ``k(theta)`` jumps (a relieved cell starts or stops carrying load,
``V_i^T X_S = de_i`` in Eq. (25)), where NLTE' jumps (the cell realising NLTE changes,
Eq. (9)) and where TE_S kinks (a cell crosses a relief start) move with the tip relief;
a table with knots fixed at build gives derivatives that miss the boundary terms of the
moving jumps. As in the torsional model (:mod:`gearjax.models.torsional`, "Derivatives
with respect to the design"), the tabulated te and perturbation formulations record at
build the kind and cells of every event of the table brackets
(:attr:`event_thetas`, :attr:`event_kinds`, :attr:`event_cells`), :meth:`jump_angles_rad`
moves them by Newton iterations on the switching functions (implicit differentiation),
and the model integrates in the simulation angle ``s`` with ``theta = phi(s)``
(:class:`gearjax.models.torsional.AngleMap`, identity at the build design): the table
holds ``q(phi(s))``, :meth:`vector_field` is ``phi'(s) dy/dtheta``, NLTE derivatives are
taken with respect to theta by the chain rule, outputs are evaluated at ``phi(s)``.
Forward results at the build design are unchanged. The perturbation formulation needs
the map even without NLTE terms: its forcing ``TE_S - w_x0`` kinks where the loaded set
changes and at the relief starts, and a table with fixed knots differentiates the
interpolant, not the kinks' motion (measured, short relief, 300/500 rad/s: d(peak force)
/ dL_c -4.5e3 N against +8.46e3 N by central differences; with the map 3e-6). The
reference formulation has no table and no map (its contact law is continuous in the
gaps, but its NLTE' jumps stay at the build angles: not checked against differences).
``k_m`` (the splitting constant of ``K_bar`` and the modal basis) stays the build value:
exact for te (Eq. (42) only splits ``k(theta)``); for the perturbation formulation the
derivative holds ``k_m`` fixed. Measured (spur, short relief, modes < 3 kHz, 300 rad/s,
periodic steady state): jacfwd of the peak mesh force / DTE peak-to-peak against central
differences of the same model 8e-5 / 2e-7 (amplitude), 2e-7 / 3e-7 (extent); event
angles moved by Newton equal the rebuilt bisection to 1e-13 rad. Against models rebuilt
at P_c +- h the peak-force derivative agrees to 1 % with 2048 samples per mesh period
(16 % with 128): the peak sits at a jump of ``k(theta)``, where a sample grid fixed in
theta (rebuilt) and one moving with ``phi`` (same model) see different maxima.
The map is valid while the design keeps the discrete structure of the build (the
quasi-static state on each side of every knot); :meth:`prepare` checks it and sets
:attr:`structure_ok` (a traced bool: :class:`gearjax.design.DynamicObjective` rebuilds the
model when it is False).

Inertial excitations E, F, G (text after Eq. (14))
--------------------------------------------------
* ``E``: ``J2 Rb1 / Rb2^2`` on the torsional dof of the input torque (Eq. (5); ``J2`` the
  polar inertia of the gear shaft line, ``r_2^T M r_2`` with ``r_2`` the unit rigid rotation
  of the gear line) plus ``M r_2 / Rb2`` (``I_pi / Rb2`` at every torsional dof of the gear
  shaft line for lumped inertias; the consistent-mass generalisation otherwise), plus the
  gear-eccentricity components of ``E~``.
* ``F``, ``G``: eccentricities of pinion and gear (mass ``m_k`` of the pinion/gear discs).
  Phases follow :mod:`gearjax.gears.modifications`: the mass centre of gear k sits at
  ``e_k (cos psi_k, sin psi_k)`` in (s, t) with ``psi_1 = theta - lambda_1 - pi/2`` and
  ``psi_2 = lambda_2 - pi/2 - theta Rb1/Rb2`` (the gear turns backwards), which is the
  offset whose projection on the normal gives the geometric excess
  ``e_k cos b_b sin(phi_k - lambda_k)`` used in the gaps de_i. Then
  ``G~ = -m_1 e_1 (cos, sin)psi_1`` at the pinion (v, w), ``-m_2 e_2 (Rb1/Rb2)^2 (cos, sin)psi_2``
  at the gear, ``F~ = 2 m_2 e_2 Rb1/Rb2^2 (cos, sin)psi_2`` and ``E~ = m_2 e_2/Rb2
  (-sin, cos)psi_2`` at the gear (v, w): the paper's vectors up to the phase origin.

Without eccentricity G, F and E~ are not compiled; without NLTE terms (``nlte_terms=False``,
or NLTE identically zero) E and F are not compiled, and in the te/perturbation formulations
``TE_S - NLTE`` becomes ``TE_S`` (as the torsional model and the paper's Fig. 10 "with NLTE
= 0"); DTE is then ``W^T X``.

NLTE'' without differentiating a kinked function
-----------------------------------------------
NLTE has kinks, so NLTE'' has Dirac parts. With ``u = q' + NLTE' e(theta)`` (``q`` modal
coordinates, ``M_r = I``, ``e = T^T E``) the equation ``Omega^2 q'' + ... = -Omega^2 NLTE'' e``
becomes ``u' = (...)/Omega^2 + NLTE' e'``, ``q' = u - NLTE' e``: only NLTE' (exact
forward-mode derivative of the minimum, piecewise smooth) enters, and the kinks are passed
to the integrator as ``jump_thetas``. This is the torsional model's substitution written on
the velocity, and it also covers the angle-dependent ``E~`` of an eccentric gear.

Modal coordinates, reduction, damping
-------------------------------------
``X = T q`` with ``T`` from :func:`gearjax.structure.reduced_model` on ``(M, K_bar)``: all
modes (``max_frequency_hz=None``, exact) or the modes below a cut-off plus static-correction
pseudo-modes for the load patterns ``F_0``, ``E`` and unit loads on the 12 pinion-gear dofs
(so every static mesh response, hence ``X_0``, ``X_S`` and ``C_v``, is reproduced exactly).
``M_r = I``; ``K_bar,r`` diagonal; damping ``C = M Phi diag(2 zeta omega) Phi^T M`` with all
modes of ``(M, K_bar)`` (unique modal damping factor, Section 6.1), projected.

State and scaling
-----------------
``y = ((q - q_0)/a, u / (r a))`` with ``q_0`` the modal coordinates of ``X_0`` (so the large
static wind-up of the shafts is not integrated), ``r_j = omega_j / Omega`` and ``a`` the
largest modal coordinate of ``X^_0 = F_S C_v`` (Eq. (A.2)), so that ``rtol``/``atol`` of the
step-size controller act on quantities of the size of the static mesh deflection.

Outputs
-------
Mesh force: reference ``sum_i k_i max(0, V(M_i)^T X - de_i)``; te/perturbation Eq. (41)
``F_D = F_S + k(theta) V^T (X - X_S)`` with ``V^T X_S = v_x0 + cos b_b (TE_S - NLTE - w_x0)``
(Eq. (36)). DTE ``= W^T X + NLTE`` (Eq. (10)). Acceleration of the pinion centre along s
(dof v of the pinion node): ``Omega^2 X_v''`` (the Dirac part of NLTE'' excluded).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Literal

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..gears.mesh import Mesh
from ..gears.modifications import ToothModifications
from ..gears.quasistatic import contact_gaps, static_mesh_force
from ..structure.element import PinionGearElement
from .torsional import (
    _EV_FIXED,
    AngleMap,
    ModelError,
    ModelOutputs,
    PeriodicHermiteTable,
    _event_kinds,
    _quiet_origin,
    check_event_roots,
    moved_event_angles,
    switch_value,
    unilateral_solve_pairwise,
)

__all__ = [
    "Geared3DModel",
    "Condensation",
    "QuasiStatic3D",
    "quasi_static_3d",
    "MESH_VECTORS",
    "default_max_frequency_hz",
]

# default modal cut-off of the 3D model: 3 mesh harmonics of the highest speed x 1.5
# (benchmarks/bench_cutoff.py, results/cutoff.md; see default_max_frequency_hz)
CUTOFF_MESH_HARMONICS = 3
CUTOFF_MARGIN = 1.5
CUTOFF_FLOOR_HZ = 6000.0


def default_max_frequency_hz(max_speed_rad_s: float, z1: int, *,
                             n_harmonics: int = CUTOFF_MESH_HARMONICS,
                             margin: float = CUTOFF_MARGIN,
                             floor_hz: float = CUTOFF_FLOOR_HZ) -> float:
    """Modal cut-off (Hz) of the reduced 3D model for pinion speeds up to
    ``max_speed_rad_s`` (rad/s): ``max(floor_hz, margin * n_harmonics * f_m)`` with the
    mesh frequency of the highest speed ``f_m = z1 Omega_max / (2 pi)`` (Hz, ``z1`` pinion
    teeth).

    The reduced model keeps the modes of ``(M, K_bar)`` below the cut-off plus static
    corrections (the static mesh response, ``X_0``, ``X_S`` and ``C_v`` of Eqs. (33)-(36),
    stays exact), so a dropped mode at ``f_j`` only loses its dynamic amplification at
    the mesh harmonics ``h f_m``; the margin keeps the modes just above the highest
    harmonic of interest, which that harmonic excites nearly resonantly.

    Measured (``benchmarks/bench_cutoff.py``, ``benchmarks/results/cutoff.md``: spur rig,
    te Eq. (42), short relief, zeta 0.1, steady state by shooting, against all 258 modes):
    with the cut-off 3 x 1.5 = 4.5 f_m of the top speed of the range the dynamic factor
    moves by 3.6e-5 / 1.6e-4 / 6.3e-6 and the DTE peak-to-peak by 5.9e-4 / 1.1e-4 / 3e-7
    at 300 / 860 / 1500 rad/s; 3 or 4 f_m without margin move K_v by up to 1.9e-3 / 3.2e-3
    (300 rad/s: the 4th harmonic just below modes at 5.05-5.14 kHz), the former fixed
    6 kHz by 7.5e-4 / 1.7e-3 / 4.4e-3. The error is not monotone in the cut-off at low
    speed (300 rad/s: 4.5 f_m 3.6e-5, 6 kHz = 4.8 f_m 7.5e-4): high mesh harmonics reach
    the modes above it. Lower speeds of a range see more harmonics below the cut-off
    (300 rad/s with the 16.8 kHz of the default sweep to 900 rad/s: 4.9e-5).
    ``floor_hz`` (the former fixed 6 kHz) keeps ranges below 322 rad/s (z1 = 26)
    unchanged. Cost at 900 rad/s (16.8 kHz: 146 modal coordinates against 91 at 6 kHz):
    a transient ``sweep`` 4.8 s against 2.8 s per speed, shooting 5.3 s against 2.1 s.
    """
    f_mesh_hz = z1 * float(max_speed_rad_s) / (2 * math.pi)
    return max(float(floor_hz), margin * n_harmonics * f_mesh_hz)


FORMULATIONS = ("reference", "te", "perturbation")
MESH_VECTORS = ("cells", "mean")
Formulation = Literal["reference", "te", "perturbation"]


# ====================================================================== quasi-static
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
        into K, -1 for a clamped element dof, whose component then stays zero).

        With ``k_m`` and ``v_local`` (12,) also fills ``x0_local`` (element dofs of
        ``K_bar^-1 F_0``); otherwise it is zero.
        """
        pos = np.asarray(element_dofs, dtype=int)
        keep = pos >= 0 if free12 is None else np.asarray(free12, dtype=bool)
        c = _condense(np.asarray(K, float), np.asarray(F0, float), np.asarray(W, float), pos, keep)
        if k_m is not None:
            v = np.asarray(v_local, float) * keep
            x0 = np.linalg.solve(np.asarray(c.k_cc) + k_m * np.outer(v, v), np.asarray(c.f_c))
            c = dataclasses.replace(c, x0_local=jnp.asarray(x0))
        return c


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
    iterations : active-set iterations used (0 for ``"mean"`` vectors).
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


def _active_set_solve(cond: Condensation, vecs, k, de, active0, max_iter: int):
    """Exact unilateral contact on the condensed 12-dof system (Eq. (25)).

    Returns (x, active, iterations, converged); ``x`` is a final solve with the converged
    active set (no gradient through the set itself)."""

    def solve(active):
        ka = jnp.where(active, k, 0.0)
        kt = cond.k_cc + (vecs.T * ka[None, :]) @ vecs
        rhs = cond.f_c + vecs.T @ (ka * de)
        return jnp.linalg.solve(kt, rhs)

    def new_set(x):
        return (k > 0) & (vecs @ x - de > 0)

    def body(c):
        active, _, it = c
        nxt = new_set(solve(active))
        return nxt, jnp.any(nxt != active), it + 1

    def cond_fn(c):
        return c[1] & (c[2] < max_iter)

    active, changed, it = jax.lax.while_loop(
        cond_fn, body, (active0, jnp.asarray(True), jnp.asarray(0))
    )
    active = jax.lax.stop_gradient(active)
    x = solve(active)
    return x, active, it, ~changed


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
    x, active, it, ok = _active_set_solve(cond, vecs, k, de, active0, max_iter)
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


# ====================================================================== the model
class _Ecc(eqx.Module):
    """Eccentricity data: masses (kg), amplitudes (m), phases (rad)."""

    masses_kg: jax.Array
    e_m: jax.Array
    phase_rad: jax.Array


class Geared3DModel(eqx.Module):
    """3D geared system, Eqs. (14), (42), (48a); simulation interface of
    :mod:`gearjax.dynamics.simulate` (``prepare``, ``initial_state``, ``vector_field``, ``outputs``,
    ``decay_rate_per_rad``, ``period_rad``, ``mesh_period_rad``, ``jump_thetas``,
    ``static_force_N``, ``formulation``). Build with :meth:`build` (or :meth:`baud_velex`).

    Array attributes (modal basis ``T``, r columns; element dofs ``l``)
    ------------------------------------------------------------------
    mesh, mods, element : mesh model, tooth modifications, pinion-gear element (on the free
        dofs).
    t_local : (12, r) rows of ``T`` at the element dofs.
    kbar_r : (r, r) ``T^T K_bar T`` (diagonal up to round-off).
    c_r : (r, r) ``T^T C T``.
    omega_r : (r,) ``sqrt(diag(kbar_r))`` (rad/s), for the state scaling.
    v_r, w_r, acc_r : (r,) ``T^T V``, ``T^T W`` and the row of ``T`` at the pinion v dof.
    e_r : (r,) ``T^T E`` (constant part of E), zeros when unused.
    q0 : (r,) modal coordinates of ``X_0 = K_bar^-1 F_0``.
    c_v_r : (r,) modal coordinates of ``C_v = K_bar^-1 V``.
    v_local : (12,) averaged structure vector ``V`` at the element dofs.
    free12 : (12,) 1 for free element dofs, 0 for clamped ones.
    cond : :class:`Condensation` for the quasi-static solve.
    k_m : mean loaded quasi-static stiffness (N/m), the splitting constant of K_bar.
    pinion_torque_Nm, damping_ratio, scale_a : C_m0 (N m), zeta, state scale ``a``.
    ecc : eccentricity data or None.

    Static attributes
    -----------------
    formulation, mesh_vectors, nlte_terms, n_modes, n_static, period_rad, jump_thetas,
    decay_omega_rad_s (slowest mode with a mesh participation above ``participation_tol``),
    qs_max_iter.
    """

    mesh: Mesh
    mods: ToothModifications
    element: PinionGearElement
    t_local: jax.Array
    kbar_r: jax.Array
    c_r: jax.Array
    omega_r: jax.Array
    v_r: jax.Array
    w_r: jax.Array
    acc_r: jax.Array
    e_r: jax.Array
    q0: jax.Array
    c_v_r: jax.Array
    v_local: jax.Array
    free12: jax.Array
    cond: Condensation
    k_m: jax.Array
    pinion_torque_Nm: jax.Array
    damping_ratio: jax.Array
    scale_a: jax.Array
    ecc: _Ecc | None
    table_knots: jax.Array | None
    table_cell_first: jax.Array | None
    table_side: jax.Array | None
    table: PeriodicHermiteTable | None
    formulation: str = eqx.field(static=True)
    mesh_vectors: str = eqx.field(static=True)
    nlte_terms: bool = eqx.field(static=True)
    n_modes: int = eqx.field(static=True)
    n_static: int = eqx.field(static=True)
    period_rad: float = eqx.field(static=True)
    jump_thetas: tuple = eqx.field(static=True)
    decay_omega_rad_s: float = eqx.field(static=True)
    qs_max_iter: int = eqx.field(static=True)
    table_origin: float = eqx.field(static=True, default=0.0)
    table_cells: int = eqx.field(static=True, default=0)
    table_max_extra: int = eqx.field(static=True, default=1)
    excitation: str = eqx.field(static=True, default="table")
    harmonic_start: bool = eqx.field(static=True, default=False)
    event_thetas: tuple = eqx.field(static=True, default=())
    event_kinds: tuple = eqx.field(static=True, default=())
    event_cells: tuple = eqx.field(static=True, default=())
    angle_map: AngleMap | None = None
    table_codes: jax.Array | None = None
    structure_ok: jax.Array | None = None

    # ------------------------------------------------------------------ construction
    @classmethod
    def build(
        cls,
        structure,
        mesh: Mesh,
        mods: ToothModifications | None = None,
        *,
        pinion_torque_Nm: float = 254.8,
        torque_node: int | None = None,
        encoder_nodes: tuple[int, int] | None = None,
        damping_ratio: float = 0.03,
        formulation: Formulation = "reference",
        mesh_vectors: str = "cells",
        nlte_terms: bool | None = None,
        max_frequency_hz: float | None = None,
        fixed_dofs=(),
        eccentric_masses_kg=None,
        mean_stiffness_N_per_m: float | None = None,
        n_table: int = 256,
        participation_tol: float = 1e-3,
        qs_max_iter: int = 30,
        excitation: str = "table",
        harmonic_start: bool = False,
    ) -> "Geared3DModel":
        """Build a 3D model (outside ``jit``: checks, modal basis, k_m, jump angles).

        Parameters
        ----------
        structure : :class:`gearjax.structure.Structure` with ``pinion_node`` and
            ``gear_node`` set; ``K`` must leave the pinion shaft line free in torsion (the
            motor torque is imposed, the resisting load is a torsional stiffness on the
            gear line), so that ``K_bar = K + k_m V V^T`` is invertible.
        mesh : the mesh model.
        mods : tooth modifications (default none).
        pinion_torque_Nm : motor torque C_m0 (N m), > 0; F_S = C_m0 / (Rb1 cos b_b).
        torque_node : node whose torsional dof carries C_m0 (default the pinion node; the
            Baud-Velex rig uses its motor node).
        encoder_nodes : nodes (I, II) of the TE encoders (Eq. (9)); default the pinion and
            gear nodes (Fig. 7 position 1).
        damping_ratio : unique modal damping factor zeta in [0, 1).
        formulation : ``"reference"`` (Eq. (14)), ``"te"`` (Eq. (42)) or
            ``"perturbation"`` (Eq. (48a)).
        mesh_vectors : ``"cells"`` (V(M_i), paper) or ``"mean"`` (averaged V everywhere:
            the reference contact and the quasi-static TE_S then use V, Eq. (27)).
        nlte_terms : keep NLTE in the equations (default: unless NLTE is identically zero).
        max_frequency_hz : modal cut-off (Hz); None keeps all modes (exact).
        fixed_dofs : dof indices clamped to zero (removed), e.g. to make a torsional-only
            structure.
        eccentric_masses_kg : (m1, m2) for the eccentricity terms; default the masses of
            the discs at the pinion and gear nodes.
        mean_stiffness_N_per_m : k_m (N/m) of ``K_bar = K + k_m V V^T``; default the mean
            of the loaded quasi-static stiffness over the ``n_table`` scan. The te
            formulation is exact for any k_m (it only splits k(theta)); the perturbation
            formulation and the damping use it as the mean mesh stiffness.
        n_table : samples per mesh period for k_m and the jump scan.
        participation_tol : modes whose share of the static mesh compliance
            ``(phi^T V)^2 / omega^2 / C_vv`` is below this are ignored when sizing the
            transient (:meth:`decay_rate_per_rad`).
        qs_max_iter : maximum active-set iterations of the quasi-static solve.
        excitation : te/perturbation only: ``"table"`` (default) tabulates ``TE_S - NLTE -
            w_x0``, ``k(theta)`` and NLTE once (in :meth:`prepare`, inside ``jit``, so they
            stay differentiable in the modifications) on a jump-aware periodic Hermite
            table, or ``"inline"`` solves the quasi-static contact at every right-hand side
            (slow with ``"cells"`` vectors; kept to check the table).
        harmonic_start : perturbation without NLTE/eccentricity terms: start exactly on the
            periodic steady state (:meth:`harmonic_state`, see :attr:`periodic_start`).

        Raises
        ------
        ModelError
            naming the field, its value and the reason.
        """
        from ..structure import reduced_model

        if formulation not in FORMULATIONS:
            raise ModelError("formulation", formulation, f"must be one of {FORMULATIONS}")
        if mesh_vectors not in MESH_VECTORS:
            raise ModelError("mesh_vectors", mesh_vectors, f"must be one of {MESH_VECTORS}")
        if excitation not in ("table", "inline"):
            raise ModelError("excitation", excitation, "must be 'table' or 'inline'")
        if mods is None:
            mods = ToothModifications.none()
        mods.check_against(mesh.pair)
        torque = float(pinion_torque_Nm)
        if not (math.isfinite(torque) and torque > 0):
            raise ModelError("pinion_torque_Nm", pinion_torque_Nm, "must be finite and > 0")
        zeta = float(damping_ratio)
        if not (math.isfinite(zeta) and 0.0 <= zeta < 1.0):
            raise ModelError("damping_ratio", damping_ratio, "must lie in [0, 1)")
        if structure.pinion_node is None or structure.gear_node is None:
            raise ModelError("structure", "pinion_node/gear_node", "set them with set_pinion_node/set_gear_node")
        pn, gn = structure.pinion_node, structure.gear_node
        torque_node = pn if torque_node is None else int(torque_node)
        enc = (pn, gn) if encoder_nodes is None else tuple(int(n) for n in encoder_nodes)
        n_all = structure.n_dof
        for name, node in (("torque_node", torque_node), ("encoder_nodes[0]", enc[0]), ("encoder_nodes[1]", enc[1])):
            if not 0 <= node < structure.n_nodes:
                raise ModelError(name, node, f"not a node of the structure (0..{structure.n_nodes - 1})")
        M_all = np.asarray(structure.M, dtype=float)
        K_all = np.asarray(structure.K, dtype=float)
        fixed = np.unique(np.asarray(fixed_dofs, dtype=int))
        if fixed.size and (fixed.min() < 0 or fixed.max() >= n_all):
            raise ModelError("fixed_dofs", fixed_dofs, f"indices must lie in [0, {n_all})")
        free = np.setdiff1d(np.arange(n_all), fixed)
        pos = -np.ones(n_all, dtype=int)
        pos[free] = np.arange(free.size)
        n = free.size
        M, K = M_all[np.ix_(free, free)], K_all[np.ix_(free, free)]
        loc_all = np.concatenate([6 * pn + np.arange(6), 6 * gn + np.arange(6)])
        loc_free = loc_all[pos[loc_all] >= 0]
        keep12 = pos[loc_all] >= 0  # which of the 12 element components are free

        pair = mesh.pair
        rb1, rb2 = pair.base_radii_m
        f_s = static_mesh_force(pair, torque)

        # element on the full numbering; vectors are restricted to the free dofs below
        el = PinionGearElement.at_nodes(mesh, n_all, pn, gn)
        v_loc12 = np.asarray(eqx.filter_jit(lambda e: e.mean_local_vector())(el))
        mask12 = keep12.astype(float)

        def to_free(vec_all):
            return np.asarray(vec_all)[free]

        tors = lambda node: 6 * node + 5  # noqa: E731
        for name, d in (("torque_node", tors(torque_node)), ("encoder_nodes[0]", tors(enc[0])),
                        ("encoder_nodes[1]", tors(enc[1]))):
            if pos[d] < 0:
                raise ModelError(name, d // 6, "its torsional dof is fixed")
        F0 = np.zeros(n)
        F0[pos[tors(torque_node)]] = torque
        W = np.zeros(n)
        W[pos[tors(enc[0])]] += rb1
        W[pos[tors(enc[1])]] += rb2
        V = np.zeros(n)
        V[pos[loc_free]] = v_loc12[keep12]

        # pinion line must be torsionally free in K (imposed motor torque)
        lines = structure.node_lines
        r1 = np.zeros(n_all)
        r2 = np.zeros(n_all)
        for node, ln in enumerate(lines):
            if ln == lines[pn]:
                r1[tors(node)] = 1.0
            if ln == lines[gn]:
                r2[tors(node)] = 1.0
        r1f, r2f = to_free(r1), to_free(r2)
        kscale = np.abs(K).max() if np.abs(K).max() > 0 else 1.0
        if np.abs(K @ r1f).max() > 1e-9 * kscale:
            raise ModelError(
                "structure.K", f"line {lines[pn]!r}",
                "the pinion shaft line must be free in torsion (motor torque imposed, "
                "resisting load a torsional stiffness on the gear line), Section 6.1",
            )

        # quasi-static scan with the condensed structure -> k_m
        cond = _condense(K, F0, W, pos[loc_all], keep12)
        period = mods.excitation_period_rad(pair)
        n_mesh = int(round(period / pair.mesh_period_rad))
        n_tab = int(n_table) * n_mesh
        if int(n_table) < 16:
            raise ModelError("n_table", n_table, "must be >= 16 samples per mesh period")
        theta_tab = np.arange(n_tab) * (period / n_tab)
        qs_fn = jax.jit(jax.vmap(lambda t: quasi_static_3d(
            cond, el, mods, t, f_s, jnp.asarray(v_loc12 * mask12), mesh_vectors, qs_max_iter,
            jnp.asarray(mask12))))
        qs = qs_fn(jnp.asarray(theta_tab))
        if not bool(np.all(np.asarray(qs.converged))):
            bad = theta_tab[~np.asarray(qs.converged)]
            raise ModelError("qs_max_iter", qs_max_iter, f"active set did not converge at theta={bad[:3]}")
        k_m = float(np.mean(np.asarray(qs.loaded_stiffness_N_per_m)))
        if mean_stiffness_N_per_m is not None:
            k_m = float(mean_stiffness_N_per_m)
            if not (math.isfinite(k_m) and k_m > 0):
                raise ModelError("mean_stiffness_N_per_m", mean_stiffness_N_per_m, "must be finite and > 0")
        nlte_tab = np.asarray(qs.nlte_m)
        if nlte_terms is None:
            nlte_terms = bool(np.max(np.abs(nlte_tab - 0.0)) > 0.0)

        v12 = v_loc12 * mask12
        x0_loc = np.linalg.solve(np.asarray(cond.k_cc) + k_m * np.outer(v12, v12), np.asarray(cond.f_c))
        cond = dataclasses.replace(cond, x0_local=jnp.asarray(x0_loc))

        # modal basis of (M, K_bar)
        kbar = K + k_m * np.outer(V, V)
        E = np.zeros(n)
        if nlte_terms:
            j2 = r2f @ M @ r2f
            E = M @ r2f / rb2
            E[pos[tors(torque_node)]] += j2 * rb1 / rb2**2
        unit = np.zeros((n, loc_free.size))
        unit[pos[loc_free], np.arange(loc_free.size)] = 1.0
        loads = np.concatenate([F0[:, None], E[:, None], V[:, None], unit], axis=1)
        red = reduced_model(M, kbar, loads, max_frequency_hz=max_frequency_hz, zeta=zeta)
        T = np.asarray(red.basis)
        kbar_r = np.asarray(red.K)
        t12 = np.zeros((12, T.shape[1]))
        t12[keep12] = T[pos[loc_free]]
        v_r = T.T @ V
        q0 = np.linalg.solve(kbar_r, T.T @ F0)
        c_v_r = np.linalg.solve(kbar_r, v_r)
        omega_r = np.sqrt(np.clip(np.diag(kbar_r), 0.0, None))
        part = v_r**2 / np.where(omega_r > 0, omega_r, np.inf) ** 2
        part = part / part.sum()
        decay_omega = float(np.min(omega_r[part >= participation_tol]))
        acc_dof = pos[6 * pn + 1]
        acc_r = T[acc_dof] if acc_dof >= 0 else np.zeros(T.shape[1])

        ecc = None
        if mods.eccentricity_m is not None and np.any(np.asarray(mods.eccentricity_m) != 0):
            if eccentric_masses_kg is None:
                eccentric_masses_kg = (_disc_mass(structure, pn, M_all), _disc_mass(structure, gn, M_all))
            ecc = _Ecc(jnp.asarray(eccentric_masses_kg, dtype=float), jnp.asarray(mods.eccentricity_m),
                       jnp.asarray(mods.eccentricity_phase_rad))
        scale_a = float(np.max(np.abs(f_s * c_v_r)))

        model = cls(
            mesh=mesh, mods=mods, element=el,
            t_local=jnp.asarray(t12), kbar_r=jnp.asarray(kbar_r), c_r=jnp.asarray(red.C),
            omega_r=jnp.asarray(omega_r), v_r=jnp.asarray(v_r), w_r=jnp.asarray(T.T @ W),
            acc_r=jnp.asarray(acc_r), e_r=jnp.asarray(T.T @ E), q0=jnp.asarray(q0),
            c_v_r=jnp.asarray(c_v_r), v_local=jnp.asarray(v_loc12 * mask12),
            free12=jnp.asarray(mask12), cond=cond,
            k_m=jnp.asarray(k_m), pinion_torque_Nm=jnp.asarray(torque),
            damping_ratio=jnp.asarray(zeta), scale_a=jnp.asarray(scale_a), ecc=ecc,
            formulation=formulation, mesh_vectors=mesh_vectors, nlte_terms=bool(nlte_terms),
            n_modes=int(red.n_modes), n_static=int(red.n_static), period_rad=float(period),
            jump_thetas=(), decay_omega_rad_s=decay_omega, qs_max_iter=int(qs_max_iter),
            table_knots=None, table_cell_first=None, table_side=None, table=None,
            excitation=excitation, harmonic_start=bool(harmonic_start),
        )
        lo, hi = _jump_brackets(model, theta_tab)
        jumps = _bracket_midpoints(lo, hi, period)
        model = dataclasses.replace(model, jump_thetas=tuple(float(t) for t in jumps))
        if formulation != "reference" and excitation == "table":
            # brackets again, bisected *in table coordinates* [origin, origin + P): folding
            # adjacent floats near 0 into the table would merge them
            origin = _quiet_origin(jumps, period)
            lo_u, hi_u, *codes = _jump_brackets(model, origin + theta_tab, kinks=True,
                                                codes=True)
            knots, cell_first, max_extra = PeriodicHermiteTable.layout(
                origin, period, n_tab, np.concatenate([lo_u, hi_u]))
            side = np.zeros(knots.shape)
            side[np.isin(knots, lo_u)] = -1.0
            side[np.isin(knots, hi_u)] = 1.0
            model = dataclasses.replace(
                model, table_knots=jnp.asarray(knots), table_cell_first=jnp.asarray(cell_first, dtype=jnp.int32),
                table_side=jnp.asarray(side), table_origin=float(origin), table_cells=n_tab,
                table_max_extra=int(max_extra))
            # events of the table move with the design (module docstring)
            model = dataclasses.replace(model, **_moving_events(lo_u, hi_u, *codes,
                                                                mesh.n_cells, period))
            kinds, cells = check_event_roots(_bare(model)._switch_function, model.event_thetas,
                                             model.event_kinds, model.event_cells,
                                             mesh.pair.mesh_period_rad)
            model = dataclasses.replace(model, event_kinds=tuple(int(k) for k in kinds),
                                        event_cells=tuple((int(a), int(b)) for a, b in cells))
            if model.event_thetas:  # discrete state on each knot's side (prepare checks it)
                at = jnp.asarray(knots + side * (1e-9 * period))
                model = dataclasses.replace(model, table_codes=_state_codes(_bare(model), at, True))
        return model

    @classmethod
    def baud_velex(
        cls,
        helical: bool = False,
        mods: ToothModifications | None = None,
        *,
        law: str = "iso6336",
        cells_per_line: int | None = None,
        encoder_position: int = 1,
        **kwargs,
    ) -> "Geared3DModel":
        """The Baud & Velex rig of Section 6.1 (258 dof, Table 1 gears, Table 2 bearings,
        254.8 N m on the motor node); ``kwargs`` go to :meth:`build`."""
        from ..gears.geometry import baud_velex_pair
        from ..rigs.baud_velex import MOTOR_NODE, baud_velex_structure, encoder_nodes

        mesh = Mesh.build(baud_velex_pair(helical), law, cells_per_line=cells_per_line)
        kwargs.setdefault("torque_node", MOTOR_NODE)
        kwargs.setdefault("encoder_nodes", encoder_nodes(encoder_position))
        return cls.build(baud_velex_structure(), mesh, mods, **kwargs)

    @classmethod
    def from_rig(
        cls,
        rig,
        mods: ToothModifications | None = None,
        *,
        law: str = "iso6336",
        cells_per_line: int | None = None,
        encoder_position: int = 1,
        mesh: Mesh | None = None,
        **kwargs,
    ) -> "Geared3DModel":
        """A 3D model of a :class:`gearjax.rigs.registry.Rig` (built-in or rig file): its structure,
        gear pair, motor node, torque and encoder positions; ``mesh`` (default: built from
        the rig's pair with ``law`` and ``cells_per_line``) a ready mesh of that pair;
        ``kwargs`` go to :meth:`build`."""
        if mesh is None:
            mesh = Mesh.build(rig.pair, law, cells_per_line=cells_per_line)
        kwargs.setdefault("torque_node", rig.torque_node)
        kwargs.setdefault("encoder_nodes", rig.encoder_nodes(encoder_position))
        kwargs.setdefault("pinion_torque_Nm", rig.pinion_torque_Nm)
        return cls.build(rig.structure(), mesh, mods, **kwargs)

    # ------------------------------------------------------------------ constants
    @property
    def cos_bb(self) -> float:
        return math.cos(self.mesh.pair.base_helix_angle_rad)

    @property
    def mesh_period_rad(self) -> float:
        """One mesh period in theta, 2 pi / z1 (rad)."""
        return self.mesh.pair.mesh_period_rad

    @property
    def static_force_N(self):
        """F_S = C_m0 / (Rb1 cos b_b) (N)."""
        return self.pinion_torque_Nm / (self.mesh.pair.base_radii_m[0] * self.cos_bb)

    @property
    def output_names(self) -> tuple[str, ...]:
        return ("mesh_force_N", "dte_m", "accel_m_s2")

    @property
    def n_reduced(self) -> int:
        """Number of modal coordinates r (modes + static-correction pseudo-modes)."""
        return int(self.omega_r.shape[0])

    @property
    def v_x0(self):
        """V^T X_0 (m), = F_S / k_m (Eq. (34))."""
        return self.v_r @ self.q0

    @property
    def w_x0(self):
        """W^T X_0 (m), Eq. (30)."""
        return self.w_r @ self.q0

    @property
    def c_wv(self):
        """C_wv = W^T K_bar^-1 V, = 1 / (k_m cos b_b) (Eq. (35))."""
        return self.w_r @ self.c_v_r

    @property
    def c_vv(self):
        """C_vv = V^T K_bar^-1 V, = 1 / k_m (Eq. (33))."""
        return self.v_r @ self.c_v_r

    def prepare(self) -> "Geared3DModel":
        """Fill the excitation table of the te/perturbation formulations (``excitation=
        "table"``): exact quasi-static solves at the knots, slopes by forward-mode AD, the
        knots bracketing every jump of ``k(theta)`` and kink of ``TE_S``/NLTE evaluated on
        their own side. With moving events the table holds
        ``q(phi(s))`` in the simulation angle ``s`` (:attr:`angle_map`, module docstring
        "Derivatives with respect to the design"). Call inside ``jit`` (simulate does) so
        that the table stays a differentiable function of the model data; idempotent.
        Other models: ``self``."""
        if self.table is not None or self.table_knots is None:
            return self
        delta = 1e-9 * self.period_rad
        amap = self._angle_map() if self.event_thetas else None

        if amap is None:
            def one(t, side):
                v, d = jax.jvp(self._excitation_exact, (t + side * delta,), (jnp.ones_like(t),))
                return v - side * delta * d, d  # back to the knot
        else:
            def one(t, side):
                def f(s):
                    return self._excitation_exact(amap(s)[0] + side * delta)

                v, d = jax.jvp(f, (t,), (jnp.ones_like(t),))
                return v - side * delta * d / amap(t)[1], d

        vals, slopes = jax.vmap(one)(self.table_knots, self.table_side)
        table = PeriodicHermiteTable(
            knots=self.table_knots, values=vals, slopes=slopes, cell_first=self.table_cell_first,
            origin=self.table_origin, period=self.period_rad, n_cells=self.table_cells,
            max_extra=self.table_max_extra)
        m = eqx.tree_at(lambda m: m.table, self, table, is_leaf=lambda x: x is None)
        if amap is not None:
            m = eqx.tree_at(lambda m: m.angle_map, m, amap, is_leaf=lambda x: x is None)
        if self.table_codes is not None:
            # the design keeps the discrete structure the table was built with: same
            # quasi-static state on each side of every mapped knot (else rebuild)
            at = (jax.vmap(amap)(self.table_knots)[0] if amap is not None
                  else self.table_knots) + self.table_side * delta
            codes = jax.vmap(lambda t: _state_code(self, t, True))(at)
            m = eqx.tree_at(lambda m: m.structure_ok, m, jnp.all(codes == self.table_codes),
                            is_leaf=lambda x: x is None)
        return m

    # ------------------------------------------------------------------ moving events
    def _switch_function(self, kind, a, b, theta):
        """g(theta) whose root is the angle of an event of ``kind`` (same kinds as
        :meth:`gearjax.models.torsional.TorsionalModel._switch_function`): loaded set
        (cell a): ``V_a^T x_S - de_a`` (approach = gap in the 3D quasi-static solution,
        Eq. (25)); NLTE cell (a -> b): ``r_a - r_b``; pinion / gear relief start (cell a):
        ``xi_a - (xi_e - L_c1 g_alpha)`` / ``xi_a - (xi_start + L_c2 g_alpha)``."""
        cells, de, _ = contact_gaps(self.mesh, self.mods, theta)
        x = self.quasi_static(theta).x_local
        return switch_value(self.mesh, self.mods, cells, theta,
                            self._vectors(cells)[a] @ x - de[a], kind, a, b)

    def jump_angles_rad(self, newton_steps: int = 4):
        """The event angles ``theta_j`` (rad) of the current design, one per entry of
        :attr:`event_thetas`: Newton iterations on :meth:`_switch_function` from the
        build-time angle (geometric events stay fixed); differentiable in the modifications
        (at the root ``d theta_j = -(dg/d design) / (dg/d theta)``)."""
        return moved_event_angles(self._switch_function, self.event_thetas, self.event_kinds,
                                  self.event_cells, newton_steps)

    def _angle_map(self) -> AngleMap:
        return AngleMap.through(self.event_thetas, self.jump_angles_rad(), self.period_rad)

    def angle(self, s):
        """(theta, dtheta/ds): the pinion angle (rad) at the simulation angle ``s`` (rad);
        ``(s, None)`` without moving events. Identity at the build-time design."""
        if self.angle_map is None:
            return s, None
        return self.angle_map(s)

    # ------------------------------------------------------------------ quasi-static
    def quasi_static(self, theta) -> QuasiStatic3D:
        """Quasi-static 3D solution (Eq. (25)) at ``theta`` (scalar; vmap for several)."""
        return quasi_static_3d(self.cond, self.element, self.mods, theta, self.static_force_N,
                               self.v_local, self.mesh_vectors, self.qs_max_iter, self.free12)

    def _excitation(self, theta):
        """(d, k) with d = TE_S - NLTE - w_x0 (or TE_S - w_x0 without NLTE terms) and the
        loaded quasi-static stiffness k(theta), for te/perturbation (tabulated after
        :meth:`prepare`, else exact)."""
        if self.table is not None:
            vals, _ = self.table(theta)
            return vals[0], vals[1]
        d, k, _ = self._excitation_exact(theta)
        return d, k

    def _excitation_exact(self, theta):
        """(d, k, NLTE) from the exact quasi-static solve at ``theta`` (stacked (3,))."""
        d, k = self._excitation_solve(theta)
        nlte = contact_gaps(self.mesh, self.mods, theta)[2]
        return jnp.stack([d, k, nlte])

    def _excitation_solve(self, theta):
        if self.mesh_vectors == "mean":
            # exact shortcut: V^T X_S is the torsional root (total mesh force F_S), and
            # X_S = X_0 + phi C_v (Eq. (29)) gives TE_S - NLTE = w_x0 + phi C_wv.
            cells, de, nlte = contact_gaps(self.mesh, self.mods, theta)
            y, k_s = unilateral_solve_pairwise(cells.stiffness_N_per_m, de, self.static_force_N)
            d = (y - self.v_x0) / self.c_vv * self.c_wv
            if not self.nlte_terms:
                d = d + nlte
            return d, k_s
        qs = self.quasi_static(theta)
        d = self.cond.g_w @ (qs.x_local - self.cond.x0_local)  # W^T (X_S - X_0)
        if not self.nlte_terms:
            d = d + qs.nlte_m
        return d, qs.loaded_stiffness_N_per_m

    def _static_q(self, theta):
        """Modal coordinates of the quasi-static X_S seen by this formulation."""
        if self.formulation == "reference":
            # K X_S = F_0 - f_mesh with K = K_bar - k_m V V^T and V^T X_S = V_l^T x_l
            qs = self.quasi_static(theta)
            cells, _, _ = contact_gaps(self.mesh, self.mods, theta)
            f_loc = self._vectors(cells).T @ qs.cell_load_N
            rhs = -(self.t_local.T @ f_loc) + self.k_m * self.v_r * (self.v_local @ qs.x_local)
            return self.q0 + jnp.linalg.solve(self.kbar_r, rhs)
        d, _ = self._excitation(theta)
        return self.q0 + d / self.c_wv * self.c_v_r

    # ------------------------------------------------------------------ excitation vectors
    def _vectors(self, cells):
        if self.mesh_vectors == "cells":
            return self.element.cell_vectors(cells) * self.free12[None, :]
        return jnp.broadcast_to(self.v_local, (cells.xi_m.shape[0], 12))

    def _ecc_local(self, theta):
        """(E~, F~, G~) at the 12 element dofs (Eq. (14), see module docstring)."""
        ecc = self.ecc
        rb1, rb2 = self.mesh.pair.base_radii_m
        m1, m2 = ecc.masses_kg[0], ecc.masses_kg[1]
        e1, e2 = ecc.e_m[0], ecc.e_m[1]
        psi1 = theta - ecc.phase_rad[0] - 0.5 * math.pi
        psi2 = ecc.phase_rad[1] - 0.5 * math.pi - theta * rb1 / rb2
        z = jnp.zeros(())
        c2, s2 = jnp.cos(psi2), jnp.sin(psi2)
        # node order (u, v, w, ...): v along s, w along t
        e_loc = jnp.stack([z, z, z, z, z, z, z, -m2 * e2 / rb2 * s2, m2 * e2 / rb2 * c2, z, z, z])
        f_loc = jnp.stack([z] * 7 + [2 * m2 * e2 * rb1 / rb2**2 * c2, 2 * m2 * e2 * rb1 / rb2**2 * s2, z, z, z])
        g2 = m2 * e2 * (rb1 / rb2) ** 2
        g_loc = jnp.stack([z, -m1 * e1 * jnp.cos(psi1), -m1 * e1 * jnp.sin(psi1), z, z, z,
                           z, -g2 * c2, -g2 * s2, z, z, z])
        return e_loc, f_loc, g_loc

    def _inertial(self, theta):
        """(e(theta), e'(theta), f(theta), g(theta)) in modal coordinates; None when absent."""
        use_e = self.nlte_terms
        if self.ecc is None:
            e = self.e_r if use_e else None
            return e, (jnp.zeros_like(self.e_r) if use_e else None), None, None
        tl = self.t_local.T

        def e_fun(t):
            return self.e_r + tl @ self._ecc_local(t)[0]

        _, f_loc, g_loc = self._ecc_local(theta)
        g = tl @ g_loc
        if not use_e:
            return None, None, None, g
        e, ep = jax.jvp(e_fun, (theta,), (jnp.ones_like(theta),))
        return e, ep, tl @ f_loc, g

    def _nlte_derivs(self, s, order: int = 1):
        """NLTE and its derivatives with respect to theta (1 or 2) at the simulation angle
        ``s`` (chain rule through the angle map: d/dtheta = (d/ds) / phi')."""
        if self.table is not None:
            f = lambda t: self.table(t)[0][2]  # noqa: E731  (exact at the kinks: knots)
        else:
            f = lambda t: contact_gaps(self.mesh, self.mods, t)[2]  # noqa: E731

        def d1(t):
            n0, n1 = jax.jvp(f, (t,), (jnp.ones_like(t),))
            dth = self.angle(t)[1]
            return n0, (n1 if dth is None else n1 / dth)

        if order == 1:
            return d1(s)
        (n0, n1), (_, n2) = jax.jvp(d1, (s,), (jnp.ones_like(s),))
        dth = self.angle(s)[1]
        return n0, n1, (n2 if dth is None else n2 / dth)

    # ------------------------------------------------------------------ dynamics
    def _unscale(self, y, omega):
        r = self.omega_r / omega
        nr = self.n_reduced
        z = y[:nr] * self.scale_a
        u = y[nr:] * r * self.scale_a
        return z, u, r

    def _elastic(self, s, q):
        """(restoring minus static force in modal coordinates, mesh force F_D (N)) at the
        simulation angle ``s``."""
        z = q - self.q0
        f_s = self.static_force_N
        if self.formulation == "reference":  # no angle map: s = theta
            cells, de, _ = contact_gaps(self.mesh, self.mods, s)
            vecs = self._vectors(cells)
            x_loc = self.t_local @ q
            loads = cells.stiffness_N_per_m * jnp.maximum(vecs @ x_loc - de, 0.0)
            f_loc = vecs.T @ loads
            # K q - F0 = K_bar z - k_m V (V^T q) + k_m v_x0 V ... with K_bar q0 = F0
            force = self.kbar_r @ z - self.k_m * self.v_r * (self.v_r @ q) + self.t_local.T @ f_loc
            return force, jnp.sum(loads)
        d, k = self._excitation(s)
        v_q = self.v_r @ q
        v_xs = self.v_x0 + self.cos_bb * d
        f_d = f_s + k * (v_q - v_xs)  # Eq. (41)
        if self.formulation == "te":
            force = (self.kbar_r @ z + (k - self.k_m) * v_q * self.v_r
                     - (k * self.cos_bb * d + (k - self.k_m) * f_s / self.k_m) * self.v_r)
        else:
            force = self.kbar_r @ z - self.k_m * self.cos_bb * d * self.v_r
        return force, f_d

    def _accel(self, s, y, omega):
        """(q, q', u') for the state y at the simulation angle ``s`` (derivatives with
        respect to theta): the equations of motion in modal coordinates."""
        z, u, r = self._unscale(y, omega)
        q = self.q0 + z
        e, ep, f, g = self._inertial(self.angle(s)[0])
        nl1 = None
        if e is not None:
            _, nl1 = self._nlte_derivs(s)
            qp = u - nl1 * e
        else:
            qp = u
        force, _ = self._elastic(s, q)
        up = -(force + omega * (self.c_r @ qp)) / omega**2
        if e is not None:
            up = up + nl1 * ep
            if f is not None:
                up = up - nl1 * f
        if g is not None:
            up = up - g
        return q, qp, up

    def vector_field(self, s, y, omega):
        """d y / d s for the scaled state ``y = ((q - q_0)/a, u/(r a))`` (module
        docstring): ``phi'(s)`` times d y / d theta at ``theta = phi(s)`` (``s = theta``
        at the build-time design); ``omega`` is the pinion speed Omega1 (rad/s)."""
        _, qp, up = self._accel(s, y, omega)
        r = self.omega_r / omega
        dyth = jnp.concatenate([qp / self.scale_a, up / (r * self.scale_a)])
        dth = self.angle(s)[1]
        return dyth if dth is None else dyth * dth

    @property
    def state_size(self) -> int:
        """Length of the scaled state ``y`` (2 r)."""
        return 2 * self.n_reduced

    def homogeneous_vector_field(self, theta, y, omega):
        """The linear part of :meth:`vector_field` (te/perturbation: the right-hand side is
        affine in ``y``), for the Floquet analysis of :mod:`gearjax.dynamics.stability`."""
        if self.formulation == "reference":
            raise ModelError("formulation", "reference", "the contact law is not linear; the "
                             "linearisation about the quasi-static contact is the te formulation")
        return self.vector_field(theta, y, omega) - self.vector_field(theta, jnp.zeros_like(y), omega)

    @property
    def periodic_start(self) -> bool:
        """True when :meth:`initial_state` is already the periodic steady state (opt-in
        ``harmonic_start=True`` at build, perturbation formulation without NLTE and
        eccentricity terms: see :meth:`harmonic_state`), so that no transient needs
        integrating. Opt-in because a chunked 45-speed CLI sweep starting there hung
        (non-deterministically, after 2-3 chunks that each ran in 0.3 s) and the cause is
        not found yet; single speeds and single batches run fine (tests)."""
        return self.harmonic_start and self._constant_coefficients

    @property
    def _constant_coefficients(self) -> bool:
        """Eq. (48a) without NLTE and eccentricity terms, excitation tabulated."""
        return (self.formulation == "perturbation" and not self.nlte_terms and self.ecc is None
                and self.table_knots is not None)

    def harmonic_state(self, omega, theta0=0.0, n_harmonics: int | None = None):
        """Periodic steady state of Eq. (48a) at ``theta0``, exact in the frequency domain.

        Without NLTE and eccentricity terms Eq. (48a) is linear with *constant* coefficients
        and a periodic forcing ``k_m cos(b_b) d(theta) V``, ``d = TE_S - w_x0`` (tabulated), so
        each harmonic ``h`` of the excitation period P answers independently (modal
        coordinates, ``M_r = I``, frequency ``w_h = h (2 pi / P) Omega``)::

            z_h = (K_bar_r - w_h^2 I + i w_h C_r)^-1 k_m cos(b_b) d_h v_r

        with ``d_h`` the discrete Fourier coefficients of the tabulated ``d`` sampled 8 times
        finer than the table (``n_harmonics`` kept, default 128 per mesh period). ``d`` has
        kinks (relief starts, engagements), so ``d_h = O(h^-2)`` and ``z_h = O(h^-4)`` above
        the modes: the sum converges fast. Returns the scaled state (see the module
        docstring). Cost: one complex (r, r) solve per harmonic.
        """
        if not self._constant_coefficients:
            raise ModelError("formulation", self.formulation,
                             "harmonic_state needs the perturbation formulation without NLTE "
                             "or eccentricity terms and with the excitation table")
        m = self.prepare()
        n_mesh = max(1, round(m.period_rad / m.mesh_period_rad))
        n_h = 128 * n_mesh if n_harmonics is None else int(n_harmonics)
        # sample d 8x finer than the table knots: the DFT of a kinked signal aliases at
        # O(N^-2) (measured: 1e-4 of the state at 128 samples per mesh period)
        n = 8 * max(m.table_cells, 2 * n_h + 2)
        period = m.period_rad
        th = m.table_origin + jnp.arange(n) * (period / n)
        d = jax.vmap(lambda t: m._excitation(t)[0])(th)
        c = jnp.fft.rfft(d)[: n_h + 1] / n
        h = jnp.arange(n_h + 1)
        nu = 2.0 * jnp.pi / period
        # coefficients of d(theta) = sum c_h exp(i h nu (theta - origin)), at theta0
        c = c * jnp.exp(1j * h * nu * (jnp.asarray(theta0, dtype=float) - m.table_origin))
        w_h = h * nu * omega
        r = m.n_reduced
        eye = jnp.eye(r)
        a = (m.kbar_r[None] - (w_h**2)[:, None, None] * eye[None]
             + 1j * w_h[:, None, None] * m.c_r[None])
        g = jnp.linalg.solve(a, jnp.broadcast_to(m.v_r.astype(a.dtype), (n_h + 1, r))[..., None])[..., 0]
        z_h = g * (m.k_m * m.cos_bb * c)[:, None]
        weight = jnp.where(h > 0, 2.0, 1.0)[:, None]
        z = jnp.real(jnp.sum(weight * z_h, axis=0))
        zp = jnp.real(jnp.sum(weight * (1j * h * nu)[:, None] * z_h, axis=0))  # d/dtheta
        rr = m.omega_r / omega
        return jnp.concatenate([z / m.scale_a, zp / (rr * m.scale_a)])

    def initial_state(self, omega, theta0=0.0):
        """Scaled state at ``theta0``: the periodic steady state when
        :attr:`periodic_start` (:meth:`harmonic_state`), else the quasi-static solution
        (X_D = X_D' = 0)."""
        if self.periodic_start:
            return self.harmonic_state(omega, theta0)
        theta0 = jnp.asarray(theta0, dtype=float)  # simulation angle s0
        qs, qs_p = jax.jvp(self._static_q, (theta0,), (jnp.ones_like(theta0),))
        th0, dth = self.angle(theta0)
        if dth is not None:
            qs_p = qs_p / dth
        e, _, _, _ = self._inertial(th0)
        u = qs_p
        if e is not None:
            u = u + self._nlte_derivs(theta0)[1] * e
        r = self.omega_r / omega
        return jnp.concatenate([(qs - self.q0) / self.scale_a, u / (r * self.scale_a)])

    def outputs(self, theta, y, omega) -> ModelOutputs:
        """Mesh force F_D (N), DTE = W^T X + NLTE (m) and the pinion-centre acceleration
        along s (m/s^2) at one angle."""
        q, qp, up = self._accel(theta, y, omega)  # theta: the simulation angle s
        _, f_d = self._elastic(theta, q)
        e, ep, _, _ = self._inertial(self.angle(theta)[0])
        qpp = up
        if e is not None:
            _, nl1, nl2 = self._nlte_derivs(theta, order=2)
            qpp = up - nl2 * e - nl1 * ep
        dte = self.w_r @ q
        if self.formulation == "reference" or self.nlte_terms:
            dte = dte + (self.table(theta)[0][2] if self.table is not None
                         else contact_gaps(self.mesh, self.mods, theta)[2])
        return ModelOutputs(mesh_force_N=f_d, dte_m=dte, accel_m_s2=omega**2 * (self.acc_r @ qpp))

    def decay_rate_per_rad(self, omega):
        """``zeta omega_min / Omega`` with ``omega_min`` the slowest mode that takes part in
        the mesh deflection (``participation_tol`` at build)."""
        return self.damping_ratio * self.decay_omega_rad_s / omega


# ---------------------------------------------------------------------- build helpers
def _condense(K, F0, W, loc_pos, keep12) -> Condensation:
    """Condensation on the free element dofs, embedded back into 12 components (fixed
    element dofs get an identity row so that they stay at zero)."""
    loc_free = loc_pos[keep12]
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
            raise ModelError("structure.K", "internal block", "singular once the pinion and gear "
                             "node dofs are held: a shaft line is not supported") from exc
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
    return Condensation(jnp.asarray(0.5 * (K12 + K12.T)), jnp.asarray(f12), jnp.asarray(c_w), jnp.asarray(g12),
                        jnp.zeros(12))


def _disc_mass(structure, node, M_all) -> float:
    for e in structure.elements_of_kind("disc"):
        if node in e.nodes:
            return e.param("mass_kg")
    return float(M_all[6 * node + 1, 6 * node + 1])


def _state_code(model: Geared3DModel, t, kinks: bool):
    """Discrete state at one angle ``t`` (traceable in the design): cells inside the path
    of contact, the cell realising NLTE, with ``kinks`` the cells in the pinion / gear tip
    relief zones (Fig. 4), and (te, perturbation) the quasi-statically loaded cells."""
    mesh, mods = model.mesh, model.mods
    cells, _, _ = contact_gaps(mesh, mods, t)
    r = mesh.removed_material(mods, cells, t)
    arg = jnp.argmin(jnp.where(cells.inside, r, jnp.inf))
    parts = [cells.inside.astype(jnp.int32), arg[None].astype(jnp.int32)]
    if kinks:
        xi_a, xi_e = mesh.pair.contact_limits_m
        ext = mods.relief_extent * mesh.pair.path_of_contact_m
        parts.append((cells.inside & (cells.xi_m > xi_e - ext[0])).astype(jnp.int32))
        parts.append((cells.inside & (cells.xi_m < xi_a + ext[1])).astype(jnp.int32))
    if model.formulation != "reference":
        q = model.quasi_static(t)
        parts.append((q.cell_load_N > 0).astype(jnp.int32))
    return jnp.concatenate(parts)


def _bare(model: Geared3DModel) -> Geared3DModel:
    """``model`` without its design-dependent static fields and tables (jump and event
    angles, table layout): what the build-time quasi-static scans need, so that their
    compiled functions are reused by every build of the same model shape."""
    return dataclasses.replace(model, jump_thetas=(), event_thetas=(), event_kinds=(),
                               event_cells=(), table_knots=None, table_cell_first=None,
                               table_side=None, table=None, table_codes=None, angle_map=None,
                               table_origin=0.0, table_cells=0, table_max_extra=1)


@eqx.filter_jit
def _state_codes(model: Geared3DModel, ts, kinks: bool):
    """:func:`_state_code` at the angles ``ts`` (vmapped; compiled once per model shape)."""
    return jax.vmap(lambda t: _state_code(model, t, kinks))(ts)


def _jump_brackets(model: Geared3DModel, theta, kinks: bool = False, codes: bool = False):
    """Brackets ``(lo, hi)`` (adjacent floats) of the angles where the right-hand side
    jumps or kinks independently of speed: cell engagement/exit, quasi-static active-set
    changes (te, perturbation) and changes of the cell realising NLTE; found on the
    uniform scan grid ``theta`` (one period, any origin) and refined by bisection. With
    ``kinks`` also the angles where a cell enters or leaves a modified zone (kinks of the
    removed material, hence of TE_S: table knots, not integrator jumps). With ``codes``
    also the discrete states at ``lo`` and ``hi`` in the layout of
    :func:`gearjax.models.torsional._code` (NLTE cell, loaded, inside, zone bits) for
    :func:`gearjax.models.torsional._event_kinds`."""
    mesh = model.mesh
    period = model.period_rad
    bare = _bare(model)

    def code_(t):
        return _state_codes(bare, t, kinks)

    def code(t):  # fixed chunks of 32 angles: a single compilation
        t = np.asarray(t, dtype=float)
        n = t.shape[0]
        size = -(-n // 32) * 32
        tp = np.concatenate([t, np.full(size - n, t[0] if n else 0.0)])
        out = [np.asarray(code_(jnp.asarray(tp[i:i + 32]))) for i in range(0, size, 32)]
        return np.concatenate(out)[:n]

    theta = np.asarray(theta, dtype=float)
    c = np.asarray(code(theta))
    changed = np.any(c != np.roll(c, -1, axis=0), axis=1)
    # pending intervals [a, b] whose end codes differ; several changes may share one grid
    # interval (cells of one tooth engaging one after the other), so after each bisection
    # the rest [hi, b] is examined again
    a = theta[changed]
    b = a + period / len(theta)
    code_b = np.roll(c, -1, axis=0)[changed]
    found_lo, found_hi = [], []
    for _ in range(64):  # at most 64 changes inside one grid interval
        if a.size == 0:
            break
        lo, hi, left = a.copy(), b.copy(), np.asarray(code(a))
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            same = np.all(np.asarray(code(mid)) == left, axis=1)
            lo = np.where(same, mid, lo)
            hi = np.where(same, hi, mid)
        found_lo.append(lo)
        found_hi.append(hi)
        more = np.any(np.asarray(code(hi)) != code_b, axis=1)
        a, b, code_b = hi[more], b[more], code_b[more]
    if not found_lo:
        empty = np.zeros(0)
        return (empty, empty, None, None) if codes else (empty, empty)
    lo, hi = np.concatenate(found_lo), np.concatenate(found_hi)
    order = np.argsort(lo)
    lo, hi = lo[order], hi[order]
    if not codes:
        return lo, hi
    n = mesh.n_cells

    def tors_layout(c):  # [inside(n), arg, zone1(n), zone2(n), loaded(n)] -> torsional _code
        inside, arg = c[:, :n], c[:, n:n + 1]
        zone = (np.where(inside > 0, c[:, n + 1:2 * n + 1] + 2 * c[:, 2 * n + 1:3 * n + 1], -1)
                if kinks else np.where(inside > 0, 0, -1))
        loaded = c[:, -n:] if model.formulation != "reference" else np.zeros_like(inside)
        return np.concatenate([arg, loaded, inside, zone], axis=1)

    return lo, hi, tors_layout(np.asarray(code(lo))), tors_layout(np.asarray(code(hi)))


def _moving_events(lo, hi, c_lo, c_hi, n_cells, period) -> dict:
    """The events of the table brackets (sorted, distinct angles in [0, period)) with the
    kind and cells of each (:func:`gearjax.models.torsional._event_kinds`): the nodes of
    the angle map (see :meth:`Geared3DModel.jump_angles_rad`)."""
    ang = np.mod(0.5 * (lo + hi), period)
    order = np.argsort(ang, kind="stable")
    events, kinds, cells = [], [], []
    for i in order:
        kind, a, b = _event_kinds(c_lo[i], c_hi[i], n_cells)
        if events and ang[i] - events[-1] <= 1e-9 * period:
            if kind == _EV_FIXED:  # coinciding events: a geometric one pins the angle
                kinds[-1], cells[-1] = kind, (a, b)
            continue
        events.append(float(ang[i]))
        kinds.append(int(kind))
        cells.append((int(a), int(b)))
    if len(events) > 1 and events[0] + period - events[-1] <= 1e-9 * period:
        events, kinds, cells = events[:-1], kinds[:-1], cells[:-1]
    return dict(event_thetas=tuple(events), event_kinds=tuple(kinds), event_cells=tuple(cells))


def _bracket_midpoints(lo, hi, period) -> np.ndarray:
    """Sorted distinct jump angles in [0, period) from their brackets."""
    ang = np.sort(np.mod(0.5 * (lo + hi), period))
    if ang.size:
        keep = np.concatenate([[True], np.diff(ang) > 1e-9 * period])
        ang = ang[keep]
    return ang
