"""Every integration of one :func:`gearjax.dynamics.simulate.simulate` call at one
``diffeqsolve`` call site.

A call integrates up to three kinds of *legs*, one after the other:

1. the accelerated transient: one excitation period per leg from the state the
   last leg left, each period's end replaced by ``model.periodic_estimate`` while the
   state's change over a period keeps falling, then by its slow-mode variant while that
   change stays within 4x its smallest (:mod:`gearjax.dynamics.simulate`, "Transient"),
   or the plain transient in one leg;
2. each measured period, from the end of the one before, saved on the output grid;
3. the refinement windows of :mod:`gearjax.dynamics.metrics`, each integrated again from
   its first grid point of the measured periods.

They are the iterations of one ``while`` loop around one ``diffeqsolve``: its tracing and
XLA compilation dominate the cost of a sweep of the 3D model (a second call site for the
transient would compile a second solver per formulation). The legs share one output length
(``n_out`` saved angles, padded with the leg's end angle, so that the last saved state is
the leg's end). Under ``vmap`` the loop runs in lockstep: a speed still in its transient
integrates a period while another integrates a measured period or a window (same arithmetic,
the inputs differ); legs of at most one period keep that from costing more than the slowest
speed's periods. Each leg restarts the step-size control (``dt0=None``), which moves the
metrics by less than their convergence measure (derivatives through contact loss, whose error
depends on where the steps fall around an impact, by more: ``tests/test_design.py``;
measurements: ``benchmarks/results/code_notes.md``, section gearjax.dynamics.legs).
"""

from __future__ import annotations

import math
from typing import Callable

import diffrax
import equinox.internal as eqxi
import jax
import jax.numpy as jnp

from .integrate import integrate

__all__ = ["solve_legs"]

# the slow-mode estimate ends when a period's change exceeds this times its smallest
SLOW_STAGE_GROWTH = 4.0


def solve_legs(model, term, solver, ctrl, omega, y0, *, ts, n_out: int, n_win: int,
               windows_of: Callable, memo, t_transient, accelerated: bool, n_transient,
               n_max_transient: int, tol: float, max_steps: int, adjoint,
               convergence_tol: float = math.inf, n_extend=0, n_max_extend: int = 0,
               n_skip=0):
    """Integrate the legs of one simulation (module docstring).

    Parameters
    ----------
    model, term, solver, ctrl, omega, max_steps, adjoint : as in ``simulate`` (``term`` is
        the model's vector field ``(theta, y, omega) -> y'``, ``ctrl`` its jump controller).
    y0 : state at theta = 0, the start of the transient.
    ts : (n_meas, n) output angles (rad) of each measured period, in
        ``[t_transient + p P, t_transient + (p + 1) P)``, ``n < n_out``.
    n_win, windows_of, memo : refinement windows; ``windows_of(ys, memo)`` maps the
        measured states on ``ts`` (flattened, (n_meas n, m)) and what the measurements
        before left (``memo``, a pytree; its initial value given) to ``(windows,
        (convergence, multiple), memo)``: the windows' start angles (n_win,), start
        states (n_win, m) and output angles (n_win, k), ``k <= n_out``, the convergence
        measure of those periods, the sub-harmonic period found (0: none) and what this
        measurement leaves to the next one should the measurement slide.
    t_transient : angle (rad) at which the measured periods start: the plain transient is
        one leg from 0 to it (none if 0). ``accelerated``: it is 0 and the transient is
        period legs, at most ``n_transient`` (traced; static bound ``n_max_transient``),
        stopping when the largest change of the state over a period is below ``tol``.
    convergence_tol, n_extend, n_max_extend : where the measured periods' convergence
        exceeds ``convergence_tol`` (and ``n_meas >= 2``), the measurement slides by one
        period (the first measured period becomes transient, one more is integrated, by
        the excitation's periodicity at the same angles) unless a sub-harmonic period is
        found, at most ``n_extend`` times
        (traced, less the accelerated transient's periods; static bound
        ``n_max_extend``, 0: never; within it at least once). A transient too short for the
        response (a contact-loss orbit decays more slowly than the linear model's estimate
        of the automatic count) then ends on a periodic response rather than a flag.
    n_skip : the last ``n_skip`` windows are not integrated (traced; their states stay 0):
        windows a speed does not need (under ``vmap`` the loop still runs until every
        speed of the batch is done).

    Returns
    -------
    grid : (n_meas, n, m) the measured states on ``ts``.
    windows : (n_win, k, m) the windows' states on their output angles.
    success, n_steps : (n_meas + n_win,) each leg ended successfully; its steps.
    transient : (periods of the accelerated transient (None if not accelerated), steps,
        all successful, measured periods slid past) of the transient legs; the
        measured periods' ``(convergence, multiple)`` and the ``memo`` of the last slide
        (``windows_of``).
    """
    period = float(model.period_rad)
    n_meas = ts.shape[0]
    n_legs = n_meas + n_win

    def pad(t, end):  # (k,) -> (n_out,): the leg's end angle repeated
        return jnp.concatenate([t, jnp.broadcast_to(end, (n_out - t.shape[0],))])

    t1_tr = period if accelerated else t_transient
    tr_ts = jnp.full(n_out, t1_tr)

    def cond(c):
        return c["leg"] < n_legs - n_skip

    def body(c):
        leg, y = c["leg"], c["y"]
        tr = leg < 0  # the plain transient, or a period of the accelerated one
        meas = (leg >= 0) & (leg < n_meas)  # a measured period
        j = jnp.maximum(leg, 0)
        p = jnp.clip(leg, 0, n_meas - 1)
        i = jnp.clip(leg - n_meas, 0, max(n_win - 1, 0))
        w_t0, w_y0, w_ts = c["windows"]
        # a window of a failed run starts from a finite state (its values are not used)
        y_w = jnp.where(jnp.isfinite(w_y0[i]), w_y0[i], 0.0)
        t0_meas = t_transient + p * period
        t1_meas = t0_meas + period
        t0 = jnp.where(tr, 0.0, jnp.where(meas, t0_meas, w_t0[i]))
        t1 = jnp.where(tr, t1_tr, jnp.where(meas, t1_meas, w_ts[i, -1]))
        save = jnp.where(tr, tr_ts, jnp.where(meas, pad(ts[p], t1_meas), pad(w_ts[i], w_ts[i, -1])))
        sol = integrate(term, solver, ctrl, t0, t1, jnp.where(tr | meas, y, y_w), omega,
                        saveat=diffrax.SaveAt(ts=save), max_steps=max_steps, adjoint=adjoint)
        good = sol.result == diffrax.RESULTS.successful
        steps = sol.stats["num_steps"]
        y_end = sol.ys[-1]
        out = dict(c)
        good_tr = good & jnp.all(jnp.isfinite(y_end))
        if accelerated:
            change = jnp.max(jnp.abs(y_end - y))
            # stage 2: every mode estimated, 1: the slow modes only, 0: none. A stage ends
            # when its estimate misleads: the change over a period grows (stage 2) or
            # exceeds 4x its smallest in the stage (stage 1: integration noise and the
            # contact law's erratic decay, up to 1.3x per period and 5x at the noise floor
            # at 800 rad/s, zeta 0.03, are not a divergence)
            grow = jnp.where(c["stage"] == 2, 1.0, SLOW_STAGE_GROWTH)
            worse = change >= grow * c["best"]
            stage = jnp.where(worse, jnp.maximum(c["stage"] - 1, 0), c["stage"])
            best = jnp.where(worse, change, jnp.minimum(c["best"], change))
            y_next = jnp.where(
                stage == 2, model.periodic_estimate(y, y_end, omega),
                jnp.where(stage == 1, model.periodic_estimate(y, y_end, omega, slow_only=True),
                          y_end))
            y_next = jnp.where(good_tr, y_next, y)
            k = c["k"] + 1
            stop = ~good_tr | (change <= tol) | (k >= n_transient)
            out.update(k=jnp.where(tr, k, c["k"]), best=jnp.where(tr, best, c["best"]),
                       stage=jnp.where(tr, stage, c["stage"]))
        else:
            y_next, stop = y_end, True
        out["y"] = jnp.where(tr, y_next, jnp.where(meas, y_end, y))
        out["steps_tr"] = c["steps_tr"] + jnp.where(tr, steps, 0)
        out["ok_tr"] = c["ok_tr"] & (~tr | good_tr)
        out["leg"] = jnp.where(tr, jnp.where(stop, 0, -1), leg + 1)
        keep = lambda a, k, on, new: a.at[k].set(jnp.where(on, new, a[k]))  # noqa: E731
        out["grid"] = keep(c["grid"], p, meas, sol.ys[: ts.shape[1]])
        out["wins"] = keep(c["wins"], i, ~tr & ~meas, sol.ys[: n_fine])
        out["success"] = keep(c["success"], j, ~tr, good)
        out["n_steps"] = keep(c["n_steps"], j, ~tr, steps)
        # after the last measured period: the windows and the convergence (a cond on a
        # per-speed flag: under vmap both sides are evaluated, a few hundred output
        # evaluations per leg)
        grid = out["grid"].reshape((-1,) + y0.shape)
        last = leg == n_meas - 1
        out["windows"], (out["conv"], out["multiple"]), memo = jax.lax.cond(
            last, lambda: windows_of(grid, c["memo"]),
            lambda: (c["windows"], (c["conv"], c["multiple"]), c["memo"]))
        if n_max_extend > 0 and n_meas >= 2:  # slide the measured periods by one
            # within the budget, and once in any case (a contact-loss measure needs a
            # change before it to read the decay: an accelerated transient may have used
            # the whole count)
            used = c["extra"] + (c["k"] if accelerated else 0)
            slide = last & good & (out["conv"] > convergence_tol) & (out["multiple"] == 0) & (
                (used < n_extend) | (c["extra"] < 1))
            roll = lambda a: a.at[:n_meas].set(jnp.roll(a[:n_meas], -1, axis=0))  # noqa: E731
            out["steps_tr"] = out["steps_tr"] + jnp.where(slide, out["n_steps"][0], 0)
            out["ok_tr"] = out["ok_tr"] & (~slide | out["success"][0])
            for name in ("grid", "success", "n_steps"):
                out[name] = jnp.where(slide, roll(out[name]), out[name])
            out["extra"] = c["extra"] + slide
            out["memo"] = jax.tree.map(lambda new, old: jnp.where(slide, new, old), memo,
                                       c["memo"])
            out["leg"] = jnp.where(slide, leg, out["leg"])
        return out

    grid0 = jax.ShapeDtypeStruct((ts.size,) + y0.shape, y0.dtype)
    inf = jnp.asarray(jnp.inf, y0.dtype)
    zero_windows, _, _ = jax.tree.map(lambda a: jnp.zeros(a.shape, a.dtype),
                                      jax.eval_shape(windows_of, grid0, memo))
    n_fine = zero_windows[2].shape[1]
    has_transient = (n_transient > 0) if accelerated else (t_transient > 0)
    init = dict(
        leg=jnp.where(has_transient, -1, 0), y=y0, windows=zero_windows,
        grid=jnp.zeros(ts.shape + y0.shape, y0.dtype),
        wins=jnp.zeros((n_win, n_fine) + y0.shape, y0.dtype),
        success=jnp.zeros(n_legs, bool), n_steps=jnp.zeros(n_legs, jnp.asarray(0).dtype),
        steps_tr=jnp.asarray(0), ok_tr=jnp.asarray(True), conv=inf, multiple=jnp.asarray(0),
        memo=memo,
        extra=jnp.asarray(0),
    )
    if accelerated:
        init.update(k=jnp.asarray(0.0), best=jnp.asarray(jnp.inf), stage=jnp.asarray(2))
    kind = "lax" if isinstance(adjoint, diffrax.ForwardMode) else "checkpointed"
    bound = (n_max_transient if accelerated else 1) + n_legs + n_max_extend
    c = eqxi.while_loop(cond, body, init, max_steps=bound, kind=kind)
    k = c["k"] if accelerated else None
    return (c["grid"], c["wins"], c["success"], c["n_steps"],
            (k, c["steps_tr"], c["ok_tr"], c["extra"]), (c["conv"], c["multiple"]), c["memo"])
