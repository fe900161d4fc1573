"""Optimisation of a design objective with optax Adam (:func:`optimise`), from several
starts (:func:`multi_start`, :func:`coarse_starts`)."""

from __future__ import annotations

import dataclasses
import time

import jax
import jax.numpy as jnp
import numpy as np
import optax

from ..dynamics.progress import AbstractProgressMeter, NoProgressMeter, check_meter
from .spaces import ReliefSpace

__all__ = ["OptimisationResult", "optimise", "optimise_lockstep", "coarse_starts", "multi_start"]


@dataclasses.dataclass
class OptimisationResult:
    """Result of :func:`optimise`.

    Attributes
    ----------
    x, smooth, exact : the best design found and its smoothed / exact objective.
    x0, smooth0, exact0 : the starting design and its objective.
    history : list of dicts (iteration, x, smooth, exact, grad_norm_u, structure_ok).
    iterations : optimiser steps taken.
    stop_reason : ``"tolerance"``, ``"small-step"`` or ``"max-iter"``.
    wall_time_s : seconds spent.
    """

    x: np.ndarray
    smooth: float
    exact: float
    x0: np.ndarray
    smooth0: float
    exact0: float
    history: list
    iterations: int
    stop_reason: str
    wall_time_s: float

    def as_dict(self, space: ReliefSpace) -> dict:
        out = {n: float(v) for n, v in zip(space.names, self.x)}
        out.update({"objective_before": self.exact0, "objective_after": self.exact,
                    "smooth_before": self.smooth0, "smooth_after": self.smooth,
                    "start": {n: float(v) for n, v in zip(space.names, self.x0)},
                    "iterations": self.iterations, "stop_reason": self.stop_reason,
                    "wall_time_s": self.wall_time_s})
        return out


def optimise(objective, x0, *, learning_rate: float = 0.15, max_iter: int = 60,
             rtol: float = 1e-4, patience: int = 8, step_tol: float = 1e-4,
             callback=None,
             progress: AbstractProgressMeter = NoProgressMeter()) -> OptimisationResult:
    """Minimise ``objective`` (a :class:`QuasiStaticObjective` or :class:`DynamicObjective`)
    from ``x0`` with optax Adam on the unconstrained variables of its
    :class:`ReliefSpace` (bounds hold by construction), learning rate decayed by cosine
    to 5 % over ``max_iter``.

    Stopping rule: the best smoothed value has not improved by more than ``rtol``
    (relative) for ``patience`` iterations ("tolerance"), or the Adam step in ``u`` is
    below ``step_tol`` ("small-step"), or ``max_iter`` steps ("max-iter"). Returns the best
    iterate (by the smoothed value) with the history.

    ``callback(record)`` is called with every history record; ``progress`` is told of the
    start and of every evaluation done (between evaluations: a host meter may release
    compiled code there, as a structure change compiles the objective again).
    """
    space = objective.space
    x0 = space.check(x0, "x0")
    t0 = time.perf_counter()
    sched = optax.cosine_decay_schedule(learning_rate, max(1, max_iter), alpha=0.05)
    opt = optax.adam(sched)
    u = jnp.asarray(space.to_unconstrained(x0))
    state = opt.init(u)
    hist = []
    best = None
    since = 0
    reason = "max-iter"
    first = None
    it = 0
    check_meter(progress).start("optimise", max_iter + 1, f"from {x0.tolist()}")
    for it in range(max_iter + 1):
        x = np.asarray(space.from_unconstrained(u))
        x = np.clip(x, space.lower, space.upper)
        ev = objective(x, grad=True)
        if first is None:
            first = ev
        dxdu = np.asarray(jax.vmap(jax.grad(lambda v, i: space.from_unconstrained(v)[i],
                                            argnums=0), in_axes=(None, 0))(
            u, jnp.arange(space.size))).diagonal()
        g_u = ev.grad * dxdu
        hist.append({"iteration": it, "x": x.tolist(), "smooth": ev.smooth, "exact": ev.exact,
                     "grad_norm_u": float(np.linalg.norm(g_u)), "structure_ok": ev.structure_ok})
        if callback is not None:
            callback(hist[-1])
        progress.update("optimise", it + 1, max_iter + 1, f"objective {ev.exact:.6g}",
                        elapsed_s=time.perf_counter() - t0)
        if best is None or ev.smooth < best.smooth * (1 - rtol) - 1e-300:
            since = 0
        else:
            since += 1
        if best is None or ev.smooth < best.smooth:
            best = ev
        if since >= patience:
            reason = "tolerance"
            break
        if it == max_iter:
            break
        upd, state = opt.update(jnp.asarray(g_u), state, u)
        if float(jnp.max(jnp.abs(upd))) < step_tol:
            reason = "small-step"
            break
        u = optax.apply_updates(u, upd)
    return OptimisationResult(
        x=best.x, smooth=best.smooth, exact=best.exact, x0=x0, smooth0=first.smooth,
        exact0=first.exact, history=hist, iterations=it, stop_reason=reason,
        wall_time_s=time.perf_counter() - t0,
    )


def coarse_starts(space: ReliefSpace, n_per_axis: int = 2) -> np.ndarray:
    """Starting designs on a coarse grid inside the bounds (interior points at
    ``(i + 1) / (n + 1)`` of each range), shape ``(n_per_axis ** size, size)``."""
    lo, hi = space.lower, space.upper
    f = (np.arange(n_per_axis) + 1.0) / (n_per_axis + 1.0)
    axes = [lo[i] + (hi[i] - lo[i]) * f for i in range(space.size)]
    return np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, space.size)


def multi_start(objective, starts, *, learning_rate: float = 0.15, max_iter: int = 60,
                rtol: float = 1e-4, patience: int = 8, step_tol: float = 1e-4, callback=None,
                progress: AbstractProgressMeter = NoProgressMeter(),
                lockstep: bool | None = None) -> tuple[OptimisationResult, list]:
    """:func:`optimise` from every row of ``starts`` with these options (its own);
    returns (best by exact value, all).

    ``lockstep``: a :class:`~gearjax.design.DynamicObjective` runs the starts in lockstep
    (:func:`optimise_lockstep`: every step evaluates all starts in one compiled call);
    else one start after the other. Default (None): in lockstep on an accelerator, one
    after the other on a CPU, where one design's speeds and orbit starts already fill the
    cores (a lockstep step costs about the sum of its starts', and a start that has
    stopped is still evaluated at every step until the last stops:
    ``benchmarks/results/design_loop.md``). Either way each start's path is the one
    :func:`optimise` takes from it alone (to the models' round-off: a lockstep row keeps
    a model of its own)."""
    from ..dynamics.batching import on_cpu
    from .objectives import DynamicObjective

    options = dict(learning_rate=learning_rate, max_iter=max_iter, rtol=rtol,
                   patience=patience, step_tol=step_tol, callback=callback, progress=progress)
    starts = np.asarray(starts, dtype=float)
    if lockstep is None:
        lockstep = not on_cpu()
    if lockstep and isinstance(objective, DynamicObjective) and starts.shape[0] > 1:
        results = optimise_lockstep(objective, starts, **options)
    else:
        results = [optimise(objective, x0, **options) for x0 in starts]
    return min(results, key=lambda r: r.exact), results


def optimise_lockstep(objective, starts, *, learning_rate: float = 0.15, max_iter: int = 60,
                      rtol: float = 1e-4, patience: int = 8, step_tol: float = 1e-4,
                      callback=None,
                      progress: AbstractProgressMeter = NoProgressMeter()) -> list:
    """:func:`optimise` from every row of ``starts`` at once: each step evaluates the
    current designs of all starts by ``objective.batch`` (one compiled call) and updates
    each start's Adam state; a start that has stopped (its stopping rule, as
    :func:`optimise`'s) keeps its last design until every start has. The records given
    to ``callback`` carry their start's index (``"start"``). Returns one
    :class:`OptimisationResult` per start."""
    space = objective.space
    x0s = [space.check(x0, "x0") for x0 in np.asarray(starts, dtype=float)]
    n = len(x0s)
    t0 = time.perf_counter()
    sched = optax.cosine_decay_schedule(learning_rate, max(1, max_iter), alpha=0.05)
    opt = optax.adam(sched)
    us = [jnp.asarray(space.to_unconstrained(x0)) for x0 in x0s]
    states = [opt.init(u) for u in us]
    hists = [[] for _ in range(n)]
    best, first = [None] * n, [None] * n
    since, its = [0] * n, [0] * n
    reason = ["max-iter"] * n
    done = [False] * n
    jac = jax.vmap(jax.grad(lambda v, i: space.from_unconstrained(v)[i], argnums=0),
                   in_axes=(None, 0))
    check_meter(progress).start("optimise", max_iter + 1, f"{n} starts in lockstep")
    for it in range(max_iter + 1):
        xs = [np.clip(np.asarray(space.from_unconstrained(u)), space.lower, space.upper)
              for u in us]
        evs = objective.batch(np.stack(xs), grad=True)
        for i, ev in enumerate(evs):
            if done[i]:
                continue
            first[i] = first[i] or ev
            its[i] = it
            g_u = ev.grad * np.asarray(jac(us[i], jnp.arange(space.size))).diagonal()
            rec = {"iteration": it, "x": ev.x.tolist(), "smooth": ev.smooth,
                   "exact": ev.exact, "grad_norm_u": float(np.linalg.norm(g_u)),
                   "structure_ok": ev.structure_ok, "start": i}
            hists[i].append(rec)
            if callback is not None:
                callback(rec)
            if best[i] is None or ev.smooth < best[i].smooth * (1 - rtol) - 1e-300:
                since[i] = 0
            else:
                since[i] += 1
            if best[i] is None or ev.smooth < best[i].smooth:
                best[i] = ev
            if since[i] >= patience:
                reason[i], done[i] = "tolerance", True
                continue
            if it == max_iter:
                done[i] = True
                continue
            upd, states[i] = opt.update(jnp.asarray(g_u), states[i], us[i])
            if float(jnp.max(jnp.abs(upd))) < step_tol:
                reason[i], done[i] = "small-step", True
                continue
            us[i] = optax.apply_updates(us[i], upd)
        progress.update("optimise", it + 1, max_iter + 1,
                        f"best objective {min(b.exact for b in best):.6g}",
                        elapsed_s=time.perf_counter() - t0)
        if all(done):
            break
    wall = time.perf_counter() - t0
    return [OptimisationResult(x=best[i].x, smooth=best[i].smooth, exact=best[i].exact,
                               x0=x0s[i], smooth0=first[i].smooth, exact0=first[i].exact,
                               history=hists[i], iterations=its[i], stop_reason=reason[i],
                               wall_time_s=wall) for i in range(n)]
