"""Pseudo-arclength continuation of periodic orbits in speed: the whole response curve,
stable and unstable, through folds (Velex & Ajmi, Section 6.3.1: the contact losses and
amplitude jumps near the tooth critical speed, Fig. 8).

Unknowns: the periodic start ``y`` at ``theta = 0`` and the speed ``p = Omega /
Omega_s``; equations: the shooting residual over one excitation period (a fixed angle:
``y(P; y, Omega) - y = 0``) and the arclength condition (:mod:`gearjax.dynamics.corrector`:
the bordered system and its Jacobian). This module is the host loop (Keller's method):

1. **Predictor**: ``u_p = u_k + ds t_k`` along the unit tangent ``t_k`` (norm
   ``|dy|^2 + (dOmega / Omega_s)^2``; ``Omega_s`` the speed spacing of the request unless
   :attr:`Arclength.speed_scale_rad_s` says otherwise).
2. **Corrector**: Newton with the border ``t_k . (u - u_p) = 0`` or (large models) chord
   iterations with the Jacobian of ``u_k`` (:func:`gearjax.dynamics.corrector.chord`: one
   period of the state per iteration), then the Jacobian of the new point (its tangent
   and multipliers). A point is accepted where the corrector converges, the correction is at most
   ``max_correction`` steps, and the secant and then the new tangent turn by less than
   half of and all of ``acos(min_cos)``.
3. **Step control**: a failed step is retried ``shrink`` times as long, a point reached in
   ``fast_iterations`` or fewer lets the next grow by ``grow``, within ``[min_step,
   max_step]``; below ``min_step`` the segment stops (``point = "stop"``).
4. **Floquet multipliers** at every point (:func:`gearjax.dynamics.bifurcation.
   multipliers`); the bifurcations crossed between two points (:func:`~gearjax.dynamics.
   bifurcation.crossing_kinds`) are located by the Illinois regula falsi on their test
   function along the first point's predictor line (``|test| <= locate_tol``).

A segment ends at the ends of the speed range (its last point corrected at fixed speed
exactly there, ``point = "end"``) or where it joins a traced curve (``"join"``). Segment 0
starts at the lowest speed from the quasi-static start (Newton at fixed speed; where that
finds no stable orbit, a transient first). Then the stable orbit of the highest speed and,
at every bifurcation that ends a stable branch, the orbit that a transient from the bifurcation orbit settles on at
``landing_offset`` beyond it (:func:`gearjax.dynamics.corrector.settle`: the jump of a slow
sweep) are checked against the curve (a fixed-speed Newton from the curve interpolated
there must land on them); one that is not on it starts a new segment, traced both ways,
up to ``max_segments``.

Every point is measured as :func:`gearjax.dynamics.steady.steady_state` measures an orbit
(:func:`gearjax.dynamics.corrector.measure`). Not done: following the doubled period
after a period doubling (flagged and located only).
"""

from __future__ import annotations

import dataclasses
import math
import time
import types

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..errors import SimulationError
from .bifurcation import (BIFURCATION_KINDS, Bifurcation, Jump, TracedBranches,
                          crossing_kinds, crossing_multiplier, crossing_test, metrics_dict,
                          metrics_of, multipliers)
from .corrector import (CorrectorOptions, chord, correct, linearise, measure, settle,
                        tangent)
from .steady import shooting_solver
from .orbit import metric_status
from .progress import AbstractProgressMeter, NoProgressMeter, check_meter
from .results import FLAG_FIELDS, METRIC_FIELDS, SweepResult, empty_metrics
from .stability import check_speeds

__all__ = ["Arclength", "trace_speed", "CHORD_MIN_STATES"]

# above this many states the chord corrector is the default: a period of the state alone
# then costs far less than one with the n + 1 variational columns
CHORD_MIN_STATES = 8


class Arclength(eqx.Module):
    """Options of :func:`trace_speed` (module docstring; step lengths in the scaled
    arclength ``sqrt(|dy|^2 + (dOmega / Omega_s)^2)``).

    Attributes
    ----------
    step, min_step, max_step : first, smallest and largest step.
    grow, shrink : step factors after a fast point and after a failed step.
    fast_iterations : Newton iterations at or below which the step grows (twice as many
        chord iterations).
    chord : correct by chord iterations with the last point's Jacobian (each one period of
        the state alone, at a hundredth of the corrector's tolerances) instead of Newton
        (each one period of the state with its ``n + 1`` variational columns); None: where
        the model has more than :data:`CHORD_MIN_STATES` states (the 3D model).
    max_chord : chord iterations of a step.
    min_cos : smallest cosine between consecutive unit tangents.
    max_correction : largest distance of a corrected point from its predictor, in steps
        (a larger one means the curve bends within the step: a fold pair may hide in it).
    speed_scale_rad_s : ``Omega_s`` (rad/s); None: the median spacing of the speeds asked.
    max_points : points over all segments.
    max_segments : segments (the first and those started from orbits off the curve).
    locate_tol, max_locate : tolerance on a bifurcation's test function and secant
        iterations.
    landing_offset_rad_s : how far beyond a bifurcation the landing transient runs (rad/s;
        at most to the end of the range); None: half the speed spacing.
    corrector : the Newton corrector's options
        (:class:`~gearjax.dynamics.corrector.CorrectorOptions`).
    convergence_tol : periodicity threshold of the metrics' ``converged``.
    transient_decay, min_transient_mesh_periods, max_transient_mesh_periods : the landing
        and start transients (:func:`gearjax.dynamics.corrector.settle`).
    """

    step: float = 1.0
    min_step: float = 1e-4
    max_step: float = 2.0
    grow: float = 1.5
    shrink: float = 0.5
    fast_iterations: int = 3
    chord: bool | None = None
    max_chord: int = 12
    min_cos: float = 0.9
    max_correction: float = 0.25
    speed_scale_rad_s: float | None = None
    max_points: int = 2000
    max_segments: int = 4
    locate_tol: float = 1e-6
    max_locate: int = 20
    landing_offset_rad_s: float | None = None
    corrector: CorrectorOptions = CorrectorOptions(newton_tol=1e-8)
    convergence_tol: float = 1e-3
    transient_decay: float = 1e-6
    min_transient_mesh_periods: int = 8
    max_transient_mesh_periods: int = 400

    def __check_init__(self):
        pos = {"step": self.step, "min_step": self.min_step, "max_step": self.max_step,
               "locate_tol": self.locate_tol, "convergence_tol": self.convergence_tol}
        for name, v in pos.items():
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise SimulationError(name, v, "must be a finite number > 0")
        if not self.min_step <= self.step <= self.max_step:
            raise SimulationError("step", self.step,
                                  f"must lie in [min_step, max_step] = [{self.min_step}, "
                                  f"{self.max_step}]")
        if not (self.grow >= 1.0 and 0.0 < self.shrink < 1.0):
            raise SimulationError("grow", (self.grow, self.shrink),
                                  "need grow >= 1 and 0 < shrink < 1")
        if not 0.0 < self.min_cos < 1.0:
            raise SimulationError("min_cos", self.min_cos, "must lie in (0, 1)")
        if not 0.0 < self.max_correction <= 1.0:
            raise SimulationError("max_correction", self.max_correction, "must lie in (0, 1]")
        for name in ("max_points", "max_segments", "max_locate", "fast_iterations",
                     "max_chord"):
            v = getattr(self, name)
            if int(v) != v or v < 1:
                raise SimulationError(name, v, "must be an integer >= 1")
        for name in ("speed_scale_rad_s", "landing_offset_rad_s"):
            v = getattr(self, name)
            if v is not None and not (math.isfinite(v) and v > 0):
                raise SimulationError(name, v, "must be None or a finite speed > 0 (rad/s)")


@dataclasses.dataclass(eq=False)
class _Point:
    """A corrected point (host values)."""

    y: np.ndarray
    omega: float
    tangent: np.ndarray  # unit, oriented along the travel
    mu: np.ndarray
    iterations: int
    point: str = "regular"
    segment: int = 0
    located: bool = True
    metrics: tuple | None = None
    jac: np.ndarray | None = None  # the bordered Jacobian's first n rows, (n, n + 1)


class _Tracer:
    """The host loop of :func:`trace_speed` (one per call)."""

    def __init__(self, model, lo, hi, scale, opts: Arclength, progress, estimate):
        self.model, self.lo, self.hi, self.opts = model, lo, hi, opts
        self.n = int(model.state_size)
        self.scale = jnp.asarray(scale, dtype=float)
        self.s = float(scale)
        self.e_p = np.zeros(self.n + 1)
        self.e_p[-1] = 1.0
        self.progress, self.estimate = progress, estimate
        self.task = f"arclength continuation {model.formulation}"
        self.t0 = time.perf_counter()
        self.count = 0
        self.segments: list[list[_Point]] = []
        self.chord = opts.chord if opts.chord is not None else self.n > CHORD_MIN_STATES
        # the chord's residual alone is integrated: 100 times tighter, so that its error
        # stays below the corrector's tolerance (the Jacobian's columns tighten the
        # corrector's steps)
        c = opts.corrector
        rtol, atol = shooting_solver(None, c.rtol, c.atol)[1:]
        self.chord_options = dataclasses.replace(c, max_newton=opts.max_chord, rtol=rtol / 100,
                                                 atol=atol / 100)
        self.fast = opts.fast_iterations * (2 if self.chord else 1)

    # ---------------------------------------------------------------- corrections
    def _u(self, p: _Point) -> np.ndarray:
        return np.concatenate([p.y, [p.omega / self.s]])

    def _linearised(self, y, w, orientation, iterations):
        """The point ``(y, w)`` with its Jacobian, tangent and multipliers, or None."""
        lin = jax.device_get(linearise(self.model, y, w, self.scale, self.opts.corrector))
        if not bool(lin.ok):
            return None
        t = tangent(lin.jacobian, orientation)
        if not np.all(np.isfinite(t)):
            return None
        return _Point(y=np.asarray(y, dtype=float), omega=float(w), tangent=t,
                      mu=multipliers(lin.phi), iterations=int(iterations),
                      jac=np.asarray(lin.jacobian))

    def natural(self, w, y_start, direction: float = 1.0):
        """The orbit at fixed speed ``w`` from ``y_start`` by Newton (tangent pointing to
        ``direction`` in speed), or None."""
        u = np.concatenate([np.asarray(y_start, float), [w / self.s]])
        c = jax.device_get(correct(self.model, y_start, w, u, self.e_p, self.scale,
                                   self.opts.corrector))
        if not bool(c.converged):
            return None
        return self._linearised(np.asarray(c.y), float(c.omega), direction * self.e_p,
                                int(c.iterations))

    def stable_orbit_at(self, w, y_start):
        """The stable orbit at ``w``: Newton from ``y_start``, else after a transient."""
        p = self.natural(w, y_start)
        if p is None or np.max(np.abs(p.mu)) >= 1.0:
            y = jax.device_get(self._settle(w, y_start))
            p = self.natural(w, y) if np.all(np.isfinite(y)) else None
        return p

    def _settle(self, w, y):
        o = self.opts
        return settle(self.model, jnp.asarray(float(w)), jnp.asarray(y), o.transient_decay,
                      o.min_transient_mesh_periods, o.max_transient_mesh_periods)

    def along(self, a: _Point, sigma: float, check: bool = False):
        """The corrected point at arclength ``sigma`` along ``a``'s predictor line, or
        None: Newton, or chord iterations with ``a``'s Jacobian (:attr:`Arclength.chord`;
        where they fail without ``check``, Newton). With ``check``, None also where the
        corrected point is farther than ``max_correction`` steps from the predictor or the
        secant turns from ``a``'s tangent by more than half ``acos(min_cos)`` (cheap tests
        before its Jacobian)."""
        o = self.opts
        u_pred = self._u(a) + sigma * a.tangent
        c = None
        if self.chord:
            c = jax.device_get(chord(self.model, u_pred[:-1], u_pred[-1] * self.s, u_pred,
                                     a.tangent, a.jac, self.scale, self.chord_options))
        if c is None or (not bool(c.converged) and not check):
            c = jax.device_get(correct(self.model, u_pred[:-1], u_pred[-1] * self.s, u_pred,
                                       a.tangent, self.scale, o.corrector))
        if not bool(c.converged):
            return None
        u = np.concatenate([np.asarray(c.y), [float(c.omega) / self.s]])
        if check:
            sec = u - self._u(a)
            half = math.sqrt(0.5 * (1.0 + o.min_cos))
            if (float(np.linalg.norm(u - u_pred)) > o.max_correction * sigma
                    or float(a.tangent @ sec) < half * float(np.linalg.norm(sec))):
                return None
        return self._linearised(np.asarray(c.y), float(c.omega), a.tangent, int(c.iterations))

    # ------------------------------------------------------------------ tracing
    def _accept(self, a: _Point, b: _Point | None) -> bool:
        return b is not None and float(a.tangent @ b.tangent) >= self.opts.min_cos

    def _out(self, w) -> bool:
        return w < self.lo or w > self.hi

    def half(self, start: _Point, seg: int, known: list[list[_Point]]) -> list[_Point]:
        """The points after ``start`` along its tangent, to an end of the range or to a
        point of the curves ``known`` (``point = "join"``)."""
        o = self.opts
        pts: list[_Point] = []
        a, ds = start, o.step
        bound = self.hi if a.tangent[-1] > 0 else self.lo
        if a.omega == bound:
            return pts
        while self.count < o.max_points:
            b = self.along(a, ds, check=True)
            if not self._accept(a, b):
                if ds * o.shrink < o.min_step:
                    a.point = "stop" if a.point == "regular" else a.point
                    break
                ds *= o.shrink
                continue
            end = self._out(b.omega)
            if end:  # the last point exactly at the end of the range, at fixed speed
                w_end = self.hi if b.omega > self.hi else self.lo
                f = (w_end - a.omega) / (b.omega - a.omega)
                b = self.natural(w_end, a.y + f * (b.y - a.y), np.sign(b.omega - a.omega))
                if b is None:
                    a.point = "stop" if a.point == "regular" else a.point
                    break
                b.point = "end"
            b.segment = seg
            joined = not end and len(pts) >= 2 and self._joins(b, known, ds)
            if joined:
                b.point = "join"
            pts += self._between(a, b, seg) + [b]
            self._report(b)
            if end or joined:
                break
            if b.iterations <= self.fast:
                ds = min(ds * o.grow, o.max_step)
            a = b
        else:
            a.point = "stop" if a.point == "regular" else a.point
        return pts

    def segment(self, start: _Point) -> list[_Point]:
        """A segment through ``start``, traced both ways to the ends of the range."""
        seg = len(self.segments)
        start.segment = seg
        self._report(start)
        back_start = dataclasses.replace(start, tangent=-start.tangent)
        back = self.half(back_start, seg, self.segments + [[start]])
        if back_start.point == "stop" and start.point == "regular":
            start.point = "stop"
        for p in back:
            p.tangent = -p.tangent
        pts = back[::-1] + [start]
        pts += self.half(start, seg, self.segments + [back[::-1]])
        self.segments.append(pts)
        return pts

    def _joins(self, b: _Point, known: list[list[_Point]], step: float) -> bool:
        """``b`` lies on a traced curve of ``known`` (:meth:`_near`), or within ``step`` of
        a lone point, the tangents parallel (a closed curve back at its start)."""
        for pts in known:
            if len(pts) == 1:
                if (float(np.linalg.norm(self._u(pts[0]) - self._u(b))) <= step
                        and abs(float(pts[0].tangent @ b.tangent)) >= self.opts.min_cos):
                    return True
            elif self._near(b, pts) is not None:
                return True
        return False

    def _near(self, b: _Point, pts: list[_Point]):
        """The index ``i`` of the chord ``(pts[i], pts[i + 1])`` that ``b`` lies on: within
        a tenth of its length of it (more than the sagitta of a chord whose tangents turn
        by at most ``acos(min_cos)``), the tangents parallel (not a crossing); or None."""
        if len(pts) < 2:
            return None
        u = self._u(b)
        us = np.stack([self._u(p) for p in pts])
        p0, chord = us[:-1], np.diff(us, axis=0)
        length = np.linalg.norm(chord, axis=1)
        f = np.clip(np.einsum("ij,ij->i", u - p0, chord) / np.maximum(length ** 2, 1e-300),
                    0.0, 1.0)
        dist = np.linalg.norm(p0 + f[:, None] * chord - u, axis=1)
        cos = np.abs(chord @ b.tangent) / np.maximum(length, 1e-300)
        near = np.flatnonzero((dist <= 0.1 * length + 1e-6) & (cos >= self.opts.min_cos))
        return int(near[np.argmin(dist[near])]) if near.size else None

    def _between(self, a: _Point, b: _Point, seg: int) -> list[_Point]:
        """The bifurcations crossed from ``a`` to ``b``, located and sorted."""
        found = []
        sigma_b = float(a.tangent @ (self._u(b) - self._u(a)))
        for kind in crossing_kinds(a.mu, b.mu, a.tangent[-1], b.tangent[-1]):
            p, sigma = self._locate(a, b, sigma_b, kind)
            if p is not None:
                p.point, p.segment = kind, seg
                found.append((sigma, p))
        return [p for _, p in sorted(found, key=lambda sp: sp[0])]

    def _locate(self, a: _Point, b: _Point, sigma_b: float, kind: str):
        """Illinois regula falsi on the test function of ``kind`` along ``a``'s predictor
        line, between ``0`` (at ``a``) and ``sigma_b`` (at ``b``)."""
        o = self.opts
        test = lambda p: crossing_test(kind, p.mu, p.tangent[-1])  # noqa: E731
        s0, s1, f0, f1 = 0.0, sigma_b, test(a), test(b)
        best, side = None, 0
        for _ in range(o.max_locate):
            s = s1 - f1 * (s1 - s0) / (f1 - f0) if f1 != f0 else 0.5 * (s0 + s1)
            w = s1 - s0
            if not (s0 + 1e-3 * w < s < s1 - 1e-3 * w):
                s = 0.5 * (s0 + s1)
            p = self.along(a, s)
            if p is None:  # Newton failed inside: bisect the other way next
                s = 0.5 * (s0 + s1)
                p = self.along(a, s)
                if p is None:
                    break
            f, best = test(p), (p, s)
            if abs(f) <= o.locate_tol:
                break
            if np.sign(f) == np.sign(f0):
                s0, f0 = s, f
                if side == -1:
                    f1 *= 0.5
                side = -1
            else:
                s1, f1 = s, f
                if side == 1:
                    f0 *= 0.5
                side = 1
        if best is None:
            return None, None
        p, s = best
        p.located = abs(test(p)) <= o.locate_tol
        return p, s

    def _report(self, p: _Point):
        self.count += 1
        rho = float(np.max(np.abs(p.mu)))
        self.progress.update(
            self.task, self.count, max(self.count, self.estimate),
            f"{p.omega:9.4f} rad/s, rho {rho:.4f}, {p.iterations} iterations"
            f"{'' if p.point == 'regular' else ', ' + p.point}",
            elapsed_s=time.perf_counter() - self.t0)

    # ------------------------------------------------------------------ orbits
    def metrics(self, p: _Point) -> tuple:
        if p.metrics is None:
            p.metrics = tuple(np.asarray(v) for v in jax.device_get(measure(
                self.model, jnp.asarray(p.omega), jnp.asarray(p.y), self.opts.convergence_tol)))
        return p.metrics

    def on_curve(self, q: _Point):
        """``(segment, index)`` of a traced point next to which ``q`` lies on the curve, or
        None: on one of its chords (:meth:`_near`), else where a fixed-speed Newton from
        the curve interpolated at ``q``'s speed lands on ``q``."""
        for si, pts in enumerate(self.segments):
            i = self._near(q, pts)
            if i is not None:
                return si, i
        cands = []
        for si, pts in enumerate(self.segments):
            for i in range(len(pts) - 1):
                a, b = pts[i], pts[i + 1]
                if min(a.omega, b.omega) <= q.omega <= max(a.omega, b.omega):
                    f = 0.0 if b.omega == a.omega else (q.omega - a.omega) / (b.omega - a.omega)
                    y = a.y + f * (b.y - a.y)
                    cands.append((float(np.linalg.norm(y - q.y)), si, i, y))
        tol = 1e-6 * (1.0 + float(np.linalg.norm(q.y)))
        for _, si, i, y in sorted(cands, key=lambda c: c[0])[:3]:
            r = self.natural(q.omega, y)
            if r is not None and float(np.linalg.norm(r.y - q.y)) <= tol:
                return si, i
        return None

    def landing(self, seg: int, i: int, offset: float):
        """The :class:`Jump` data at the bifurcation ``segments[seg][i]`` where it ends a
        stable branch, or None: (sweep, landing speed, landing point or None)."""
        pts = self.segments[seg]
        p = pts[i]
        sides = [q for q in (pts[i - 1] if i > 0 else None,
                             pts[i + 1] if i + 1 < len(pts) else None)
                 if q is not None and q.point not in BIFURCATION_KINDS
                 and np.max(np.abs(q.mu)) < 1.0]
        if not sides:
            return None
        sweep = "up" if sides[0].omega < p.omega else "down"
        w = min(p.omega + offset, self.hi) if sweep == "up" else max(p.omega - offset, self.lo)
        if w == p.omega:  # at the end of the range: nothing beyond it to land on
            return sweep, w, None, None
        self.progress.note(self.task, f"a transient at {w:.4f} rad/s, past the {p.point} at "
                                      f"{p.omega:.4f} rad/s: where a sweep {sweep} lands")
        y = jax.device_get(self._settle(w, p.y))
        if not np.all(np.isfinite(y)):
            return sweep, w, None, None
        q = self.natural(w, y)
        if q is None or np.max(np.abs(q.mu)) >= 1.0:
            return sweep, w, None, y
        return sweep, w, q, y


def _speeds(speeds_rad_s):
    w = np.unique(np.asarray(speeds_rad_s, dtype=float).reshape(-1))
    check_speeds(w)
    if w.size < 2:
        raise SimulationError("speeds_rad_s", w.tolist(),
                              "a continuation needs a speed range: at least two speeds")
    return w


def trace_speed(model, speeds_rad_s, arclength: Arclength = Arclength(), *,
                progress: AbstractProgressMeter = NoProgressMeter()) -> TracedBranches:
    """The curve of periodic orbits of ``model`` over the speed range of ``speeds_rad_s``
    (rad/s; their lowest and highest, and their median spacing as the speed scale), by
    pseudo-arclength continuation (module docstring): every branch met, stable and
    unstable, with the Floquet multipliers of every point, the folds, period doublings
    and tori located on it, and the jumps of sweeps at the ends of its stable branches.

    Parameters
    ----------
    model : any :class:`gearjax.models.base.AbstractGearModel` (sdof or 3D, every
        formulation).
    speeds_rad_s : at least two distinct speeds > 0 (rad/s).
    arclength : the :class:`Arclength` options.
    progress : the meter told of every point (default none).

    Returns
    -------
    :class:`gearjax.dynamics.bifurcation.TracedBranches`.

    Raises
    ------
    SimulationError
        for bad speeds, options or meter; or where no periodic orbit is found at the
        lowest speed.
    """
    speeds = _speeds(speeds_rad_s)
    check_meter(progress)
    model.require_structure()
    spacing = float(np.median(np.diff(speeds)))
    scale = arclength.speed_scale_rad_s or spacing
    offset = arclength.landing_offset_rad_s or 0.5 * spacing
    lo, hi = float(speeds[0]), float(speeds[-1])
    tr = _Tracer(model, lo, hi, scale, arclength, progress, speeds.size)
    progress.start(tr.task, speeds.size, f"{lo:g}-{hi:g} rad/s, speed scale {scale:g} rad/s")
    start = tr.stable_orbit_at(lo, model.initial_state(jnp.asarray(lo)))
    if start is None:
        raise SimulationError("speeds_rad_s", lo, "no periodic orbit found at the lowest "
                              "speed (Newton from the quasi-static start and a transient)")
    tr.segment(start)
    top = tr.stable_orbit_at(hi, model.initial_state(jnp.asarray(hi)))
    if top is not None and tr.on_curve(top) is None:
        tr.segment(top)
    jumps, done = [], set()
    while True:
        todo = [(si, i) for si, pts in enumerate(tr.segments) for i, p in enumerate(pts)
                if p.point in BIFURCATION_KINDS and (si, i) not in done]
        if not todo:
            break
        for si, i in todo:
            done.add((si, i))
            land = tr.landing(si, i, offset)
            if land is None:
                continue
            sweep, w, q, y_settled = land
            where = None
            if q is not None:
                where = tr.on_curve(q)
                if where is None and len(tr.segments) < arclength.max_segments:
                    pts = tr.segment(q)
                    where = (len(tr.segments) - 1, next(k for k, p in enumerate(pts) if p is q))
            jumps.append((si, i, sweep, w, q, y_settled, where))
            progress.update(tr.task, tr.count, max(tr.count, tr.estimate),
                            f"landed at {w:.4f} rad/s: " + ("no stable periodic orbit" if q is None
                                                           else "a stable periodic orbit"),
                            elapsed_s=time.perf_counter() - tr.t0)
    return _result(model, tr, jumps, scale)


def _result(model, tr: _Tracer, jumps, scale) -> TracedBranches:
    """Measure every point, number the branches and build the result."""
    pts = [p for seg in tr.segments for p in seg]
    first = np.cumsum([0] + [len(s) for s in tr.segments])
    n_pts = len(pts)
    out = empty_metrics(n_pts)
    task = f"measuring the orbits of the {model.formulation} curve"
    tr.progress.start(task, n_pts)
    for j, p in enumerate(pts):
        for f, v in zip(METRIC_FIELDS, tr.metrics(p)):
            out[f][j] = v
        tr.progress.update(task, j + 1, n_pts, f"{p.omega:9.4f} rad/s",
                           elapsed_s=time.perf_counter() - tr.t0)
    branch = np.zeros(n_pts, dtype=np.int64)
    stable = np.array([p.point not in BIFURCATION_KINDS and float(np.max(np.abs(p.mu))) < 1.0
                       for p in pts])
    b = -1
    for j, p in enumerate(pts):
        prev = pts[j - 1] if j > 0 else None
        if (prev is None or prev.segment != p.segment or prev.point in BIFURCATION_KINDS
                or (p.point not in BIFURCATION_KINDS and stable[j] != stable[j - 1])):
            b += 1
        branch[j] = b
    for f in FLAG_FIELDS:
        out[f] = out[f] > 0
    rho = np.array([float(np.max(np.abs(p.mu))) for p in pts])
    status = metric_status(out["solver_ok"], out["converged"], rho)
    out["converged"] = out["converged"] & np.array(
        [p.point not in BIFURCATION_KINDS for p in pts]) & stable
    out["n_steps"] = np.nan_to_num(out["n_steps"]).astype(np.int64)
    flat = types.SimpleNamespace(**out)
    bifs = []
    for j, p in enumerate(pts):
        if p.point in BIFURCATION_KINDS:
            near = [k for k in (j - 1, j + 1) if 0 <= k < n_pts and pts[k].segment == p.segment]
            bifs.append(Bifurcation(
                kind=p.point, speed_rad_s=p.omega, index=j,
                multiplier=crossing_multiplier(p.point, p.mu),
                crossing_test=float(crossing_test(p.point, p.mu, p.tangent[-1])),
                located=bool(p.located), ends_stable_branch=bool(any(stable[near])),
                metrics=metrics_dict(flat, j)))
    out_jumps = []
    for si, i, sweep, w, q, y_settled, where in jumps:
        j = int(first[si] + i)
        after = {}
        if q is not None:
            after = metrics_of(tr.metrics(q))
        elif y_settled is not None:
            met = jax.device_get(measure(model, jnp.asarray(w), jnp.asarray(y_settled),
                                         tr.opts.convergence_tol))
            after = metrics_of(met)
        landed = -1
        if where is not None:
            k = int(first[where[0]] + where[1])
            landed = int(branch[k + 1] if pts[k].point in BIFURCATION_KINDS else branch[k])
        out_jumps.append(Jump(
            sweep=sweep, kind=pts[j].point, from_rad_s=pts[j].omega, to_rad_s=float(w),
            max_mesh_force_before_N=float(out["max_mesh_force_N"][j]),
            max_mesh_force_after_N=float(after.get("max_mesh_force_N", float("nan"))),
            landed_branch=landed, landed_periodic=q is not None, index=j,
            metrics_after=after))
    return TracedBranches(
        points=SweepResult(**out, formulation=model.formulation,
                           solver=np.full(n_pts, "arclength"), spectral_radius=rho,
                           status=status),
        stable=stable, branch=branch, segment=np.array([p.segment for p in pts]),
        multipliers=np.stack([p.mu for p in pts]),
        tangent_speed=np.array([float(p.tangent[-1]) for p in pts]),
        point=np.array([p.point for p in pts]),
        newton_iterations=np.array([p.iterations for p in pts], dtype=np.int64),
        y0=np.stack([p.y for p in pts]), bifurcations=tuple(bifs), jumps=tuple(out_jumps),
        speed_scale_rad_s=float(scale))
