"""Build-time layout of the sdof torsional model's excitation table
(:class:`gearjax.models.torsional.TorsionalModel`): one NumPy scan of the exact quasi-static
solution over the excitation period finds the table origin, every change of the discrete
quasi-static state (bracketed by adjacent floats), the geometric engagement angles, the
knots of the :class:`~gearjax.excitation.tables.PeriodicHermiteTable` and the kind of each
switching event (fixed or moving with the design, :mod:`gearjax.excitation.events`).

Static structure only: the values at the knots are assembled (traceably) by the model.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ..errors import ModelError
from ..excitation.events import (EV_FIXED, check_event_roots, classify_events, code,
                                 engagement_angles, find_brackets, quiet_origin)
from ..excitation.sdof import sdof_signature_fn, sdof_switch
from ..excitation.tables import PeriodicHermiteTable
from ..gears.backlash import back_flank_angle_rad
from ..gears.mesh import Mesh
from ..gears.modifications import ToothModifications

__all__ = ["sdof_table_layout", "with_back_flank_jumps"]


def sdof_table_layout(mesh: Mesh, mods: ToothModifications, force: float, n_table: int) -> dict:
    """The static table layout of the sdof model over one excitation period.

    Parameters
    ----------
    mesh, mods : the (possibly merged) mesh and the tooth modifications.
    force : static mesh force F_S (N).
    n_table : uniform knots per mesh period (also the scan used to find the jumps).

    Returns
    -------
    dict with ``period`` (rad), ``nlte_max`` (max |NLTE| over the scan, m), and the model
    fields ``table_knots``, ``table_side``, ``table_cell_first``, ``table_origin``,
    ``table_max_extra``, ``jump_thetas``, ``jump_kinds``, ``jump_cells``, ``table_codes``.

    Raises
    ------
    ModelError
        when the quasi-static solve finds no contact at some angle.
    """
    period = mods.excitation_period_rad(mesh.pair)
    n_mesh = int(round(period / mesh.pair.mesh_period_rad))
    sig = sdof_signature_fn(mesh, mods, force)
    theta = np.arange(n_table * n_mesh) * (period / (n_table * n_mesh))
    scan = {k: np.asarray(v) for k, v in sig(jnp.asarray(theta)).items()}
    if not np.all(np.isfinite(scan["x_s"])):
        raise ModelError("mods", "...", "the quasi-static solve has no contact at some angle "
                         "(modifications larger than the static deflection everywhere?)")
    # table origin far from every change of the discrete quasi-static state, then the
    # changes bracketed by adjacent floats *in table coordinates* [origin, origin + P)
    c0 = code(scan)
    coarse = theta[np.any(c0 != np.roll(c0, -1, axis=0), axis=1)]
    origin = quiet_origin(coarse, period)
    grid = origin + theta
    scan_u = {k: np.asarray(v) for k, v in sig(jnp.asarray(grid)).items()}
    lo, hi = find_brackets(lambda t: code(sig(jnp.asarray(t))), grid, code(scan_u), period)
    geo = engagement_angles(mesh, period)
    jumps = np.unique(np.mod(np.concatenate([geo, hi]), period))
    jumps = jumps[np.concatenate([[True], np.diff(jumps) > 1e-12 * period])]
    if jumps.size > 1 and jumps[-1] > period * (1 - 1e-12) and jumps[0] < 1e-12 * period:
        jumps = jumps[:-1]
    knots, cell_first, max_extra = PeriodicHermiteTable.layout(
        origin, period, n_table * n_mesh, np.concatenate([lo, hi])
    )
    side = np.zeros(knots.shape)
    side[np.isin(knots, lo)] = -1.0
    side[np.isin(knots, hi)] = 1.0
    # design-dependent switching angles: kind and cells of the event at every jump, so
    # that the assembly can move them with the modifications (torsional module docstring,
    # "Derivatives with respect to the design")
    kinds, cells_ab = [EV_FIXED] * jumps.size, [(0, 0)] * jumps.size
    if lo.size:
        kinds, cells_ab = classify_events(jumps, lo, hi, code(sig(jnp.asarray(lo))),
                                          code(sig(jnp.asarray(hi))), mesh.n_cells, period)
    kinds, cells_ab = check_event_roots(
        eqx.Partial(sdof_switch, mesh, mods, jnp.asarray(force)),
        jumps, kinds, cells_ab, mesh.pair.mesh_period_rad)
    codes = None
    if any(k != EV_FIXED for k in kinds):
        delta = 1e-9 * period
        codes = jnp.asarray(code(sig(jnp.asarray(knots + side * delta))), dtype=jnp.int32)
    return dict(
        period=float(period), nlte_max=float(np.max(np.abs(scan["nlte"]))),
        table_knots=jnp.asarray(knots), table_side=jnp.asarray(side),
        table_cell_first=jnp.asarray(cell_first, dtype=jnp.int32),
        table_origin=float(origin), table_max_extra=max_extra,
        jump_thetas=tuple(float(t) for t in jumps),
        jump_kinds=tuple(int(k) for k in kinds),
        jump_cells=tuple((int(a), int(b)) for a, b in cells_ab), table_codes=codes,
    )


def with_back_flank_jumps(layout: dict, mesh: Mesh) -> dict:
    """``layout`` (of :func:`sdof_table_layout`) with the angles where back-flank cells
    enter or leave the path of contact (the engagement angles mirrored through
    :func:`gearjax.gears.backlash.back_flank_angle_rad`) added to the integrator's jumps as
    fixed events: the reference formulation with backlash, whose back-flank force jumps
    there while the back flanks are in contact. Angles within ``1e-12`` periods of a jump
    already there are not repeated; the jumps stay sorted with their kinds and cells."""
    period = float(layout["period"])
    phi0 = back_flank_angle_rad(mesh.pair)
    back = np.mod(phi0 - engagement_angles(mesh, period), period)
    old = np.asarray(layout["jump_thetas"], dtype=float)
    tol = 1e-12 * period
    new = []
    for t in np.unique(back):
        d = np.abs(np.mod(np.concatenate([old, new]) - t + period / 2, period) - period / 2)
        if not np.any(d <= tol):
            new.append(float(t))
    thetas = np.concatenate([old, new])
    kinds = list(layout["jump_kinds"]) + [EV_FIXED] * len(new)
    cells = list(layout["jump_cells"]) + [(0, 0)] * len(new)
    order = np.argsort(thetas, kind="stable")
    return dict(layout, jump_thetas=tuple(float(thetas[i]) for i in order),
                jump_kinds=tuple(kinds[i] for i in order),
                jump_cells=tuple(cells[i] for i in order))
