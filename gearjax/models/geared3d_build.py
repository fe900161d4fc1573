"""Building a :class:`gearjax.models.geared3d.Geared3DModel` (its ``build`` classmethod):
checks, the quasi-static scan giving k_m, the modal basis of ``(M, K_bar)``, the jump angles
and the excitation table, all outside ``jit``. Kept apart from the model's equations
(:mod:`gearjax.models.geared3d`)."""

from __future__ import annotations

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..errors import ModelError
from ..excitation.jumps import JumpSet
from ..excitation.mesh3d import QuasiStaticMesh3D
from ..excitation.te_file import TETable
from ..gears.backlash import check_model_backlash
from ..gears.contact import TEContactLaw
from ..gears.mesh import Mesh
from ..gears.modifications import ToothModifications
from ..gears.quasistatic import contact_gaps, static_mesh_force
from ..structure.condensation import Condensation, quasi_static_3d
from ..structure.geared import Eccentricity, disc_mass, geared_structure
from .formulations import AbstractFormulation, Reference, formulation_of
from .geared3d_excitation import file_mean_stiffness, own_table_fields, te_file_fields


def modal_structure(kbar_r, c_r, n_modes: int, tol: float = 1e-6) -> dict:
    """How the vector field may apply the reduced matrices (static fields of
    :class:`Geared3DModel`): ``diagonal_stiffness`` when every off-diagonal entry of
    ``kbar_r`` is below ``tol`` of the geometric mean of its two diagonal entries (the modes
    of ``(M, K_bar)``, static corrections orthogonalised: round-off, ~1e-8 for the slowest
    mode of the Baud-Velex rig); ``damping_split = n_modes`` when ``c_r`` passes the same
    test except on its trailing static-correction block (modal damping), else 0 (dense). A
    step of the 3D rig (146 coordinates) spent most of its time in these two dense
    products (``benchmarks/results/code_notes.md``, section gearjax.models.geared3d_modal,
    and ``modal_products.md`` there)."""
    k, c = np.asarray(kbar_r, dtype=float), np.asarray(c_r, dtype=float)

    def diagonal(a):  # off-diagonal entries small against sqrt(a_ii a_jj)
        d = np.sqrt(np.abs(np.diag(a)))
        off = np.abs(a - np.diag(np.diag(a)))
        return bool(np.all(off <= tol * np.outer(d, d)))

    p = int(n_modes)
    head = np.array(c, copy=True)
    head[p:, p:] = np.diag(np.diag(c)[p:])  # the static-correction block may be dense
    split = p if 0 < p <= c.shape[0] and diagonal(head) else 0
    return {"diagonal_stiffness": diagonal(k), "damping_split": split}


NLTE_SCAN = 256  # samples per mesh period of nlte_vanishes (the build's n_table default)


def shares_nlte_programs(formulation, excitation: str, te_table, harmonic_start: bool) -> bool:
    """Whether a 3D build keeps its NLTE terms whatever its design's NLTE (``nlte_terms``
    None): a tabulated te/perturbation model of the mesh's own geometry, without a TE file
    and without the constant-coefficient start (``harmonic_start`` needs the terms
    absent). Every relief of the rig then shares the model's compiled programs: where NLTE
    is identically zero the terms vanish (NLTE' = 0 in the table), and the direction of
    ``NLTE'' E`` is in the modal basis either way. The reference formulation and
    ``excitation="inline"`` (NLTE' from the contact geometry at every right-hand side) and
    a TE file (whose design cannot change) keep them only where NLTE is not identically
    zero."""
    return (not isinstance(formulation, Reference) and excitation == "table"
            and te_table is None and not harmonic_start)


def nlte_vanishes(mesh: Mesh, mods: ToothModifications, period: float,
                  n_per_mesh: int = NLTE_SCAN):
    """() bool: NLTE (m, :func:`gearjax.gears.quasistatic.contact_gaps`) is exactly 0 at
    ``n_per_mesh`` uniform samples per mesh period over ``period`` (rad): the build's test
    for "identically zero" (which reads its own quasi-static scan, ``n_table`` samples per
    mesh period), at the default sampling. Traceable in ``mods``: a model built without
    NLTE terms stays valid for a design only where this holds
    (:meth:`~gearjax.models.geared3d.Geared3DModel.with_modifications`)."""
    n = int(n_per_mesh) * max(1, round(period / mesh.pair.mesh_period_rad))
    theta = jnp.arange(n) * (period / n)
    nlte = jax.vmap(lambda t: contact_gaps(mesh, mods, t)[2])(theta)
    return jnp.all(nlte == 0.0)


@eqx.filter_jit
def _quasi_static_scan(cond, el, mods, thetas, f_s, v12, mesh_vectors, max_iter, mask12):
    """:func:`quasi_static_3d` at the angles ``thetas`` (the build's table scan): one
    compilation per model shape, shared by the formulations' builds (a closure over the
    design compiled anew for each, at every build)."""
    return jax.vmap(lambda t: quasi_static_3d(cond, el, mods, t, f_s, v12, mesh_vectors,
                                              max_iter, mask12))(thetas)

MESH_VECTORS = ("cells", "mean")
EXCITATIONS = ("table", "inline")


def build_geared3d(
    cls,
    structure,
    mesh: Mesh,
    mods: ToothModifications | None = None,
    *,
    pinion_torque_Nm: float = 254.8,
    torque_node: int | None = None,
    encoder_nodes: tuple[int, int] | None = None,
    damping_ratio: float = 0.03,
    formulation: AbstractFormulation | str = "reference",
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
    te_table: TETable | None = None,
    nlte_inertia: bool = True,
    moving_events: bool = True,
    backlash_m: float | None = None,
    contact_law: TEContactLaw = TEContactLaw.MESH,
):
    """Build a complete 3D model, a :class:`~gearjax.models.geared3d.Geared3DModel`
    (outside ``jit``: checks, modal basis, k_m, jump and event angles, excitation table).

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
    formulation : :class:`~gearjax.models.formulations.Reference` (Eq. (14)),
        :class:`~gearjax.models.formulations.TransmissionError` (Eq. (42)) or
        :class:`~gearjax.models.formulations.Perturbation` (Eq. (48a)), or its name
        (``"reference"``, ``"te"``, ``"perturbation"``).
    mesh_vectors : ``"cells"`` (V(M_i), paper) or ``"mean"`` (averaged V everywhere:
        the reference contact and the quasi-static TE_S then use V, Eq. (27)).
    nlte_terms : keep NLTE in the equations; False: NLTE = 0 everywhere. Default: kept
        by a tabulated te/perturbation model of the mesh's own geometry (no ``te_table``,
        no ``harmonic_start``), so that every relief of the rig shares its compiled
        programs (where NLTE is identically zero the terms vanish); elsewhere kept unless
        NLTE is identically zero (:func:`shares_nlte_programs`).
    nlte_inertia : False drops ``NLTE'' E + NLTE' F`` alone (Section 6.3.2, "NLTE'' set
        at zero"): ``TE_S - NLTE`` stays in the forcing, NLTE in the DTE, E out of the basis.
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
        w_x0``, ``k(theta)`` and NLTE on a jump-aware periodic Hermite table (at
        build, and again in :meth:`with_modifications`, differentiable in the
        modifications), or ``"inline"`` solves the quasi-static contact at every
        right-hand side (slow with ``"cells"`` vectors; kept to check the table).
    harmonic_start : perturbation without NLTE/eccentricity terms: start exactly on the
        periodic steady state (:meth:`harmonic_state`, see :attr:`periodic_start`).
    te_table : te/perturbation: TE_S, NLTE and (if given) k from a TE file (Section 6.2,
        :mod:`gearjax.models.geared3d_excitation`); its mean stiffness is k_m unless
        ``mean_stiffness_N_per_m`` is given; ``nlte_terms`` None: kept unless its NLTE
        is identically 0.
    moving_events : te/perturbation table: False keeps the switching angles at the build
        angles (no angle map: the same model at the build design, built faster for
        forward sweeps; :meth:`with_modifications` then moves no switching angle).
    backlash_m : clearance between the back flanks (m, in ``[0, m_n]``; None: none): the
        reference formulation's back-flank cells on the second base plane with their
        structure vectors ``V'(M_i)``, te/perturbation's mesh-level back-flank law along
        ``V' = H V`` (:mod:`gearjax.models.geared3d`, "Backlash").
    contact_law : te/perturbation contact law (:class:`gearjax.gears.contact.TEContactLaw`):
        ``MESH`` (default, the mesh as a whole) or ``CELLS`` (cell by cell; the table then
        also holds the element dofs of X_S; not with ``te_table``); the reference ignores it.

    Raises
    ------
    ModelError
        naming the field, its value and the reason.
    """
    formulation = formulation_of(formulation)
    if mesh_vectors not in MESH_VECTORS:
        raise ModelError("mesh_vectors", mesh_vectors, f"must be one of {MESH_VECTORS}")
    if excitation not in EXCITATIONS:
        raise ModelError("excitation", excitation, f"must be one of {EXCITATIONS}")
    if not isinstance(contact_law, TEContactLaw):
        raise ModelError("contact_law", contact_law,
                         f"must be a TEContactLaw ({', '.join(c.name for c in TEContactLaw)})")
    if contact_law is TEContactLaw.CELLS and te_table is not None:
        raise ModelError("contact_law", "CELLS", "the per-cell contact law needs the cells' "
                         "gaps; a TE file gives TE_S alone (use TEContactLaw.MESH)")
    if mods is None:
        mods = ToothModifications.none()
    mods.check_against(mesh.pair)
    backlash = check_model_backlash(backlash_m, mods, mesh.pair,
                                    reference=isinstance(formulation, Reference),
                                    cell_contact=contact_law is TEContactLaw.CELLS)
    torque = float(pinion_torque_Nm)
    if not (math.isfinite(torque) and torque > 0):
        raise ModelError("pinion_torque_Nm", pinion_torque_Nm, "must be finite and > 0")
    zeta = float(damping_ratio)
    if not (math.isfinite(zeta) and 0.0 <= zeta < 1.0):
        raise ModelError("damping_ratio", damping_ratio, "must lie in [0, 1)")
    gs = geared_structure(structure, mesh, torque, torque_node, encoder_nodes, fixed_dofs)
    K, F0, W = gs.K, gs.F0, gs.W
    pair = mesh.pair
    f_s = static_mesh_force(pair, torque)
    el, keep12, v12 = gs.element, gs.keep12, gs.v_local12
    mask12 = keep12.astype(float)

    # quasi-static scan with the condensed structure -> k_m
    cond = Condensation.build(K, F0, W, gs.element_dofs, keep12)
    period = mods.excitation_period_rad(pair)
    n_mesh = int(round(period / pair.mesh_period_rad))
    n_tab = int(n_table) * n_mesh
    if int(n_table) < 16:
        raise ModelError("n_table", n_table, "must be >= 16 samples per mesh period")
    theta_tab = np.arange(n_tab) * (period / n_tab)
    qs = _quasi_static_scan(cond, el, mods, jnp.asarray(theta_tab), jnp.asarray(f_s),
                            jnp.asarray(v12), mesh_vectors, int(qs_max_iter),
                            jnp.asarray(mask12))
    if not bool(np.all(np.asarray(qs.converged))):
        bad = theta_tab[~np.asarray(qs.converged)]
        raise ModelError("qs_max_iter", qs_max_iter, f"active set did not converge at theta={bad[:3]}")
    k_m = float(np.mean(np.asarray(qs.loaded_stiffness_N_per_m)))
    if te_table is not None:
        if isinstance(formulation, Reference) or excitation != "table":
            raise ModelError("te_table", te_table.source, "a TE file drives te or perturbation"
                             " with excitation='table', not the reference formulation "
                             "(Eq. (14): a gap per cell)")
        k_m = file_mean_stiffness(te_table) or k_m
    if mean_stiffness_N_per_m is not None:
        k_m = float(mean_stiffness_N_per_m)
        if not (math.isfinite(k_m) and k_m > 0):
            raise ModelError("mean_stiffness_N_per_m", mean_stiffness_N_per_m, "must be finite and > 0")
    nlte_tab = np.asarray(qs.nlte_m)
    if te_table is not None:
        nlte_tab = np.asarray(te_table.values[:, 1])
    if nlte_terms is None:  # the rule of the ``nlte_terms`` parameter
        nlte_terms = (shares_nlte_programs(formulation, excitation, te_table, harmonic_start)
                      or bool(np.max(np.abs(nlte_tab - 0.0)) > 0.0))
    cond = Condensation.build(K, F0, W, gs.element_dofs, keep12, k_m=k_m, v_local=v12)

    # modal basis of (M, K_bar), projected vectors
    E = gs.inertial_vector() if nlte_terms and nlte_inertia else np.zeros(F0.shape)
    red = gs.modal(k_m, E, max_frequency_hz, zeta)
    if red.n_modes == 0:  # static corrections alone: no dynamics, no natural frequency
        raise ModelError("max_frequency_hz", max_frequency_hz,
                         "keeps no vibration mode of (M, K_bar), only static corrections; "
                         "give a cut-off above the lowest natural frequency, or None for all "
                         "modes")
    omega_r, v_r, q0, c_v_r = red.omega_r, red.v_r, red.q0, red.c_v_r
    part = v_r**2 / np.where(omega_r > 0, omega_r, np.inf) ** 2
    part = part / part.sum()
    decay_omega = float(np.min(omega_r[part >= participation_tol]))

    ecc = None
    if mods.eccentricity_m is not None and np.any(np.asarray(mods.eccentricity_m) != 0):
        if eccentric_masses_kg is None:
            eccentric_masses_kg = (disc_mass(structure, structure.pinion_node),
                                   disc_mass(structure, structure.gear_node))
        ecc = Eccentricity(jnp.asarray(eccentric_masses_kg, dtype=float),
                           jnp.asarray(mods.eccentricity_m),
                           jnp.asarray(mods.eccentricity_phase_rad))
    scale_a = float(np.max(np.abs(f_s * c_v_r)))
    v_r_j, q0_j, c_v_r_j, w_r_j = (jnp.asarray(a) for a in (v_r, q0, c_v_r, red.w_r))
    qsm = QuasiStaticMesh3D(
        mesh=mesh, mods=mods, element=el, cond=cond, v_local=jnp.asarray(v12),
        free12=jnp.asarray(mask12), static_force_N=jnp.asarray(f_s), v_x0=v_r_j @ q0_j,
        c_vv=v_r_j @ c_v_r_j, c_wv=w_r_j @ c_v_r_j, mesh_vectors=mesh_vectors,
        qs_max_iter=int(qs_max_iter), nlte_terms=bool(nlte_terms),
        loaded_codes=not isinstance(formulation, Reference),
        cell_states=contact_law is TEContactLaw.CELLS and not isinstance(formulation, Reference))

    # speed-independent RHS jumps (te/perturbation: + table events: NLTE' jumps at zone
    # kinks), laid out in one program per rig (the reference with backlash: + the angles
    # where back cells enter or leave, fixed)
    tabulated = not isinstance(formulation, Reference) and excitation == "table"
    back_flanks = backlash is not None and isinstance(formulation, Reference)
    jumps, layout = own_table_fields(qsm, n_tab, float(period), tabulated, moving_events,
                                     back_flanks)
    if te_table is not None:
        file_jumps, layout, period = te_file_fields(te_table, layout, jumps.angles(),
                                                    red.w_r @ red.q0, nlte_terms)
        jumps = JumpSet.from_angles(file_jumps, period, mesh_period=pair.mesh_period_rad)

    return cls(
        mesh=mesh, mods=mods, element=el,
        t_local=jnp.asarray(red.t_local), kbar_r=jnp.asarray(red.kbar_r), c_r=jnp.asarray(red.c_r),
        omega_r=jnp.asarray(omega_r), v_r=v_r_j, w_r=w_r_j,
        acc_r=jnp.asarray(red.acc_r), e_r=jnp.asarray(red.e_r), q0=q0_j,
        c_v_r=c_v_r_j, v_local=jnp.asarray(v12), free12=jnp.asarray(mask12), cond=cond,
        k_m=jnp.asarray(k_m), pinion_torque_Nm=jnp.asarray(torque),
        damping_ratio=jnp.asarray(zeta), scale_a=jnp.asarray(scale_a), ecc=ecc,
        formulation=formulation, mesh_vectors=mesh_vectors, nlte_terms=bool(nlte_terms),
        n_modes=int(red.n_modes), n_static=int(red.n_static), period_rad=float(period),
        jumps=jumps, decay_omega_rad_s=jnp.asarray(decay_omega),
        qs_max_iter=int(qs_max_iter), excitation=excitation,
        harmonic_start=bool(harmonic_start),
        te_source=None if te_table is None else te_table.source,
        nlte_inertia=bool(nlte_inertia), **modal_structure(red.kbar_r, red.c_r, red.n_modes),
        te_weight=None if isinstance(formulation, Reference) else jnp.asarray(formulation.te_weight),
        backlash_m=None if backlash is None else jnp.asarray(backlash),
        contact_law=contact_law,
        **layout,
    )
