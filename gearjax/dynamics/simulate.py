"""Steady-state dynamic response at one pinion speed: diffrax in theta = Omega1 t.

:func:`simulate` integrates any :class:`gearjax.models.base.AbstractGearModel` (sdof
Eqs. (16)/(20)/(47a), 3D Eqs. (14)/(42)/(48a)) at one speed through a transient to its
periodic steady state and measures that state, asking the model only what the base class
declares. It integrates in the angle ``theta`` (rad) from ``model.transient_start``
(:func:`gearjax.dynamics.integrate.integrate`); the transient, each measured period and
each refinement window are legs of one call site (:mod:`gearjax.dynamics.legs`).

Transient: ``n_transient_periods`` excitation periods, or (``None``) per speed
``n = ceil(ln(1/transient_decay) / (decay_rate * period))`` clipped to
``[min_transient_mesh_periods, max_transient_mesh_periods]``, so that the slowest free
response of the linearised model decays by ``transient_decay`` (every speed then costs
about the same steps, as a lockstep vmapped sweep needs). Models with a modal state
(``model.periodic_estimate``) cut it short: each period's end state is replaced by the
model's periodic estimate (:func:`gearjax.models.base.modal_periodic_estimate`, shooting
with each mode's free-decay monodromy as the Jacobian: exact for uncoupled linear modes),
until the state changes by less than ``10 rtol`` over a period; once that change grows,
only the slow modes are estimated (``slow_only``), then none. Where the measured periods of
an automatic transient (forward mode) have not converged, the measurement slides on period
by period within ``max_transient_mesh_periods`` (contact loss decays more slowly than the
linear model). Measurements: ``benchmarks/results/code_notes.md``, gearjax.dynamics.simulate.

Jumps: the right-hand side jumps or kinks at speed-independent angles
(``model.jumps``); :class:`~gearjax.dynamics.integrate.PeriodicJumpController` ends a step just before each and
restarts just after it. The contact laws' state-dependent kinks (contact loss, back-flank
impacts) are left to the error control. Solvers and tolerances: :func:`default_solver`.

Metrics per speed, exact to the integration tolerance (read on the output grid of
:mod:`gearjax.dynamics.metrics` by the dense interpolant and refined between grid points
and after the largest jumps): max and min mesh force F_D (N, Eqs. (22)/(24)), dynamic factor
``max F_D / F_S``, DTE and acceleration peak-to-peak, ``contact_loss`` (``min F_D <= 0``),
``back_contact`` (``min F_D < 0``: backlash), ``convergence``, ``period_multiple``
(:mod:`gearjax.dynamics.periodicity`) and ``converged`` ("periodic with the excitation
period to within ``convergence_tol``"). A failed integration gives ``solver_ok = False``,
``converged = False`` and NaN metrics.

Derivatives: every operation on the metric path is differentiable; the default
``adjoint=diffrax.ForwardMode()`` differentiates through the solve, and the models' angle
maps keep the jumps fixed in the simulation angle while the switching angles move.
"""

from __future__ import annotations

import math

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from ..errors import SimulationError, check_float64
from ..models.base import AbstractGearModel, AbstractModalModel
from ..models.formulations import formulation_of
from .integrate import PeriodicJumpController, jump_controller
from .legs import solve_legs
from .measure import (N_REFINE, extrema, measure_grid, mesh_orders, n_windows, observer,
                      ringing, windows)
from .orders import N_MESH_ORDERS
from .periodicity import (convergence_measure, initial_memo,
                          with_periods_slid_past)

__all__ = [
    "simulate",
    "SimulationResult",
    "Signals",
    "default_solver",
    "SimulationError",
    "PeriodicJumpController",
    "jump_density",
    "jump_controller",
    "transient_periods",
    "transient_start",
]


# Solver and tolerances per formulation, chosen by measurement (see module
# ``benchmarks/bench_sweep_sdof.py`` and the docstring of :func:`default_solver`).
_DEFAULTS = {
    "reference": ("tsit5", 1e-7, 1e-9),
    "te": ("dopri8", 1e-7, 1e-9),
    "perturbation": ("dopri8", 1e-7, 1e-9),
}

_SOLVERS = {
    "tsit5": diffrax.Tsit5,
    "dopri5": diffrax.Dopri5,
    "dopri8": diffrax.Dopri8,
    "bosh3": diffrax.Bosh3,
}


_MANY_JUMPS = 20  # jumps per mesh period above which steps are forced short


def jump_density(model) -> float:
    """Separated jump angles per mesh period of ``model`` (its jump set's static
    ``density``: jumps closer than 1e-3 of a mesh period count once, so the cells of one 3D
    contact line engaging one after the other cost a few tiny steps together, not a cut of
    every step as the 240 spread-out helical jumps do)."""
    return float(model.jumps.density)


def default_solver(formulation, jumps_per_mesh_period: float = 0.0):
    """(solver, rtol, atol) used when :func:`simulate` is given none, for a
    :class:`~gearjax.models.formulations.AbstractFormulation` (or its name).

    Reference: Tsit5, rtol 1e-7. te/perturbation: Dopri8, rtol 1e-7 -- unless the model
    has more than 20 separated jump angles per mesh period (:func:`jump_density`) (helical gears: every one of the 40 cells
    of a contact line enters and leaves the path, about 240 per mesh period), where the
    steps are cut at the jumps anyway and the cheaper stages of Tsit5 win: Tsit5 at rtol
    1e-8. ``atol = rtol / 100``; both act on the dimensionless state (lengths relative to
    the mean static approach). Measured choices: ``benchmarks/results/model_notes.md`` and
    ``benchmarks/results/code_notes.md``, section gearjax.dynamics.simulate.
    """
    name, rtol, atol = _DEFAULTS[formulation_of(formulation).name]
    if name == "dopri8" and jumps_per_mesh_period > _MANY_JUMPS:
        name, rtol, atol = "tsit5", rtol / 10, atol / 10
    return _SOLVERS[name](), rtol, atol


class Signals(eqx.Module):
    """Time signals over the measured periods (leading axis: samples)."""

    theta_rad: jax.Array
    mesh_force_N: jax.Array
    dte_m: jax.Array
    accel_m_s2: jax.Array | None


class SimulationResult(eqx.Module):
    """Steady-state metrics at one speed (scalars; a leading speed axis after vmap).

    Attributes
    ----------
    speed_rad_s : pinion speed Omega1 (rad/s).
    max_mesh_force_N, min_mesh_force_N : extrema of the dynamic mesh force F_D (N).
    dynamic_factor : max F_D / F_S.
    dte_ptp_m : peak-to-peak dynamic transmission error (m).
    accel_ptp_m_s2 : peak-to-peak acceleration (m/s^2); NaN for models without one.
    contact_loss : min F_D <= 0 over the measured periods.
    back_contact : min F_D < 0 over the measured periods: the back flanks carried load (a
        model with backlash; never for one without, whose mesh force is never tensile).
    convergence : largest relative change of per-period extrema between the last two
        measured periods.
    converged : convergence <= tolerance and solver_ok.
    solver_ok : the integration succeeded with finite states.
    n_steps : accepted + rejected steps of all windows.
    transient_periods : excitation periods integrated before measuring.
    period_multiple : the response's period in excitation periods: 1 where ``converged``;
        m = 2..4 (:data:`gearjax.dynamics.periodicity.MAX_PERIOD_MULTIPLE`) for a
        sub-harmonic orbit (an automatic transient's sliding measurement found the last
        period's extrema repeat m periods back, to ``convergence_tol``; the metrics then
        cover all m periods); 0 neither (not yet periodic within the transient's budget,
        quasi-periodic, chaotic or growing).
    mesh_force_orders_N, dte_orders_m, accel_orders_m_s2 : (5,) single-sided peak
        amplitudes of mesh orders 1..5 of F_D (N), DTE (m) and the acceleration (m/s^2;
        NaN for models without one) over the measured periods
        (:mod:`gearjax.dynamics.orders`).
    signals : :class:`Signals` or None.
    """

    speed_rad_s: jax.Array
    max_mesh_force_N: jax.Array
    min_mesh_force_N: jax.Array
    dynamic_factor: jax.Array
    dte_ptp_m: jax.Array
    accel_ptp_m_s2: jax.Array
    contact_loss: jax.Array
    back_contact: jax.Array
    convergence: jax.Array
    converged: jax.Array
    solver_ok: jax.Array
    n_steps: jax.Array
    transient_periods: jax.Array
    period_multiple: jax.Array
    mesh_force_orders_N: jax.Array
    dte_orders_m: jax.Array
    accel_orders_m_s2: jax.Array
    signals: Signals | None = None




def transient_period_bounds(model, min_transient_mesh_periods: int,
                            max_transient_mesh_periods: int) -> tuple[int, int]:
    """(min, max) excitation periods of the automatic transient: the bounds in mesh periods
    rounded up to whole excitation periods (max at least min)."""
    n_mesh = int(round(float(model.period_rad) / model.mesh_period_rad))
    n_min = int(math.ceil(min_transient_mesh_periods / n_mesh))
    return n_min, max(n_min, int(math.ceil(max_transient_mesh_periods / n_mesh)))


def transient_periods(model, omega, transient_decay: float, min_transient_mesh_periods: int,
                      max_transient_mesh_periods: int):
    """Excitation periods of the automatic transient (module docstring): until the
    slowest free mode of the linearised model decays by ``transient_decay``, clipped to
    ``[min, max]_transient_mesh_periods`` (the maximum where the model is undamped)."""
    period = float(model.period_rad)
    n_min, n_max = transient_period_bounds(model, min_transient_mesh_periods,
                                           max_transient_mesh_periods)
    n = jnp.ceil(math.log(1.0 / transient_decay) / (model.decay_rate_per_rad(omega) * period))
    return jnp.clip(jnp.nan_to_num(n, nan=n_max, posinf=n_max), n_min, n_max)


def transient_start(model, omega):
    """Start of the transient at theta = 0: ``model.transient_start(omega)`` (see
    :meth:`gearjax.models.base.AbstractGearModel.transient_start`)."""
    return model.transient_start(omega)


# simulate's measured periods: two, the least the convergence measure (last two periods)
# and the refinement windows (an extreme at the span's ends has an interior periodic copy)
# need (timings: benchmarks/results/code_notes.md, section gearjax.dynamics.simulate)
DEFAULT_MEASURED_PERIODS = 2
DEFAULT_SAMPLES_PER_MESH_PERIOD = 128  # and its output grid density


def grid_size(model, n_measured_periods: int, samples_per_mesh_period: int):
    """(samples per excitation period, output grid points per period (the samples and
    both sides of every jump of the model's jump set, padding included:
    :func:`gearjax.dynamics.grid.period_grid`), length of each leg of :func:`simulate`'s
    solve (:mod:`gearjax.dynamics.legs`): one period's grid and its end, or the
    ``2 N_REFINE`` points of a refinement window if longer)."""
    period = float(model.period_rad)
    n_samples = samples_per_mesh_period * int(round(period / model.mesh_period_rad))
    per_period = n_samples + 2 * model.jumps.bound
    return n_samples, per_period, max(per_period + 1, 2 * N_REFINE)


def simulate(
    model,
    omega,
    n_transient_periods: int | None = None,
    n_measured_periods: int = DEFAULT_MEASURED_PERIODS,
    *,
    solver=None,
    rtol: float | None = None,
    atol: float | None = None,
    save_signals: bool = False,
    samples_per_mesh_period: int = DEFAULT_SAMPLES_PER_MESH_PERIOD,
    transient_decay: float = 1e-6,
    min_transient_mesh_periods: int = 8,
    max_transient_mesh_periods: int = 400,
    convergence_tol: float = 1e-3,
    max_steps: int = 2_000_000,
    adjoint=None,
    start: str = "auto",
    extrapolate: bool = True,
    accelerate: bool = True,
    y0=None,
) -> SimulationResult:
    """Integrate ``model`` at pinion speed ``omega`` to steady state and measure it.

    Jit- and vmap-compatible in ``omega`` (and in the array data of ``model``); all other
    arguments are static configuration.

    Parameters
    ----------
    model : a model with the simulation interface (module docstring).
    omega : pinion speed Omega1 (rad/s), > 0.
    n_transient_periods : excitation periods integrated before measuring; ``None`` chooses
        them per speed from the model's decay rate (module docstring).
    n_measured_periods : periods over which metrics are taken (>= 2 for the convergence
        measure).
    solver, rtol, atol : diffrax solver and tolerances on the dimensionless state; default
        :func:`default_solver` for the model's formulation.
    save_signals : also return the sampled signals over the measured periods.
    samples_per_mesh_period : output grid density (extrema are maxima over this grid).
    transient_decay, min_transient_mesh_periods, max_transient_mesh_periods : automatic
        transient (bounds in mesh periods, rounded up to whole excitation periods).
    convergence_tol : threshold on ``convergence`` for ``converged``; with the automatic
        transient (and the forward-mode adjoint) also the measurement's: it slides on
        period by period until met (module docstring, "Transient"); ``transient_periods``
        counts the periods slid past.
    max_steps : step limit of each leg of the integration (the transient, or each of its
        periods when accelerated; each measured period; each refinement window);
        exceeded -> ``solver_ok=False``.
    adjoint : diffrax adjoint, default ``diffrax.ForwardMode()``.
    start : ``"auto"`` (:func:`transient_start`: modal models start their slow modes on
        the period mean of the quasi-static state) or ``"initial"``
        (``model.initial_state(omega)``).
    y0 : explicit start state at theta = 0 (overrides ``start``), e.g. a periodic orbit.
    extrapolate : for modal models, estimate what is left of the transient
        (:mod:`gearjax.dynamics.periodicity`: per mode from the state, or the slowest
        output mode's ``1 / |1 - mu|``), not only the last change of the extrema.
    accelerate : for the automatic transient (``n_transient_periods=None``) of a model
        with :meth:`~gearjax.models.base.AbstractGearModel.periodic_estimate` (the 3D
        model), integrate it period by period and replace each period's end state by the
        model's estimate of the periodic state (every mode while the change over a period
        falls, then the slow modes only: module docstring, "Transient"); stop when the
        change is below ``10 rtol``. The
        automatic count stays the upper bound. False: one plain transient of that count.

    Returns
    -------
    SimulationResult

    Raises
    ------
    SimulationError
        for a concrete non-positive or non-finite speed or inconsistent configuration.
    """
    if not isinstance(model, AbstractGearModel):
        raise SimulationError("model", type(model).__name__,
                              "must be a gear model (gearjax.models.base.AbstractGearModel)")
    _check_config(n_transient_periods, n_measured_periods, samples_per_mesh_period,
                  transient_decay, min_transient_mesh_periods, max_transient_mesh_periods)
    check_float64()
    if not isinstance(omega, jax.core.Tracer):
        w = np.asarray(omega, dtype=float)
        if w.ndim != 0:
            raise SimulationError("omega", w.shape, "simulate takes one speed; use sweep()")
        if not (np.isfinite(w) and w > 0):
            raise SimulationError("omega", float(w), "pinion speed must be finite and > 0 (rad/s)")
    density = jump_density(model)
    d_solver, d_rtol, d_atol = default_solver(model.formulation, density)
    solver = d_solver if solver is None else solver
    rtol = d_rtol if rtol is None else rtol
    atol = d_atol if atol is None else atol
    adjoint = diffrax.ForwardMode() if adjoint is None else adjoint

    omega = jnp.asarray(omega, dtype=float)
    period = float(model.period_rad)
    def term(t, y, args):  # the model's vector field in theta (args: omega)
        return model.vector_field(t, y, args)


    # ---------------------------------------------------------------- one solve
    rate = model.decay_rate_per_rad(omega)
    if n_transient_periods is None:
        n_tr = transient_periods(model, omega, transient_decay, min_transient_mesh_periods,
                                 max_transient_mesh_periods)
    else:
        n_tr = jnp.asarray(float(n_transient_periods))
    if start not in ("auto", "initial"):
        raise SimulationError("start", start, 'must be "auto" or "initial"')
    if y0 is None:
        y0 = model.transient_start(omega) if start == "auto" else model.initial_state(omega)
    y0 = jnp.asarray(y0)
    ctrl = jump_controller(model, rtol, atol)
    accelerated = (accelerate and n_transient_periods is None
                   and isinstance(model, AbstractModalModel))
    n_max = transient_period_bounds(model, min_transient_mesh_periods,
                                    max_transient_mesh_periods)[1] if accelerated else 0
    accelerated = accelerated and n_max > 0
    t_tr = 0.0 if accelerated else n_tr * period
    # output grid: mid-cell samples (never on an engagement angle) plus both sides of
    # every jump, per measured period (gearjax.dynamics.metrics)
    # (gearjax.dynamics.measure, from the model's jump set in the program)
    mg = measure_grid(model, n_measured_periods, samples_per_mesh_period)
    n_out = max(mg.per_period + 1, 2 * N_REFINE)
    ts = t_tr + mg.offsets()
    observed = observer(model, omega)  # the one measure (gearjax.dynamics.measure)

    n_grid = ts.shape[0]
    n_ref, n_jw = n_windows(mg, jax.eval_shape(observed, ts[0], y0).shape[0])
    ring, resolved = ringing(model, omega, mg)  # resolved: no windows after the jumps
    n_win = n_ref + n_jw
    f_s = model.static_force_N

    def windows_of(g, memo):  # the measured states on the grid -> the windows' legs,
        vals = mg.valued(jax.vmap(observed)(ts, g))  # the convergence, what a slide keeps
        win = windows(mg, vals, ts, ring)
        return ((ts[win.first], g[win.first], win.angles()),) + convergence_measure(
            model, omega, vals, g, memo, n_periods=n_measured_periods,
            extrapolate=extrapolate, slide=slide, convergence_tol=convergence_tol)

    has_acc = jax.eval_shape(observed, ts[0], y0).shape[0] > 2
    memo = initial_memo(n_ref)  # the measurement before: its change, the periods slid past
    # an automatic transient too short for the response (a contact-loss orbit decays
    # more slowly than the linear model's count) slides the measured periods on, up to
    # the automatic maximum in all (forward mode: a reverse-mode adjoint checkpoints
    # the loop to its bound)
    slide = (n_transient_periods is None and isinstance(adjoint, diffrax.ForwardMode)
             and n_measured_periods >= 2)
    n_ext_max = transient_period_bounds(model, min_transient_mesh_periods,
                                        max_transient_mesh_periods)[1] if slide else 0

    # transient, measured periods and refinement windows: legs of one diffeqsolve call
    # site (gearjax.dynamics.legs; a second one would compile a second solver per program)
    grid_ys, win_ys, success, n_steps, (k_tr, steps_tr, ok_tr, n_slid), (
        conv, multiple), memo = solve_legs(
        model, term, solver, ctrl, omega, y0, ts=ts.reshape(n_measured_periods, -1),
        n_out=n_out, n_win=n_win, windows_of=windows_of, memo=memo, t_transient=t_tr,
        accelerated=accelerated, n_transient=n_tr, n_max_transient=n_max, tol=10.0 * rtol,
        max_steps=max_steps, adjoint=adjoint, convergence_tol=convergence_tol,
        n_extend=n_ext_max - (0 if accelerated else n_tr), n_max_extend=n_ext_max,
        n_skip=jnp.where(resolved, n_win - n_ref, 0))
    if accelerated:
        n_tr = k_tr
    n_tr = n_tr + n_slid
    n_meas = n_measured_periods
    ys = grid_ys.reshape((n_grid,) + y0.shape)
    ok = ok_tr & jnp.all(success[:n_meas]) & jnp.all(jnp.isfinite(ys))
    steps = steps_tr + jnp.sum(n_steps[:n_meas])
    vals = mg.valued(jax.vmap(observed)(ts, ys))
    win = windows(mg, vals, ts, ring)
    wvals = jax.vmap(jax.vmap(observed))(win.angles(), win_ys)  # (n_win, k, q)
    v_max, v_min = extrema(mg, vals, ts, win, wvals, resolved)
    # a sub-harmonic orbit of more periods than measured: its other periods' extrema
    v_max, v_min = with_periods_slid_past(v_max, v_min, memo, multiple, n_measured_periods)
    f_max, f_min = v_max[0], v_min[0]
    dte_ptp = v_max[1] - v_min[1]
    acc_ptp = v_max[2] - v_min[2] if has_acc else jnp.asarray(jnp.nan)
    orders = mesh_orders(model, mg, vals)  # (q, 5): F_D, DTE (, accel)
    finite = jnp.isfinite(f_max) & jnp.isfinite(f_min) & jnp.isfinite(dte_ptp)
    ok = ok & finite
    nan = jnp.asarray(jnp.nan)
    bad = lambda v: jnp.where(ok, v, nan)
    signals = None
    if save_signals:  # the uniform mid-cell samples only (one-sided jump points left out)
        mid = mg.sample_index()
        signals = Signals(
            theta_rad=ts[mid], mesh_force_N=vals[mid, 0], dte_m=vals[mid, 1],
            accel_m_s2=vals[mid, 2] if has_acc else None,
        )
    # undamped (decay rate 0): the free response of the start never dies, so no transient
    # reaches the steady state -- never "converged" (see the docstring)
    converged = ok & (conv <= convergence_tol) & (rate > 0)
    return SimulationResult(
        speed_rad_s=omega,
        max_mesh_force_N=bad(f_max),
        min_mesh_force_N=bad(f_min),
        dynamic_factor=bad(f_max / f_s),
        dte_ptp_m=bad(dte_ptp),
        accel_ptp_m_s2=bad(acc_ptp) if has_acc else nan,
        contact_loss=ok & (f_min <= 0.0),
        back_contact=ok & (f_min < 0.0),
        convergence=jnp.where(ok, conv, jnp.inf),
        converged=converged,
        period_multiple=jnp.where(converged, 1, jnp.where(ok, multiple, 0)),
        solver_ok=ok,
        n_steps=steps,
        transient_periods=n_tr,
        mesh_force_orders_N=bad(orders[0]),
        dte_orders_m=bad(orders[1]),
        accel_orders_m_s2=bad(orders[2]) if has_acc else jnp.full(N_MESH_ORDERS, jnp.nan),
        signals=signals,
    )


def _check_config(n_tr, n_meas, n_samp, decay, n_min, n_max):
    if n_tr is not None and (int(n_tr) != n_tr or n_tr < 0):
        raise SimulationError("n_transient_periods", n_tr, "must be None or an integer >= 0")
    if int(n_meas) != n_meas or n_meas < 1:
        raise SimulationError("n_measured_periods", n_meas, "must be an integer >= 1")
    if int(n_samp) != n_samp or n_samp < 4:
        raise SimulationError("samples_per_mesh_period", n_samp, "must be an integer >= 4")
    if not (0.0 < decay < 1.0):
        raise SimulationError("transient_decay", decay, "must lie in (0, 1)")
    if not (0 <= n_min <= n_max):
        raise SimulationError(
            "min_transient_mesh_periods", n_min,
            f"must satisfy 0 <= min <= max_transient_mesh_periods={n_max}",
        )
