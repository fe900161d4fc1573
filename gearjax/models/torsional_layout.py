"""The excitation layout of the sdof torsional model
(:class:`gearjax.models.torsional.TorsionalModel`), computed in the program: one scan of
the exact quasi-static solution over the excitation period finds the table origin, every
change of the discrete quasi-static state (bracketed by adjacent floats), the knots of the
:class:`~gearjax.excitation.tables.PeriodicHermiteTable` and the kind of each switching
event (fixed, or moving with the design: :mod:`gearjax.excitation.events`), with the
geometric engagement angles added to the jumps (and, for the reference formulation with
backlash, the angles where back-flank cells enter or leave the path of contact: the
engagement angles mirrored through :func:`gearjax.gears.backlash.back_flank_angle_rad`,
fixed events where the back-flank force jumps while the back flanks are in contact).

Traced (:mod:`gearjax.excitation.layout`): arrays of static bounds
(:func:`sdof_bounds`, a function of the mesh and the excitation period only), so the
model of every design of a rig is one program. The values at the knots are assembled by
the model.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..excitation.events import code_jnp, engagement_angles
from ..excitation.jumps import JumpSet, round_up, separated_density
from ..excitation.events import classify_events
from ..excitation.layout import LayoutBounds, fix_unlocated, scan_layout
from ..excitation.layout import classify_events as classify_traced
from ..excitation.sdof import sdof_signature, sdof_switch
from ..gears.backlash import back_flank_angle_rad
from ..gears.mesh import Mesh
from ..gears.modifications import ToothModifications

__all__ = ["sdof_scan_layout", "sdof_classify_host", "sdof_classify_traced",
           "sdof_events_layout", "sdof_bounds", "geometric_jumps", "back_flank_jumps",
           "distinct_geometric_count", "geometric_density", "classify_events"]


def geometric_jumps(mesh: Mesh, period: float, back_flanks: bool = False) -> np.ndarray:
    """The engagement angles (rad) of ``mesh`` in ``[0, period)``: where cells enter or
    leave the path of contact (design-independent; NumPy); with ``back_flanks`` also where
    back-flank cells do (the engagement angles mirrored through
    :func:`gearjax.gears.backlash.back_flank_angle_rad`)."""
    geo = np.asarray(engagement_angles(mesh, period), dtype=float)
    if not back_flanks:
        return geo
    return np.concatenate([geo, back_flank_jumps(mesh, period)])


def back_flank_jumps(mesh: Mesh, period: float) -> np.ndarray:
    """The distinct angles (rad, in ``[0, period)``) where back-flank cells enter or leave
    the path of contact: the engagement angles mirrored through
    :func:`gearjax.gears.backlash.back_flank_angle_rad` (NumPy)."""
    geo = np.asarray(engagement_angles(mesh, period), dtype=float)
    return np.unique(np.mod(back_flank_angle_rad(mesh.pair) - geo, period))


def distinct_geometric_count(mesh: Mesh, period: float, back_flanks: bool = False) -> int:
    """How many distinct angles :func:`geometric_jumps` holds over one ``period`` (rad),
    folded into it and merged to 1e-12 of it: the design-independent part of the layout
    bounds (:func:`sdof_bounds`, :func:`gearjax.models.geared3d_layout.geared3d_bounds`)."""
    geo = np.round(np.mod(geometric_jumps(mesh, period, back_flanks), period) / period, 12)
    return int(np.unique(geo).size)


def geometric_density(mesh: Mesh, period: float, back_flanks: bool = False) -> float:
    """The :func:`gearjax.excitation.jumps.separated_density` of the distinct
    :func:`geometric_jumps` (design-independent, so one integrator for every design of a
    rig): the jump density of both gear models' jump sets."""
    geo = np.unique(np.mod(geometric_jumps(mesh, period, back_flanks), period))
    return separated_density(geo, mesh.pair.mesh_period_rad, period)


def sdof_bounds(mesh: Mesh, period: float, back_flanks: bool = False) -> LayoutBounds:
    """Static bounds of the sdof layout for every design of ``mesh`` over ``period``:
    the distinct engagement angles, plus per mesh period and cell of a contact line two
    relief-zone starts and two changes of the loaded set, plus two changes of the cell
    realising NLTE (rounded up to multiples of 8); brackets an eighth more; 4 extra knots
    per table cell (16 where there are more than 16 jumps per mesh period); ``back_flanks``:
    the back-flank engagement angles too (:func:`geometric_jumps`)."""
    n_mesh = int(round(period / mesh.pair.mesh_period_rad))
    jumps = round_up(distinct_geometric_count(mesh, period, back_flanks)
                     + (4 * mesh.cells_per_line + 2) * n_mesh)
    extra = 8 if jumps <= 16 * n_mesh else 16
    brackets = round_up(1.125 * jumps + 4)
    return LayoutBounds(jumps=jumps, brackets=brackets, max_extra=extra, intervals=brackets)


def sdof_scan_layout(mesh: Mesh, mods: ToothModifications, force, n_table: int,
                     period: float, bounds: LayoutBounds, back_flanks: bool = False) -> dict:
    """The layout of the sdof model over one excitation period up to the classification
    of its events (traced; ``mesh``, ``n_table``, ``period`` and ``bounds`` static in
    effect): the table origin, the brackets of every state change, the jump angles and
    the table knots.

    Parameters
    ----------
    mesh, mods : the (possibly merged) mesh and the tooth modifications.
    force : static mesh force F_S (N).
    n_table : uniform knots per mesh period (also the scan used to find the jumps).
    period : the excitation period (rad).
    bounds : the static sizes (:func:`sdof_bounds`).
    back_flanks : the back-flank engagement angles join the jumps (:func:`geometric_jumps`).

    Returns
    -------
    dict with the model fields ``table_knots``, ``table_side``, ``table_cell_first``,
    ``table_origin``, ``table_codes``; ``thetas`` (bounds.jumps,) the jump angles sorted
    and ``n_jumps``; the brackets ``lo``, ``hi``, ``c_lo``, ``c_hi``
    (:class:`~gearjax.excitation.layout.Changes`); and the diagnostics ``nlte_max`` (max
    |NLTE| over the scan, m), ``contact`` (the quasi-static solve has contact at every
    scan angle), ``need`` (the bounds this design needs, a :class:`LayoutBounds` of traced
    ints, the events' count as found here).
    """
    n_mesh = int(round(period / mesh.pair.mesh_period_rad))
    n = n_table * n_mesh
    force = jnp.asarray(force, dtype=float)

    def signature(t):
        return sdof_signature(mesh, mods, force, t)

    def code_fn(t):
        return jax.vmap(lambda tt: code_jnp(signature(tt)))(t)

    scan = jax.vmap(signature)(jnp.arange(n) * (period / n))
    lay = scan_layout(code_fn, jax.vmap(code_jnp)(scan), period, bounds,
                      geometric_jumps(mesh, period, back_flanks))
    ch = lay.changes
    return dict(
        table_knots=lay.knots, table_side=lay.side, table_cell_first=lay.cell_first,
        table_origin=lay.origin, table_codes=lay.knot_codes(code_fn, period),
        thetas=lay.thetas, n_jumps=lay.n_jumps, lo=ch.lo, hi=ch.hi, c_lo=ch.c_lo, c_hi=ch.c_hi,
        nlte_max=jnp.max(jnp.abs(scan["nlte"])), contact=jnp.all(jnp.isfinite(scan["x_s"])),
        need=lay.need,
    )


def sdof_classify_host(scan: dict, n_cells: int, period: float, classify) -> tuple:
    """Kind and cells of every jump of the concrete ``scan`` (:func:`sdof_scan_layout`'s
    output) by the NumPy rule ``classify`` (:func:`gearjax.excitation.events.
    classify_events`): (kinds (bound,), cells (bound, 2)) int32 arrays, the unused
    entries fixed."""
    n = int(scan["n_jumps"])
    b = int(scan["thetas"].shape[0])
    valid = np.isfinite(np.asarray(scan["hi"]))
    kinds = np.zeros(b, np.int32)
    cells = np.zeros((b, 2), np.int32)
    if valid.any() and n:
        k, c = classify(np.asarray(scan["thetas"])[:min(n, b)], np.asarray(scan["lo"])[valid],
                        np.asarray(scan["hi"])[valid], np.asarray(scan["c_lo"])[valid],
                        np.asarray(scan["c_hi"])[valid], n_cells, period)
        kinds[:len(k)] = np.asarray(k, np.int32)
        cells[:len(c)] = np.asarray(c, np.int32).reshape(-1, 2)
    return jnp.asarray(kinds), jnp.asarray(cells)


def sdof_classify_traced(scan: dict, n_cells: int, period: float) -> tuple:
    """:func:`sdof_classify_host`'s kinds and cells in the program
    (:func:`gearjax.excitation.layout.classify_events`, the same rule)."""
    return classify_traced(scan["thetas"], scan["lo"], scan["hi"], scan["c_lo"],
                           scan["c_hi"], n_cells, period)


def sdof_events_layout(mesh: Mesh, mods: ToothModifications, force, period: float,
                       bounds: LayoutBounds, scan: dict, kinds, cells,
                       back_flanks: bool = False) -> tuple:
    """The :class:`~gearjax.excitation.jumps.JumpSet` of the classified jumps, after the
    build-time check of their switching functions (:func:`gearjax.excitation.layout.
    fix_unlocated`: a moving event its Newton iterations do not hold at its angle is kept
    fixed). Returns ``(jumps, unlocated)``."""
    valid = jnp.arange(bounds.jumps) < scan["n_jumps"]
    switch = eqx.Partial(sdof_switch, mesh, mods, jnp.asarray(force, dtype=float))
    kinds, cells, unlocated = fix_unlocated(switch, scan["thetas"], kinds, cells, valid,
                                            mesh.pair.mesh_period_rad)
    jumps = JumpSet.padded(scan["thetas"], kinds, cells, scan["n_jumps"], period,
                           bounds.jumps, geometric_density(mesh, period, back_flanks))
    return jumps, unlocated
