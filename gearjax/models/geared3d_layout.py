"""The excitation layout of the 3D model (:class:`gearjax.models.geared3d.Geared3DModel`),
computed in the program: one scan of the exact 3D quasi-static solution (paper Eq. (25))
over the excitation period finds every change of its discrete state (cells entering or
leaving the path of contact, the loaded set, the cell realising NLTE and, for the table of
the te/perturbation formulations, the relief zones: kinks of TE_S) bracketed by adjacent
floats, the integrator's jump angles, the knots of the
:class:`~gearjax.excitation.tables.PeriodicHermiteTable` and the kind of each switching
event (fixed, or moving with the design: :mod:`gearjax.excitation.events`).

Traced (:mod:`gearjax.excitation.layout`): arrays of static bounds (:func:`geared3d_bounds`,
a function of the mesh and the excitation period only), so every relief, pitch-error set,
damping ratio and torque of one rig builds its layout with the same program, and the
models of those designs share their sweep programs. A design whose layout outgrows a bound
is laid out again with larger bounds (:func:`layout_3d`: a second program, once).
"""

from __future__ import annotations

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp

from ..excitation.jumps import JumpSet, round_up
from ..excitation.layout import (LayoutBounds, classify_events, fix_unlocated, scan_layout,
                                 warn_unlocated)
from ..excitation.mesh3d import QuasiStaticMesh3D
from ..gears.mesh import Mesh
from .torsional_layout import (back_flank_jumps, distinct_geometric_count, geometric_density,
                               sdof_bounds)

__all__ = ["geared3d_bounds", "layout_3d", "Layout3D"]


def geared3d_bounds(mesh: Mesh, period: float, back_flanks: bool = False) -> LayoutBounds:
    """Static bounds of the 3D layout for every design of ``mesh`` over ``period`` (rad):
    the rule of :func:`gearjax.models.torsional_layout.sdof_bounds` with the 3D mesh's own
    cells per contact line (jumps, brackets; helical teeth: the cells change one after
    the other, every bracket in a scan interval of its own, 8 extra knots in a table cell,
    16 beyond 16 jumps per mesh period). Spur teeth: the cells of a contact line change
    their loaded state within one scan interval and one table cell, so the scan intervals
    holding changes are about the distinct geometric jump angles plus eight per mesh
    period (a multiple of 16), and a table cell holds up to two extra knots per cell of a
    line and four more."""
    bounds = sdof_bounds(mesh, period, back_flanks)
    if not mesh.pair.spur:
        return bounds
    n_mesh = int(round(period / mesh.pair.mesh_period_rad))
    n_geo = distinct_geometric_count(mesh, period, back_flanks)
    return bounds._replace(max_extra=round_up(2 * mesh.cells_per_line + 4),
                           intervals=round_up(n_geo + 8 * n_mesh, 16))


class Layout3D(eqx.Module):
    """The layout of one 3D design (:func:`layout_3d`).

    Attributes
    ----------
    jumps : the integrator's jump angles with the kind and cells of each event
        (:class:`~gearjax.excitation.jumps.JumpSet`, padded to the bound).
    knots, side, cell_first : the table's knots (padded with its last one), the side
        (-1/+1) each knot bracketing a jump is read on, the first knot of each uniform
        cell; None without a table.
    origin : () the table's origin (rad), far from every state change.
    codes : (knots, n_code) the discrete state on each side of every knot (for the
        structure flag), or None (no table, or events fixed).
    max_extra : the bound of extra knots in one uniform cell (static).
    """

    jumps: JumpSet
    knots: jax.Array | None
    side: jax.Array | None
    cell_first: jax.Array | None
    origin: jax.Array
    codes: jax.Array | None
    max_extra: int = eqx.field(static=True)


@eqx.filter_jit
def _scan(qsm: QuasiStaticMesh3D, n: int, period: float, bounds: LayoutBounds,
          extra: tuple, tabulated: bool, moving: bool, density: float):
    """The layout of ``qsm`` (traced; every argument but ``qsm`` static) and what it needs:
    ``(Layout3D, need (LayoutBounds of traced ints), unlocated)``."""
    def code_fn(t):
        return jax.vmap(lambda tt: qsm.state_code(tt, tabulated))(t)

    lay = scan_layout(code_fn, code_fn(jnp.arange(n) * (period / n)), period, bounds, extra,
                      tol=1e-9, table=tabulated)
    kinds = jnp.zeros(bounds.jumps, jnp.int32)
    cells = jnp.zeros((bounds.jumps, 2), jnp.int32)
    unlocated = jnp.asarray(0)
    if tabulated and moving:
        ch, valid = lay.changes, jnp.arange(bounds.jumps) < lay.n_jumps
        kinds, cells = classify_events(lay.thetas, ch.lo, ch.hi, ch.c_lo, ch.c_hi,
                                       qsm.mesh.n_cells, period)
        kinds, cells, unlocated = fix_unlocated(qsm.switch_function, lay.thetas, kinds, cells,
                                                valid, qsm.mesh.pair.mesh_period_rad)
    jumps = JumpSet.padded(lay.thetas, kinds, cells, lay.n_jumps, period, bounds.jumps, density)
    codes = lay.knot_codes(code_fn, period) if tabulated and moving else None
    out = Layout3D(jumps=jumps, knots=lay.knots, side=lay.side, cell_first=lay.cell_first,
                   origin=lay.origin, codes=codes, max_extra=bounds.max_extra)
    return out, lay.need, unlocated


def layout_3d(qsm: QuasiStaticMesh3D, n: int, period: float, *, tabulated: bool,
              moving_events: bool = True, back_flanks: bool = False) -> Layout3D:
    """The layout of the 3D design of ``qsm`` over one excitation period ``period`` (rad)
    from a uniform scan of ``n`` angles, in one compiled program per rig, options and
    bounds (:func:`geared3d_bounds`; grown and laid out again where the design outgrows
    them).

    Parameters
    ----------
    tabulated : te/perturbation with a table: the relief zones join the state (kinks of
        TE_S are table knots and events) and the table's knots are placed; else the jumps
        alone (every event fixed).
    moving_events : tabulated: classify the events (moving with the design through the
        angle map; a moving event whose switching function Newton does not hold at its
        angle is kept fixed, with a ``RuntimeWarning``) and record the state codes at the
        knots; False: every event fixed at its build angle, no codes.
    back_flanks : the angles where back-flank cells enter or leave the path of contact
        join the jumps as fixed events (the reference formulation with backlash,
        :func:`gearjax.models.torsional_layout.back_flank_jumps`).
    """
    mesh = qsm.mesh
    extra = tuple(float(a) for a in back_flank_jumps(mesh, period)) if back_flanks else ()
    density = geometric_density(mesh, period, back_flanks)
    bounds = geared3d_bounds(mesh, period, back_flanks)
    # the layout reads the discrete state alone, not d: one program whether NLTE is kept
    qsm = dataclasses.replace(qsm, nlte_terms=True)
    while True:
        lay, need, unlocated = _scan(qsm, int(n), float(period), bounds, extra,
                                     bool(tabulated), bool(moving_events), float(density))
        need = LayoutBounds(*(int(v) for v in need))
        if all(k <= b for k, b in zip(need, bounds)):
            break
        bounds = bounds.grown(need)  # a larger program, once
    warn_unlocated(int(unlocated))
    return lay
