"""The excitation layout of a design, computed in the program: state changes bracketed by
bisection, switching events classified, table knots placed, all in arrays of static bounds.

The quasi-static solution (paper Eqs. (9), (17)-(19)) changes its discrete state (the
integer *code* rows of :func:`gearjax.excitation.events.code`) at a design-dependent set of
angles. :func:`find_changes` brackets every change between adjacent floating-point angles
from a uniform scan (as :func:`gearjax.excitation.events.find_brackets`, same order, same
floats), :func:`classify_events` names the event at each jump angle (as the NumPy
:func:`gearjax.excitation.events.classify_events`), :func:`distinct_jumps`,
:func:`quiet_origin` and :func:`table_knots` give the integrator's jump angles, the table's
origin and its knots; :func:`scan_layout` chains them from a uniform scan, the layout of
both gear models. Every array has a static length (the :class:`LayoutBounds` of the
model: a rig, not a design, fixes them); invalid entries are masked, and the bracket
angles of unused slots are ``+inf``. An overflow of a bound is reported as a flag (the
builder then grows the bound: a new program, once).

Because the layout is traced, the model of a design is a pure JAX function of the design
(its builder compiles once per rig, and ``jit``/``vmap`` of "build the model at x and
sweep" is one program over many designs); the layout itself is piecewise constant in the
design (a bisection), so derivatives flow through the angle map instead
(:mod:`gearjax.excitation.events`, "Derivatives with respect to the design").
"""

from __future__ import annotations

import warnings
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .events import EV_FIXED, EV_LOADED, EV_NLTE, EV_ZONE1, EV_ZONE2, NEWTON_STEPS, moved_event_angles

__all__ = ["LayoutBounds", "Changes", "find_changes", "event_kinds", "classify_events",
           "distinct_jumps", "quiet_origin", "table_knots", "knot_sides", "fix_unlocated",
           "ScanLayout", "scan_layout", "warn_unlocated"]

BISECTIONS = 80  # halvings of a scan interval: adjacent floats from any spacing >= 2^-80
MAX_ROUNDS = 64  # state changes found in one scan interval, one per round


class LayoutBounds(NamedTuple):
    """Static bounds of a model's layout: ``jumps`` (integrator jump angles), ``brackets``
    (state changes per period, each one bracket of two table knots), ``max_extra``
    (extra knots in one uniform table cell) and ``intervals`` (intervals of the uniform
    scan in which the state changes, bisected side by side: where several changes share
    one interval, as the cells of a 3D contact line do, fewer than ``brackets``)."""

    jumps: int
    brackets: int
    max_extra: int
    intervals: int

    def grown(self, need: "LayoutBounds") -> "LayoutBounds":
        """Bounds that hold ``need`` (each at least doubled where it does not fit)."""
        from .jumps import round_up

        def g(have, want):
            return have if want <= have else round_up(max(2 * have, want))
        return LayoutBounds(g(self.jumps, need.jumps), g(self.brackets, need.brackets),
                            g(self.max_extra, need.max_extra),
                            g(self.intervals, need.intervals))


class Changes(NamedTuple):
    """Brackets of the state changes (:func:`find_changes`): ``lo``, ``hi`` (bound,)
    adjacent floats around each change (``+inf`` in unused slots), ``c_lo``, ``c_hi``
    (bound, n_code) the codes there, ``count`` () the number found (more than the bound:
    overflow), ``n_intervals`` () the scan intervals in which the state changes."""

    lo: jax.Array
    hi: jax.Array
    c_lo: jax.Array
    c_hi: jax.Array
    count: jax.Array
    n_intervals: jax.Array


def find_changes(code_fn, theta, period: float, bound: int,
                 intervals: int | None = None) -> Changes:
    """Every change of the discrete state over one period, bracketed by adjacent floats
    (traced :func:`gearjax.excitation.events.find_brackets`: bisection from the uniform scan
    ``theta`` (n,) of spacing ``period / n``; several changes in one scan interval are found
    one per round, the brackets in round order, then scan order, as there).

    ``code_fn`` maps a (m,) array of angles to the (m, n_code) int code matrix (traceable,
    any m). At most ``bound`` changes are kept, found in at most ``intervals`` (default
    ``bound``) scan intervals bisected side by side; ``count`` and ``n_intervals`` say how
    many there were."""
    n = theta.shape[0]
    c = code_fn(theta)
    nxt = jnp.roll(c, -1, axis=0)
    changed = jnp.any(c != nxt, axis=1)
    n_changed = jnp.sum(changed)
    slots = bound if intervals is None else int(intervals)
    idx = jnp.nonzero(changed, size=slots, fill_value=0)[0]
    active = jnp.arange(slots) < n_changed
    h = period / n
    a = theta[idx]
    b = a + h
    ca, cb = c[idx], nxt[idx]
    inf = jnp.full(bound, jnp.inf)

    def bisect(a, b, ca, cb, on):
        # the codes at the ends are those the bisection read there (a code re-read at an
        # end in another program may round the other way a few floats from a change)
        # (halving stops once every bracket is two adjacent floats: a halving more would
        # change nothing, and each one costs a code evaluation of every slot)
        def interior_of(lo, hi):
            mid = 0.5 * (lo + hi)
            return mid, on & (mid > lo) & (mid < hi)

        def cond(st):
            i, lo, hi, _ = st
            return (i < BISECTIONS) & jnp.any(interior_of(lo, hi)[1])

        def body(st):
            i, lo, hi, c_hi = st
            mid, interior = interior_of(lo, hi)
            c_mid = code_fn(mid)
            same = jnp.all(c_mid == ca, axis=1)
            move_hi = interior & ~same
            return (i + 1, jnp.where(interior & same, mid, lo), jnp.where(move_hi, mid, hi),
                    jnp.where(move_hi[:, None], c_mid, c_hi))

        return jax.lax.while_loop(cond, body, (jnp.asarray(0), a, b, cb))[1:]

    def cond(s):
        return jnp.any(s["on"]) & (s["round"] < MAX_ROUNDS)

    def body(s):
        on = s["on"]
        lo, hi, c_hi = bisect(s["a"], s["b"], s["ca"], s["cb"], on)
        c_lo = s["ca"]  # lo moved only onto angles whose code was ca
        pos = jnp.where(on, s["count"] + jnp.cumsum(on) - 1, bound)  # bound: dropped
        put = lambda arr, v: arr.at[pos].set(v, mode="drop")  # noqa: E731
        more = on & jnp.any(c_hi != s["cb"], axis=1)  # another change between hi and b
        return dict(a=hi, b=s["b"], ca=c_hi, cb=s["cb"], on=more, round=s["round"] + 1,
                    count=s["count"] + jnp.sum(on), lo=put(s["lo"], lo), hi=put(s["hi"], hi),
                    c_lo=put(s["c_lo"], c_lo), c_hi=put(s["c_hi"], c_hi))

    codes = jnp.zeros((bound,) + ca.shape[1:], ca.dtype)
    init = dict(a=a, b=b, ca=ca, cb=cb, on=active, round=jnp.asarray(0),
                count=jnp.asarray(0), lo=inf, hi=inf, c_lo=codes, c_hi=codes)
    s = jax.lax.while_loop(cond, body, init)
    # more changed scan intervals than slots: count them as overflow too
    count = jnp.where(n_changed > slots, jnp.maximum(s["count"], n_changed), s["count"])
    return Changes(s["lo"], s["hi"], s["c_lo"], s["c_hi"], count, n_changed)


def event_kinds(c_lo, c_hi, n):
    """Kind and cells ``(kind, a, b)`` of the switching event between codes ``c_lo`` and
    ``c_hi`` (rows of 1 + 3 n; traceable, batched over leading axes): the rule of
    :func:`gearjax.excitation.events.event_kinds`."""
    d = c_lo != c_hi
    ins, load = d[..., 1 + n:1 + 2 * n], d[..., 1:1 + n]
    zone = d[..., 1 + 2 * n:]
    z_lo, z_hi = c_lo[..., 1 + 2 * n:], c_hi[..., 1 + 2 * n:]
    outside = jnp.any(zone & ((z_lo < 0) | (z_hi < 0)), axis=-1)
    cz = jnp.argmax(zone, axis=-1)
    bits = jnp.take_along_axis(z_lo ^ z_hi, cz[..., None], axis=-1)[..., 0]
    cl = jnp.argmax(load, axis=-1)
    kind = jnp.where(
        jnp.any(ins, axis=-1) | outside, EV_FIXED,
        jnp.where(jnp.any(zone, axis=-1), jnp.where(bits & 1, EV_ZONE1, EV_ZONE2),
                  jnp.where(jnp.any(load, axis=-1), EV_LOADED,
                            jnp.where(d[..., 0], EV_NLTE, EV_FIXED))))
    a = jnp.where(kind == EV_NLTE, c_lo[..., 0],
                  jnp.where(kind == EV_LOADED, cl, jnp.where(kind == EV_FIXED, 0, cz)))
    b = jnp.where(kind == EV_NLTE, c_hi[..., 0], jnp.where(kind == EV_FIXED, 0, a))
    return kind.astype(jnp.int32), a.astype(jnp.int32), b.astype(jnp.int32)


# which of coinciding state changes names the event (events.classify_events)
_PRIORITY = np.asarray([3, 1, 2, 0, 0])  # by kind: fixed (never chosen), loaded, nlte, zones


def classify_events(angles, lo, hi, c_lo, c_hi, n_cells: int, period: float,
                    rtol: float = 1e-9):
    """Kind and cells of the event at each of ``angles`` (traced
    :func:`gearjax.excitation.events.classify_events`, same rule): the brackets whose
    ``hi`` lies within ``rtol * period`` of the angle (circularly; ``+inf`` brackets are
    unused) name it, a fixed one among them pins it, else the first of the highest
    priority gives kind and cells; an angle without a bracket is fixed.

    Returns ``(kinds (n,) int32, cells (n, 2) int32)``."""
    kind, a, b = event_kinds(c_lo, c_hi, n_cells)
    at = jnp.mod(hi, period)
    dist = jnp.abs(at[None, :] - angles[:, None])
    dist = jnp.minimum(dist, period - dist)
    near = dist <= rtol * period  # NaN (unused bracket) compares False
    fixed = jnp.any(near & (kind == EV_FIXED)[None, :], axis=1) | ~jnp.any(near, axis=1)
    m = kind.shape[0]
    score = jnp.where(near, jnp.asarray(_PRIORITY)[kind][None, :] * m + jnp.arange(m)[None, :],
                      jnp.iinfo(jnp.int32).max)
    i = jnp.argmin(score, axis=1)
    kinds = jnp.where(fixed, EV_FIXED, kind[i]).astype(jnp.int32)
    cells = jnp.where(fixed[:, None], 0, jnp.stack([a[i], b[i]], axis=1)).astype(jnp.int32)
    return kinds, cells


def distinct_jumps(angles, valid, period: float, bound: int, tol: float = 1e-12):
    """Sorted distinct angles in ``[0, period)`` of the valid ``angles`` (folded into the
    period; an angle within ``tol * period`` of the one before it dropped, and the last one
    dropped where it is within that of the period end while the first is within that of
    0), as the sdof build's rule. Returns ``(sorted (bound,) with the valid ones first,
    count)``; ``count`` may exceed ``bound`` (overflow)."""
    v = jnp.where(valid, jnp.mod(angles, period), jnp.inf)
    v = jnp.sort(v)
    fin = jnp.isfinite(v)
    keep = fin & jnp.concatenate([jnp.ones(1, bool), jnp.diff(v) > tol * period])
    # the wrap-around rule on the kept ones: last > period (1 - tol) and first < tol period
    n = jnp.sum(keep)
    kv = jnp.where(keep, v, -jnp.inf)
    last = jnp.max(kv)
    first = jnp.min(jnp.where(keep, v, jnp.inf))
    drop_last = (n > 1) & (last > period * (1 - tol)) & (first < tol * period)
    keep = keep & ~(drop_last & (v == last))
    n = jnp.sum(keep)
    idx = jnp.nonzero(keep, size=bound, fill_value=0)[0]
    return v[idx], n


def quiet_origin(points, valid, period: float):
    """A table origin far from every valid point (the middle of the widest cyclic gap
    between them; 0 without points), as :func:`gearjax.excitation.events.quiet_origin`."""
    p = jnp.sort(jnp.where(valid, jnp.mod(points, period), jnp.inf))
    n = jnp.sum(valid)
    idx = jnp.arange(p.shape[0])
    nxt = jnp.where(idx + 1 < n, jnp.roll(p, -1), p[0] + period)
    gaps = jnp.where(idx < n, nxt - p, -jnp.inf)
    i = jnp.argmax(gaps)
    return jnp.where(n > 0, jnp.mod(p[i] + 0.5 * gaps[i], period), 0.0)


def table_knots(origin, period: float, n_cells: int, extra, valid, bound: int):
    """Knots of a :class:`~gearjax.excitation.tables.PeriodicHermiteTable` (traced
    :meth:`~gearjax.excitation.tables.PeriodicHermiteTable.layout`): the uniform grid of
    ``n_cells`` cells from ``origin`` plus the valid ``extra`` inside ``(origin, origin +
    period)``, distinct and sorted, padded to ``n_cells + 1 + bound`` knots with the last
    one (``origin + period``: zero-width segments). Returns ``(knots, cell_first,
    n_knots, max_extra)`` (the largest number of extra knots in a cell)."""
    grid = origin + jnp.arange(n_cells + 1) * (period / n_cells)
    grid = grid.at[-1].set(origin + period)
    inside = valid & (extra > origin) & (extra < origin + period)
    allk = jnp.sort(jnp.concatenate([grid, jnp.where(inside, extra, jnp.inf)]))
    fin = jnp.isfinite(allk)
    keep = fin & jnp.concatenate([jnp.ones(1, bool), jnp.diff(allk) != 0.0])
    size = n_cells + 1 + bound
    n_knots = jnp.sum(keep)
    idx = jnp.nonzero(keep, size=size, fill_value=0)[0]
    knots = jnp.where(jnp.arange(size) < n_knots, allk[idx], origin + period)
    cell_first = jnp.searchsorted(knots, grid[:-1], side="left").astype(jnp.int32)
    counts = jnp.diff(jnp.concatenate([cell_first, (n_knots - 1)[None]])) - 1
    return knots, cell_first, n_knots, jnp.max(counts)


def knot_sides(knots, lo, hi):
    """-1 at the knots equal to a bracket's ``lo``, +1 at those equal to its ``hi``, 0
    elsewhere (the one-sided evaluation of the table's jump knots)."""
    def member(values):
        s = jnp.sort(values)
        i = jnp.clip(jnp.searchsorted(s, knots), 0, s.shape[0] - 1)
        return s[i] == knots

    if lo.shape[0] == 0:
        return jnp.zeros_like(knots)
    return jnp.where(member(hi), 1.0, jnp.where(member(lo), -1.0, 0.0))


def fix_unlocated(switch, s_j, kinds, cells, valid, mesh_period: float, rtol: float = 1e-8):
    """The build-time self-check of :func:`gearjax.excitation.events.check_event_roots`,
    traced: a moving event whose :data:`NEWTON_STEPS` Newton iterations from its angle do
    not stay within ``rtol`` mesh periods (or end non-finite) becomes fixed. Returns
    ``(kinds, cells, n_fixed)``."""
    moved = moved_event_angles(switch, s_j, kinds, cells, NEWTON_STEPS)
    ok = jnp.abs(moved - s_j) <= rtol * mesh_period
    bad = valid & (kinds != EV_FIXED) & ~ok
    kinds = jnp.where(bad, EV_FIXED, kinds).astype(jnp.int32)
    cells = jnp.where(bad[:, None], 0, cells).astype(jnp.int32)
    return kinds, cells, jnp.sum(bad)


class ScanLayout(NamedTuple):
    """A design's layout from one uniform scan (:func:`scan_layout`): ``origin`` () the
    table origin (rad); ``changes`` the brackets of the state changes in table coordinates
    (:class:`Changes`); ``thetas`` (bounds.jumps,) the sorted distinct jump angles (rad)
    and ``n_jumps``; ``knots``, ``side``, ``cell_first`` the table's knots, the side each
    is read on and the first knot of each uniform cell (:func:`table_knots`,
    :func:`knot_sides`; None without a table); ``need`` the bounds this design needs
    (a :class:`LayoutBounds` of traced ints: more than the bounds is an overflow)."""

    origin: jax.Array
    changes: Changes
    thetas: jax.Array
    n_jumps: jax.Array
    knots: jax.Array | None
    side: jax.Array | None
    cell_first: jax.Array | None
    need: LayoutBounds

    def knot_codes(self, code_fn, period: float):
        """The (knots, n_code) discrete state on the side of every knot it is read on
        (``1e-9 period`` off a jump knot): the codes of the structure check."""
        return code_fn(self.knots + self.side * (1e-9 * period))


def scan_layout(code_fn, codes, period: float, bounds: LayoutBounds, fixed=(), *,
                tol: float = 1e-12, table: bool = True) -> ScanLayout:
    """The layout of one design over one excitation period ``period`` (rad), traced: the
    table origin far from every state change of the uniform scan (:func:`quiet_origin`),
    every change bracketed by adjacent floats from that origin (:func:`find_changes`),
    the jump angles (the changes' upper brackets and the ``fixed`` angles, host floats in
    rad, distinct to ``tol`` periods: :func:`distinct_jumps`) and, with ``table``, the
    table's knots (the uniform grid and both floats of every bracket:
    :func:`table_knots`).

    ``code_fn`` maps (m,) angles to the (m, n_code) int code matrix (traceable, any m);
    ``codes`` is its value at the uniform scan ``k period / n``, k = 0..n-1 (n = its
    length, also the table's cells), which the caller computes with whatever else it
    reads there; ``bounds`` the static sizes (:class:`LayoutBounds`)."""
    n = codes.shape[0]
    theta = jnp.arange(n) * (period / n)
    changed0 = jnp.any(codes != jnp.roll(codes, -1, axis=0), axis=1)
    origin = quiet_origin(theta, changed0, period)
    ch = find_changes(code_fn, origin + theta, period, bounds.brackets, bounds.intervals)
    fixed = jnp.asarray(np.asarray(fixed, dtype=float).reshape(-1))
    cand = jnp.concatenate([fixed, ch.hi])
    ok = jnp.concatenate([jnp.ones(fixed.shape[0], bool), jnp.isfinite(ch.hi)])
    thetas, n_jumps = distinct_jumps(cand, ok, period, bounds.jumps, tol=tol)
    knots = side = cell_first = None
    max_extra = jnp.asarray(0)
    if table:
        pts = jnp.concatenate([ch.lo, ch.hi])
        knots, cell_first, _, max_extra = table_knots(origin, period, n, pts,
                                                      jnp.isfinite(pts), 2 * bounds.brackets)
        side = knot_sides(knots, ch.lo, ch.hi)
    need = LayoutBounds(jumps=n_jumps, brackets=ch.count, max_extra=jnp.maximum(1, max_extra),
                        intervals=ch.n_intervals)
    return ScanLayout(origin=jnp.asarray(origin), changes=ch, thetas=thetas, n_jumps=n_jumps,
                      knots=knots, side=side, cell_first=cell_first, need=need)


def warn_unlocated(count: int, stacklevel: int = 3) -> None:
    """``RuntimeWarning`` for ``count`` > 0 moving events :func:`fix_unlocated` kept fixed
    at their build angles."""
    if count:
        warnings.warn(
            f"{count} design-dependent switching angles could not be located by their "
            "switching function at the build design; they are kept at their build angles "
            "(forward results exact, their design derivative is not followed)",
            RuntimeWarning, stacklevel=stacklevel + 1)
