"""The pinion-gear element: structure vectors V(M_i) of the contact cells (Fig. 1, Eq. (8a)).

Frame (right-handed, unit vectors s, t, z): z along the shafts; s along the transverse line
of action from T1 towards T2; t completes the frame. With O1 at the origin,

    T1 = O1 - Rb1 t,   T2 = T1 + L s   (L = T1T2),   O2 = O1 + L s - (Rb1 + Rb2) t,

so ``|O1O2| = a_w``. A cell at line-of-action coordinate xi and face coordinate eta sits at
``M = T1 + xi s + (eta - b/2) z`` (axial origin at the face mid-plane, where the pinion and
gear nodes are). The outer normal of the pinion flank is ``n = cos(beta_b) s + sin(beta_b) z``
(sign of ``sin`` = hand of the helix).

Per node the dofs are ``(u, v, w, phi, psi, theta)``: translations along (z, s, t) and
rotations about (s, t, z) (see :mod:`gearjax.structure`). The 12 pinion-gear components of
Eq. (8a), ``V~(M)^T = (n, O1M x n, -n, -O2M x n)``, are therefore

    pinion: (n_z, n_s, n_t, (O1M x n)_s, (O1M x n)_t, (O1M x n)_z)
    gear:   minus the same with O2M.

The torsional components are ``Rb1 cos(beta_b)`` and ``Rb2 cos(beta_b)``: Eq. (8b).

Back flanks (backlash, :mod:`gearjax.gears.backlash`): they mesh on the second base plane,
the image of the first under the half-turn ``H`` about the line of centres in the face
mid-plane (``c = O1O2 / a_w``: ``R = 2 c c^T - I`` on the (s, t, z) components, which
fixes the pinion and gear centre nodes). A back-flank cell that is the image of a drive
cell ``M`` has ``V'(M') = H V(M)`` (Eq. (8a) at ``H M`` with the normal ``H n``: a proper
rotation keeps cross products), so ``V'^T X = V^T (H X)``; in torsion ``V'^T X = -V^T X``.
"""

from __future__ import annotations

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..gears.mesh import Mesh

__all__ = ["PinionGearElement"]


def _cross(a, b):
    return jnp.stack(
        [
            a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1],
            a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2],
            a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0],
        ],
        axis=-1,
    )


class PinionGearElement(eqx.Module):
    """Couples the mesh cells to the 6 + 6 dofs of the pinion and gear centre nodes.

    Attributes
    ----------
    mesh : the :class:`gearjax.gears.mesh.Mesh`.
    n_dof : total number of dofs of the structure.
    pinion_dofs, gear_dofs : the 6 global dof indices of each centre node, in the order
        (u, v, w, phi, psi, theta).
    """

    mesh: Mesh
    n_dof: int = eqx.field(static=True)
    pinion_dofs: tuple = eqx.field(static=True)
    gear_dofs: tuple = eqx.field(static=True)

    @classmethod
    def at_nodes(cls, mesh: Mesh, n_dof: int, pinion_node: int, gear_node: int):
        """Element on 0-based nodes ``pinion_node`` and ``gear_node`` (6 dofs per node)."""
        for name, node in (("pinion_node", pinion_node), ("gear_node", gear_node)):
            if not (0 <= node and 6 * node + 6 <= n_dof):
                raise ValueError(f"{name}={node}: outside the structure's {n_dof // 6} nodes")
        if pinion_node == gear_node:
            raise ValueError(f"gear_node={gear_node}: must differ from pinion_node")
        return cls(
            mesh,
            int(n_dof),
            tuple(range(6 * pinion_node, 6 * pinion_node + 6)),
            tuple(range(6 * gear_node, 6 * gear_node + 6)),
        )

    # ------------------------------------------------------------------ geometry
    def _frame(self):
        p = self.mesh.pair
        rb1, rb2 = p.base_radii_m
        big_l = p.line_of_action_length_m
        sb = math.copysign(math.sin(p.base_helix_angle_rad), p.helix_angle_rad) if not p.spur else 0.0
        cb = math.cos(p.base_helix_angle_rad)
        # components in (s, t, z)
        n = jnp.array([cb, 0.0, sb])
        o2 = jnp.array([big_l, -(rb1 + rb2), 0.0])
        t1 = jnp.array([0.0, -rb1, 0.0])
        return n, o2, t1

    def local_vectors(self, xi_m, eta_m):
        """V~(M) (..., 12) at base-plane points (xi, eta), Eq. (8a), dof order of the nodes."""
        n, o2, t1 = self._frame()
        b = self.mesh.pair.face_width_m
        xi_m, eta_m = jnp.asarray(xi_m), jnp.asarray(eta_m)
        rel = jnp.stack([xi_m, jnp.zeros_like(xi_m), eta_m - 0.5 * b], axis=-1)
        m = jnp.broadcast_to(t1, rel.shape) + rel  # O1M (O1 at the origin)
        nb = jnp.broadcast_to(n, m.shape)
        r1 = _cross(m, nb)
        r2 = _cross(m - jnp.broadcast_to(o2, m.shape), nb)  # O2M x n
        # (s, t, z) -> node order: translations (z, s, t); rotations (s, t, z)
        trans = jnp.stack([nb[..., 2], nb[..., 0], nb[..., 1]], axis=-1)
        return jnp.concatenate([trans, r1, -trans, -r2], axis=-1)

    def half_turn(self) -> np.ndarray:
        """The (3, 3) half-turn ``R = 2 c c^T - I`` about the line of centres, in (s, t, z)."""
        p = self.mesh.pair
        rb1, rb2 = p.base_radii_m
        o2 = np.array([p.line_of_action_length_m, -(rb1 + rb2), 0.0])  # as _frame
        c = o2 / np.linalg.norm(o2)
        return 2.0 * np.outer(c, c) - np.eye(3)

    def back_vectors(self, v12):
        """``V' = H V`` (..., 12): the back-flank structure vectors of the cells whose
        drive-flank vectors are ``v12`` (module docstring; node dof order)."""
        r = jnp.asarray(self.half_turn())
        v12 = jnp.asarray(v12)

        def node(v6):  # translations (z, s, t), rotations (s, t, z)
            tr = jnp.stack([v6[..., 1], v6[..., 2], v6[..., 0]], axis=-1) @ r.T  # (s, t, z)
            rot = v6[..., 3:6] @ r.T
            return jnp.concatenate([tr[..., 2:3], tr[..., 0:2], rot], axis=-1)

        return jnp.concatenate([node(v12[..., :6]), node(v12[..., 6:])], axis=-1)

    def cell_vectors(self, cells):
        """V~(M_i) for every cell (n_cells, 12)."""
        return self.local_vectors(cells.xi_m, cells.eta_m)

    def mean_local_vector(self, n_positions: int = 256):
        """Averaged structure vector V (12,) of Section 4.2: the stiffness-weighted mean of
        V(M_i) over one mesh period, i.e. V at the centroid M_0 of the mesh stiffness
        (V is affine in the contact position), Eq. (A.1)."""
        th = self.mesh.theta_grid(n_positions)

        def one(theta):
            c = self.mesh.cells(theta)
            k = c.stiffness_N_per_m
            return jnp.sum(k), jnp.sum(k * c.xi_m), jnp.sum(k * c.eta_m)

        k, kx, ke = jax.vmap(one)(th)
        xi0, eta0 = jnp.sum(kx) / jnp.sum(k), jnp.sum(ke) / jnp.sum(k)
        return self.local_vectors(xi0, eta0)

    # ------------------------------------------------------------------ global vectors
    @property
    def dofs(self) -> np.ndarray:
        return np.array(self.pinion_dofs + self.gear_dofs)

    def scatter(self, v12):
        """Place 12-component vectors (..., 12) into the global dof vector (..., n_dof)."""
        v12 = jnp.asarray(v12)
        out = jnp.zeros(v12.shape[:-1] + (self.n_dof,), dtype=v12.dtype)
        return out.at[..., self.dofs].set(v12)

    def mean_vector(self, n_positions: int = 256):
        """Averaged structure vector V in global dofs (n_dof,)."""
        return self.scatter(self.mean_local_vector(n_positions))

    def torsional_vector(self, pinion_torsion_dof: int, gear_torsion_dof: int):
        """W of Eq. (10): Rb1 and Rb2 at the encoder torsional dofs (n_dof,)."""
        rb1, rb2 = self.mesh.pair.base_radii_m
        return jnp.zeros(self.n_dof).at[pinion_torsion_dof].set(rb1).at[gear_torsion_dof].set(rb2)
