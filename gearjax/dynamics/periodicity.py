"""Is a measured response periodic? The convergence measure and the sub-harmonic
recognition of :func:`gearjax.dynamics.simulate.simulate`.

:func:`convergence_measure` reads the measured periods of one speed (the outputs on the
output grid of :mod:`gearjax.dynamics.metrics` and the states there) and returns the
``convergence`` measure and the sub-harmonic period ``period_multiple``; its ``memo``
carries what a sliding measurement (:mod:`gearjax.dynamics.legs`) needs of the measurements
before: the last one-period change and the extrema of the periods slid past.

``convergence`` is the largest relative change of the per-period extrema between the last
two measured periods (forces over F_S, DTE and acceleration over their peak-to-peak) or, if
larger, what is left of the transient: modal models (``model.transient_amplitudes``)
extrapolate the state's change over the last period mode by mode, ``|mu_j| / |1 - mu_j|``
times each mode's change (``mu_j`` its free-decay multiplier per period), and sum the modes'
shares of each output (:class:`gearjax.models.base.AbstractModalModel`); a model without a
modal state has its extrema's change alone. The extrapolation reads the linear model's free
decay; with contact loss in the measured periods (``min F_D <= 0``) a sliding measurement
also takes the change's own ratio ``q`` between successive periods, ``change q / (1 - q)``
(the linear reading alone can pass an orbit whose force is ten times
``convergence_tol`` off). ``converged`` means "periodic with the excitation period to within
``convergence_tol``": a sub-harmonic (``period_multiple``, below), quasi-periodic or growing
response (parametric instability, :mod:`gearjax.dynamics.stability`) or an insufficient
transient reads as not converged, and an undamped model (decay rate 0) never does.

A sliding measurement also recognises a sub-harmonic orbit: it stops once the last
period's extrema equal those m = 2..``MAX_PERIOD_MULTIPLE`` periods back (measured, then
slid past) to ``convergence_tol`` while the change over one period stays above 100
``convergence_tol`` (so a period-1 transient decaying with an alternating ratio is not
mistaken for one), and reports ``period_multiple = m`` with the extrema taken over all m
periods (:func:`with_periods_slid_past`: those slid past on the grid); ``converged`` stays
False. Measurements of these readings: ``benchmarks/results/code_notes.md``, section
gearjax.dynamics.periodicity.
"""

from __future__ import annotations

import jax.numpy as jnp

from ..models.base import AbstractModalModel

__all__ = ["convergence_measure", "initial_memo", "per_period_extrema",
           "with_periods_slid_past", "Q_CONTACT_LOSS_MAX", "MAX_PERIOD_MULTIPLE"]

# the largest decay ratio per period that the convergence measure of a contact-loss orbit
# extrapolates (module docstring): what is left is read as at most 99 times the last change
Q_CONTACT_LOSS_MAX = 0.99
# the longest sub-harmonic period (in excitation periods) a sliding measurement
# recognises (SimulationResult.period_multiple)
MAX_PERIOD_MULTIPLE = 4


def per_period_extrema(vals, n_periods: int):
    """The outputs on the grid ``(n_periods * per_period, n_out)`` -> (the same split by
    period ``(n_periods, per_period, n_out)``, the per-period extrema ``(n_periods, 2
    n_out)``: F max, F min, DTE max, DTE min (, accel max, accel min))."""
    per = vals.reshape(n_periods, -1, vals.shape[-1])
    return per, jnp.stack([per.max(1), per.min(1)], axis=2).reshape(n_periods, -1)


def initial_memo(n_windows: int) -> dict:
    """The memo before any measurement: no one-period change yet (inf) and no periods slid
    past (NaN extrema), ``n_windows`` = 2 n_out."""
    return dict(change=jnp.asarray(jnp.inf),
                past=jnp.full((MAX_PERIOD_MULTIPLE, n_windows), jnp.nan))


def convergence_measure(model, omega, vals, ys, memo: dict, *, n_periods: int,
                        extrapolate: bool, slide: bool, convergence_tol: float):
    """(``convergence``, ``period_multiple``), next memo, of the measured periods.

    Parameters
    ----------
    model, omega : the model and pinion speed (rad/s).
    vals : (n_periods * per_period, n_out) outputs on the grid (mesh force N, DTE m, and
        the acceleration m/s^2 where the model has one).
    ys : the states at those grid points.
    memo : :func:`initial_memo` or the memo the previous measurement returned.
    n_periods : measured periods (< 2: no measure, inf).
    extrapolate : add what is left of the transient (module docstring).
    slide : the measurement slides (contact loss then reads the change's own ratio, and
        sub-harmonic orbits are recognised in the periods slid past).
    convergence_tol : tolerance of the sub-harmonic test.
    """
    none = jnp.asarray(0)
    if n_periods < 2:
        return (jnp.asarray(jnp.inf), none), memo
    _, ext = per_period_extrema(vals, n_periods)
    per_period = vals.shape[0] // n_periods
    has_acc = vals.shape[1] > 2
    f_s = model.static_force_N
    # last two periods; forces / F_S, DTE / DTE ptp, accel / accel ptp (the grid's ptp
    # over the measured periods, floored at 1e-3 of the largest |value|, for signals
    # that hardly vary)
    ptp = jnp.max(ext[:, 0::2], axis=0) - jnp.min(ext[:, 1::2], axis=0)
    dte_s = jnp.maximum(ptp[1], 1e-3 * jnp.max(jnp.abs(ext[:, 2:4])))
    acc_s = jnp.maximum(ptp[2], 1e-3 * jnp.max(jnp.abs(ext[:, 4:6]))) if has_acc else None
    scales = [f_s, f_s, dte_s, dte_s] + ([acc_s, acc_s] if has_acc else [])
    scales = jnp.stack([jnp.maximum(jnp.abs(s), 1e-300) for s in scales])
    change = conv = jnp.max(jnp.abs(ext[-1] - ext[-2]) / scales)
    # what is left of the transient: modal models extrapolate the state's change over
    # the last period mode by mode (model.transient_amplitudes); others measure the
    # extrema's change alone
    if extrapolate and isinstance(model, AbstractModalModel):
        # the state's change over the last period, at one phase; the floored scales: an
        # output that is identically zero (no pinion-centre motion in a torsional
        # structure) has a zero remainder, not 0/0
        last = (n_periods - 1) * per_period
        amps = model.transient_amplitudes(ys[last] - ys[last - per_period], omega)
        left = [amps[0] / scales[0], amps[1] / scales[2]] + (
            [amps[2] / scales[4]] if has_acc else [])
        conv = jnp.maximum(conv, jnp.max(jnp.stack(left)))
    if slide:
        # contact loss: the free decay of the linear model does not bound what is
        # left; the change's own ratio q over successive periods does, as
        # change q / (1 - q); without a measurement before, none yet (inf: slide on).
        # q is capped at Q_CONTACT_LOSS_MAX: at the noise floor of the extrema q is a
        # random ratio that a looser cap amplifies (benchmarks/results/code_notes.md,
        # section gearjax.dynamics.periodicity)
        before = memo["change"]
        q = jnp.clip(change / before, 0.0, Q_CONTACT_LOSS_MAX)
        seen = jnp.where(jnp.isfinite(before), change * q / (1.0 - q), jnp.inf)
        conv = jnp.where(jnp.min(vals[:, 0]) <= 0.0, jnp.maximum(conv, seen), conv)
    # a sub-harmonic orbit: the last period's extrema repeat m = 2..MAX_PERIOD_MULTIPLE
    # periods back (the measured periods, then those slid past, most recent first;
    # NaN where not yet seen), while the change over one period stays large: a
    # period-1 transient decaying with an alternating (or rotating) ratio lambda has
    # its m-back residual below convergence_tol only once its one-period change is
    # below ~convergence_tol / (1 - |lambda|), so a change over 1 / (1 -
    # Q_CONTACT_LOSS_MAX) = 100 times convergence_tol leaves only |lambda| > 0.99,
    # which the period-1 measure caps at Q_CONTACT_LOSS_MAX anyway (a weaker
    # sub-harmonic stays 0: not yet periodic)
    seq = jnp.concatenate([ext[::-1], memo["past"]])
    back = jnp.max(jnp.abs(seq[2:MAX_PERIOD_MULTIPLE + 1] - seq[:1]) / scales[None], axis=1)
    hit = (back <= convergence_tol) & (
        change >= convergence_tol / (1.0 - Q_CONTACT_LOSS_MAX))
    multiple = jnp.where(jnp.any(hit), jnp.argmax(hit) + 2, 0).astype(none.dtype)
    past = jnp.concatenate([ext[:1], memo["past"][:-1]])  # should ext[0] be slid past
    return (conv, multiple), dict(change=change, past=past)


def with_periods_slid_past(v_max, v_min, memo: dict, multiple, n_periods: int):
    """The extrema ``v_max``, ``v_min`` (n_out,) of the measured periods, extended over
    the other periods of a sub-harmonic orbit of ``multiple`` > ``n_periods`` periods
    (on the grid, slid past just before: ``memo["past"]``)."""
    if MAX_PERIOD_MULTIPLE <= n_periods:
        return v_max, v_min
    use = (jnp.arange(MAX_PERIOD_MULTIPLE) < multiple - n_periods)[:, None]
    v_max = jnp.maximum(v_max, jnp.max(jnp.where(use, memo["past"][:, 0::2], -jnp.inf), 0))
    v_min = jnp.minimum(v_min, jnp.min(jnp.where(use, memo["past"][:, 1::2], jnp.inf), 0))
    return v_max, v_min
