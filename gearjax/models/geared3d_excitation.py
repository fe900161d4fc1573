"""Excitation layout of the 3D model (:class:`gearjax.models.geared3d.Geared3DModel`):
the jump-aware table of the te/perturbation formulations, from the model's own quasi-static
solve or from a TE file.

Eqs. (42) and (48a) see the mesh only through three scalar functions of the pinion angle
(the averaged mesh vector V of Eq. (27) carries the geometry): ``d = TE_S - NLTE - w_x0``
(Eqs. (36)-(41); ``TE_S - w_x0`` without NLTE terms), the loaded quasi-static stiffness
``k(theta)`` and NLTE. :func:`own_table_fields` tabulates them from the model's per-cell
quasi-static contact (Eq. (25), moving switching angles through an angle map);
:func:`te_file_fields` takes TE_S, NLTE and (if given) k from a
:class:`~gearjax.excitation.te_file.TETable` instead: the paper's Section 6.2, "this
numerical approach to excitations in no way precludes the use of experimental transmission
error measurements for generating the forcing terms in Eqs. (42) and (48a)". TE_S is read
at the model's encoders (``w_x0 = W^T X_0`` is the static approach seen there, Eq. (30)),
so a file measured at another encoder position drives the model built with that position.

Own table: jump-aware and periodic Hermite (:mod:`gearjax.excitation.mesh3d`), exact at the
jumps of ``k`` and the kinks of ``TE_S`` and NLTE (``excitation="inline"`` solves the contact
at every right-hand side instead, to check it).

Design derivatives (moving events): the angles where ``k`` jumps, NLTE' jumps or ``TE_S``
kinks move with the tip relief. The tabulated formulations record every event at build
(``Geared3DModel.jumps``: angles, kinds, cells, padded), move them by Newton on
their switching functions (``Geared3DModel.jump_angles_rad``) and integrate in the simulation angle
``s`` with ``theta = phi(s)`` (:class:`gearjax.excitation.tables.AngleMap`, the identity at
the build design): ``Geared3DModel.vector_field`` is ``phi'(s) dy/dtheta``. The model is complete
when built; ``Geared3DModel.with_modifications`` gives the model of another design (table, map and
:attr:`structure_ok`, whether the design keeps the build's discrete quasi-static state,
recomputed; traceable). ``k_m`` stays the build value (exact for te, held fixed in the
perturbation derivative). The reference formulation has no table and no map.
A TE file's jumps stay where the file puts them (no angle map).
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ..excitation.jumps import JumpSet
from ..excitation.mesh3d import QuasiStaticMesh3D, tabulate
from ..excitation.te_file import TETable, excitation_table
from .geared3d_layout import layout_3d

__all__ = ["own_table_fields", "te_file_fields", "file_mean_stiffness"]


@eqx.filter_jit
def _tabulated(qsm: QuasiStaticMesh3D, knots, side, cell_first, origin, events, codes, *,
               period: float, n_cells: int, max_extra: int):
    """:func:`gearjax.excitation.mesh3d.tabulate` at build time, compiled once per rig and
    layout bounds (the layout is data)."""
    return tabulate(qsm, knots, side, cell_first, origin=origin, period=period,
                    n_cells=n_cells, max_extra=max_extra, events=events, table_codes=codes)


def _no_table() -> dict:
    """Layout fields of a model without table (a function: a jnp array at import would
    start the XLA backend, which must wait for ``jax.distributed.initialize``)."""
    return dict(table_knots=None, table_cell_first=None, table_side=None, table_codes=None,
                table=None, angle_map=None, structure_ok=jnp.asarray(True),
                table_origin=jnp.asarray(0.0), table_cells=0, table_max_extra=1)


def own_table_fields(qsm: QuasiStaticMesh3D, n_scan: int, period: float, tabulated: bool,
                     moving_events: bool = True,
                     back_flanks: bool = False) -> tuple[JumpSet, dict]:
    """(jump set, layout fields) of a model excited by its own quasi-static mesh, laid out
    in the build's program (:func:`gearjax.models.geared3d_layout.layout_3d`, from a
    uniform scan of ``n_scan`` angles over ``period``): the speed-independent right-hand
    side jumps and, when ``tabulated`` (te/perturbation with ``excitation="table"``), the
    table of ``(d, k, NLTE)`` with the zone kinks of NLTE' as events (moving with the
    design through the angle map; with ``moving_events=False`` they stay at the build
    angles: no angle map, the same table at the build design). ``back_flanks``: the
    back-flank engagement angles join the jumps, fixed."""
    lay = layout_3d(qsm, n_scan, period, tabulated=tabulated, moving_events=moving_events,
                    back_flanks=back_flanks)
    if not tabulated:
        return lay.jumps, _no_table()
    events = lay.jumps if moving_events else None
    table, amap, ok = _tabulated(qsm, lay.knots, lay.side, lay.cell_first, lay.origin, events,
                                 lay.codes, period=float(period), n_cells=int(n_scan),
                                 max_extra=lay.max_extra)
    return lay.jumps, dict(table_knots=lay.knots, table_cell_first=lay.cell_first,
                           table_side=lay.side, table_codes=lay.codes, table=table,
                           angle_map=amap, structure_ok=ok, table_origin=lay.origin,
                           table_cells=int(n_scan), table_max_extra=lay.max_extra)


def file_mean_stiffness(te: TETable) -> float | None:
    """Exact mean (N/m) of the file's loaded stiffness over its period (the Hermite
    interpolant's), or None when the file has no stiffness column."""
    if not te.has_stiffness:
        return None
    table, _, _ = excitation_table(te)
    return float(table.mean()[1])


def te_file_fields(te: TETable, own: dict, own_jumps, w_x0: float, nlte_terms: bool):
    """(jump angles (rad), layout fields, period (rad)) of a model driven by the TE file
    ``te``: the table of ``(d, k, NLTE)`` with ``d = TE_S - NLTE - w_x0`` (``TE_S - w_x0``
    without NLTE terms) from :func:`gearjax.excitation.te_file.excitation_table` (``k`` from
    the model's own table ``own`` when the file has none); the file's jumps are fixed
    integrator jumps (no angle map, no moving events)."""
    table, side, jumps = excitation_table(te, own["table"], own["table_side"], own_jumps)
    v, d = np.asarray(table.values), np.asarray(table.slopes)
    shift = -float(w_x0) + (0.0 if nlte_terms else v[:, 2])
    v = np.column_stack([v[:, 0] + shift, v[:, 1], v[:, 2]])
    if not nlte_terms:
        d = np.column_stack([d[:, 0] + d[:, 2], d[:, 1], d[:, 2]])
    table = eqx.tree_at(lambda t: (t.values, t.slopes), table, (jnp.asarray(v), jnp.asarray(d)))
    fields = dict(_no_table(), table_knots=table.knots, table_cell_first=table.cell_first,
                  table_side=jnp.asarray(side), table=table,
                  table_origin=jnp.asarray(table.origin), table_cells=int(table.n_cells),
                  table_max_extra=int(table.max_extra))
    return tuple(float(j) for j in jumps), fields, float(table.period)
