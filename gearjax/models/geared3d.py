"""3D geared-system model: shafts + bearings + pinion-gear element (paper Section 4).

The structure (``M``, ``K``: shafts, discs, bearings, couplings, the resisting torsional
spring; :mod:`gearjax.structure`) is coupled to the mesh cells of :mod:`gearjax.gears.mesh`
through the structure vectors ``V(M_i)`` of the pinion-gear element (Eq. (8a),
:class:`gearjax.structure.element.PinionGearElement`). Three formulations, a static choice so
that each compiles only its own terms (``' = d/dtheta``, ``theta = Omega1 t`` in rad,
``X`` in m and rad, forces in N)::

    "reference"    Eq. (14):  Omega^2 M X'' + Omega C X' + K X
                              + sum_i k_i max(0, V(M_i)^T X - de_i) V(M_i)
                              = F_0 - Omega^2 [NLTE'' E + NLTE' F + G]
    "te"           Eq. (42):  Omega^2 M X'' + Omega C X' + [K_bar + alpha k_m g V V^T] X
                              = F_0 + [k(theta) cos b_b (TE_S - NLTE - w_x0) + alpha F_S g] V
                                - Omega^2 [NLTE'' E + NLTE' F + G]
    "perturbation" Eq. (48a): Omega^2 M X'' + Omega C X' + K_bar X
                              = F_0 + k_m cos b_b (TE_S - NLTE - w_x0) V
                                - Omega^2 [NLTE'' E + NLTE' F + G]

with ``K_bar = K + k_m V V^T`` (Eq. (27)), ``k(theta) = k_m (1 + alpha g)`` the loaded
quasi-static stiffness (N/m) and ``k_m`` its mean over one excitation period, so that
``alpha k_m g = k(theta) - k_m``. Contact algorithm (Section 6.2) in (42)/(48a): their mesh
term acts along ``V`` with the linear force ``F_S + k v_xD`` (``k_m`` in (48a)), kept while
compressive and cut to zero (stiffness and TE forcing together) when it would be tensile
(:func:`gearjax.gears.contact.te_contact`); ``V`` the averaged structure vector (Eq. (A.1)), ``W``
the TE projection vector (Rb1, Rb2 at the encoder torsional dofs, Eq. (10)),
``X_0 = K_bar^-1 F_0``, ``w_x0 = W^T X_0``, ``v_x0 = V^T X_0``. With
``contact_law=TEContactLaw.CELLS`` the contact is resolved cell by cell
(:func:`gearjax.gears.contact.te_cell_contact`): the force along ``V`` is Eq. (37) with the
unilateral law per cell, ``sum_i k_i max(0, a_i + v_xD)``, ``a_i = V(M_i)^T X_S - de_i``
each cell's approach in the quasi-static solution (Eq. (25); its element dofs are
tabulated beside ``d, k``) and ``v_xD = V^T (X - X_S)`` (Eq. (41)); it is Eq. (42)/(48a)
bit for bit while every cell keeps its quasi-static state, and differs from the reference
Eq. (14) only through the averaged ``V`` of the dynamic approach and through ``X_S`` of Eq.
(32).

Quasi-static solution and excitation (Eqs. (25), (36)): the structure is condensed onto the
12 pinion-gear dofs and solved with unilateral contact
(:mod:`gearjax.structure.condensation`); te/perturbation tabulate ``(TE_S - NLTE - w_x0,
k(theta), NLTE)`` once per design, with the switching angles moving with the design, or
take TE_S, NLTE and k from a TE file (:mod:`gearjax.models.geared3d_excitation`).

Inertial excitations (text after Eq. (14)): ``E`` (Eq. (5), :meth:`gearjax.structure.geared.
GearedStructure.inertial_vector`) plus the eccentricity parts ``E~``, ``F~``, ``G~``
(:class:`gearjax.structure.geared.Eccentricity`). Without eccentricity these are not
compiled; without NLTE terms (``nlte_terms=False``, or NLTE identically zero where the build
does not keep them for every design, :func:`gearjax.models.geared3d_build.shares_nlte_programs`)
E and F are not compiled and ``TE_S - NLTE`` becomes ``TE_S``; ``nlte_inertia=False`` (Section
6.3.2, "NLTE'' set at zero") drops the E and F terms alone, with no substitution (``u = q'``).
``E_0`` is projected once at build (``e_r = T^T E_0``); the eccentricity parts act at the
12 element dofs; ``G~`` (the unbalance of eccentric bodies, no NLTE in it) stays whenever
there is an eccentricity.

NLTE'' without differentiating a kinked function: with ``u = q' + NLTE' e(theta)`` (``q``
modal coordinates, ``M_r = I``, ``e = T^T E``) the equations are integrated as
``u' = (...)/Omega^2 + NLTE' e'``, ``q' = u - NLTE' e``: only NLTE' enters and its kinks
are integrator jumps (:attr:`jump_thetas`).

Backlash (reference formulation, ``backlash_m``): the back flanks mesh on the second base
plane (:mod:`gearjax.gears.backlash`): at ``theta`` the cells of the drive pattern at the
mirror angle ``phi0 - theta``, with the structure vectors ``V'(M_i) = H V(M_i)`` of the
half-turn about the line of centres
(:meth:`gearjax.structure.element.PinionGearElement.back_vectors`), add
``sum_i k_i max(0, V'(M_i)^T X - b - r_min - r'_min - de'_i) V'(M_i)`` to Eq. (14); the
mesh force is the drive cells' total minus the back cells' (negative on the back flanks).
te/perturbation: the mesh-level law of each flank along its averaged vector, the drive
flanks' ``F_S + k v_xD`` along ``V`` as in Section 6.2 and the back flanks' ``k max(0,
delta_b)`` along ``V' = H V`` with ``delta_b = V'^T (X - X_nl) - b``, ``X_nl = X_S - (F_S /
k) C_v / C_vv`` the drive flanks' no-load position on the static compliance line (the
stiffness ``k`` of the equation: k(theta) in (42), ``k_m`` in (48a); reported with the
loaded one); in torsion ``delta_b = -delta - b``, the sdof law of
:func:`gearjax.gears.contact.te_backlash_contact`. The quasi-static solution, ``k_m`` and
the modal basis are the drive flanks' (the static load never reaches the back flanks).

Modal coordinates: ``X = T q`` with ``T`` from :func:`gearjax.structure.reduced_model` on
``(M, K_bar)``: all modes (exact) or those below a cut-off plus static-correction
pseudo-modes for ``F_0``, ``E`` and unit loads on the 12 element dofs (every static mesh
response, hence ``X_0``, ``X_S`` and ``C_v``, stays exact); ``M_r = I``; damping
``C = M Phi diag(2 zeta omega) Phi^T M`` (unique modal damping factor, Section 6.1).
State: ``y = ((q - q_0)/a, u / (r a))`` (dimensionless) with ``q_0`` the coordinates of
``X_0``, ``r_j = omega_j / Omega`` and ``a`` the largest modal coordinate of
``F_S C_v`` (Eq. (A.2)).

Outputs: mesh force (N), reference ``sum_i k_i max(0, V(M_i)^T X - de_i)``, te/perturbation
Eq. (41) ``F_D = F_S + k(theta) V^T (X - X_S)`` (0 while separated) with ``V^T X_S = v_x0 +
cos b_b (TE_S - NLTE - w_x0)`` (Eq. (36)); DTE ``= W^T X + NLTE`` (m, Eq. (10)); acceleration of the pinion
centre along s ``Omega^2 X_v''`` (m/s^2, the Dirac part of NLTE'' excluded).
Measurements behind these choices: ``benchmarks/results/model_notes.md`` ("geared3d").
"""

from __future__ import annotations

import dataclasses
import math

import equinox as eqx
import jax
import jax.numpy as jnp

from ..errors import ModelError
from ..linalg import solve as dense_solve
from ..excitation.events import NEWTON_STEPS
from ..excitation.jumps import JumpSet
from ..excitation.mesh3d import (QuasiStaticMesh3D, fourier_coefficients, harmonic_response,
                                 tabulate)
from ..excitation.tables import AngleMap, PeriodicHermiteTable
from ..gears.mesh import Mesh
from ..gears.modifications import ToothModifications
from ..gears.backlash import back_flank_angle_rad, back_flank_gaps
from ..gears.contact import TEContactLaw, te_cell_contact, te_contact
from ..gears.quasistatic import contact_gaps, static_mesh_force
from ..structure.condensation import Condensation, QuasiStatic3D
from ..structure.element import PinionGearElement
from ..structure.geared import Eccentricity
from .base import (LINEAR_FORMULATIONS, AbstractModalModel, ModelOutputs,
                   modal_periodic_estimate, modal_transient_amplitudes, modal_transient_start)
from .formulations import (AbstractFormulation, Perturbation, Reference, TransmissionError,
                           formulation_of)
from .geared3d_build import EXCITATIONS, MESH_VECTORS, build_geared3d, nlte_vanishes
from .cutoff import (CUTOFF_FLOOR_HZ, CUTOFF_MARGIN, CUTOFF_MESH_HARMONICS,  # re-exported
                     default_max_frequency_hz)

__all__ = ["Geared3DModel", "MESH_VECTORS", "default_max_frequency_hz", "CUTOFF_FLOOR_HZ",
           "CUTOFF_MARGIN", "CUTOFF_MESH_HARMONICS"]



class Geared3DModel(AbstractModalModel):
    """3D geared system, Eqs. (14), (42), (48a). Build with :meth:`build`; complete when
    built (table, angle map and structure flag of the build design included).

    Array attributes (modal basis ``T``, r columns; element dofs ``l``)
    ------------------------------------------------------------------
    mesh, mods, element : mesh model, tooth modifications, pinion-gear element.
    t_local : (12, r) rows of ``T`` at the element dofs.
    kbar_r, c_r : (r, r) ``T^T K_bar T`` (diagonal up to round-off), ``T^T C T``.
    omega_r : (r,) ``sqrt(diag(kbar_r))`` (rad/s).
    v_r, w_r, acc_r : (r,) ``T^T V``, ``T^T W`` and the row of ``T`` at the pinion v dof.
    e_r : (r,) ``T^T E`` (constant part of E), zeros when unused.
    q0, c_v_r : (r,) modal coordinates of ``X_0 = K_bar^-1 F_0`` and ``C_v = K_bar^-1 V``.
    v_local, free12 : (12,) averaged ``V`` at the element dofs; 1 for free element dofs.
    cond : :class:`gearjax.structure.condensation.Condensation` (quasi-static solve).
    k_m : mean loaded quasi-static stiffness (N/m), the splitting constant of K_bar.
    pinion_torque_Nm, damping_ratio, scale_a : C_m0 (N m), zeta, state scale ``a`` (m).
    ecc : eccentricity data or None.
    table_knots, table_cell_first, table_side, table_codes : build layout of the
        excitation table (te/perturbation with ``excitation="table"``, else None), padded
        to the rig's layout bounds (:mod:`gearjax.models.geared3d_layout`).
    table_origin : () the table's first knot (rad), far from every jump.
    jumps : the integrator's jump angles with the kind and cells of each switching event
        (:class:`~gearjax.excitation.jumps.JumpSet`, padded); the angle map moves the
        events of moving kinds (:meth:`jump_angles_rad`).
    decay_omega_rad_s : () the slowest natural frequency (rad/s) with a mesh participation
        above ``participation_tol``: it sizes the transient (:meth:`decay_rate_per_rad`).
    table, angle_map : the excitation table and the angle map of this design (None
        without table / without moving events).
    structure_ok : (bool array) this design keeps the discrete structure of the build.
    te_weight : te/perturbation: 1.0 for Eq. (42), 0.0 for Eq. (48a) (the stiffness of the
        linear mesh term, k(theta) or k_m, chosen by data: :meth:`compiled_form`); None for
        the reference formulation.
    backlash_m : clearance between the back flanks (m), or None: no back flanks (module
        docstring, "Backlash").
    contact_law : te/perturbation contact law, :class:`gearjax.gears.contact.TEContactLaw`
        (static; ``CELLS``: the table also holds the 12 element dofs of X_S).

    Static attributes: formulation, mesh_vectors, nlte_terms, nlte_inertia, n_modes, n_static,
    diagonal_stiffness and damping_split
    (:func:`~gearjax.models.geared3d_build.modal_structure`: ``kbar_r`` is applied as its
    diagonal, ``c_r`` as its diagonal on the first ``damping_split`` coordinates and a
    dense block on the rest),
    period_rad, qs_max_iter, table_cells, table_max_extra (the bound of the layout),
    excitation, harmonic_start, te_source (the TE file driving the excitation, or None).
    The layout of the events and the table is data, so every design of one rig (relief,
    pitch errors, damping, torque) shares the model's compiled programs.
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
    ecc: Eccentricity | None
    table_knots: jax.Array | None
    table_cell_first: jax.Array | None
    table_side: jax.Array | None
    table_codes: jax.Array | None
    table: PeriodicHermiteTable | None
    angle_map: AngleMap | None
    structure_ok: jax.Array
    jumps: JumpSet
    table_origin: jax.Array
    decay_omega_rad_s: jax.Array
    formulation: AbstractFormulation = eqx.field(static=True)
    mesh_vectors: str = eqx.field(static=True)
    nlte_terms: bool = eqx.field(static=True)
    n_modes: int = eqx.field(static=True)
    n_static: int = eqx.field(static=True)
    period_rad: float = eqx.field(static=True)
    qs_max_iter: int = eqx.field(static=True)
    table_cells: int = eqx.field(static=True)
    table_max_extra: int = eqx.field(static=True)
    excitation: str = eqx.field(static=True)
    harmonic_start: bool = eqx.field(static=True)
    te_source: str | None = eqx.field(static=True, default=None)
    nlte_inertia: bool = eqx.field(static=True, default=True)
    diagonal_stiffness: bool = eqx.field(static=True, default=False)
    damping_split: int = eqx.field(static=True, default=0)
    te_weight: jax.Array | None = None
    backlash_m: jax.Array | None = None
    contact_law: TEContactLaw = eqx.field(static=True, default=TEContactLaw.MESH)

    def __check_init__(self):
        if not isinstance(self.formulation, AbstractFormulation):
            raise ModelError("formulation", self.formulation, "must be a formulation object "
                             "(gearjax.models.formulations; the builders also take its name)")
        if self.mesh_vectors not in MESH_VECTORS:
            raise ModelError("mesh_vectors", self.mesh_vectors, f"must be one of {MESH_VECTORS}")
        if self.excitation not in EXCITATIONS:
            raise ModelError("excitation", self.excitation, f"must be one of {EXCITATIONS}")
        if (self.table is None) != (self.table_knots is None):
            raise ModelError("table", None, "the excitation table and its layout go together")
        if (self.angle_map is not None) and self.table is None:
            raise ModelError("angle_map", "...", "an angle map needs the excitation table")
        if not isinstance(self.contact_law, TEContactLaw):
            raise ModelError("contact_law", self.contact_law,
                             f"must be a TEContactLaw ({', '.join(c.name for c in TEContactLaw)})")
        if self.cell_contact and self.te_source is not None:
            raise ModelError("contact_law", "CELLS", "the per-cell contact law needs the cells' "
                             "gaps; a TE file gives TE_S alone (use TEContactLaw.MESH)")
        if self.cell_contact and self.table is not None and self.table.values.shape[1] != 15:
            raise ModelError("table", self.table.values.shape, "the per-cell contact law needs "
                             "(d, k, NLTE) and the 12 element dofs of X_S at every knot")

    # ------------------------------------------------------------------ construction
    build = classmethod(build_geared3d)

    def with_formulation(self, formulation) -> "Geared3DModel":
        """This model in the other linearised formulation, te <-> perturbation (an
        :class:`~gearjax.models.formulations.AbstractFormulation` or its name).
        Eqs. (42) and (48a) take the same quasi-static table, ``k_m`` and modal basis from
        the build (only the mesh term of the equations differs), so a sweep of both
        builds once (the reference formulation has no table: build it)."""
        formulation = formulation_of(formulation)
        if not (self.formulation.linear and formulation.linear):
            raise ModelError("formulation", formulation.name, f"only {LINEAR_FORMULATIONS} share "
                             f"a build; this model is {self.formulation.name!r}")
        return dataclasses.replace(self, formulation=formulation,
                                   te_weight=jnp.asarray(formulation.te_weight))

    def compiled_form(self) -> "Geared3DModel":
        """A perturbation model is handed to compiled sweeps as the te model with its
        :attr:`te_weight` 0: the two formulations' equations differ only in that weight
        (:meth:`_elastic`), their solver and transient in nothing, so the main job
        compiles one program for both (one tracing and XLA compile saved). The
        perturbation model's own ``harmonic_start`` state keeps it apart."""
        if (isinstance(self.formulation, Perturbation) and self.te_weight is not None
                and not self.periodic_start):
            return dataclasses.replace(self, formulation=TransmissionError())
        return self

    # ------------------------------------------------------------------ constants
    @property
    def cell_contact(self) -> bool:
        """te/perturbation with the per-cell contact law (:attr:`contact_law` ``CELLS``)."""
        return self.contact_law is TEContactLaw.CELLS and not isinstance(self.formulation, Reference)

    @property
    def mesh_level_contact(self) -> bool:
        """False with the per-cell contact law (:attr:`cell_contact`)."""
        return not self.cell_contact

    @property
    def cos_bb(self) -> float:
        """cos of the base helix angle b_b."""
        return math.cos(self.mesh.pair.base_helix_angle_rad)

    @property
    def mesh_period_rad(self) -> float:
        """One mesh period in theta, 2 pi / z1 (rad)."""
        return self.mesh.pair.mesh_period_rad

    @property
    def static_force_N(self):
        """F_S = C_m0 / (Rb1 cos b_b) (N)."""
        return static_mesh_force(self.mesh.pair, self.pinion_torque_Nm)

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
        """C_wv = W^T K_bar^-1 V (m/N), = 1 / (k_m cos b_b) (Eq. (35))."""
        return self.w_r @ self.c_v_r

    @property
    def c_vv(self):
        """C_vv = V^T K_bar^-1 V (m/N), = 1 / k_m (Eq. (33))."""
        return self.v_r @ self.c_v_r

    # ------------------------------------------------------------------ design
    def quasi_static_mesh(self) -> QuasiStaticMesh3D:
        """The quasi-static mesh of this design (Eqs. (25), (36)): the speed-independent
        side of the model (:mod:`gearjax.excitation.mesh3d`)."""
        return QuasiStaticMesh3D(
            mesh=self.mesh, mods=self.mods, element=self.element, cond=self.cond,
            v_local=self.v_local, free12=self.free12, static_force_N=self.static_force_N,
            v_x0=self.v_x0, c_vv=self.c_vv, c_wv=self.c_wv, mesh_vectors=self.mesh_vectors,
            qs_max_iter=self.qs_max_iter, nlte_terms=self.nlte_terms,
            loaded_codes=not isinstance(self.formulation, Reference), cell_states=self.cell_contact)

    def with_modifications(self, mods: ToothModifications) -> "Geared3DModel":
        """The complete model of the design ``mods`` (same structure, modal basis, ``k_m``
        and build layout): excitation table, angle map through the moved events and
        :attr:`structure_ok` recomputed (False also where a model without NLTE terms meets
        NLTE: :func:`~gearjax.models.geared3d_build.nlte_vanishes`). Traceable in ``mods``."""
        if self.te_source is not None:
            raise ModelError("te_source", self.te_source, "the excitation comes from a TE file; "
                             "tooth modifications cannot change it (build the model without it)")
        m = eqx.tree_at(lambda m: m.mods, self, mods)
        table, amap, ok = m.table, m.angle_map, jnp.asarray(True)
        if m.table_knots is not None:
            table, amap, ok = tabulate(
                m.quasi_static_mesh(), m.table_knots, m.table_side, m.table_cell_first,
                origin=m.table_origin, period=m.period_rad, n_cells=m.table_cells,
                max_extra=m.table_max_extra, events=None if m.angle_map is None else m.jumps,
                table_codes=m.table_codes)
        if not m.nlte_terms:  # built without NLTE terms: valid while the design has none
            ok = ok & nlte_vanishes(m.mesh, mods, m.period_rad)
        return eqx.tree_at(lambda m: (m.table, m.angle_map, m.structure_ok), m,
                           (table, amap, ok), is_leaf=lambda x: x is None)

    def jump_angles_rad(self, newton_steps: int = NEWTON_STEPS):
        """The event angles ``theta_j`` (rad) of the current design, one per entry of
        :attr:`jumps` (padding included): Newton iterations on the switching functions
        from the build-time angle (fixed events stay); differentiable in the
        modifications (at the root ``d theta_j = -(dg/d design) / (dg/d theta)``)."""
        j = self.jumps
        return self.quasi_static_mesh().event_angles(j.thetas, j.kinds, j.cells, newton_steps)

    def angle(self, s):
        """(theta, dtheta/ds): the pinion angle (rad) at the simulation angle ``s`` (rad);
        ``(s, None)`` without moving events. Identity at the build-time design."""
        if self.angle_map is None:
            return s, None
        return self.angle_map(s)

    # ------------------------------------------------------------------ quasi-static
    def quasi_static(self, theta) -> QuasiStatic3D:
        return self.quasi_static_mesh().solve(theta)  # Eq. (25) at theta (rad, scalar)

    def _excitation(self, theta):
        """(d (m), k (N/m)) with d = TE_S - NLTE - w_x0 (or TE_S - w_x0 without NLTE terms)
        and the loaded quasi-static stiffness k(theta), for te/perturbation (tabulated, or
        the exact solve with ``excitation="inline"``)."""
        if self.table is not None:
            vals, _ = self.table(theta)
            return vals[0], vals[1]
        e = self.quasi_static_mesh().excitation(theta)
        return e[0], e[1]

    def _static_local(self, s):
        """The 12 element dofs of the quasi-static X_S (Eq. (25)) at the simulation angle
        ``s`` (m, rad): tabulated with the per-cell contact law, else solved."""
        if self.table is not None:
            return self.table(s)[0][3:]
        return self.quasi_static(self.angle(s)[0]).x_local

    def _static_q(self, theta):
        """Modal coordinates of the quasi-static X_S seen by this formulation."""
        if isinstance(self.formulation, Reference):
            # K X_S = F_0 - f_mesh with K = K_bar - k_m V V^T and V^T X_S = V_l^T x_l
            qs = self.quasi_static(theta)
            cells, _, _ = contact_gaps(self.mesh, self.mods, theta)
            f_loc = self.quasi_static_mesh().vectors(cells).T @ qs.cell_load_N
            rhs = -(self.t_local.T @ f_loc) + self.k_m * self.v_r * (self.v_local @ qs.x_local)
            return self.q0 + dense_solve(self.kbar_r, rhs)
        d, _ = self._excitation(theta)
        return self.q0 + d / self.c_wv * self.c_v_r

    # ------------------------------------------------------------------ excitation vectors
    @property
    def nlte_inertial_terms(self) -> bool:
        """``NLTE'' E + NLTE' F`` are in the equations (``nlte_terms`` and ``nlte_inertia``)."""
        return self.nlte_terms and self.nlte_inertia

    def _inertial(self, theta):
        """``(e, e', f, g)`` (r,) in modal coordinates at the pinion angle ``theta`` (rad):
        ``T^T E``, its theta-derivative, ``T^T F~`` and ``T^T G~``; None for the terms that
        are absent (no eccentricity: E constant, no E', F~, G~; no NLTE inertial terms)."""
        use_e = self.nlte_inertial_terms
        if self.ecc is None:
            return (self.e_r if use_e else None), None, None, None
        tl = self.t_local.T
        rb1, rb2 = self.mesh.pair.base_radii_m
        _, f_loc, g_loc = self.ecc.local_vectors(theta, rb1, rb2)
        if not use_e:
            return None, None, None, tl @ g_loc
        e, ep = jax.jvp(lambda t: self.e_r + tl @ self.ecc.local_vectors(t, rb1, rb2)[0],
                        (theta,), (jnp.ones_like(theta),))
        return e, ep, tl @ f_loc, tl @ g_loc

    def _nlte_derivs(self, s, order: int = 1):
        """NLTE (m) and its derivatives with respect to theta (``order`` 1 or 2) at the
        simulation angle ``s`` (chain rule through the angle map: d/dtheta = (d/ds) /
        phi'): from the excitation table (its Hermite segment's own derivative, the lookup
        that :meth:`_excitation` makes; exact at the kinks, which are knots) or the exact
        :func:`gearjax.gears.quasistatic.contact_gaps`."""

        def d1(t):
            if self.table is not None:
                n0, n1 = (v[2] for v in self.table(t))
            else:
                n0, n1 = jax.jvp(lambda t: contact_gaps(self.mesh, self.mods, t)[2], (t,),
                                 (jnp.ones_like(t),))
            dth = self.angle(t)[1]
            return n0, (n1 if dth is None else n1 / dth)

        if order == 1:
            return d1(s)
        (n0, n1), (_, n2) = jax.jvp(d1, (s,), (jnp.ones_like(s),))
        dth = self.angle(s)[1]
        return n0, n1, (n2 if dth is None else n2 / dth)

    def _stiffness_product(self, z):
        """``kbar_r @ z`` (modal coordinates), as the diagonal product where
        :attr:`diagonal_stiffness` (the two dense products took most of a step)."""
        if self.diagonal_stiffness:
            return jnp.diagonal(self.kbar_r) * z
        return self.kbar_r @ z

    def _damping_product(self, qp):
        """``c_r @ qp``: diagonal on the first :attr:`damping_split` (modal) coordinates,
        dense on the static-correction block after them (0: dense everywhere)."""
        p = self.damping_split
        if p == 0:
            return self.c_r @ qp
        head = jnp.diagonal(self.c_r)[:p] * qp[:p]
        return jnp.concatenate([head, self.c_r[p:, p:] @ qp[p:]])

    # ------------------------------------------------------------------ dynamics
    def _unscale(self, y, omega):
        r = self.omega_r / omega
        nr = self.n_reduced
        z = y[:nr] * self.scale_a
        u = y[nr:] * r * self.scale_a
        return z, u, r

    def _elastic(self, s, q, contact: bool = True):
        """(restoring minus static force in modal coordinates, mesh force F_D (N)) at the
        simulation angle ``s``; te/perturbation with the contact law of
        :func:`gearjax.gears.contact.te_contact` unless ``contact=False`` (linear)."""
        z = q - self.q0
        f_s = self.static_force_N
        if isinstance(self.formulation, Reference):  # no angle map: s = theta
            cells, de, nlte = contact_gaps(self.mesh, self.mods, s)
            qsm = self.quasi_static_mesh()
            vecs = qsm.vectors(cells)
            x_loc = self.t_local @ q
            loads = cells.stiffness_N_per_m * jnp.maximum(vecs @ x_loc - de, 0.0)
            f_loc = vecs.T @ loads
            f_d = jnp.sum(loads)
            if self.backlash_m is not None:  # back flanks: the module docstring, "Backlash"
                b_loc, b_load = self._back_flanks(s, x_loc, nlte, qsm)
                f_loc, f_d = f_loc + b_loc, f_d - b_load
            # K q - F0 = K_bar z - k_m V (V^T q) + k_m v_x0 V ... with K_bar q0 = F0
            force = (self._stiffness_product(z) - self.k_m * self.v_r * (self.v_r @ q)
                     + self.t_local.T @ f_loc)
            return force, f_d
        d, k = self._excitation(s)
        v_q = self.v_r @ q
        v_xs = self.v_x0 + self.cos_bb * d
        f_d = f_s + k * (v_q - v_xs)  # Eq. (41)
        # force = K_bar z - k_m v_q V + f_eq V: f_eq the equation's linear mesh force, Eq.
        # (42) with k(theta), Eq. (48a) the same with k_m (te_weight 1 / 0: data, so that
        # both formulations run in one compiled program, compiled_form)
        k_eq = k
        if self.te_weight is not None:
            k_eq = jnp.where(self.te_weight > 0.5, k, self.k_m)
        elif isinstance(self.formulation, Perturbation):
            k_eq = self.k_m
        f_eq = k_eq * v_q - k_eq * self.cos_bb * d - (k_eq - self.k_m) * f_s / self.k_m
        force = self._stiffness_product(z) + (f_eq - self.k_m * v_q) * self.v_r
        if not contact:
            return force, f_d
        if self.cell_contact:  # each cell's quasi-static approach V(M_i)^T X_S - de_i
            cells, de, _ = contact_gaps(self.mesh, self.mods, self.angle(s)[0])
            a = self.quasi_static_mesh().vectors(cells) @ self._static_local(s) - de
            cut, f_d = te_cell_contact(f_eq, f_d, cells.stiffness_N_per_m, a, v_q - v_xs,
                                       k_eq / k)
        else:
            cut, f_d = te_contact(f_eq, f_d)
        if self.backlash_m is not None:  # the back flanks: module docstring, "Backlash"
            vb_r = self.t_local.T @ self.element.back_vectors(self.v_local)
            q_s = self.q0 + d / self.c_wv * self.c_v_r  # X_S, Eq. (29)
            shift = (vb_r @ self.c_v_r) / self.c_vv  # V'^T C_v / C_vv (-1 in torsion)
            delta_b = vb_r @ (q - q_s) + f_s / k_eq * shift - self.backlash_m
            load = jnp.maximum(delta_b, 0.0)
            read = jnp.maximum(vb_r @ (q - q_s) + f_s / k * shift - self.backlash_m, 0.0)
            f_d = f_d - jnp.where(delta_b > 0.0, k * read, 0.0)  # read as Eq. (41)
            return force - cut * self.v_r + k_eq * load * vb_r, f_d
        return force - cut * self.v_r, f_d

    def _back_flanks(self, theta, x_loc, nlte, qsm):
        """(12,) element forces and total load (N) of the back-flank cells at ``theta``
        for the element displacements ``x_loc``: the cells of the mirror angle with their
        vectors ``V'(M_i) = H V(M_i)``, loaded ``k_i max(0, V'^T x - (b + r_min + r'_min)
        - gap'_i)`` (:mod:`gearjax.gears.backlash`; ``r_min = NLTE cos b_b`` of the drive
        flanks at ``theta``)."""
        cells, gaps, b_min = back_flank_gaps(self.mesh, self.mods, theta,
                                             back_flank_angle_rad(self.mesh.pair))
        vecs = self.element.back_vectors(qsm.vectors(cells)) * self.free12[None, :]
        clearance = self.backlash_m + nlte * self.cos_bb + b_min
        loads = cells.stiffness_N_per_m * jnp.maximum(vecs @ x_loc - clearance - gaps, 0.0)
        return vecs.T @ loads, jnp.sum(loads)

    def _accel(self, s, y, omega, contact: bool = True):
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
        force, _ = self._elastic(s, q, contact)
        up = -(force + omega * self._damping_product(qp)) / omega**2
        if ep is not None:
            up = up + nl1 * ep
        if f is not None:
            up = up - nl1 * f
        if g is not None:
            up = up - g
        return q, qp, up

    def vector_field(self, s, y, omega, contact: bool = True):
        """d y / d s for the scaled state ``y = ((q - q_0)/a, u/(r a))`` (module
        docstring): ``phi'(s)`` times d y / d theta at ``theta = phi(s)`` (``s = theta``
        at the build-time design); ``omega`` is the pinion speed Omega1 (rad/s)."""
        _, qp, up = self._accel(s, y, omega, contact)
        r = self.omega_r / omega
        dyth = jnp.concatenate([qp / self.scale_a, up / (r * self.scale_a)])
        dth = self.angle(s)[1]
        return dyth if dth is None else dyth * dth

    @property
    def state_size(self) -> int:
        return 2 * self.n_reduced  # the scaled state y = ((q - q_0)/a, u/(r a))

    def homogeneous_vector_field(self, theta, y, omega):
        """The linear part of :meth:`vector_field` (te/perturbation without the contact law,
        affine in ``y``), for the Floquet analysis of :mod:`gearjax.dynamics.stability`."""
        if isinstance(self.formulation, Reference):
            raise ModelError("formulation", "reference", "the contact law is not linear; the "
                             "linearisation about the quasi-static contact is the te formulation")
        f = lambda y: self.vector_field(theta, y, omega, contact=False)  # noqa: E731
        return f(y) - f(jnp.zeros_like(y))

    @property
    def periodic_start(self) -> bool:
        """True when :meth:`initial_state` is already the periodic steady state (opt-in
        ``harmonic_start=True`` at build, perturbation formulation without NLTE and
        eccentricity terms: see :meth:`harmonic_state`), so that no transient needs
        integrating (why opt-in: ``benchmarks/results/model_notes.md``)."""
        return self.harmonic_start and self._constant_coefficients

    speed_scaled_state = True  # ((q-q0)/a, u/(r a)), r = omega_r/Omega: Omega^-1 A(theta)

    @property
    def _constant_coefficients(self) -> bool:
        """Eq. (48a) without NLTE inertial and eccentricity terms, excitation tabulated."""
        return (isinstance(self.formulation, Perturbation) and not self.nlte_inertial_terms
                and self.ecc is None and self.table_knots is not None)

    def harmonic_state(self, omega, theta0=0.0, n_harmonics: int | None = None):
        """Periodic steady state of Eq. (48a) at ``theta0`` (scaled state), exact in the
        frequency domain while contact holds: without NLTE inertial and eccentricity terms Eq.
        (48a) has *constant* coefficients and the forcing ``k_m cos(b_b) d(theta) V``, ``d =
        TE_S - NLTE - w_x0`` (``TE_S - w_x0`` without NLTE), so each harmonic answers alone
        by the modal receptance (:func:`~gearjax.excitation.mesh3d.harmonic_response`;
        ``d`` sampled 8x finer than the table knots against the aliasing of a kinked signal,
        ``n_harmonics`` kept, default 128 per mesh period: ``d_h = O(h^-2)``, ``z_h =
        O(h^-4)``)."""
        if not self._constant_coefficients:
            raise ModelError("formulation", self.formulation.name,
                             "harmonic_state needs the perturbation formulation without NLTE "
                             "or eccentricity terms and with the excitation table")
        n_mesh = max(1, round(self.period_rad / self.mesh_period_rad))
        n_h = 128 * n_mesh if n_harmonics is None else int(n_harmonics)
        c = fourier_coefficients(lambda t: self._excitation(t)[0], self.table_origin,
                                 self.period_rad, 8 * max(self.table_cells, 2 * n_h + 2), n_h,
                                 theta0)
        z, zp = harmonic_response(self.kbar_r, self.c_r, self.v_r, self.k_m * self.cos_bb * c,
                                  self.period_rad, omega)
        rr = self.omega_r / omega
        return jnp.concatenate([z / self.scale_a, zp / (rr * self.scale_a)])

    def initial_state(self, omega, theta0=0.0):
        """Scaled state at ``theta0``: :meth:`harmonic_state` when :attr:`periodic_start`,
        else the quasi-static solution (X_D = X_D' = 0)."""
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

    def deflected_start(self, omega, factor):
        """The quasi-static state with its modal displacements ``q_S`` scaled by ``factor``
        (``q = factor q_S``, so ``factor = -1`` mirrors the static deflection of the mesh
        and of the shafts), velocities kept (the state measures ``q`` from ``q_0``)."""
        y = self.initial_state(omega)
        r = self.n_reduced
        q_s = y[:r] * self.scale_a + self.q0
        return y.at[:r].set((factor * q_s - self.q0) / self.scale_a)

    def outputs(self, theta, y, omega, contact: bool = True) -> ModelOutputs:
        """Mesh force F_D (N), DTE = W^T X + NLTE (m) and the pinion-centre acceleration
        along s (m/s^2) at one angle."""
        q, qp, up = self._accel(theta, y, omega, contact)  # theta: the simulation angle s
        _, f_d = self._elastic(theta, q, contact)
        e, ep, _, _ = self._inertial(self.angle(theta)[0])
        qpp = up
        if e is not None:
            _, nl1, nl2 = self._nlte_derivs(theta, order=2)
            qpp = up - nl2 * e - (0.0 if ep is None else nl1 * ep)
        dte = self.w_r @ q
        if isinstance(self.formulation, Reference) or self.nlte_terms:
            dte = dte + (self.table(theta)[0][2] if self.table is not None
                         else contact_gaps(self.mesh, self.mods, theta)[2])
        return ModelOutputs(mesh_force_N=f_d, dte_m=dte, accel_m_s2=omega**2 * (self.acc_r @ qpp))

    def decay_rate_per_rad(self, omega):
        """``zeta omega_min / Omega``, ``omega_min`` the slowest mode in the mesh deflection."""
        return self.damping_ratio * self.decay_omega_rad_s / omega

    def transient_start(self, omega):
        """Transient start at theta = 0: the slow modes on their period mean, the fast
        ones on the quasi-static state (:func:`gearjax.models.base.modal_transient_start`
        with the modal frequencies :attr:`omega_r`)."""
        return modal_transient_start(self, omega, self.omega_r)

    def transient_amplitudes(self, dy, omega):
        """Free response left in a transient (:func:`gearjax.models.base.modal_transient_amplitudes`
        on the modes and static corrections of the basis): mesh force ``k_m v_j``, DTE
        ``w_j`` and pinion-centre acceleration ``acc_j`` per unit modal displacement."""
        return modal_transient_amplitudes(dy, omega, self.period_rad, self.omega_r,
                                          self.damping_ratio, self.scale_a,
                                          self.k_m * self.v_r, self.w_r, self.acc_r)

    def periodic_estimate(self, y_start, y_end, omega, slow_only: bool = False):
        """Periodic state estimated from one period of a transient, mode by mode
        (:func:`gearjax.models.base.modal_periodic_estimate`)."""
        return modal_periodic_estimate(y_start, y_end, omega, self.period_rad, self.omega_r,
                                       self.damping_ratio, slow_only=slow_only)

    def natural_frequency_rad_s(self):
        """Frequency (rad/s) of the mode of ``(M, K_bar)`` with the largest share of strain
        energy in the mesh, ``k_m (phi^T V)^2 / omega^2`` (shares of ``k_m C_vv = 1``,
        Eq. (33); static-correction pseudo-modes excluded)."""
        w, v = self.omega_r[: self.n_modes], self.v_r[: self.n_modes]
        share = jnp.where(w > 0, v**2 / jnp.where(w > 0, w, 1.0) ** 2, 0.0)
        return w[jnp.argmax(share)]

