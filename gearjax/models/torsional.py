"""Sdof torsional gear model, paper Section 3 (Eqs. (15)-(24)) and Section 5 (Eq. (47a)).

The pinion-gear pair is two rigid inertias ``J1, J2`` (pinion and gear shaft lines) linked by
the mesh cells of :mod:`gearjax.gears.mesh` (Fig. 2). The single unknown is the transverse elastic
approach on the base plane ``x = Rb1 theta1 + Rb2 theta2`` (m), written in the angular
variable ``theta = Omega1 t`` (rad), with ``' = d/dtheta``. Three formulations (a static
choice, so each compiles only its own terms):

``"reference"`` -- Eq. (16) with instantaneous unilateral contact on every cell::

    Omega^2 m_eq x'' + Omega c x' + cos(b_b) sum_i k_i max(0, x cos(b_b) - de_i)
        = F_t - Omega^2 (J2 / Rb2^2) NLTE''

``"te"`` -- transmission-error based Eq. (20), with the *loaded* quasi-static stiffness
``k(theta) = (sum k_i)^S`` (the stiffness of the cells loaded in the quasi-static solution,
Eqs. (17)-(19))::

    Omega^2 m_eq x'' + Omega c x' + k(theta) cos^2(b_b) x
        = k(theta) cos^2(b_b) (TE_S - NLTE) - Omega^2 (J2 / Rb2^2) NLTE''

``"perturbation"`` -- main-order perturbation Eq. (47a): the same with the constant
``k_m``, the mean of ``(sum k_i)^S`` over one period. Contact algorithm (Section 6.2) in
(20)/(47a): the mesh term (stiffness and TE forcing together) acts while its force ``F_S +
k cos(b_b) x_D`` is compressive and is zero when that would be tensile
(:func:`gearjax.gears.contact.te_contact`; unchanged, bit for bit, while contact holds).
``contact_law=TEContactLaw.CELLS`` resolves it cell by cell instead
(:func:`gearjax.gears.contact.te_cell_contact`: Eq. (22) with each cell's quasi-static
approach ``x_S cos b_b - de_i``; unchanged, bit for bit, while every cell keeps its
quasi-static state). On this model Eq. (20) with that law is Eq. (16) again: undoing (18a)
cell by cell restores the reference's force ``sum_i k_i max(0, x cos b_b - de_i)``.

Here ``m_eq = J1 J2 / (J1 Rb2^2 + J2 Rb1^2)`` (kg), ``F_t = C_m0 / Rb1`` (N) and the viscous
damping is ``c = 2 zeta sqrt(k_m cos^2(b_b) m_eq)`` (N s/m), the same ``k_m`` for all three
formulations so that they differ only in their mesh terms.

Dynamic mesh force
------------------
* reference: the sum of the cell forces, Eq. (22), ``F_D = sum_i k_i max(0, x cos b_b - de_i)``.
* te and perturbation: Eq. (24), ``F_D = F_S + k(theta) cos(b_b) x_D`` (0 while separated)
  with ``x_D = x - x_S`` and the *loaded* quasi-static stiffness ``k(theta)`` for both; for
  Eq. (47a) the paper's choice (Section 6.2 reads the tooth load of Eq. (48a) through Eq.
  (41)); ``F_S + k_m cos(b_b) x_D`` would differ at order alpha, which (47a) neglects.

Excitations: a jump-aware periodic table (default) or inline solves
------------------------------------------------------------------
``TE_S``, ``NLTE`` and ``(sum k_i)^S`` do not depend on speed. With ``excitation="table"``
(default) they are tabulated once per call (by the traceable assembly, so they stay
differentiable in the modifications) by the exact unilateral quasi-static solve at the knots
of a :class:`~gearjax.excitation.tables.PeriodicHermiteTable` (``n_table`` uniform knots per
mesh period plus the two floats bracketing every change of the quasi-static state, found by
bisection at build time; exact slopes by forward-mode AD): exact at the jumps and kinks,
O(h^4) elsewhere, a few flops per lookup against an O(n^2) unilateral solve over the cells
at every right-hand side with ``excitation="inline"`` (kept to check the table).

NLTE' and NLTE'' (no-load transmission error derivatives)
--------------------------------------------------------
NLTE has kinks, so NLTE'' holds Dirac terms: ``nlte_method="substitution"`` (default) removes
it exactly by ``z = x + kappa NLTE`` (only NLTE and NLTE', exact by forward-mode AD, enter
the vector field; the kinks are ``jump_thetas``); ``"spectral"`` keeps x with a Fourier
NLTE'' (``nlte_harmonics``), to check it. ``nlte_terms=False``: NLTE = 0 in the equations
(Fig. 10's "TE-based formulation (with NLTE = 0)"; None: False where NLTE is identically
zero); ``nlte_inertia=False``: the NLTE'' term alone dropped (Section 6.3.2). Its reaction
torque (``nlte_reaction``) acts on the drive (``"drive"``, default, as the 3D model:
``kappa = 1``) or on the pinion (``"pinion"``, Eqs. (15)-(16) as written: ``kappa = J2 /
(Rb2^2 m_eq)``). The reasoning: docs/concepts/formulations.md, "NLTE'' terms and where
their reaction acts".

TE from a file (Section 6.2, :meth:`TorsionalModel.with_te`): TE_S, NLTE and, if given, the
loaded stiffness of a :class:`~gearjax.excitation.te_file.TETable` replace the quasi-static
table (its rows as knots, its jumps fixed integrator jumps; else this model's stiffness).

State and scaling
-----------------
The integrated state is dimensionless, ``y = (z / x_ref, z' / (r x_ref))`` with
``x_ref = F_S / (k_m cos b_b)`` (the mean static approach, m) and ``r = omega_n / Omega``
(``omega_n^2 = k_m cos^2(b_b) / m_eq``), so that a free oscillation has components of equal
size and ``rtol``/``atol`` of the step-size controller are relative to ``x_ref``. With that
scaling (``f`` the elastic mesh force over F_t)::

    du/dtheta = r v,    dv/dtheta = -r [ f(theta, x) - 1 + 2 zeta (v - kappa NLTE' / (r x_ref)) ]

Default inertias: solid steel cylinders of the pitch radii and face widths
(:func:`solid_cylinder_inertias`) when nothing better is known.

Backlash (``backlash_m``)
------------------------
A clearance ``b`` between the back flanks (:mod:`gearjax.gears.backlash`) makes every mesh
law three-state (:func:`gearjax.gears.contact.three_state_force`): drive flanks, free
flight, back flanks (a force of the other sign, F_D < 0). Reference: Eq. (22) plus the back
cells of the mirror angle, first back contact at ``x cos b_b = -(b + r_min + r'_min)``
(:func:`gearjax.gears.backlash.cell_backlash_force`; their engagement angles join
``jump_thetas``). te/perturbation: the mesh-level law of
:func:`gearjax.gears.contact.te_backlash_contact`, back contact ``b`` behind the drive
flanks' no-load contact, through the same stiffness. None (default): the paper's model.

Derivatives with respect to the design (moving switching angles)
----------------------------------------------------------------
The model is forward-mode differentiable in its array data (speed, inertias, torque,
damping, modifications). The jumps of the te/perturbation excitations (and of NLTE') move
with the tip relief; the model integrates in the simulation angle ``s``, ``theta = phi(s)``
(:class:`~gearjax.excitation.tables.AngleMap` through :meth:`TorsionalModel.jump_angles_rad`;
derivation in :mod:`gearjax.excitation.events`), valid while
:attr:`TorsionalModel.structure_ok` holds (else :mod:`gearjax.design` rebuilds). The
reference contact law is continuous in the gaps, so its derivative needs no map.
"""

from __future__ import annotations

import dataclasses
import math

import equinox as eqx
import jax
import jax.numpy as jnp

from ..gears.geometry import STEEL_DENSITY_KG_M3, GearPair, solid_cylinder_inertias  # re-exported
from ..gears.mesh import Mesh
from ..gears.modifications import ToothModifications
from ..gears.backlash import cell_backlash_force
from ..gears.contact import (TEContactLaw, solve_unilateral, te_backlash_contact,
                             te_cell_contact, te_contact, unilateral_solve_pairwise)
from ..gears.quasistatic import contact_gaps, static_mesh_force
from ..excitation.mesh3d import fourier_coefficients
from ..excitation.events import EV_FIXED, NEWTON_STEPS, code_jnp, moved_event_angles
from ..excitation.jumps import JumpSet
from ..excitation.sdof import sdof_signature, sdof_switch
from ..excitation.tables import (AngleMap, PeriodicHermiteTable, keeps_structure,
                                 one_sided_samples)
from ..excitation.te_file import te_model_fields
from .base import AbstractGearModel, ModelOutputs
from .formulations import AbstractFormulation, Perturbation, Reference, TransmissionError
from .torsional_build import EXCITATIONS, NLTE_METHODS, NLTE_REACTIONS, build_torsional
from ..errors import ModelError

__all__ = ["TorsionalModel", "ModelOutputs", "ModelError", "solid_cylinder_inertias",
           "EXCITATIONS", "NLTE_METHODS", "NLTE_REACTIONS"]

_X_S, _K_S, _NLTE = 0, 1, 2


class _TorsionalInputs(eqx.Module):
    """Inputs and build-time layout of the sdof model, with the quasi-static helpers that
    the derived arrays are computed from (abstract: see :class:`TorsionalModel`)."""

    mesh: Mesh
    mods: ToothModifications
    inertias_kg_m2: jax.Array
    pinion_torque_Nm: jax.Array
    damping_ratio: jax.Array
    table_knots: jax.Array
    table_cell_first: jax.Array
    table_side: jax.Array
    table_origin: jax.Array
    jumps: JumpSet
    nlte_weight: jax.Array
    formulation: AbstractFormulation = eqx.field(static=True)
    nlte_method: str = eqx.field(static=True)
    nlte_harmonics: int = eqx.field(static=True)
    excitation: str = eqx.field(static=True)
    period_rad: float = eqx.field(static=True)
    n_table: int = eqx.field(static=True)
    table_max_extra: int = eqx.field(static=True)
    nlte_reaction: str = eqx.field(static=True, default="drive")
    nlte_inertia: bool = eqx.field(static=True, default=True)
    moving_events: bool = eqx.field(static=True, default=True)
    table_codes: jax.Array | None = None
    te_input: PeriodicHermiteTable | None = None  # from a TE file (with_te): the table itself
    backlash_m: jax.Array | None = None  # clearance of the back flanks (m); None: none
    contact_law: TEContactLaw = eqx.field(static=True, default=TEContactLaw.MESH)

    @property
    def nlte_terms(self) -> bool:
        """NLTE is kept in the equations (host-level reading of :attr:`nlte_weight`)."""
        return bool(self.nlte_weight)

    @property
    def jump_kinds(self) -> tuple:
        """The kinds of the valid events of :attr:`jumps` (concrete models only)."""
        return self.jumps.kind_tuple()

    @property
    def jump_cells(self) -> tuple:
        """The cell pairs of the valid events of :attr:`jumps` (concrete models only)."""
        return self.jumps.cell_tuple()

    @property
    def pair(self) -> GearPair:
        return self.mesh.pair

    @property
    def cos_bb(self) -> float:
        return math.cos(self.mesh.pair.base_helix_angle_rad)

    @property
    def mesh_period_rad(self) -> float:
        """One mesh period in theta, 2 pi / z1 (rad)."""
        return self.mesh.pair.mesh_period_rad

    @property
    def static_force_N(self):
        """F_S = C_m0 / (Rb1 cos b_b) (N) (Section 3)."""
        return static_mesh_force(self.pair, self.pinion_torque_Nm)

    @property
    def equivalent_mass_kg(self):
        """m_eq = J1 J2 / (J1 Rb2^2 + J2 Rb1^2) (kg), Eq. (16)."""
        j1, j2 = self.inertias_kg_m2[0], self.inertias_kg_m2[1]
        rb1, rb2 = self.pair.base_radii_m
        return j1 * j2 / (j1 * rb2**2 + j2 * rb1**2)

    @property
    def nlte_inertia_ratio(self):
        """kappa: NLTE'' coefficient over m_eq (dimensionless). ``nlte_reaction="drive"``
        (default): 1; ``"pinion"`` (Eq. (16)): ``J2 / (Rb2^2 m_eq) = 1 + J2 Rb1^2 / (J1
        Rb2^2)`` (module docstring, "Where the NLTE'' reaction torque acts")."""
        rb2 = self.pair.base_radii_m[1]
        if self.nlte_reaction == "drive":
            return jnp.ones_like(self.inertias_kg_m2[1])
        return self.inertias_kg_m2[1] / (rb2**2 * self.equivalent_mass_kg)

    # ------------------------------------------------------------------ quasi-static
    def _qs(self, theta):
        """(x_S, k_S, NLTE) at theta: exact unilateral quasi-static solve (Eq. (17))."""
        cells, delta_e, nlte = contact_gaps(self.mesh, self.mods, theta)
        k = cells.stiffness_N_per_m
        if self.excitation == "inline":  # inside the vector field: no sort
            y, k_s = unilateral_solve_pairwise(k, delta_e, self.static_force_N)
        else:  # table knots: sort-based root, O(n log n) for the 160 helical cells
            y, _ = solve_unilateral(k, delta_e, self.static_force_N)
            k_s = jnp.sum(jnp.where((k > 0) & (delta_e < y), k, 0.0))
        return jnp.stack([y / self.cos_bb, k_s, nlte])

    @property
    def moving_jumps(self):
        """Some switching angles depend on the design (module docstring); traced bool."""
        return jnp.any(self.jumps.valid & (self.jumps.kinds != EV_FIXED))

    def _switch_function(self, kind, a, b, theta):
        """g(theta) (m) whose root is the switching angle of an event of ``kind`` (cells
        a, b): :func:`gearjax.excitation.sdof.sdof_switch`."""
        return sdof_switch(self.mesh, self.mods, self.static_force_N, kind, a, b, theta)

    def _moved_jumps(self, newton_steps: int = NEWTON_STEPS):
        """The switching angles of the current design for every entry of :attr:`jumps`
        (padding included), by :func:`gearjax.excitation.events.moved_event_angles`."""
        j = self.jumps
        return moved_event_angles(self._switch_function, j.thetas, j.kinds, j.cells,
                                  newton_steps)

    def jump_angles_rad(self, newton_steps: int = NEWTON_STEPS):
        """The switching angles ``theta_j`` (rad) of the current design, one per entry of
        :attr:`jump_thetas`: Newton iterations on :meth:`_switch_function` from the
        build-time angle (geometric ones stay fixed). Differentiable in the modifications:
        at the root, ``d theta_j = -(dg/d design) / (dg/d theta)`` (implicit function
        theorem) is what the unrolled iterations return. Where the jump set itself is
        traced (a model built inside ``jit``), every padded entry of :attr:`jumps`."""
        moved = self._moved_jumps(newton_steps)
        if isinstance(self.jumps.count, jax.core.Tracer):
            return moved
        return moved[: int(self.jumps.count)]

    def _angle_map(self) -> AngleMap:
        return AngleMap.through(self.jumps.thetas, self._moved_jumps(), self.period_rad)

    @property
    def nlte_inertial_terms(self) -> bool:
        """The NLTE'' inertial term can be in the equations (``nlte_inertia``; its weight
        is :attr:`nlte_weight`)."""
        return self.nlte_inertia

    @property
    def _substitution(self) -> bool:
        return self.nlte_inertial_terms and self.nlte_method == "substitution"

    def _assemble(self) -> dict:
        """The derived arrays of :class:`TorsionalModel` from these inputs (traceable, so
        they stay differentiable functions of the modifications): the excitation table
        of (x_S, (sum k)^S, NLTE) with exact slopes, ``k_m``, ``x_ref``, ``omega_n``,
        ``kappa``, the angle map of the moving switching angles and its validity flag,
        and the spectral NLTE'' coefficients."""
        n_mesh = int(round(self.period_rad / self.mesh_period_rad))
        layout = dict(knots=self.table_knots, cell_first=self.table_cell_first,
                      origin=self.table_origin, period=self.period_rad,
                      n_cells=self.n_table * n_mesh, max_extra=self.table_max_extra)
        amap = None
        if self.te_input is not None:
            structure_ok, table = jnp.asarray(True), self.te_input
            k_m = table.mean()[_K_S]
        elif not self.moving_events:  # switching angles fixed at the build's: no map
            structure_ok = jnp.asarray(True)
            vals, slopes = one_sided_samples(lambda t, _: self._qs(t), self.table_knots,
                                             self.table_side, self.period_rad)
            table = PeriodicHermiteTable(values=vals, slopes=slopes, **layout)
            k_m = table.mean()[_K_S]
        else:
            # tabulate q(phi(s)) and, for the mean over theta, (sum k)^S(phi(s)) phi'(s);
            # phi is the identity at the build design (every design: no program of its own)
            amap = self._angle_map()

            def q(th, dth):
                v = self._qs(th)
                return jnp.concatenate([v, v[_K_S:_K_S + 1] * dth])

            vals, slopes = one_sided_samples(q, self.table_knots, self.table_side,
                                             self.period_rad, amap)
            table = PeriodicHermiteTable(values=vals[:, :3], slopes=slopes[:, :3], **layout)
            k_m = PeriodicHermiteTable(values=vals[:, 3:], slopes=slopes[:, 3:], **layout).mean()[0]
            structure_ok = keeps_structure(
                lambda t: code_jnp(sdof_signature(self.mesh, self.mods, self.static_force_N, t)),
                self.table_knots, self.table_side, self.period_rad, self.table_codes, amap)
        m_eq = self.equivalent_mass_kg
        omega_n = jnp.sqrt(k_m * self.cos_bb**2 / m_eq)
        x_ref = self.static_force_N / (k_m * self.cos_bb)
        kappa = (self.nlte_weight * self.nlte_inertia_ratio if self._substitution
                 else jnp.zeros(()))
        coeffs = None
        if self.nlte_method == "spectral" and self.nlte_inertial_terms:
            n_keep = self.nlte_harmonics * n_mesh
            c = fourier_coefficients(lambda t: contact_gaps(self.mesh, self.mods, t)[2], 0.0,
                                     self.period_rad, self.n_table * n_mesh, n_keep)
            h = jnp.arange(n_keep + 1)
            w = 2.0 * jnp.pi * h / self.period_rad
            coeffs = self.nlte_weight * jnp.where(h > 0, -(w**2) * 2.0 * c[: n_keep + 1], 0.0)
        return dict(angle_map=amap, structure_ok=structure_ok, table=table, k_m=k_m,
                    x_ref=x_ref, omega_n=omega_n, kappa=kappa, nlte_dd_coeffs=coeffs)


class _TorsionalData(_TorsionalInputs):
    """The inputs alone (final): what :meth:`TorsionalModel.with_modifications` assembles."""


@eqx.filter_jit
def _assemble(data: _TorsionalData) -> dict:
    """:meth:`_TorsionalInputs._assemble`, compiled (inlined when traced inside ``jit``)."""
    return data._assemble()


class TorsionalModel(_TorsionalInputs, AbstractGearModel):
    """Sdof torsional model of a gear pair (paper Section 3, Eqs. (16), (20), (47a)).

    Build with :meth:`build`. Array fields are differentiable data; the configuration
    (formulation, which terms exist, period, jump angles, table layout) is static.

    Complete when built: :meth:`build` scans the quasi-static solution once (NumPy, static
    layout) and assembles the derived arrays (traceable); :meth:`with_modifications`
    re-assembles them for new modifications. The solver interface is
    :class:`gearjax.models.base.AbstractGearModel`.

    Attributes
    ----------
    mesh : :class:`gearjax.gears.mesh.Mesh` (cells and stiffness law).
    mods : :class:`gearjax.gears.modifications.ToothModifications`.
    inertias_kg_m2 : (2,) polar inertias J1, J2 of the pinion and gear shaft lines (kg m^2).
    pinion_torque_Nm : input torque C_m0 on the pinion (N m), > 0.
    damping_ratio : zeta in [0, 1), ``c = 2 zeta sqrt(k_m cos^2 b_b m_eq)``.
    formulation : :class:`~gearjax.models.formulations.AbstractFormulation`: Reference
        (Eq. (16)), TransmissionError (Eq. (20)) or Perturbation (Eq. (47a)).
    nlte_weight : () 1.0 to keep the NLTE terms, 0.0 for NLTE = 0 (module docstring;
        data, so both are one program); ``nlte_terms`` reads it on the host.
    nlte_inertia : keep the NLTE'' inertial term (False: Section 6.3.2, NLTE'' = 0 only).
    nlte_method : ``"substitution"`` (exact, default) or ``"spectral"``.
    nlte_harmonics : harmonics of the mesh frequency kept by the spectral method.
    excitation : ``"table"`` (default) or ``"inline"`` quasi-static excitations.
    period_rad : period of the excitation in theta (rad): one mesh period ``2 pi / z1``
        without pitch errors or eccentricity, else the common period of the rotations
        that carry them (one pinion revolution for pinion errors only).
    jumps : :class:`~gearjax.excitation.jumps.JumpSet` of the angles in ``[0, period_rad)``
        where the right-hand side jumps or kinks independently of speed (cell
        engagement/exit, quasi-static active-set changes, NLTE kinks, back-flank
        engagement), padded to a static bound; ``jump_thetas`` its valid angles.
    moving_events : the switching angles move with the design through the angle map.
    table_knots, table_cell_first : layout of the excitation table (see
        :class:`PeriodicHermiteTable`).
    table_side : (K,) -1 / +1 for the knots just left / right of a jump, 0 elsewhere: their
        one-sided values come from ``1e-9`` periods inside the branch, not from round-off.
    angle_map : :class:`AngleMap` from the simulation angle to the pinion angle, None when
        no switching angle depends on the design.
    structure_ok : traced bool, the discrete quasi-static state at every knot is the
        build one (the angle map and table are valid).
    table : :class:`PeriodicHermiteTable` of (x_S (m), (sum k)^S (N/m), NLTE (m)).
    k_m : mean loaded quasi-static stiffness (N/m).
    x_ref : ``F_S / (k_m cos b_b)`` (m).
    omega_n : ``sqrt(k_m cos^2 b_b / m_eq)`` (rad/s).
    kappa : ``J2 / (Rb2^2 m_eq)`` (pinion reaction) or 1 (drive) with the substitution,
        else 0.
    nlte_dd_coeffs : complex Fourier coefficients of NLTE'' (spectral method), else None.
    backlash_m : clearance between the back flanks (m), or None (module docstring).
    contact_law : :class:`~gearjax.gears.contact.TEContactLaw` of te/perturbation (static).
    """

    angle_map: AngleMap | None = eqx.field(kw_only=True)
    structure_ok: jax.Array = eqx.field(kw_only=True)
    table: PeriodicHermiteTable = eqx.field(kw_only=True)
    k_m: jax.Array = eqx.field(kw_only=True)
    x_ref: jax.Array = eqx.field(kw_only=True)
    omega_n: jax.Array = eqx.field(kw_only=True)
    kappa: jax.Array = eqx.field(kw_only=True)
    nlte_dd_coeffs: jax.Array | None = eqx.field(kw_only=True)

    def __check_init__(self):
        if not isinstance(self.formulation, AbstractFormulation):
            raise ModelError("formulation", self.formulation, "must be a formulation object")
        if self.inertias_kg_m2.shape != (2,):
            raise ModelError("inertias_kg_m2", self.inertias_kg_m2.shape, "must have shape (2,)")
        if self.table.values.shape != (self.table_knots.shape[0], 3):
            raise ModelError("table", self.table.values.shape,
                             "must hold (x_S, (sum k)^S, NLTE) at every table knot")
        if not isinstance(self.contact_law, TEContactLaw):
            raise ModelError("contact_law", self.contact_law,
                             f"must be a TEContactLaw ({', '.join(c.name for c in TEContactLaw)})")
        if self.contact_law is TEContactLaw.CELLS and self.te_input is not None:
            raise ModelError("contact_law", "CELLS", "the per-cell contact law needs the cells' "
                             "gaps; a TE file gives TE_S alone (use TEContactLaw.MESH)")

    # ------------------------------------------------------------------ construction
    @classmethod
    def _complete(cls, **inputs) -> "TorsionalModel":
        """The complete model of these inputs (derived arrays assembled, traceable)."""
        return cls(**inputs, **_assemble(_TorsionalData(**inputs)))

    def with_modifications(self, mods: ToothModifications) -> "TorsionalModel":
        """The model with tooth modifications ``mods`` (same shapes as the build ones) and
        every derived array recomputed from them: traceable (jit / vmap / jacfwd), the
        switching angles follow the design through the angle map while
        :attr:`structure_ok` holds (module docstring)."""
        inputs = {f.name: getattr(self, f.name) for f in dataclasses.fields(_TorsionalData)}
        inputs["mods"] = mods
        return TorsionalModel._complete(**inputs)

    def with_te(self, te, nlte_terms: bool | None = None) -> "TorsionalModel":
        """This te/perturbation model driven by a TE file (module docstring, "TE from a
        file"); ``nlte_terms`` None: kept iff the file's NLTE is not 0."""
        if isinstance(self.formulation, Reference) or (self.excitation, self.nlte_method) != ("table", "substitution"):
            raise ModelError("formulation", self.formulation.name, "a TE file drives te or perturbation"
                             " (excitation='table', nlte_method='substitution'), not the reference"
                             " formulation (Eq. (16): a gap per cell)")
        inputs = {f.name: getattr(self, f.name) for f in dataclasses.fields(_TorsionalData)}
        inputs.update(te_model_fields(te, self.table, self.table_side, self.jump_thetas, nlte_terms))
        return TorsionalModel._complete(**inputs)

    build = classmethod(build_torsional)

    @property
    def mesh_level_contact(self) -> bool:
        """False with the per-cell contact law (:attr:`contact_law` ``CELLS``)."""
        return self.contact_law is TEContactLaw.MESH

    def angle(self, s):
        """(theta, dtheta/ds): the pinion angle (rad) at the simulation angle ``s`` (rad).
        Identity at the build-time design; see the module docstring."""
        amap = self.angle_map
        if amap is None:
            return s, None
        return amap(s)

    def _table(self, s):
        """Tabulated (x_S, (sum k)^S, NLTE) at the simulation angle ``s`` and their
        derivatives with respect to theta (the table holds d/ds)."""
        val, der = self.table(s)
        dth = self.angle(s)[1]
        return (val, der) if dth is None else (val, der / dth)

    def excitations(self, theta):
        """Tabulated (x_S, (sum k)^S, NLTE) at ``theta`` and their theta-derivatives:
        two (3,) arrays (m, N/m, m and per rad). ``theta`` is the simulation angle (equal
        to the pinion angle at the build-time design, see :meth:`angle`)."""
        return self._table(theta)

    def natural_frequency_rad_s(self):
        """omega_n = sqrt(k_m cos^2 b_b / m_eq) (rad/s) with the mean loaded stiffness."""
        return self.omega_n

    speed_scaled_state = True  # (z/x_ref, z'/(r x_ref)), r = omega_n/Omega: Omega^-1 A(theta)

    def mean_stiffness_N_per_m(self):
        """k_m: mean of the loaded quasi-static stiffness (sum k_i)^S over one period (N/m)."""
        return self.k_m

    def _nlte_dd(self, theta):
        """NLTE'' (m/rad^2) from the truncated Fourier series (spectral method)."""
        c = self.nlte_dd_coeffs
        h = jnp.arange(c.shape[0])
        ph = 2.0 * jnp.pi * h * theta / self.period_rad
        return jnp.sum(jnp.real(c) * jnp.cos(ph) - jnp.imag(c) * jnp.sin(ph))

    # ------------------------------------------------------------------ dynamics
    def _x_and_slope(self, theta, y, omega, exc):
        """Physical approach x (m) and x' (m/rad) from the scaled state."""
        r = self.omega_n / omega
        z = y[0] * self.x_ref
        zp = y[1] * r * self.x_ref
        if self._substitution:
            val, der = exc
            return z - self.kappa * val[_NLTE], zp - self.kappa * der[_NLTE]
        return z, zp

    def _static_part(self, theta, exc):
        """(x_static, k_S, x_S) used by te/perturbation: x_S, or TE_S without NLTE terms,
        the loaded stiffness and the quasi-static approach x_S itself (m)."""
        if self.excitation == "inline":
            q = self._qs(theta)
        else:
            q = exc[0]
        x_static = q[_X_S] + (1.0 - self.nlte_weight) * q[_NLTE]
        return x_static, q[_K_S], q[_X_S]

    def _mesh_terms(self, theta, x, exc, contact=True):
        """((F_elastic - F_t) / F_t, F_D (N)) at theta for the transverse approach x; te
        and perturbation linear, as printed, with ``contact=False``. With backlash the
        three-state law of :func:`gearjax.gears.contact.three_state_force` (module
        docstring, "Backlash"): F_D < 0 on the back flanks."""
        f_s = self.static_force_N
        if isinstance(self.formulation, Reference):
            if self.backlash_m is not None:
                f_d = cell_backlash_force(self.mesh, self.mods, theta, x * self.cos_bb,
                                          self.backlash_m)
                return f_d / f_s - 1.0, f_d
            cells, delta_e, _ = contact_gaps(self.mesh, self.mods, theta)
            loads = cells.stiffness_N_per_m * jnp.maximum(x * self.cos_bb - delta_e, 0.0)
            f_d = jnp.sum(loads)  # Eq. (22)
            return f_d / f_s - 1.0, f_d
        x_static, k_s, x_s = self._static_part(theta, exc)
        x_d = x - x_static
        stiff = k_s if isinstance(self.formulation, TransmissionError) else self.k_m
        # Eq. (24) with the loaded stiffness for both; contact law: gears.contact
        f_eq, f_ld = f_s + stiff * self.cos_bb * x_d, f_s + k_s * self.cos_bb * x_d
        if not contact:
            cut, f_d = 0.0, f_ld
        elif self.contact_law is TEContactLaw.CELLS:  # each cell's approach x_S cos b_b - de_i
            cells, delta_e, _ = contact_gaps(self.mesh, self.mods, theta)
            cut, f_d = te_cell_contact(f_eq, f_ld, cells.stiffness_N_per_m,
                                       x_s * self.cos_bb - delta_e, x_d * self.cos_bb,
                                       stiff / k_s)
        elif self.backlash_m is not None:
            cut, f_d = te_backlash_contact(f_eq, f_ld, stiff, k_s, self.backlash_m)
        else:
            cut, f_d = te_contact(f_eq, f_ld)
        return (stiff * self.cos_bb * x_d - cut) / f_s, f_d

    def _exc(self, s):
        needs = self._substitution or (not isinstance(self.formulation, Reference) and self.excitation == "table")
        return self._table(s) if needs else None

    def vector_field(self, s, y, omega, contact: bool = True):
        """dy/ds for the scaled state ``y = (z/x_ref, z'/(r x_ref))``, Eqs. (16), (20),
        (47a) (module docstring; ``contact=False``: te/perturbation without the contact
        law): ``phi'(s)`` times dy/dtheta at ``theta = phi(s)`` (``s = theta`` at the
        build-time design); ``omega`` is the pinion speed Omega1 (rad/s)."""
        theta, dth = self.angle(s)
        exc = self._exc(s)
        r = self.omega_n / omega
        x, xp = self._x_and_slope(theta, y, omega, exc)
        resid, _ = self._mesh_terms(theta, x, exc, contact)
        acc = -r * (resid + 2.0 * self.damping_ratio * xp / (r * self.x_ref))
        if self.nlte_inertial_terms and self.nlte_method == "spectral":
            acc = acc - self.nlte_inertia_ratio * self._nlte_dd(theta) / (r * self.x_ref)
        dydth = jnp.stack([r * y[1], acc])
        return dydth if dth is None else dydth * dth

    def initial_state(self, omega, theta0=0.0):
        """Scaled state at ``theta0`` on the quasi-static solution: x = x_S, x' = x_S'
        (dynamic part x_D = x_D' = 0)."""
        r = self.omega_n / omega
        val, der = self._table(jnp.asarray(theta0, dtype=float))
        x_s, x_s_p = val[_X_S], der[_X_S]
        if not isinstance(self.formulation, Reference):  # TE_S without NLTE terms (weight 0)
            w = 1.0 - self.nlte_weight
            x_s, x_s_p = x_s + w * val[_NLTE], x_s_p + w * der[_NLTE]
        if self._substitution:
            x_s = x_s + self.kappa * val[_NLTE]
            x_s_p = x_s_p + self.kappa * der[_NLTE]
        return jnp.stack([x_s / self.x_ref, x_s_p / (r * self.x_ref)])

    def outputs(self, theta, y, omega, contact: bool = True) -> ModelOutputs:
        """Mesh force F_D (N, Eq. (22) or (24)) and DTE = x + NLTE (m) at one angle."""
        exc = self._table(theta)
        theta, _ = self.angle(theta)  # pinion angle of the simulation angle
        x, _ = self._x_and_slope(theta, y, omega, exc)
        _, f_d = self._mesh_terms(theta, x, exc, contact)
        # DTE = x + NLTE; x alone where NLTE = 0 in the model (weight 0, paper Fig. 10)
        w = 1.0 if isinstance(self.formulation, Reference) else self.nlte_weight
        dte = x + w * exc[0][_NLTE]
        return ModelOutputs(mesh_force_N=f_d, dte_m=dte, accel_m_s2=None)

    @property
    def state_size(self) -> int:
        return 2  # (z / x_ref, z' / (r x_ref))

    def homogeneous_vector_field(self, theta, y, omega):
        """Linear homogeneous part of the equation of motion for the dynamic part
        ``y = (x_D/x_ref, x_D'/(r x_ref))``: ``Omega^2 m_eq x_D'' + Omega c x_D' + k(theta)
        cos^2(b_b) x_D = 0`` with ``k = (sum k_i)^S`` (te; the reference formulation
        linearised about the quasi-static contact) or ``k_m`` (perturbation). Used by
        :mod:`gearjax.dynamics.stability`."""
        r = self.omega_n / omega
        if isinstance(self.formulation, Perturbation):
            ratio = jnp.ones(())
        else:
            ratio = self.table(theta)[0][_K_S] / self.k_m
        dydth = jnp.stack([r * y[1], -r * (ratio * y[0] + 2.0 * self.damping_ratio * y[1])])
        dth = self.angle(theta)[1]
        return dydth if dth is None else dydth * dth

    def decay_rate_per_rad(self, omega):
        """Free-decay rate of the linearised model per radian of theta,
        ``zeta omega_n / Omega`` (sizes the automatic transient)."""
        return self.damping_ratio * self.omega_n / omega
