"""The structure seen by the pinion-gear element: free dofs, load and observation vectors.

The 3D model (paper Section 4) couples the structure ``M``, ``K`` to the mesh through the
pinion-gear element at the pinion and gear nodes. :func:`geared_structure` restricts the
matrices to the free dofs and forms the constant vectors of Eqs. (5), (10), (14), (27):
``F_0`` (motor torque C_m0 on the torsional dof of the torque node, N m), ``W`` (``Rb1``,
``Rb2`` on the torsional dofs of the encoder nodes, Eq. (10)), the averaged structure vector
``V`` (Eq. (A.1)) and the inertial vector ``E`` (Eq. (5)). Dof order per node
``(u, v, w, phi, psi, theta)``; SI units.
"""

from __future__ import annotations

from typing import NamedTuple

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..errors import ModelError
from ..gears.mesh import Mesh
from .element import PinionGearElement
from .modal import reduced_model

__all__ = ["GearedStructure", "GearedModal", "geared_structure", "disc_mass", "Eccentricity"]


def _tors(node: int) -> int:
    return 6 * node + 5


class GearedModal(NamedTuple):
    """Reduced modal model of ``(M, K_bar)`` (``r`` coordinates, ``M_r = I``) and the
    projected vectors of the geared system (NumPy); see :meth:`GearedStructure.modal`."""

    kbar_r: np.ndarray
    c_r: np.ndarray
    t_local: np.ndarray
    omega_r: np.ndarray
    v_r: np.ndarray
    w_r: np.ndarray
    e_r: np.ndarray
    acc_r: np.ndarray
    q0: np.ndarray
    c_v_r: np.ndarray
    n_modes: int
    n_static: int


class GearedStructure(NamedTuple):
    """The structure on its ``n`` free dofs with the geared-system vectors (NumPy).

    Attributes
    ----------
    M, K : (n, n) mass (kg, kg m^2) and stiffness (N/m, N m/rad) on the free dofs.
    F0, W, V : (n,) motor load (N m), TE projection (m/rad), averaged structure vector.
    gear_rotation : (n,) unit rigid rotation of the gear shaft line ``r_2``.
    torque_dof : free-dof index of the torsional dof carrying C_m0.
    pos : (n_all,) free-dof index of every dof of the structure, -1 when fixed.
    element_dofs : (12,) free-dof indices of the element dofs (-1 when fixed).
    keep12 : (12,) bool, which element dofs are free.
    v_local12 : (12,) averaged V at the element dofs (zero where fixed).
    element : the pinion-gear element on the full numbering.
    accel_dof : free-dof index of the pinion node's v dof (-1 when fixed).
    """

    M: np.ndarray
    K: np.ndarray
    F0: np.ndarray
    W: np.ndarray
    V: np.ndarray
    gear_rotation: np.ndarray
    torque_dof: int
    pos: np.ndarray
    element_dofs: np.ndarray
    keep12: np.ndarray
    v_local12: np.ndarray
    element: PinionGearElement
    accel_dof: int

    def inertial_vector(self) -> np.ndarray:
        """``E`` of Eq. (14) without eccentricity (kg): ``M r_2 / Rb2`` plus
        ``J2 Rb1 / Rb2^2`` on the torque dof (Eq. (5); ``J2 = r_2^T M r_2``)."""
        rb1, rb2 = self.element.mesh.pair.base_radii_m
        r2 = self.gear_rotation
        e = self.M @ r2 / rb2
        e[self.torque_dof] += (r2 @ self.M @ r2) * rb1 / rb2**2
        return e

    def modal(self, k_m: float, E, max_frequency_hz: float | None, zeta: float) -> GearedModal:
        """Modal reduction of ``(M, K_bar)``, ``K_bar = K + k_m V V^T`` (Eq. (27), ``k_m``
        in N/m), with :func:`gearjax.structure.modal.reduced_model`: all modes
        (``max_frequency_hz`` None) or those below the cut-off (Hz) plus static
        corrections for ``F_0``, ``E`` (the inertial vector) and unit loads on the free
        element dofs, so ``X_0 = K_bar^-1 F_0`` and ``C_v = K_bar^-1 V`` stay exact;
        modal damping ratio ``zeta``. ``acc_r`` is the row of the basis at the pinion
        node's v dof (zeros when fixed)."""
        kbar = self.K + k_m * np.outer(self.V, self.V)
        loc_free = self.element_dofs[self.keep12]
        unit = np.zeros((self.F0.shape[0], loc_free.size))
        unit[loc_free, np.arange(loc_free.size)] = 1.0
        loads = np.concatenate([self.F0[:, None], E[:, None], self.V[:, None], unit], axis=1)
        red = reduced_model(self.M, kbar, loads, max_frequency_hz=max_frequency_hz, zeta=zeta)
        T = np.asarray(red.basis)
        kbar_r = np.asarray(red.K)
        t12 = np.zeros((12, T.shape[1]))
        t12[self.keep12] = T[loc_free]
        v_r = T.T @ self.V
        acc_dof = self.accel_dof
        return GearedModal(
            kbar_r=kbar_r, c_r=np.asarray(red.C), t_local=t12,
            omega_r=np.sqrt(np.clip(np.diag(kbar_r), 0.0, None)), v_r=v_r, w_r=T.T @ self.W,
            e_r=T.T @ E, acc_r=T[acc_dof] if acc_dof >= 0 else np.zeros(T.shape[1]),
            q0=np.linalg.solve(kbar_r, T.T @ self.F0), c_v_r=np.linalg.solve(kbar_r, v_r),
            n_modes=int(red.n_modes), n_static=int(red.n_static))


@eqx.filter_jit
def _mean_local_vector(element: PinionGearElement):
    """The element's averaged V (12,), one program per mesh shape (a lambda jitted in the
    build would trace and compile again at every build)."""
    return element.mean_local_vector()


def geared_structure(structure, mesh: Mesh, torque_Nm: float, torque_node: int | None = None,
                     encoder_nodes: tuple[int, int] | None = None,
                     fixed_dofs=()) -> GearedStructure:
    """Free dofs and vectors of ``structure`` (with ``pinion_node``/``gear_node`` set)
    meshing through ``mesh``; ``torque_node`` (default the pinion node) carries
    ``torque_Nm``, ``encoder_nodes`` (default pinion and gear nodes) the TE encoders,
    ``fixed_dofs`` are clamped. The pinion shaft line must be free in torsion in ``K``
    (imposed motor torque, resisting load a torsional stiffness on the gear line).

    Raises
    ------
    ModelError
        naming the field, its value and the reason.
    """
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
    rb1, rb2 = mesh.pair.base_radii_m

    # element on the full numbering; vectors are restricted to the free dofs below
    el = PinionGearElement.at_nodes(mesh, n_all, pn, gn)
    v_loc12 = np.asarray(_mean_local_vector(el))
    for name, d in (("torque_node", _tors(torque_node)), ("encoder_nodes[0]", _tors(enc[0])),
                    ("encoder_nodes[1]", _tors(enc[1]))):
        if pos[d] < 0:
            raise ModelError(name, d // 6, "its torsional dof is fixed")
    F0 = np.zeros(n)
    F0[pos[_tors(torque_node)]] = torque_Nm
    W = np.zeros(n)
    W[pos[_tors(enc[0])]] += rb1
    W[pos[_tors(enc[1])]] += rb2
    V = np.zeros(n)
    V[pos[loc_free]] = v_loc12[keep12]

    # pinion line must be torsionally free in K (imposed motor torque)
    lines = structure.node_lines
    r1 = np.zeros(n_all)
    r2 = np.zeros(n_all)
    for node, ln in enumerate(lines):
        if ln == lines[pn]:
            r1[_tors(node)] = 1.0
        if ln == lines[gn]:
            r2[_tors(node)] = 1.0
    r1f, r2f = r1[free], r2[free]
    kscale = np.abs(K).max() if np.abs(K).max() > 0 else 1.0
    if np.abs(K @ r1f).max() > 1e-9 * kscale:
        raise ModelError(
            "structure.K", f"line {lines[pn]!r}",
            "the pinion shaft line must be free in torsion (motor torque imposed, "
            "resisting load a torsional stiffness on the gear line), Section 6.1",
        )
    return GearedStructure(M=M, K=K, F0=F0, W=W, V=V, gear_rotation=r2f,
                           torque_dof=int(pos[_tors(torque_node)]), pos=pos,
                           element_dofs=pos[loc_all], keep12=keep12,
                           v_local12=v_loc12 * keep12.astype(float), element=el,
                           accel_dof=int(pos[6 * pn + 1]))


def disc_mass(structure, node: int) -> float:
    """Mass (kg) of the disc at ``node`` (else the translational mass entry of M)."""
    for e in structure.elements_of_kind("disc"):
        if node in e.nodes:
            return e.param("mass_kg")
    return float(np.asarray(structure.M)[6 * node + 1, 6 * node + 1])


class Eccentricity(eqx.Module):
    """Eccentricities of the pinion (1) and gear (2) and their inertial loads (Eq. (14)).

    The mass centre of gear k sits at ``e_k (cos psi_k, sin psi_k)`` in the base-plane
    frame (s, t) with ``psi_1 = theta - lambda_1 - pi/2`` and ``psi_2 = lambda_2 - pi/2 -
    theta Rb1/Rb2`` (the gear turns backwards): the offset whose projection on the normal
    gives the geometric excess ``e_k cos b_b sin(phi_k - lambda_k)`` of the gaps
    (:mod:`gearjax.gears.modifications`).

    Attributes
    ----------
    masses_kg : (2,) masses m_1, m_2 of the pinion and gear discs (kg).
    e_m : (2,) eccentricities e_1, e_2 (m).
    phase_rad : (2,) phases lambda_1, lambda_2 (rad).
    """

    masses_kg: jax.Array
    e_m: jax.Array
    phase_rad: jax.Array

    def local_vectors(self, theta, rb1: float, rb2: float):
        """``(E~, F~, G~)`` (12,) at the element dofs (pinion node then gear node, dofs
        ``(u, v, w, ...)``, v along s, w along t) at the pinion angle ``theta`` (rad):
        ``E~ = m_2 e_2/Rb2 (-sin, cos)psi_2`` (kg) and ``F~ = 2 m_2 e_2 Rb1/Rb2^2
        (cos, sin)psi_2`` (kg) at the gear (v, w); ``G~ = -m_1 e_1 (cos, sin)psi_1`` at the
        pinion and ``-m_2 e_2 (Rb1/Rb2)^2 (cos, sin)psi_2`` at the gear (kg m)."""
        m1, m2 = self.masses_kg[0], self.masses_kg[1]
        e1, e2 = self.e_m[0], self.e_m[1]
        psi1 = theta - self.phase_rad[0] - 0.5 * math.pi
        psi2 = self.phase_rad[1] - 0.5 * math.pi - theta * rb1 / rb2
        z = jnp.zeros(())
        c2, s2 = jnp.cos(psi2), jnp.sin(psi2)
        # node order (u, v, w, ...): v along s, w along t
        e_loc = jnp.stack([z, z, z, z, z, z, z, -m2 * e2 / rb2 * s2, m2 * e2 / rb2 * c2, z, z, z])
        f_loc = jnp.stack([z] * 7 + [2 * m2 * e2 * rb1 / rb2**2 * c2, 2 * m2 * e2 * rb1 / rb2**2 * s2, z, z, z])
        g2 = m2 * e2 * (rb1 / rb2) ** 2
        g_loc = jnp.stack([z, -m1 * e1 * jnp.cos(psi1), -m1 * e1 * jnp.sin(psi1), z, z, z,
                           z, -g2 * c2, -g2 * s2, z, z, z])
        return e_loc, f_loc, g_loc
