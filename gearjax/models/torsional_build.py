"""Building a :class:`gearjax.models.torsional.TorsionalModel` (its ``build`` classmethod):
checks of the inputs on the host, then one compiled program that finds the excitation
layout of the design (:mod:`gearjax.models.torsional_layout`) and assembles the model.

The program's shapes are the layout bounds of the mesh and period
(:func:`gearjax.models.torsional_layout.sdof_bounds`), not of the design, so every relief,
pitch-error set, damping ratio, torque and inertia of one mesh builds with the same
program; a design whose layout outgrows a bound (checked on the host after the build)
is built again with larger bounds (a second program, once). The build is traceable in
the design: called inside ``jit``, ``vmap`` or ``jacfwd`` it is part of the caller's
program (the layout, a bisection, is piecewise constant in the design; derivatives flow
through the angle map, :mod:`gearjax.excitation.events`), and there the model's
``structure_ok`` is False where a bound is outgrown.
"""

from __future__ import annotations

import dataclasses
import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..errors import ModelError
from ..excitation.layout import LayoutBounds, warn_unlocated
from ..gears.backlash import check_model_backlash
from ..gears.contact import TEContactLaw
from ..gears.geometry import solid_cylinder_inertias
from ..gears.mesh import Mesh
from ..gears.modifications import ToothModifications
from ..gears.quasistatic import static_mesh_force
from . import torsional_layout
from .formulations import AbstractFormulation, Reference, formulation_of

__all__ = ["build_torsional", "NLTE_METHODS", "EXCITATIONS", "NLTE_REACTIONS"]

NLTE_METHODS = ("substitution", "spectral")
EXCITATIONS = ("table", "inline")
NLTE_REACTIONS = ("drive", "pinion")  # default first


def _traced(x) -> bool:
    return any(isinstance(leaf, jax.core.Tracer) for leaf in jax.tree_util.tree_leaves(x))


def _check_value(name, value, ok: bool, why: str):
    if not ok:
        raise ModelError(name, value, why)


def build_torsional(
    cls,
    mesh: Mesh,
    mods: ToothModifications | None = None,
    *,
    pinion_torque_Nm: float = 254.8,
    inertias_kg_m2=None,
    damping_ratio: float = 0.03,
    formulation: AbstractFormulation | str = "reference",
    nlte_terms: bool | None = None,
    nlte_method: str = "substitution",
    nlte_harmonics: int = 64,
    excitation: str = "table",
    n_table: int = 256,
    merge_spur_lines: bool = True,
    nlte_reaction: str = "drive",
    nlte_inertia: bool = True,
    moving_events: bool = True,
    bounds: LayoutBounds | None = None,
    backlash_m: float | None = None,
    contact_law: TEContactLaw = TEContactLaw.MESH,
):
    """Build a torsional model: inputs checked, excitation layout (jump angles, table
    knots, switching events) found and the model assembled, in one compiled program per
    mesh, options and layout bounds.

    Parameters
    ----------
    mesh : the mesh model.
    mods : tooth modifications (default: none).
    pinion_torque_Nm : C_m0 (N m), default 254.8 (paper Section 6.1).
    inertias_kg_m2 : (J1, J2) (kg m^2); default :func:`solid_cylinder_inertias`.
    damping_ratio : zeta in [0, 1), default 0.03 (paper Section 6.1).
    formulation : a formulation object (:mod:`gearjax.models.formulations`) or its name:
        ``"reference"``, ``"te"`` or ``"perturbation"``.
    nlte_terms : keep NLTE in the equations; None (default) keeps them unless NLTE is
        identically zero for these modifications (decided in the program: the same
        program serves both). False: NLTE = 0 everywhere.
    nlte_inertia : keep the NLTE'' inertial term (default); False drops it alone
        (Section 6.3.2, "NLTE'' set at zero"), ``TE_S - NLTE`` and the DTE kept.
    nlte_method : ``"substitution"`` or ``"spectral"`` (see the model's module docstring).
    nlte_harmonics : mesh harmonics kept by the spectral method.
    excitation : ``"table"`` or ``"inline"`` (see the model's module docstring).
    n_table : uniform table knots per mesh period (also the scan used to find jumps).
    nlte_reaction : where the torque ``J2 Rb1 / Rb2^2 Omega^2 NLTE''`` that keeps the
        pinion speed (Eq. (5)) acts: ``"drive"`` (default, as in the 3D model: kappa =
        1) or ``"pinion"`` (Eqs. (15)-(16)); see the model's module docstring.
    merge_spur_lines : for a spur pair without crowning every cell of a contact line
        has the same position on the profile, stiffness per length and gap, so the
        line is merged into one cell (``cells_per_line=1``, same total stiffness):
        identical results up to round-off, 10-30x cheaper reference right-hand sides.
        The stored ``mesh`` is then the merged one.
    moving_events : True (default): the switching angles move with the design through the
        angle map (:meth:`with_modifications` differentiates them); False: they stay at
        this build's angles (no map, every event fixed: the same model at this design,
        forward values elsewhere resolved to the table spacing).
    bounds : the static sizes of the layout (default
        :func:`gearjax.models.torsional_layout.sdof_bounds` of the mesh and period: every
        design of the mesh fits them); grown where a design needs more.
    backlash_m : clearance between the back flanks (m, normal backlash along the line
        of action, in ``[0, m_n]``); None (default): no back flanks, the model of the
        paper (the model's module docstring, "Backlash").
    contact_law : te/perturbation contact law (:class:`gearjax.gears.contact.TEContactLaw`,
        the model's module docstring): ``MESH`` (default) or ``CELLS``; the reference
        ignores it.

    Raises
    ------
    ModelError
        for an unknown option, a non-positive torque or inertia, zeta outside [0, 1),
        inconsistent sizes, modifications that leave no contact at some angle, or a
        backlash that is not finite, negative or above a module (or, reference
        formulation, with pitch errors or eccentricity, or with the per-cell law).
    """
    formulation = formulation_of(formulation)
    for name, value, allowed in (("nlte_method", nlte_method, NLTE_METHODS),
                                 ("excitation", excitation, EXCITATIONS),
                                 ("nlte_reaction", nlte_reaction, NLTE_REACTIONS)):
        if value not in allowed:
            raise ModelError(name, value, f"must be one of {allowed}")
    if mods is None:
        mods = ToothModifications.none()
    mods.check_against(mesh.pair)
    backlash = check_model_backlash(backlash_m, mods, mesh.pair,
                                    reference=isinstance(formulation, Reference),
                                    cell_contact=contact_law is TEContactLaw.CELLS)
    back_flanks = backlash is not None and isinstance(formulation, Reference)
    if not _traced(pinion_torque_Nm):
        t = float(pinion_torque_Nm)
        _check_value("pinion_torque_Nm", pinion_torque_Nm, math.isfinite(t) and t > 0,
                     "must be finite and > 0 (the contact model loads the drive flanks)")
    if not _traced(damping_ratio):
        z = float(damping_ratio)
        _check_value("damping_ratio", damping_ratio, math.isfinite(z) and 0.0 <= z < 1.0,
                     "must lie in [0, 1)")
    if inertias_kg_m2 is None:
        inertias_kg_m2 = solid_cylinder_inertias(mesh.pair)
    inert = jnp.asarray(inertias_kg_m2, dtype=float)
    if inert.shape != (2,):
        raise ModelError("inertias_kg_m2", inertias_kg_m2, "must be two finite positive values "
                         "(J1, J2)")
    if not _traced(inert):
        j = np.asarray(inert)
        _check_value("inertias_kg_m2", inertias_kg_m2,
                     bool(np.all(np.isfinite(j)) and np.all(j > 0)),
                     "must be two finite positive values (J1, J2)")
    n_table = int(n_table)
    if n_table < 16:
        raise ModelError("n_table", n_table, "must be >= 16 knots per mesh period")
    if nlte_method == "spectral" and not (1 <= int(nlte_harmonics) < n_table // 2):
        raise ModelError("nlte_harmonics", nlte_harmonics,
                         f"must lie in [1, n_table/2) = [1, {n_table // 2})")
    crowned = _traced(mods.crowning_m) or bool(np.any(np.asarray(mods.crowning_m) != 0.0))
    if merge_spur_lines and mesh.pair.spur and mesh.cells_per_line > 1 and not crowned:
        mesh = dataclasses.replace(mesh, cells_per_line=1)
    period = float(mods.excitation_period_rad(mesh.pair))
    if bounds is None:
        bounds = torsional_layout.sdof_bounds(mesh, period, back_flanks)
    options = dict(formulation=formulation, nlte_terms=nlte_terms, nlte_method=nlte_method,
                   nlte_harmonics=int(nlte_harmonics), excitation=excitation,
                   n_table=n_table, nlte_reaction=nlte_reaction,
                   nlte_inertia=bool(nlte_inertia), moving_events=bool(moving_events),
                   period=period, contact_law=contact_law, back_flanks=back_flanks)
    data = (mesh, mods, inert, jnp.asarray(pinion_torque_Nm, dtype=float),
            jnp.asarray(damping_ratio, dtype=float),
            None if backlash is None else jnp.asarray(backlash, dtype=float))
    traced = _traced(data)
    # keyed by XLA's optimisation setting too: a build program compiled without
    # optimisations (jax_disable_most_optimizations) rounds the quasi-static solves near
    # the switching angles differently, and is not reused once they are on
    options["xla_optimised"] = not jax.config.read("jax_disable_most_optimizations")
    opts_t = tuple(sorted(options.items()))
    if traced:  # inside a program: one traced build (structure_ok False where it outgrows)
        return _assembled(cls, data, opts_t, bounds, *_classified(data, opts_t, bounds))[0]
    while True:
        scan = _scan(data, opts_t, bounds)
        if not bool(scan["contact"]):
            raise ModelError("mods", "...", "the quasi-static solve has no contact at some "
                             "angle (modifications larger than the static deflection "
                             "everywhere?)")
        need = LayoutBounds(*(int(v) for v in scan["need"]))
        if any(n > b for n, b in zip(need, bounds)):
            bounds = bounds.grown(need)  # a larger program, once
            continue
        # the classification of the events on the host (NumPy: the rule of
        # gearjax.excitation.events.classify_events, read at call time)
        kinds, cells = torsional_layout.sdof_classify_host(
            scan, data[0].n_cells, period, torsional_layout.classify_events)
        model, unlocated = _finish(cls, data, opts_t, bounds, scan, kinds, cells)
        warn_unlocated(int(unlocated))
        return model


def _scan_impl(data, options, bounds: LayoutBounds):
    """The scan of the layout (:func:`gearjax.models.torsional_layout.sdof_scan_layout`)
    of ``data`` = (mesh, mods, inertias, torque, zeta, backlash), derivatives cut."""
    mesh, mods, _, torque = data[:4]
    opts = dict(options)
    force = static_mesh_force(mesh.pair, jax.lax.stop_gradient(torque))
    return torsional_layout.sdof_scan_layout(mesh, jax.lax.stop_gradient(mods), force,
                                             opts["n_table"], opts["period"], bounds,
                                             opts["back_flanks"])


_scan = eqx.filter_jit(_scan_impl)


def _classified(data, options, bounds):
    """(scan, kinds, cells) of a traced build: the scan and the classification in the
    program."""
    scan = _scan_impl(data, options, bounds)
    kinds, cells = torsional_layout.sdof_classify_traced(scan, data[0].n_cells,
                                                         dict(options)["period"])
    return scan, kinds, cells


def _assembled(cls, data, options, bounds: LayoutBounds, scan, kinds, cells):
    """The model of ``data`` = (mesh, mods, inertias, torque, zeta, backlash) from its scan
    and classified events; its ``structure_ok`` also says that the layout fits ``bounds``
    and the quasi-static solve has contact. Returns ``(model, unlocated)``."""
    mesh, mods, inert, torque, zeta, backlash = data
    opts = dict(options)
    period = opts.pop("period")
    nlte_terms = opts.pop("nlte_terms")
    back_flanks = opts.pop("back_flanks")
    opts.pop("xla_optimised")
    force = static_mesh_force(mesh.pair, jax.lax.stop_gradient(torque))
    jumps, unlocated = torsional_layout.sdof_events_layout(
        mesh, jax.lax.stop_gradient(mods), force, period, bounds, scan, kinds, cells,
        back_flanks)
    if not opts["moving_events"]:  # every event fixed at this build's angle
        jumps = eqx.tree_at(lambda j: (j.kinds, j.cells), jumps,
                            (jnp.zeros_like(jumps.kinds), jnp.zeros_like(jumps.cells)))
    weight = (jnp.where(scan["nlte_max"] > 0.0, 1.0, 0.0) if nlte_terms is None
              else jnp.asarray(float(bool(nlte_terms))))
    fields = {k: scan[k] for k in ("table_knots", "table_side", "table_cell_first",
                                   "table_origin", "table_codes")}
    model = cls._complete(
        mesh=mesh, mods=mods, inertias_kg_m2=inert, pinion_torque_Nm=torque,
        damping_ratio=zeta, nlte_weight=weight, period_rad=period,
        table_max_extra=bounds.max_extra, jumps=jumps, backlash_m=backlash, **opts, **fields)
    fits = scan["contact"]
    for n, b in zip(scan["need"], bounds):
        fits = fits & (n <= b)
    model = eqx.tree_at(lambda m: m.structure_ok, model, model.structure_ok & fits)
    return model, unlocated


_finish = eqx.filter_jit(_assembled)
