"""Speed-independent excitation of the 3D model: the quasi-static mesh at one design.

For the te and perturbation formulations (Eqs. (42), (48a)) the excitations
``d(theta) = TE_S - NLTE - w_x0`` (m; ``TE_S - w_x0`` without NLTE terms), the loaded
quasi-static stiffness ``k(theta)`` (N/m) and NLTE (m) do not depend on speed. They come
from the exact 3D quasi-static solution with unilateral contact (Eq. (25),
:func:`gearjax.structure.condensation.quasi_static_3d`): ``d = g_w^T (x_S - x_0)`` from the
condensation at the encoder dofs (Eq. (36)), or with the averaged vector for every cell
(``"mean"``, Eq. (27)) the exact shortcut ``d = (y - v_x0) C_wv / C_vv`` with ``y`` the
torsional root (Eq. (17)) -- the pinion line is torsionally free, so the total mesh force
is ``F_S``.

:class:`QuasiStaticMesh3D` holds that solution at one design and everything the events
need from it: the discrete state code of an angle (layout of
:func:`gearjax.excitation.events.code`), the switching functions, the moved event angles
(:mod:`gearjax.models.geared3d_layout` brackets the state changes and places the table's
knots in the build's program). :func:`tabulate` fills the jump-aware Hermite table (exact
values at the knots, slopes by forward-mode AD), the angle map through the moved events and
the structure flag, traceable in the design.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp

from ..gears.contact import unilateral_solve_pairwise
from ..linalg import solve as dense_solve
from ..gears.mesh import Mesh
from ..gears.modifications import ToothModifications
from ..gears.quasistatic import contact_gaps
from ..structure.condensation import Condensation, QuasiStatic3D, quasi_static_3d
from ..structure.element import PinionGearElement
from .events import NEWTON_STEPS, moved_event_angles, switch_value
from .jumps import JumpSet
from .tables import AngleMap, PeriodicHermiteTable, keeps_structure, one_sided_samples

__all__ = ["QuasiStaticMesh3D", "tabulate", "table_values", "fourier_coefficients",
           "harmonic_response"]


class QuasiStaticMesh3D(eqx.Module):
    """The 3D quasi-static mesh at one design (Eqs. (25), (27), (36)).

    Attributes
    ----------
    mesh, mods, element : mesh model, tooth modifications, pinion-gear element.
    cond : condensation of the structure on the 12 element dofs.
    v_local : (12,) averaged structure vector V at the element dofs (Eq. (A.1)).
    free12 : (12,) 1 for free element dofs, 0 for clamped ones.
    static_force_N : F_S (N).
    v_x0, c_vv, c_wv : ``V^T X_0`` (m), ``C_vv``, ``C_wv`` (m/N) of the model's K_bar
        (Eqs. (33)-(35)), for the ``"mean"`` shortcut.
    mesh_vectors : ``"cells"`` or ``"mean"`` (static).
    qs_max_iter : active-set iterations (static).
    nlte_terms : NLTE kept in the equations (static): ``d`` is ``TE_S - NLTE - w_x0``,
        else ``TE_S - w_x0``.
    loaded_codes : the state code holds the loaded set (te, perturbation; static).
    cell_states : :meth:`excitation` also gives the 12 element dofs of X_S (static; the
        per-cell contact law of te/perturbation reads every cell's quasi-static approach
        ``V_i^T x_S - de_i`` from them, :func:`gearjax.gears.contact.te_cell_contact`).
    """

    mesh: Mesh
    mods: ToothModifications
    element: PinionGearElement
    cond: Condensation
    v_local: jax.Array
    free12: jax.Array
    static_force_N: jax.Array
    v_x0: jax.Array
    c_vv: jax.Array
    c_wv: jax.Array
    mesh_vectors: str = eqx.field(static=True)
    qs_max_iter: int = eqx.field(static=True)
    nlte_terms: bool = eqx.field(static=True)
    loaded_codes: bool = eqx.field(static=True)
    cell_states: bool = eqx.field(static=True, default=False)

    def solve(self, theta) -> QuasiStatic3D:
        """Quasi-static 3D solution (Eq. (25)) at ``theta`` (rad, scalar)."""
        return quasi_static_3d(self.cond, self.element, self.mods, theta, self.static_force_N,
                               self.v_local, self.mesh_vectors, self.qs_max_iter, self.free12)

    def vectors(self, cells):
        """(cells, 12) structure vectors of the cells on the free element dofs."""
        if self.mesh_vectors == "cells":
            return self.element.cell_vectors(cells) * self.free12[None, :]
        return jnp.broadcast_to(self.v_local, (cells.xi_m.shape[0], 12))

    def excitation(self, theta):
        """(3,) stacked ``(d (m), k(theta) (N/m), NLTE (m))`` from the exact solve; with
        :attr:`cell_states` (15,): then the element dofs ``x_S`` (m, rad) of that solve."""
        qs = self.solve(theta) if self.cell_states or self.mesh_vectors != "mean" else None
        if self.mesh_vectors == "mean":
            # exact shortcut: V^T X_S is the torsional root (total mesh force F_S), and
            # X_S = X_0 + phi C_v (Eq. (29)) gives TE_S - NLTE = w_x0 + phi C_wv.
            cells, de, nlte = contact_gaps(self.mesh, self.mods, theta)
            y, k = unilateral_solve_pairwise(cells.stiffness_N_per_m, de, self.static_force_N)
            d = (y - self.v_x0) / self.c_vv * self.c_wv
            if not self.nlte_terms:
                d = d + nlte
        else:
            d = self.cond.g_w @ (qs.x_local - self.cond.x0_local)  # W^T (X_S - X_0)
            if not self.nlte_terms:
                d = d + qs.nlte_m
            k = qs.loaded_stiffness_N_per_m
        nlte = contact_gaps(self.mesh, self.mods, theta)[2]
        if self.cell_states:
            return jnp.concatenate([jnp.stack([d, k, nlte]), qs.x_local])
        return jnp.stack([d, k, nlte])

    def state_code(self, theta, kinks: bool):
        """Discrete state at ``theta`` in the layout of
        :func:`gearjax.excitation.events.code`: the cell realising NLTE, the loaded cells
        (zeros unless :attr:`loaded_codes`), the cells inside the path of contact and
        their relief zone (Fig. 4; 1 pinion, 2 gear, -1 outside the path; zeros inside
        unless ``kinks``). Traceable in the design."""
        mesh, mods = self.mesh, self.mods
        cells, _, _ = contact_gaps(mesh, mods, theta)
        inside = cells.inside
        r = mesh.removed_material(mods, cells, theta)
        arg = jnp.argmin(jnp.where(inside, r, jnp.inf))
        zone = jnp.zeros(inside.shape, jnp.int32)
        if kinks:
            xi_a, xi_e = mesh.pair.contact_limits_m
            ext = mods.relief_extent * mesh.pair.path_of_contact_m
            zone = ((cells.xi_m > xi_e - ext[0]).astype(jnp.int32)
                    + 2 * (cells.xi_m < xi_a + ext[1]).astype(jnp.int32))
        loaded = (self.solve(theta).cell_load_N > 0 if self.loaded_codes
                  else jnp.zeros(inside.shape, bool))
        return jnp.concatenate([arg[None].astype(jnp.int32), loaded.astype(jnp.int32),
                                inside.astype(jnp.int32), jnp.where(inside, zone, -1)])

    def switch_function(self, kind, a, b, theta):
        """g(theta) (m) whose root is the angle of an event of ``kind``
        (:func:`gearjax.excitation.events.switch_value`); loaded set (cell a):
        ``V_a^T x_S - de_a``, the approach minus the gap in the 3D solution (Eq. (25))."""
        cells, de, _ = contact_gaps(self.mesh, self.mods, theta)
        x = self.solve(theta).x_local
        return switch_value(self.mesh, self.mods, cells, theta,
                            self.vectors(cells)[a] @ x - de[a], kind, a, b)

    def event_angles(self, event_thetas, event_kinds, event_cells,
                     newton_steps: int = NEWTON_STEPS):
        """Event angles (rad) of this design: Newton on :meth:`switch_function` from the
        build angles (geometric events stay); differentiable in the design."""
        return moved_event_angles(self.switch_function, event_thetas, event_kinds,
                                  event_cells, newton_steps)


def tabulate(qsm: QuasiStaticMesh3D, knots, side, cell_first, *, origin, period: float,
             n_cells: int, max_extra: int, events: JumpSet | None, table_codes=None):
    """The excitation table ``(d, k, NLTE)`` of this design, the angle map and the
    structure flag (traceable: call inside ``jit`` to differentiate in the design).

    The table holds ``q(phi(s))`` in the simulation angle ``s`` at the build knots (the
    knots bracketing a jump evaluated on their own side, ``side`` -1/+1), slopes by
    forward-mode AD; ``phi`` (:class:`AngleMap`) sends the build angles of ``events``
    (a padded :class:`~gearjax.excitation.jumps.JumpSet`; fixed ones stay) to those of
    this design (None: no angle map). The flag is True when the design keeps
    the discrete state of the build on each side of every mapped knot (``table_codes``),
    else the map is not valid and the model must be rebuilt.

    Returns
    -------
    (table, angle_map, structure_ok)
    """
    vals, slopes, amap, ok = table_values(qsm, knots, side, period=period, events=events,
                                          table_codes=table_codes)
    table = PeriodicHermiteTable(knots=knots, values=vals, slopes=slopes, cell_first=cell_first,
                                 origin=origin, period=period, n_cells=n_cells,
                                 max_extra=max_extra)
    return table, amap, ok


def table_values(qsm: QuasiStaticMesh3D, knots, side, *, period: float,
                 events: JumpSet | None, table_codes=None):
    """:func:`tabulate` without the table's static layout: ``(values, slopes, angle_map,
    structure_ok)``."""
    amap = None
    if events is not None:
        amap = AngleMap.through(events.thetas, qsm.event_angles(events.thetas, events.kinds,
                                                                events.cells), period)
    vals, slopes = one_sided_samples(lambda t, _: qsm.excitation(t), knots, side, period, amap)
    ok = jnp.asarray(True)
    if table_codes is not None:
        ok = keeps_structure(lambda t: qsm.state_code(t, True), knots, side, period,
                             table_codes, amap)
    return vals, slopes, amap, ok


def fourier_coefficients(f, origin: float, period: float, n_samples: int, n_h: int, theta0=0.0):
    """(n_h + 1,) complex coefficients ``c_h`` of the periodic ``f(theta) = Re sum_h w_h c_h
    exp(i h nu (theta - theta0))`` (``nu = 2 pi / period``, ``w_0 = 1``, ``w_h = 2``): the
    DFT of ``n_samples`` uniform samples from ``origin`` (rad), shifted to ``theta0``. A
    kinked ``f`` (``c_h = O(h^-2)``) aliases at O(n_samples^-2): sample finely (measured
    in ``benchmarks/results/model_notes.md``)."""
    th = origin + jnp.arange(n_samples) * (period / n_samples)
    c = jnp.fft.rfft(jax.vmap(f)(th))[: n_h + 1] / n_samples
    h = jnp.arange(n_h + 1)
    nu = 2.0 * jnp.pi / period
    return c * jnp.exp(1j * h * nu * (jnp.asarray(theta0, dtype=float) - origin))


def harmonic_response(kbar_r, c_r, v_r, amp, period: float, omega):
    """Periodic steady response ``(z, z')`` (``z' = dz/dtheta``) of the constant-coefficient
    modal system (``M_r = I``) ``Omega^2 z'' + Omega C_r z' + K_bar_r z = f(theta) v_r`` with
    ``f = Re sum_h w_h amp_h exp(i h nu theta)`` (``amp`` as :func:`fourier_coefficients`,
    ``nu = 2 pi / period``): each harmonic answers independently at ``w_h = h nu Omega``,
    ``z_h = (K_bar_r - w_h^2 I + i w_h C_r)^-1 amp_h v_r``, one complex (r, r) solve each."""
    n_h = amp.shape[0] - 1
    h = jnp.arange(n_h + 1)
    nu = 2.0 * jnp.pi / period
    w_h = h * nu * omega
    r = kbar_r.shape[0]
    eye = jnp.eye(r)
    a = (kbar_r[None] - (w_h**2)[:, None, None] * eye[None]
         + 1j * w_h[:, None, None] * c_r[None])
    g = dense_solve(a, jnp.broadcast_to(v_r.astype(a.dtype), (n_h + 1, r))[..., None])[..., 0]
    z_h = g * amp[:, None]
    weight = jnp.where(h > 0, 2.0, 1.0)[:, None]
    z = jnp.real(jnp.sum(weight * z_h, axis=0))
    zp = jnp.real(jnp.sum(weight * (1j * h * nu)[:, None] * z_h, axis=0))  # d/dtheta
    return z, zp
