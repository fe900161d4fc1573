"""Transmission error from a file: measured or exported TE_S, NLTE and mesh stiffness as the
excitation of the TE-based and perturbation formulations.

Paper Section 6.2: "this numerical approach to excitations in no way precludes the use of
experimental transmission error measurements for generating the forcing terms in Eqs. (42)
and (48a)". Those formulations (sdof Eqs. (20), (47a)) see the mesh only through the
quasi-static transmission error under load TE_S, the no-load transmission error NLTE and
the loaded stiffness ``k(theta) = (sum k_i)^S`` (Eqs. (17)-(19)); a :class:`TETable` holds
them as read from a single-flank tester or a loaded-tooth-contact export (LDP, KISSsoft,
Romax) and :func:`excitation_table` turns it into the jump-aware
:class:`~gearjax.excitation.tables.PeriodicHermiteTable` of ``(x_S = TE_S - NLTE, k, NLTE)``
that the torsional model integrates (:meth:`gearjax.models.torsional.TorsionalModel.with_te`).
The reference formulation (Eq. (14)/(16): a gap per cell) cannot use a TE file.

File format (CSV, one header line, ``#`` comment lines allowed, extra columns ignored):

* ``mesh_cycle_fraction`` (mesh periods: 0..1 for one, 0..n for n) or ``pinion_angle_rad``
  (alias ``theta_rad``, the column of ``gearjax quasistatic --csv``): the pinion angle
  ``theta``, 0 at gearjax's ``theta = 0`` (where ``gearjax quasistatic`` starts);
* ``te_s_m``: TE_S (m, transverse on the base plane, gearjax's sign: ``TE = x + NLTE``);
* ``nlte_m`` (optional, else 0): NLTE (m);
* ``mesh_stiffness_N_per_m`` (optional): the loaded stiffness (N/m); else the model's own
  quasi-static loaded stiffness from the rig's mesh law and modifications.

The rows cover one or several whole mesh periods, or a pinion revolution (pitch errors),
with or without the closing row at the end of the period (which must then repeat the
first). Angles increase; a jump (the stiffness of an LTCA export when a tooth pair enters
or leaves contact, a kink of TE_S) is two rows at the same angle, left value first.

Interpolation: cubic Hermite between the rows (the rows are the knots), with slopes of the
local polynomial through the (up to) five nearest rows on the same side of every jump, so
that the interpolant is exact for data that are piecewise polynomials of degree <= 4
between jumps (the linear/parabolic reliefs of ``gearjax quasistatic``) and O(h^4)
elsewhere; without jumps the stencil wraps around the period (periodic). NLTE' (which
enters through the change of variable ``z = x + kappa NLTE`` that removes NLTE'',
:mod:`gearjax.models.torsional`) is the derivative of that interpolant, jumping where the
file jumps. Only ``TE_S - NLTE`` and NLTE's derivatives enter the equations: a constant
offset of TE_S (a tester measures only its variation) shifts the reported DTE by that
offset and changes nothing else.
"""

from __future__ import annotations

import csv

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..errors import GearjaxError, ModelError
from .events import quiet_origin
from .jumps import JumpSet
from .tables import PeriodicHermiteTable, hermite_segment

__all__ = ["TETable", "read_te_csv", "excitation_table", "te_model_fields", "with_jump_rows",
           "ANGLE_COLUMNS"]

ANGLE_COLUMNS = ("mesh_cycle_fraction", "pinion_angle_rad", "theta_rad")
TE_LIMIT_M = 1e-3  # a larger TE is almost surely micrometres written as metres
K_MIN_N_PER_M = 1e5  # a smaller mesh stiffness is almost surely N/um written as N/m
_SAME_ANGLE = 1e-9  # rows closer than this fraction of a mesh period share one angle
_CLOSE = 1e-6  # closing row / whole periods: tolerance in mesh periods


class TETable(eqx.Module):
    """TE_S, NLTE and mesh stiffness over one excitation period, from a file or arrays.

    Build with :meth:`from_samples` or :func:`read_te_csv` (checked there). Knots are the
    rows (rad), a jump at angle ``a`` being the knots ``a`` (left value, side -1) and the
    next float (right value, side +1); the closing knot ``origin + period`` repeats the
    first row.

    Attributes
    ----------
    knots : (K,) increasing angles (rad) from ``knots[0]`` to ``knots[0] + period_rad``.
    values, slopes : (K, 3) ``(TE_S (m), NLTE (m), k (N/m))`` and their theta-derivatives
        (per rad); ``k`` is 0 where the file has no stiffness column.
    side : (K,) -1 / +1 at the two knots of a jump, else 0.
    period_rad, mesh_period_rad : period of the data and the pair's mesh period (rad).
    jump_thetas : angles (rad, in [knots[0], knots[0] + period)) of the jumps (right knots).
    has_nlte, has_stiffness : whether the file gave those columns.
    source : where the data came from (file name), for messages.
    """

    knots: np.ndarray = eqx.field(converter=np.asarray)
    values: np.ndarray = eqx.field(converter=np.asarray)
    slopes: np.ndarray = eqx.field(converter=np.asarray)
    side: np.ndarray = eqx.field(converter=np.asarray)
    period_rad: float = eqx.field(static=True)
    mesh_period_rad: float = eqx.field(static=True)
    jump_thetas: tuple = eqx.field(static=True)
    has_nlte: bool = eqx.field(static=True)
    has_stiffness: bool = eqx.field(static=True)
    source: str = eqx.field(static=True, default="arrays")

    def __check_init__(self):
        k = self.knots.shape[0]
        if self.values.shape != (k, 3) or self.slopes.shape != (k, 3) or self.side.shape != (k,):
            raise ModelError("te_table", self.values.shape, "knots, values (K, 3), slopes and "
                             "side must describe the same knots")
        if not abs(self.knots[-1] - self.knots[0] - self.period_rad) <= 1e-9 * self.period_rad:
            raise ModelError("te_table.period_rad", self.period_rad, "the knots must span it")

    @property
    def n_mesh_periods(self) -> int:
        """Mesh periods in :attr:`period_rad`."""
        return int(round(self.period_rad / self.mesh_period_rad))

    def __call__(self, theta):
        """(values (n, 3), slopes (n, 3)) at the angles ``theta`` (rad; NumPy, build time)."""
        return _hermite(self.knots, self.values, self.slopes, np.atleast_1d(theta))

    @classmethod
    def from_samples(cls, theta_rad, te_s_m, nlte_m=None, stiffness_N_per_m=None, *,
                     mesh_period_rad: float, source: str = "arrays",
                     angle_column: str = "pinion_angle_rad", angle_unit_rad: float = 1.0,
                     rows=None) -> "TETable":
        """The table of samples (rows in file order; see the module docstring).

        Parameters
        ----------
        theta_rad : (n,) pinion angles (rad), non-decreasing, a repeated angle marks a jump.
        te_s_m, nlte_m, stiffness_N_per_m : (n,) TE_S (m), NLTE (m, default 0), loaded
            mesh stiffness (N/m, default: none, the model's own).
        mesh_period_rad : 2 pi / z1 of the pair (rad).
        source, angle_column, rows : names for the messages (file, angle column, the
            file's row numbers of the samples); ``angle_unit_rad``: the angle column's unit
            in rad (the mesh period for ``mesh_cycle_fraction``), for the messages.

        Raises
        ------
        GearjaxError
            naming the column and the row: non-finite values, decreasing angles, more than
            two rows at one angle, TE above 1 mm (micrometres given as metres?), stiffness
            <= 0 or below 1e5 N/m (N/um given as N/m?), rows not covering whole mesh
            periods, or a closing row that does not repeat the first.
        """
        m = float(mesh_period_rad)
        th = np.asarray(theta_rad, dtype=float).reshape(-1)
        n = th.size
        rows = np.arange(1, n + 1) if rows is None else np.asarray(rows)
        cols = {angle_column: th / angle_unit_rad, "te_s_m": te_s_m, "nlte_m": nlte_m,
                "mesh_stiffness_N_per_m": stiffness_N_per_m}
        cols = {c: np.asarray(v, dtype=float).reshape(-1) for c, v in cols.items() if v is not None}

        def bad(col, i, reason):
            return GearjaxError(f"{source}: {col}={float(cols[col][i])!r} in row {rows[i]}: {reason}")

        for c, v in cols.items():
            if v.size != n:
                raise GearjaxError(f"{source}: {c}: {v.size} values for {n} angles")
            if not np.all(np.isfinite(v)):
                raise bad(c, int(np.argmin(np.isfinite(v))), "not a finite number")
        if n < 4:
            raise GearjaxError(f"{source}: {n} rows: need at least 4 samples of a period")
        d = np.diff(th)
        if np.any(d < 0):
            raise bad(angle_column, int(np.argmax(d < 0)) + 1,
                      f"smaller than the row before ({float(th[np.argmax(d < 0)] / angle_unit_rad)!r}): angles must "
                      "increase (two rows at one angle mark a jump)")
        same = d <= _SAME_ANGLE * m
        if np.any(same[1:] & same[:-1]):
            raise bad(angle_column, int(np.argmax(same[1:] & same[:-1])) + 2,
                      "a third row at one angle (a jump is two rows: left value, right value)")
        for c in ("te_s_m", "nlte_m"):
            if c in cols and np.max(np.abs(cols[c])) > TE_LIMIT_M:
                raise bad(c, int(np.argmax(np.abs(cols[c]))),
                          f"above {TE_LIMIT_M:g} m: a transmission error in metres is expected "
                          "(micrometres given as metres?)")
        k = cols.get("mesh_stiffness_N_per_m")
        if k is not None:
            if np.min(k) <= 0:
                raise bad("mesh_stiffness_N_per_m", int(np.argmin(k)),
                          "must be > 0 (N/m: the loaded mesh stiffness)")
            if np.max(k) < K_MIN_N_PER_M:
                raise bad("mesh_stiffness_N_per_m", int(np.argmax(k)),
                          f"below {K_MIN_N_PER_M:g} N/m everywhere: stiffness in N/m is "
                          "expected (N/um given as N/m?)")
        data = np.stack([cols["te_s_m"], cols.get("nlte_m", np.zeros(n)),
                         np.zeros(n) if k is None else k], axis=1)
        if angle_unit_rad == 1.0:
            _question_degrees(th, m, source, angle_column, rows[-1])
        # the period: whole mesh periods, with the closing row or without it
        span = (th[-1] - th[0]) / m
        if span >= 1 - _CLOSE and abs(span - round(span)) <= _CLOSE * max(1.0, span):
            n_per = int(round(span))
            ref = np.ptp(data, axis=0)
            for j, c in enumerate(("te_s_m", "nlte_m", "mesh_stiffness_N_per_m")):
                if c in cols and abs(data[-1, j] - data[0, j]) > 1e-2 * ref[j] + 1e-12 * abs(data[0, j]):
                    raise bad(c, n - 1, f"the row at the end of the period ({n_per} mesh "
                              f"period(s)) must repeat the first row ({float(data[0, j])!r}): the "
                              "data are not periodic")
            th, data, rows = th[:-1], data[:-1], rows[:-1]
            if th[-1] >= th[0] + (n_per - _SAME_ANGLE) * m:  # a jump at the period's end:
                th = np.concatenate([[th[-1] - n_per * m], th[:-1]])  # its left row first
                data = np.concatenate([data[-1:], data[:-1]])
                rows = np.concatenate([rows[-1:], rows[:-1]])
        else:
            dist = np.diff(th)[np.diff(th) > _SAME_ANGLE * m]
            cover = span + float(np.median(dist)) / m
            n_per = int(round(cover))
            if n_per < 1 or abs(cover - n_per) > 0.01 * n_per:
                raise bad(angle_column, n - 1,
                          f"the rows cover {span:.4g} mesh periods (2 pi / z1 = {m:.6g} rad "
                          "each); a TE file covers whole mesh periods (one, several, or a "
                          "pinion revolution), with or without the closing row")
        period = n_per * m
        knots, vals, side, jumps = _knots(th, data, period, m)
        slopes = _local_slopes(knots, vals, side, period)
        return cls(knots=knots, values=vals, slopes=slopes, side=side, period_rad=period,
                   mesh_period_rad=m, jump_thetas=jumps, has_nlte="nlte_m" in cols,
                   has_stiffness=k is not None, source=source)


def _whole_periods(th, m, tol) -> bool:
    """Whether the angles ``th`` (rad) span whole mesh periods ``m``, with or without the
    closing row (then the span plus one median step), within ``tol`` of a period count."""
    d = np.diff(th)
    d = d[d > _SAME_ANGLE * m]
    span = (th[-1] - th[0]) / m
    for cover in (span, span + (float(np.median(d)) / m if d.size else 0.0)):
        n = round(cover)
        if n >= 1 and abs(cover - n) <= tol * n:
            return True
    return False


def _question_degrees(th, m, source, column, last_row) -> None:
    """Refuse angles in a radian column that are whole mesh periods only when read as
    degrees (a file exported in degrees: one mesh period of 360/z1 deg would otherwise
    read as ~57 mesh periods of a much slower excitation)."""
    deg = th * (np.pi / 180.0)
    if _whole_periods(deg, m, 1e-3) and not _whole_periods(th, m, 1e-3):
        span = float(th[-1] - th[0])
        raise GearjaxError(
            f"{source}: {column}={float(th[-1])!r} in row {last_row}: the rows span {span:.6g} "
            f"= {span / m:.4g} mesh periods if radians, but {span * np.pi / 180 / m:.4g} whole "
            "mesh period(s) if degrees: angles in degrees? The column is in radians (multiply "
            "by pi/180)")


def _knots(th, data, period, m):
    """Knots over [th[0], th[0] + period] with the jump pairs split into (a, next float)."""
    same = np.diff(th) <= _SAME_ANGLE * m
    t = th.copy()
    side = np.zeros(t.size)
    for i in np.flatnonzero(same):
        t[i + 1] = np.nextafter(t[i], np.inf)
        side[i], side[i + 1] = -1.0, 1.0
    jumps = tuple(float(x) for x in t[side > 0])
    close_side = -1.0 if side[0] < 0 else 0.0  # the closing knot repeats the first row
    knots = np.concatenate([t, [th[0] + period]])
    return knots, np.concatenate([data, data[:1]]), np.concatenate([side, [close_side]]), jumps


def _local_slopes(knots, vals, side, period):
    """Slopes at the knots: derivative of the polynomial through the (up to) five nearest
    knots of the same smooth piece (between jumps; periodic without jumps)."""
    n = knots.size - 1  # the closing knot repeats knot 0
    t, v = knots[:-1], vals[:-1]
    slopes = np.zeros_like(vals)
    if not np.any(side[:-1]):  # one periodic piece
        idx = np.arange(n)
        for i in idx:
            w = (np.arange(i - 2, i + 3)) if n >= 5 else np.arange(i - (n - 1) // 2, i - (n - 1) // 2 + n)
            x = t[w % n] + period * np.floor_divide(w, n)
            slopes[i] = _lagrange_slope(x, v[w % n], list(w).index(i))
        slopes[-1] = slopes[0]
        return slopes
    # rotate to start at a right knot: the pieces are then contiguous runs
    start = int(np.flatnonzero(side[:-1] > 0)[0])
    order = (start + np.arange(n)) % n
    x_all = t[order] + period * (order < start)
    s_all = side[:-1][order]
    ends = np.flatnonzero(s_all < 0)  # last knot of each piece
    begin = 0
    for e in ends:
        piece = np.arange(begin, e + 1)
        for j, p in enumerate(piece):
            lo = int(np.clip(j - 2, 0, max(0, piece.size - 5)))
            w = piece[lo:lo + 5]
            slopes[order[p]] = _lagrange_slope(x_all[w], v[order[w]], int(np.flatnonzero(w == p)[0]))
        begin = e + 1
    slopes[-1] = slopes[0]
    return slopes


def _lagrange_slope(x, y, j):
    """d/dx at x[j] of the polynomial through (x, y) (y: (p, q))."""
    p = x.size
    if p == 1:
        return np.zeros(y.shape[1:])
    out = np.zeros(y.shape[1:])
    for k in range(p):
        if k == j:
            out = out + y[k] * sum(1.0 / (x[j] - x[mm]) for mm in range(p) if mm != j)
        else:
            c = 1.0 / (x[k] - x[j])
            for mm in range(p):
                if mm not in (k, j):
                    c *= (x[j] - x[mm]) / (x[k] - x[mm])
            out = out + y[k] * c
    return out


def _hermite(knots, values, slopes, theta):
    """Cubic Hermite interpolation of periodic knot data (NumPy); at a knot, the value of
    the segment that starts there."""
    period = knots[-1] - knots[0]
    s = knots[0] + np.mod(theta - knots[0], period)
    j = np.clip(np.searchsorted(knots, s, side="right") - 1, 0, knots.size - 2)
    t0, t1 = knots[j], knots[j + 1]
    w = np.maximum(t1 - t0, 1e-300)
    u = np.clip((s - t0) / w, 0.0, 1.0)[:, None]
    w = w[:, None]
    return hermite_segment(values[j], values[j + 1], slopes[j] * w, slopes[j + 1] * w, u, w)


def read_te_csv(path, mesh_period_rad: float) -> TETable:
    """Read a TE file (module docstring) for a pair of mesh period ``2 pi / z1`` (rad).

    Raises
    ------
    GearjaxError
        one line naming the file, the column and the row (see :meth:`TETable.from_samples`),
        also for a missing column or a value that is not a number.
    """
    name = str(path)
    try:
        with open(path, newline="") as fh:
            lines = [(i + 1, ln) for i, ln in enumerate(fh) if ln.strip() and not ln.lstrip().startswith("#")]
    except OSError as exc:
        raise GearjaxError("--te-file", name, f"cannot be read ({exc.strerror or exc})") from None
    if not lines:
        raise GearjaxError("--te-file", name, "empty file (a header line and rows expected)")
    table = list(csv.reader([ln for _, ln in lines]))
    header = [h.strip() for h in table[0]]
    angle = next((c for c in ANGLE_COLUMNS if c in header), None)
    missing = [c for c in ("te_s_m",) if c not in header]
    if angle is None or missing:
        need = " or ".join(ANGLE_COLUMNS[:2]) if angle is None else missing[0]
        raise GearjaxError(f"{name}: missing column {need} (header: {','.join(header)}); "
                           "columns: mesh_cycle_fraction or pinion_angle_rad, te_s_m, "
                           "optional nlte_m, mesh_stiffness_N_per_m")
    wanted = [angle, "te_s_m", "nlte_m", "mesh_stiffness_N_per_m"]
    cols = {c: [] for c in wanted if c in header}
    rows = []
    for (row_no, _), rec in zip(lines[1:], table[1:]):
        for c in cols:
            j = header.index(c)
            text = rec[j].strip() if j < len(rec) else ""
            try:
                cols[c].append(float(text))
            except ValueError:
                raise GearjaxError(f"{name}: {c}={text!r} in row {row_no}: not a number") from None
        rows.append(row_no)
    th = np.asarray(cols.pop(angle))
    if angle == "mesh_cycle_fraction":
        th = th * mesh_period_rad
    return TETable.from_samples(th, cols["te_s_m"], cols.get("nlte_m"),
                                cols.get("mesh_stiffness_N_per_m"),
                                mesh_period_rad=mesh_period_rad, source=name,
                                angle_column=angle, rows=rows,
                                angle_unit_rad=mesh_period_rad if angle == ANGLE_COLUMNS[0] else 1.0)


def excitation_table(te: TETable, law: PeriodicHermiteTable | None = None, law_side=None,
                     law_jumps=()) -> tuple[PeriodicHermiteTable, np.ndarray, tuple]:
    """The model's excitation table ``(x_S = TE_S - NLTE (m), k (N/m), NLTE (m))`` from a
    :class:`TETable`, with ``k`` from ``law`` (the model's own table of ``(x_S, k, NLTE)``
    on its knots with sides ``law_side`` and jumps ``law_jumps``) when the file has no
    stiffness. Knots: the union of both tables' knots over the longer of the two periods
    (the other must divide it), so each is reproduced exactly (a Hermite cubic restricted
    to a sub-interval is itself). Returns (table, side (-1/+1 at jump knots), jump angles).
    """
    m = te.mesh_period_rad
    use_law = not te.has_stiffness
    if use_law and law is None:
        raise ModelError("te_table", te.source, "no mesh_stiffness_N_per_m column and no "
                         "model stiffness to take it from")
    n_te = te.n_mesh_periods
    n_law = int(round(law.period / m)) if use_law else n_te
    if max(n_te, n_law) % min(n_te, n_law):
        raise ModelError("te_table", te.source,
                         f"covers {n_te} mesh periods, the model's excitation {n_law}: one "
                         "must be a multiple of the other")
    n_per = max(n_te, n_law)
    period = n_per * m
    srcs = [(te.knots[:-1], te.side[:-1], te.period_rad, te.jump_thetas)]
    if use_law:
        srcs.append((np.asarray(law.knots)[:-1], np.asarray(law_side)[:-1], law.period,
                     tuple(law_jumps)))
    tiled, jumps = [], []
    for kn, sd, p, jp in srcs:
        reps = int(round(period / p))
        tiled.append((np.concatenate([kn + r * p for r in range(reps)]), np.tile(sd, reps)))
        jumps += [j + r * p for j in jp for r in range(reps)]
    jumps = np.mod(np.asarray(jumps, dtype=float), period)
    origin = quiet_origin(jumps, period) if jumps.size else float(np.mod(te.knots[0], period))
    folded = [_fold(k, sd, origin, period) for k, sd in tiled]
    extra = np.concatenate(folded)
    n_cells = max(16, int(extra.size // (1 + len(srcs))))
    knots, cell_first, max_extra = PeriodicHermiteTable.layout(origin, period, n_cells, extra)
    delta = 1e-9 * period

    def sides(f, sd):  # each source's own side at the knots it owns
        lookup = dict(zip(f.tolist(), sd.tolist()))
        return np.array([lookup.get(x, 0.0) for x in knots.tolist()])

    s_te = sides(folded[0], tiled[0][1])
    at = knots + s_te * delta
    v, d = te(at)
    v = v - (s_te * delta)[:, None] * d  # back to the knot, on the knot's side
    vals = np.stack([v[:, 0] - v[:, 1], v[:, 2], v[:, 1]], axis=1)
    slopes = np.stack([d[:, 0] - d[:, 1], d[:, 2], d[:, 1]], axis=1)
    side = s_te
    if use_law:
        s_law = sides(folded[1], tiled[1][1])
        at = jnp.asarray(knots + s_law * delta)
        lv, ld = jax.vmap(law)(at)
        lv, ld = np.asarray(lv), np.asarray(ld)
        vals[:, 1] = lv[:, 1] - s_law * delta * ld[:, 1]
        slopes[:, 1] = ld[:, 1]
        side = np.where(s_te != 0, s_te, s_law)
    table = PeriodicHermiteTable(knots=jnp.asarray(knots), values=jnp.asarray(vals),
                                 slopes=jnp.asarray(slopes),
                                 cell_first=jnp.asarray(cell_first, dtype=jnp.int32),
                                 origin=origin, period=float(period),
                                 n_cells=n_cells,
                                 max_extra=max_extra)
    jumps = np.sort(jumps)
    keep = np.concatenate([[True], np.diff(jumps) > _SAME_ANGLE * m]) if jumps.size else []
    return table, side, tuple(float(j) for j in jumps[keep])


def te_model_fields(te: TETable, law: PeriodicHermiteTable, law_side, law_jumps,
                    nlte_terms: bool | None) -> dict:
    """The excitation fields of a torsional model driven by ``te`` (its
    ``with_te``): the table of :func:`excitation_table` as the model's ``te_input`` and
    layout, its jumps as fixed integrator jumps, ``nlte_terms`` (None: kept iff the file's
    NLTE is not identically 0)."""
    table, side, jumps = excitation_table(te, law, law_side, law_jumps)
    if nlte_terms is None:
        nlte_terms = bool(np.any(te.values[:, 1] != 0.0))
    return dict(te_input=table, table_knots=table.knots, table_cell_first=table.cell_first,
                table_side=jnp.asarray(side), table_origin=jnp.asarray(table.origin),
                period_rad=table.period, table_max_extra=table.max_extra,
                jumps=JumpSet.from_angles(jumps, table.period,
                                          mesh_period=te.mesh_period_rad),
                table_codes=None, nlte_weight=jnp.asarray(float(bool(nlte_terms))))


def _fold(kn, sd, origin, period):
    """Knots folded into [origin, origin + period), the right knot of every jump kept the
    float next to its left one (folding could otherwise merge or split the pair)."""
    f = np.mod(kn - origin, period) + origin
    f = np.where(f >= origin + period, origin, f)
    right = np.flatnonzero((sd[1:] > 0) & (sd[:-1] < 0)) + 1
    f[right] = np.nextafter(f[right - 1], np.inf)
    return f


def with_jump_rows(theta, values, table: PeriodicHermiteTable, side, jump_thetas,
                   mesh_period_rad: float, fill=()):
    """File rows ``(theta (n,), values (n, 3))`` of ``(TE_S, NLTE, k)``: a quasi-static
    grid (``theta``, ``values``) plus two one-sided rows (left first) at every jump angle
    of a model's excitation table (its ``(x_S, k, NLTE)`` ``table`` with knot ``side`` -1
    / +1 around the jumps, and its integrator ``jump_thetas``, continuous ones included),
    grid rows at those angles dropped (``values`` may carry more columns: ``fill`` gives
    them in the jump rows). What ``gearjax quasistatic --csv`` writes, so that a
    file written there carries every jump and kink of the model exactly."""
    knots, side = np.asarray(table.knots), np.asarray(side)
    tv = np.asarray(table.values)
    tv = np.stack([tv[:, 0] + tv[:, 2], tv[:, 2], tv[:, 1]], axis=1)  # -> TE_S, NLTE, k
    tol, period = _SAME_ANGLE * mesh_period_rad, table.period
    lo = np.flatnonzero(side[:-1] < 0)
    lo = lo[side[lo + 1] > 0]
    ang = np.mod(np.asarray(jump_thetas, dtype=float), period)
    rows_t, rows_v = [], []
    for a in ang:
        near = lo[np.abs(np.mod(knots[lo + 1] - a + period / 2, period) - period / 2) <= tol]
        if near.size:  # one-sided values of the (first, last) knot pair at that angle
            left, right = tv[near.min()], tv[near.max() + 1]
        else:  # a continuous event (e.g. an unloaded tooth engaging): one value twice
            v = np.asarray(table(jnp.asarray(a))[0])
            left = right = np.array([v[0] + v[2], v[2], v[1]])
        rows_t += [a, a]
        rows_v += [np.concatenate([left, fill]), np.concatenate([right, fill])]
    theta, values = np.asarray(theta, dtype=float), np.asarray(values, dtype=float)
    d = np.abs(np.mod(theta[:, None] - ang[None, :] + period / 2, period) - period / 2)
    far = np.all(d > tol, axis=1)
    th = np.concatenate([theta[far], rows_t])
    order = np.argsort(th, kind="stable")
    return th[order], np.concatenate([values[far], np.reshape(rows_v, (-1, values.shape[1]))])[order]
