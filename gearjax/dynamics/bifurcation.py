"""Floquet multipliers along a traced curve of periodic orbits: what they say about
stability, which bifurcation a change of them is, and what a traced curve returns
(:class:`TracedBranches`: points, branches, bifurcations, jumps).

A periodic orbit of the forced gear equations is asymptotically stable iff every Floquet
multiplier ``mu`` (eigenvalue of the monodromy matrix) lies inside the unit circle; the
forcing fixes the period, so no multiplier is 1 by symmetry. Along a curve of orbits in
speed, stability changes where multipliers leave the unit circle:

* a real multiplier through +1: a **fold** (saddle-node: the curve turns back in speed, the
  speed component of its tangent changes sign) or, where the curve does not turn, a
  **branch point** (another curve of orbits crosses it);
* a real multiplier through -1: **period doubling** (an orbit of twice the period is born);
* a complex pair through the unit circle: **Neimark-Sacker** (a torus: quasi-periodic
  response), ``kind = "torus"``.

Test functions, continuous along the curve and zero at the bifurcation
(:func:`crossing_test`): the fold's is the speed component of the unit tangent; for the
others ``s * d`` with ``d`` the distance of the nearest multiplier of the kind to the
crossing (``|mu - 1|`` over real positive multipliers, ``|mu + 1|`` over real negative
ones, ``||mu| - 1|`` over complex ones) and ``s = (-1)^m``, ``m`` the number of multipliers
of that kind outside the unit circle (pairs counted once): ``s`` is the sign of
``det(Phi - I)``, of ``det(Phi + I)``, and of the bialternate test of the complex pairs.

For the sdof model the two multipliers obey Liouville's ``mu_1 mu_2 = exp(-2 zeta omega_n
T)`` (the trace of the vector field's Jacobian does not depend on the contact), so a complex
pair has modulus ``exp(-zeta omega_n T) < 1``: the sdof curve loses stability at folds
(and branch points) and period doublings only, never at a torus.

Jumps: where a stable branch ends at a bifurcation, a sweep in the speed direction that
leaves the branch (``sweep = "up"`` where the stable side lies below the bifurcation speed)
jumps to another attractor; :func:`gearjax.dynamics.arclength.trace_speed` finds it by a
transient beyond the bifurcation (:class:`Jump`).
"""

from __future__ import annotations

import equinox as eqx
import numpy as np

from .results import FLAG_FIELDS, METRIC_FIELDS, SweepResult

__all__ = ["BIFURCATION_KINDS", "Bifurcation", "Jump", "TracedBranches", "multipliers",
           "crossing_kinds", "crossing_test", "crossing_multiplier", "coexistence",
           "metrics_dict", "metrics_of"]

BIFURCATION_KINDS = ("fold", "branch_point", "period_doubling", "torus")
# the multipliers each kind watches, and the point they cross the unit circle at
_WATCH = {"branch_point": "positive", "fold": "positive", "period_doubling": "negative",
          "torus": "complex"}


def multipliers(phi) -> np.ndarray:
    """Floquet multipliers: eigenvalues of the monodromy matrix ``phi`` (NumPy, host), by
    decreasing modulus. LAPACK returns a real eigenvalue of a real matrix with an imaginary
    part of exactly zero, which the classification below relies on."""
    mu = np.linalg.eigvals(np.asarray(phi, dtype=float))
    return mu[np.argsort(-np.abs(mu), kind="stable")]


def _group(mu, which):
    real = mu.imag == 0
    if which == "positive":
        sel = real & (mu.real > 0)
        return mu[sel], np.abs(mu[sel] - 1.0), int(np.sum(mu[sel].real > 1.0))
    if which == "negative":
        sel = real & (mu.real < 0)
        return mu[sel], np.abs(mu[sel] + 1.0), int(np.sum(mu[sel].real < -1.0))
    sel = ~real & (mu.imag > 0)  # one of each conjugate pair
    return mu[sel], np.abs(np.abs(mu[sel]) - 1.0), int(np.sum(np.abs(mu[sel]) > 1.0))


def crossing_test(kind: str, mu, tangent_speed: float) -> float:
    """The test function of ``kind`` (module docstring) at a point with multipliers ``mu``
    and unit-tangent speed component ``tangent_speed``: changes sign where the bifurcation
    of that kind is crossed."""
    if kind == "fold":
        return float(tangent_speed)
    vals, dist, outside = _group(np.asarray(mu), _WATCH[kind])
    d = float(dist.min()) if dist.size else 1.0
    return d if outside % 2 == 0 else -d


def crossing_multiplier(kind: str, mu) -> complex:
    """The multiplier nearest the crossing point of ``kind`` (+1, -1 or the unit circle)."""
    vals, dist, _ = _group(np.asarray(mu), _WATCH[kind])
    return complex(vals[np.argmin(dist)]) if vals.size else complex("nan")


def crossing_kinds(mu_a, mu_b, tangent_speed_a: float, tangent_speed_b: float) -> list[str]:
    """The bifurcations crossed between two neighbouring points of a curve (multipliers
    ``mu_a``, ``mu_b``; tangent speed components): ``fold`` where the tangent's speed
    component changes sign, ``branch_point`` where the sign of ``det(Phi - I)`` does without
    it, ``period_doubling`` where its test function does, ``torus`` where its test function
    and the number of multipliers outside the unit circle change (not where a complex pair
    merely becomes two real multipliers)."""
    out = []
    if np.sign(tangent_speed_a) * np.sign(tangent_speed_b) < 0:
        out.append("fold")
    for kind in ("branch_point", "period_doubling", "torus"):
        if kind == "branch_point" and out:
            continue  # the fold's multiplier +1 changes det(Phi - I) as well
        if kind == "torus" and np.sum(np.abs(mu_a) > 1) == np.sum(np.abs(mu_b) > 1):
            continue  # a pair meeting on the real axis (or leaving it) crosses nothing
        if crossing_test(kind, mu_a, 0.0) * crossing_test(kind, mu_b, 0.0) < 0:
            out.append(kind)
    return out


class Bifurcation(eqx.Module):
    """A bifurcation located on a traced curve (:class:`TracedBranches`).

    Attributes
    ----------
    kind : one of :data:`BIFURCATION_KINDS`.
    speed_rad_s : where it lies (rad/s).
    index : its point in the :class:`TracedBranches` arrays.
    multiplier : the Floquet multiplier at the crossing (+1, -1 or on the unit circle to
        the location's tolerance).
    crossing_test : the test function there (:func:`crossing_test`; 0 at the exact crossing).
    located : the secant on the test function converged (else: the last iterate).
    ends_stable_branch : one of the two branches it separates is stable (a sweep jumps
        there).
    metrics : the orbit's metrics there (``max_mesh_force_N``, ... as
        :class:`~gearjax.dynamics.results.SweepResult`, SI units).
    """

    kind: str
    speed_rad_s: float
    index: int
    multiplier: complex
    crossing_test: float
    located: bool
    ends_stable_branch: bool
    metrics: dict


class Jump(eqx.Module):
    """Where a sweep leaves a stable branch at a bifurcation, and where it lands.

    Attributes
    ----------
    sweep : ``"up"`` (the stable side lies below ``from_rad_s``: a sweep of increasing
        speed leaves the branch here) or ``"down"``.
    kind : the bifurcation's kind.
    from_rad_s : the bifurcation's speed (rad/s).
    to_rad_s : the speed of the transient that found the landing orbit (rad/s; beyond the
        bifurcation in the sweep's direction).
    max_mesh_force_before_N, max_mesh_force_after_N : the max dynamic mesh force at the
        bifurcation and on the landing orbit (N; NaN where no periodic orbit was found).
    landed_branch : the branch of the curve the landing orbit lies on (-1: none traced).
    landed_periodic : the transient settled on a stable orbit of the excitation period.
    index : the bifurcation's point in the :class:`TracedBranches` arrays.
    metrics_after : the landing orbit's metrics (as :attr:`Bifurcation.metrics`; of the
        state the transient reached where it found no stable periodic orbit, measured
        over two periods; empty where the landing speed is outside the range).
    """

    sweep: str
    kind: str
    from_rad_s: float
    to_rad_s: float
    max_mesh_force_before_N: float
    max_mesh_force_after_N: float
    landed_branch: int
    landed_periodic: bool
    index: int
    metrics_after: dict

    @property
    def discontinuous(self) -> bool:
        """The response jumps: at a fold (the orbit ceases to exist) or where the transient
        landed on a stable orbit of the excitation period elsewhere. Past a period doubling
        or a torus a transient that finds no such orbit has met the period-doubled or
        quasi-periodic response born there, which may grow from the orbit continuously."""
        return self.kind == "fold" or self.landed_periodic

    @property
    def rises(self) -> bool:
        """The max mesh force jumps up (a jump-up speed)."""
        return bool(self.max_mesh_force_after_N > self.max_mesh_force_before_N)


class TracedBranches(eqx.Module):
    """Curves of periodic orbits traced in speed by pseudo-arclength continuation
    (:func:`gearjax.dynamics.arclength.trace_speed`), point by point in the order traced
    along each segment (speeds repeat where the curve folds back).

    Attributes
    ----------
    points : the :class:`~gearjax.dynamics.results.SweepResult` of the points (metrics of
        each orbit measured as :func:`gearjax.dynamics.steady.steady_state` measures one;
        ``spectral_radius`` the Floquet radius, max |multiplier|, ``status`` ``unstable``
        where it is >= 1; ``solver`` ``"arclength"``).
    stable : every Floquet multiplier inside the unit circle (False at a located
        bifurcation: a multiplier on the circle).
    branch : branch id: a branch is a run of points between bifurcations (or changes of
        stability) of one segment; a located bifurcation point ends its branch, and the
        next branch starts from it.
    segment : the traced segment (0: from the quasi-static start at the lowest speed;
        later ones from the orbits a jump landed on, or the highest speed's, where these
        were not on a traced segment).
    multipliers : (n_points, n) complex Floquet multipliers by decreasing modulus.
    tangent_speed : speed component of the unit tangent ``(dy, dOmega / speed_scale)``
        oriented along the segment (its sign changes at a fold).
    point : ``"regular"``, ``"end"`` (at an end of the speed range), ``"join"`` (where a
        later segment reaches a traced one), ``"stop"`` (the
        continuation could go no further: step below the minimum, or the point limit) or a
        bifurcation kind.
    newton_iterations : corrector iterations of the point.
    y0 : (n_points, n) periodic start at theta = 0 (the model's dimensionless state).
    bifurcations : the :class:`Bifurcation` points, in the order traced.
    jumps : the :class:`Jump` s, one per bifurcation that ends a stable branch (where a
        sweep leaves it; :attr:`Jump.discontinuous` says whether its response jumps).
    speed_scale_rad_s : the speed scale of the arclength norm (rad/s).
    """

    points: SweepResult
    stable: np.ndarray
    branch: np.ndarray
    segment: np.ndarray
    multipliers: np.ndarray
    tangent_speed: np.ndarray
    point: np.ndarray
    newton_iterations: np.ndarray
    y0: np.ndarray
    bifurcations: tuple
    jumps: tuple
    speed_scale_rad_s: float = eqx.field(static=True, kw_only=True)

    def folds(self) -> list[Bifurcation]:
        """The located folds."""
        return [b for b in self.bifurcations if b.kind == "fold"]

    def jump_up_rad_s(self) -> list[float]:
        """Speeds (rad/s) of the jumps (:attr:`Jump.discontinuous`) to a larger max mesh
        force (sorted)."""
        return sorted(j.from_rad_s for j in self.jumps if j.discontinuous and j.rises)

    def jump_down_rad_s(self) -> list[float]:
        """Speeds (rad/s) of the jumps (:attr:`Jump.discontinuous`) to a smaller max mesh
        force (sorted)."""
        return sorted(j.from_rad_s for j in self.jumps if j.discontinuous
                      and np.isfinite(j.max_mesh_force_after_N) and not j.rises)

    def branch_stable(self) -> dict[int, bool]:
        """Per branch id, whether its points are stable (its bifurcation end points, on the
        unit circle, left out)."""
        out = {}
        reg = ~np.isin(self.point, BIFURCATION_KINDS)
        for b in np.unique(self.branch):
            sel = (self.branch == b) & reg
            out[int(b)] = bool(np.all(self.stable[sel])) if sel.any() else False
        return out

    def coexistence_rad_s(self) -> list[list[float]]:
        """Speed intervals (rad/s) where two or more stable branches coexist
        (:func:`coexistence`): the hysteresis band(s)."""
        spans = []
        for b, ok in self.branch_stable().items():
            if ok:
                w = self.points.speed_rad_s[self.branch_indices(b)]
                spans.append((float(w.min()), float(w.max())))
        return coexistence(spans)

    def branch_indices(self, b: int) -> np.ndarray:
        """The points of branch ``b`` in order, with the bifurcation point it starts from
        (which belongs to the branch before it): its whole polyline."""
        idx = np.flatnonzero(self.branch == b)
        if idx.size and idx[0] > 0 and self.segment[idx[0] - 1] == self.segment[idx[0]]:
            idx = np.concatenate([[idx[0] - 1], idx])
        return idx

    def point_metrics(self, i: int) -> dict:
        """The metrics of point ``i`` as a dict of floats (SI units)."""
        return metrics_dict(self.points, i)


def metrics_dict(res, i: int) -> dict:
    """Metrics of entry ``i`` of a sweep-like result as JSON-ready values (SI units)."""
    return metrics_of(tuple(np.asarray(getattr(res, f))[i] for f in METRIC_FIELDS))


def metrics_of(values) -> dict:
    """The metrics ``values`` (one orbit's, in :data:`~gearjax.dynamics.results.
    METRIC_FIELDS` order) as a dict of JSON-ready values (SI units)."""
    out = {}
    for f, v in zip(METRIC_FIELDS, values):
        v = np.asarray(v)
        if v.ndim:
            out[f] = [float(x) for x in v]
        elif f in FLAG_FIELDS:
            out[f] = bool(v)
        else:
            out[f] = float(v)
    return out


def coexistence(spans) -> list[list[float]]:
    """Intervals covered by two or more of the closed ``spans`` ``(lo, hi)``, merged and
    sorted."""
    pieces = []
    spans = list(spans)
    for i in range(len(spans)):
        for j in range(i + 1, len(spans)):
            lo = max(spans[i][0], spans[j][0])
            hi = min(spans[i][1], spans[j][1])
            if lo < hi:
                pieces.append([lo, hi])
    pieces.sort()
    merged: list[list[float]] = []
    for lo, hi in pieces:
        if merged and lo <= merged[-1][1]:
            merged[-1][1] = max(merged[-1][1], hi)
        else:
            merged.append([lo, hi])
    return merged
