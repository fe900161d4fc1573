"""Speed grids refined around the peaks and jumps of a response curve.

A sweep on a uniform grid of pinion speeds sees a resonance peak only to within its
spacing and a jump (contact loss, a change of branch) only to within the interval that
holds it. :func:`propose_speeds` reads a :class:`~gearjax.dynamics.results.SweepResult`
(host-side NumPy, no model) and proposes the speeds that would tell more:

* **peaks**: every interior local maximum of the maximum mesh force, the DTE peak-to-peak
  and the acceleration peak-to-peak (:attr:`Refinement.metrics`) that stands out of its
  curve (:attr:`Refinement.min_height` of the curve's maximum, a prominence of
  :attr:`Refinement.prominence` of its own value). With ``w_l < w_c < w_r`` the sampled
  maximum and its neighbours, the true peak lies in ``(w_l, w_r)``: its speed is known to
  ``max(w_c - w_l, w_r - w_c) / w_c`` (located when at most :attr:`Refinement.speed_tol`),
  and the parabola through the three samples estimates how far the sampled maximum lies
  below the peak, ``|y_vertex - y_c| / y_c`` (converged when at most
  :attr:`Refinement.amplitude_tol`; a kink or jump, where no parabola fits, converges
  only at :attr:`Refinement.min_spacing`). An unconverged peak gets the midpoints of both
  sides and the parabola's vertex.
* **jumps and contact-loss edges**: neighbours whose metric changes by more than
  :attr:`Refinement.jump` of the larger value with a slope :data:`JUMP_SLOPE_RATIO` times
  that of both neighbouring intervals (a step, not a steep flank), or whose contact-loss
  flags differ, get their midpoint until they are :attr:`Refinement.speed_tol` apart.

Speeds whose orbit did not converge are left out of these readings. :func:`refine`
sweeps the proposed speeds (a callable the caller supplies: any solver, any writer),
merges them (:func:`merge_sorted`, built on :meth:`SweepResult.take` and
:func:`~gearjax.dynamics.results.merge_results`) and repeats until every peak is located
and converged, or :attr:`Refinement.max_speeds` or :attr:`Refinement.max_rounds` is
reached, recording which speeds were added and why; :func:`refine_common` does it for
several sweeps at once on one common grid (the formulations, compared speed by speed).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Callable, NamedTuple

import numpy as np

from ..errors import SimulationError
from .progress import AbstractProgressMeter, NoProgressMeter, check_meter
from .results import SweepResult, merge_results

__all__ = ["Refinement", "Peak", "Proposal", "RefinedSweep", "RefinedSweeps", "find_peaks",
           "propose_speeds", "merge_sorted", "refine", "refine_common"]

# the panels of Figs. 8-13: maximum mesh force, DTE and acceleration peak-to-peak
PEAK_METRICS = ("max_mesh_force_N", "dte_ptp_m", "accel_ptp_m_s2")
# a jump, not a steep flank: the interval's slope exceeds its neighbours' by this factor
# (a smooth curve sampled finely has neighbouring slopes alike; a discontinuity keeps its
# whole step in one interval however finely it is bisected)
JUMP_SLOPE_RATIO = 3.0


@dataclasses.dataclass(frozen=True)
class Refinement:
    """Options of :func:`propose_speeds` and :func:`refine` (module docstring).

    speed_tol : a peak's speed (and a jump's interval) located to this fraction (1 %).
    amplitude_tol : a peak's amplitude converged to this fraction (1e-3).
    max_speeds : at most this many speeds in all, the swept ones included.
    max_rounds : at most this many rounds of proposals.
    min_spacing : no two speeds closer than this fraction of their speed; a peak bracketed
        this closely is as resolved as the grid gets (a jump).
    min_height : peaks below this fraction of their curve's maximum are not refined.
    prominence : nor peaks standing less than this fraction of their value above the
        higher of the two valleys that separate them from a higher point or the end of the
        range (scipy's prominence): flat wiggles, not a broad resonance near the range's
        end (Fig. 9's, 3 %).
    jump : neighbours whose metric differs by more than this fraction of the larger
        value bracket a jump.
    metrics : the :class:`SweepResult` fields whose peaks and jumps are refined.

    Raises :class:`~gearjax.errors.SimulationError` naming a field out of range.
    """

    speed_tol: float = 0.01
    amplitude_tol: float = 1e-3
    max_speeds: int = 300
    max_rounds: int = 12
    min_spacing: float = 1e-3
    min_height: float = 0.3
    prominence: float = 0.005
    jump: float = 0.1
    metrics: tuple = PEAK_METRICS

    def __post_init__(self):
        for name in ("speed_tol", "amplitude_tol", "min_spacing", "min_height", "prominence",
                     "jump"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and 0.0 <= v < 1.0):
                raise SimulationError(name, v, "must be a fraction in [0, 1)")
        if not self.min_spacing < self.speed_tol:
            raise SimulationError("min_spacing", self.min_spacing,
                                  f"must be below speed_tol={self.speed_tol}")
        for name in ("max_speeds", "max_rounds"):
            v = getattr(self, name)
            if not (isinstance(v, (int, np.integer)) and v >= 1):
                raise SimulationError(name, v, "must be an integer >= 1")
        bad = [m for m in self.metrics if m not in PEAK_METRICS]
        if bad or not self.metrics:
            raise SimulationError("metrics", self.metrics, f"choose from {PEAK_METRICS}")


class Peak(NamedTuple):
    """A local maximum of one metric (SI units of the metric).

    metric, speed_rad_s, value : the sampled maximum and its speed.
    lower_rad_s, upper_rad_s : its neighbours: the true peak lies between them.
    speed_error : ``max(w_c - w_l, w_r - w_c) / w_c``.
    amplitude_error : ``|y_vertex - y_c| / |y_c|`` of the parabola through the three
        samples (inf where they show a kink: no concave parabola peaks between them).
    located, converged : ``speed_error <= speed_tol``; and ``amplitude_error <=
        amplitude_tol`` (or bracketed to ``min_spacing``: ``resolution_limited``).
    vertex_rad_s : the parabola's vertex (NaN where it has none inside the bracket).
    """

    metric: str
    speed_rad_s: float
    value: float
    lower_rad_s: float
    upper_rad_s: float
    speed_error: float
    amplitude_error: float
    located: bool
    converged: bool
    resolution_limited: bool
    vertex_rad_s: float


class Proposal(NamedTuple):
    """Speeds to add (rad/s, sorted), per speed why, and its rank (0 first: the peaks,
    highest first, then the jumps and edges)."""

    speeds: np.ndarray
    reasons: tuple
    priority: np.ndarray


class RefinedSweep(NamedTuple):
    """What :func:`refine` returns: the merged ``result`` (sorted by speed), the ``added``
    speeds as ``[{"speed_rad_s", "reason", "round"}]``, the final ``peaks`` and why it
    ``stopped`` (``"converged"``, ``"max_speeds"``, ``"max_rounds"``)."""

    result: SweepResult
    added: list
    peaks: list
    stopped: str


def _curve(result: SweepResult, metric: str):
    """(speeds, values) of ``metric`` at the converged finite speeds, sorted by speed."""
    w = np.asarray(result.speed_rad_s, dtype=float)
    y = np.asarray(getattr(result, metric), dtype=float)
    ok = np.isfinite(w) & np.isfinite(y) & np.asarray(result.converged, dtype=bool)
    order = np.argsort(w[ok], kind="stable")
    return w[ok][order], y[ok][order]


def _prominence(y: np.ndarray, i: int) -> float:
    """Height of ``y[i]`` above the higher of its two bounding valleys (scipy's
    definition: each side up to the first higher sample or the end)."""
    lo = []
    for step in (-1, 1):
        j, low = i + step, y[i]
        while 0 <= j < y.size and y[j] <= y[i]:
            low = min(low, y[j])
            j += step
        lo.append(low)
    return float(y[i] - max(lo))


def _vertex(w3, y3):
    """(vertex speed, vertex value) of the parabola through three points (Newton form
    ``y0 + d0 (w - w0) + a (w - w0)(w - w1)``), or None when it is not concave or its
    vertex lies outside the bracket."""
    (w0, w1, w2), (y0, y1, y2) = (float(v) for v in w3), (float(v) for v in y3)
    d0, d1 = (y1 - y0) / (w1 - w0), (y2 - y1) / (w2 - w1)
    a = (d1 - d0) / (w2 - w0)
    if not a < 0.0:
        return None
    wv = 0.5 * (w0 + w1) - d0 / (2.0 * a)
    if not w0 < wv < w2:
        return None
    return wv, y0 + d0 * (wv - w0) + a * (wv - w0) * (wv - w1)


def find_peaks(result: SweepResult, options: Refinement = Refinement()) -> list:
    """The refinable peaks of ``result`` (:class:`Peak` per metric and local maximum,
    module docstring), highest first within each metric."""
    out = []
    for metric in options.metrics:
        w, y = _curve(result, metric)
        if w.size < 3:
            continue
        top = float(np.max(np.abs(y)))
        cands = []
        for i in range(1, w.size - 1):
            if not ((y[i] >= y[i - 1] and y[i] > y[i + 1])
                    or (y[i] > y[i - 1] and y[i] >= y[i + 1])):
                continue
            if (y[i] < options.min_height * top
                    or _prominence(y, i) < options.prominence * abs(y[i])):
                continue
            w3, y3 = w[i - 1:i + 2], y[i - 1:i + 2]
            v = _vertex(w3, y3)
            amp = abs(v[1] - y[i]) / abs(y[i]) if v is not None else math.inf
            err = max(w[i] - w[i - 1], w[i + 1] - w[i]) / w[i]
            limited = err <= options.min_spacing * 2.0
            located = err <= options.speed_tol
            conv = located and (amp <= options.amplitude_tol or limited)
            cands.append(Peak(metric, float(w[i]), float(y[i]), float(w[i - 1]), float(w[i + 1]),
                              float(err), float(amp), bool(located), bool(conv), bool(limited),
                              float(v[0]) if v is not None else math.nan))
        out += sorted(cands, key=lambda p: -p.value)
    return out


def _edges(result: SweepResult, options: Refinement):
    """[(lower, upper, reason, score)] of the neighbours that bracket a jump (score: the
    step over the larger value) or a change of the contact-loss flag (score 1) and are more
    than ``speed_tol`` apart."""
    edges = []
    for metric in options.metrics:
        w, y = _curve(result, metric)
        slope = np.abs(np.diff(y)) / np.diff(w)  # per interval
        for i in range(w.size - 1):
            big = max(abs(y[i]), abs(y[i + 1]))
            steep = slope[i] > JUMP_SLOPE_RATIO * max(slope[i - 1] if i > 0 else 0.0,
                                                      slope[i + 1] if i + 1 < slope.size else 0.0)
            if big > 0 and abs(y[i + 1] - y[i]) > options.jump * big and steep:
                edges.append((w[i], w[i + 1], f"jump of {metric}", abs(y[i + 1] - y[i]) / big))
    w = np.asarray(result.speed_rad_s, dtype=float)
    ok = np.isfinite(w) & np.asarray(result.converged, dtype=bool)
    order = np.argsort(w[ok], kind="stable")
    ws, lost = w[ok][order], np.asarray(result.contact_loss, dtype=bool)[ok][order]
    for i in range(ws.size - 1):
        if lost[i] != lost[i + 1]:
            edges.append((ws[i], ws[i + 1], "contact-loss edge", 1.0))
    return [e for e in edges if (e[1] - e[0]) > options.speed_tol * e[1]]


def propose_speeds(result: SweepResult, options: Refinement = Refinement()) -> Proposal:
    """The speeds that would locate the peaks and jumps of ``result`` better (module
    docstring), none closer than ``min_spacing`` to a swept speed or to each other,
    returned sorted by speed with their reasons and ranks: by score, a peak's its height
    over its curve's maximum, a jump's its step over the larger value, a contact-loss
    edge's 1 (so each curve's main peaks and the contact-loss edges come first)."""
    have = np.sort(np.asarray(result.speed_rad_s, dtype=float))
    top = {m: float(np.max(np.abs(_curve(result, m)[1]), initial=0.0)) for m in options.metrics}
    cands = []
    for p in find_peaks(result, options):
        if p.converged:
            continue
        why = f"peak of {p.metric} near {p.speed_rad_s:.6g} rad/s"
        score = abs(p.value) / top[p.metric]
        if not math.isnan(p.vertex_rad_s):
            cands.append((score, p.vertex_rad_s, why + " (parabola vertex)"))
        cands += [(score, 0.5 * (p.lower_rad_s + p.speed_rad_s), why),
                  (score, 0.5 * (p.speed_rad_s + p.upper_rad_s), why)]
    cands += [(score, 0.5 * (lo + hi), f"{why} between {lo:.6g} and {hi:.6g} rad/s")
              for lo, hi, why, score in _edges(result, options)]
    cands.sort(key=lambda c: -c[0])  # stable: a peak's three speeds stay together
    taken, reasons = [], []
    for _, w, why in cands:
        pts = np.concatenate([have, taken])
        if pts.size and np.min(np.abs(pts - w)) <= options.min_spacing * w:
            continue
        taken.append(float(w))
        reasons.append(why)
    order = np.argsort(taken, kind="stable")
    return Proposal(np.asarray(taken, dtype=float)[order], tuple(reasons[i] for i in order),
                    np.asarray(order, dtype=int))


def merge_sorted(a: SweepResult, b: SweepResult) -> SweepResult:
    """One result over the speeds of ``a`` and ``b``, sorted by speed (``b``'s entries
    after ``a``'s at an equal speed); ``a``'s formulation."""
    wa, wb = np.asarray(a.speed_rad_s, dtype=float), np.asarray(b.speed_rad_s, dtype=float)
    order = np.argsort(np.concatenate([wa, wb]), kind="stable")
    from_b = order >= wa.size
    if not from_b.any():
        return a.take(order)
    base = a.take(np.where(from_b, 0, order)) if wa.size else b.take(order - wa.size)
    return merge_results(base, b.take(order[from_b] - wa.size), from_b)


def _propose_all(results: dict, options: Refinement) -> tuple[np.ndarray, list]:
    """The proposals of every result of ``results`` merged into one list of speeds (the
    ranks interleaved, each reason prefixed by its result's name where there are several),
    none within ``min_spacing`` of a speed any result holds or of each other; sorted by
    rank (first: what matters most)."""
    have = np.concatenate([np.asarray(r.speed_rad_s, dtype=float) for r in results.values()])
    ranked = []
    for name, res in results.items():
        prop = propose_speeds(res, options)
        tag = f"{name}: " if len(results) > 1 else ""
        ranked += [(int(r), k, float(w), tag + why)
                   for k, (w, why, r) in enumerate(zip(prop.speeds, prop.reasons, prop.priority))]
    ranked.sort(key=lambda c: (c[0], c[1]))
    speeds, reasons = [], []
    for _, _, w, why in ranked:
        pts = np.concatenate([have, speeds])
        if pts.size and np.min(np.abs(pts - w)) <= options.min_spacing * w:
            continue
        speeds.append(w)
        reasons.append(why)
    return np.asarray(speeds, dtype=float), reasons


class RefinedSweeps(NamedTuple):
    """What :func:`refine_common` returns: the merged ``results`` (name -> result sorted by
    speed, every one swept at every added speed), the ``added`` speeds as
    ``[{"speed_rad_s", "reason", "round"}]``, the final ``peaks`` (name -> list of
    :class:`Peak`) and why it ``stopped`` (``"converged"``, ``"max_speeds"``,
    ``"max_rounds"``)."""

    results: dict
    added: list
    peaks: dict
    stopped: str


def refine_common(run: Callable[[str, np.ndarray], SweepResult], results: dict,
                  options: Refinement = Refinement(), *,
                  progress: AbstractProgressMeter = NoProgressMeter()) -> RefinedSweeps:
    """Refine several sweeps of the same speeds (e.g. the three formulations, whose curves
    are compared speed by speed) on one common grid: each round the proposals of every
    result (:func:`propose_speeds`) are merged and every result is swept at all of them,
    so that the results keep common speeds; until nothing is proposed, the grid holds
    ``options.max_speeds`` speeds (the proposals kept in rank order when the cap cuts
    them) or ``options.max_rounds`` rounds have run.

    Parameters
    ----------
    run : ``run(name, speeds)`` sweeps result ``name`` at ``speeds`` (rad/s, sorted) and
        returns their :class:`SweepResult`.
    results : name -> the sweep so far (any order).
    options : :class:`Refinement`.
    progress : told of each round (:class:`~gearjax.dynamics.progress.AbstractProgressMeter`).
    """
    progress = check_meter(progress)
    res = {k: r.take(np.argsort(np.asarray(r.speed_rad_s, dtype=float), kind="stable"))
           for k, r in results.items()}
    added, stopped = [], "max_rounds"
    for rnd in range(1, options.max_rounds + 1):
        speeds, reasons = _propose_all(res, options)
        if speeds.size == 0:
            stopped = "converged"
            break
        grid = np.unique(np.concatenate([np.asarray(r.speed_rad_s, dtype=float)
                                         for r in res.values()]))
        room = options.max_speeds - grid.size
        if room <= 0:
            stopped = "max_speeds"
            break
        keep = np.sort(np.arange(speeds.size)[:room])
        order = keep[np.argsort(speeds[keep], kind="stable")]
        progress.note("refine", f"round {rnd}: {order.size} speed(s) around peaks and jumps")
        for k in res:
            res[k] = merge_sorted(res[k], run(k, speeds[order]))
        added += [{"speed_rad_s": float(speeds[i]), "reason": reasons[i], "round": rnd}
                  for i in order]
    if stopped != "converged" and _propose_all(res, options)[0].size == 0:
        stopped = "converged"  # the last round's speeds settled everything
    return RefinedSweeps(res, added, {k: find_peaks(r, options) for k, r in res.items()},
                         stopped)


def refine(run: Callable[[np.ndarray], SweepResult], result: SweepResult,
           options: Refinement = Refinement(), *,
           progress: AbstractProgressMeter = NoProgressMeter()) -> RefinedSweep:
    """Refine ``result``'s speed grid around its peaks and jumps (module docstring):
    :func:`refine_common` of one sweep, ``run(speeds)`` sweeping the speeds it is given
    (rad/s, sorted; e.g. ``lambda w: sweep(model, w, solver)``)."""
    out = refine_common(lambda _, w: run(w), {"": result}, options, progress=progress)
    return RefinedSweep(out.results[""], out.added, out.peaks[""], out.stopped)
