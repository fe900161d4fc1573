"""Steady-state dynamic response at one pinion speed: diffrax in theta = Omega1 t.

:func:`simulate` works for any model exposing the simulation interface (the torsional model
:class:`gearjax.models.torsional.TorsionalModel`, the 3D model
:class:`gearjax.models.geared3d.Geared3DModel`):

``prepare()``
    returns the model with its derived quantities filled (called inside ``jit``).
``initial_state(omega)``
    state at theta = 0 with the quasi-static deflection X_S (dynamic part zero).
``vector_field(theta, y, omega)``
    dy/dtheta.
``outputs(theta, y, omega)``
    a :class:`~gearjax.models.torsional.ModelOutputs` (mesh force, DTE, acceleration or
    None).
``decay_rate_per_rad(omega)``
    slowest free-decay rate per radian of theta (sizes the automatic transient).
``period_rad``, ``mesh_period_rad``, ``jump_thetas``, ``static_force_N``, ``formulation``.

Integration scheme
------------------
One ``diffeqsolve`` per speed, from theta = 0 to the end of the last measured period,
saving the state only on the measured grid (``samples_per_mesh_period`` points per mesh
period, at mid-cells ``(j + 1/2) P / n`` so that no sample falls on an engagement angle) by
dense interpolation, which does not constrain the step size. The outputs (mesh force, DTE,
acceleration) are evaluated on that grid and reduced to per-period extrema; nothing else
of the trajectory is kept (the signals only with ``save_signals=True``).

Start: :func:`transient_start` -- the quasi-static state X_S(0) (dynamic part zero), except
that modal models start the modes far below the excitation frequency on the period mean of
the quasi-static state (they cannot follow the ripple; started on it, the 3D rig's 61.8 rad/s
mode, weakly coupled to the mesh, outlived the automatic transient and left a silent 1e-3
error in the dynamic factor; from the mean, 1e-5 at 700-840 rad/s, no extra cost but 64
quasi-static evaluations per speed).

The transient is either ``n_transient_periods`` excitation periods, or (``None``) chosen per
speed so that the free response of the linearised model decays by ``transient_decay``:
``n = ceil(ln(1/transient_decay) / (decay_rate * period))`` clipped to
``[min_transient_mesh_periods, max_transient_mesh_periods]`` (rounded up to whole periods).
Steps per radian grow like ``1/Omega`` while the periods needed grow like ``Omega``, so every
speed costs about the same -- which a vmapped sweep needs, because diffrax advances the
batch in lockstep and the slowest member sets the cost. (Integrating period by period in a
loop would multiply the *per-period* maxima over the batch: measured several times slower.)

Jumps: the right-hand side of a gear model jumps or kinks at angles that do not depend on
speed (cell engagement, quasi-static active-set changes, NLTE kinks), ``model.jump_thetas``
within one period. :class:`PeriodicJumpController` makes every step end just before such an
angle and the next start just after it (as ``PIDController(jump_ts=...)``, i.e.
``ClipStepSizeController``, does, but in O(1) per step: the diffrax controller compares
each step with every entry of ``jump_ts``, which over 100+ periods of 6-240 jumps made the
controller, not the vector field, the cost: 7x on a helical sweep). State-dependent kinks
of the reference contact law (cells losing or regaining contact) are left to the error
control.

Solvers and tolerances (:func:`default_solver`, chosen by work-precision measurements on
16 speeds 60-1450 rad/s of the spur Table 1 pair, errors against Dopri8 at rtol 1e-11;
``benchmarks/bench_sweep_sdof.py --work-precision`` repeats them): the reference contact
law has state-dependent kinks, where a low order pays off: Tsit5 at rtol 1e-7 (error of the
dynamic factor ~1e-5, 9.0e3 steps x 6 stages for the costliest speed) beats Dopri8 at
rtol 1e-6 (5e-6, 7.4e3 x 13). The te and perturbation right-hand sides are smooth between
the jumps: Dopri8 at rtol 1e-7 (error ~1e-6, 1.9e3 x 13) beats Tsit5 at rtol 1e-7 (1e-5,
5.0e3 x 6). ``atol = 1e-9``. Both on the dimensionless state (lengths over the mean static
approach).

Metrics (per speed): max and min mesh force, dynamic factor ``max F_D / F_S``, DTE and
acceleration peak-to-peak over all measured periods, a contact-loss flag (``min F_D <= 0``:
total separation of the teeth for the reference formulation, a tensile -- unphysical --
mesh force for the linear te/perturbation formulations), the convergence measure (the
largest relative change of the per-period extrema between the last two measured periods,
forces relative to F_S, DTE relative to the DTE peak-to-peak; for modal models divided by
``|1 - mu|``, ``mu`` the free-decay multiplier per period of the slowest mode the outputs
see, :func:`slowest_output_mode`: a geometric extrapolation to the distance from the steady
state, so that a slow drift is not read as converged) and ``converged``
(``convergence <= convergence_tol`` and the solver succeeded). A model whose
``decay_rate_per_rad`` is 0 (undamped) never reads as converged: its free response keeps
the amplitude of the start (an undamped oscillator at 0.7 of the mesh frequency changed its
per-period extrema by only 9e-5 and was read as converged). ``converged`` therefore
means "periodic with the excitation period to within the tolerance": a sub-harmonic
response (after contact loss, or in a parametric instability zone of the reference), a
quasi-periodic or chaotic one, a response still growing (parametric instability of the
linear te model, see :mod:`gearjax.dynamics.stability`) or an insufficient transient all read as
not converged. A failed integration (step limit, non-finite state) gives
``solver_ok = False``, ``converged = False`` and NaN metrics: never a silent NaN.

All operations on the metric path are differentiable (max/min over the sampled grid are
exact maxima of the samples); the default ``adjoint=diffrax.ForwardMode()`` gives
forward-mode derivatives through the solve (checked against central differences for the
speed and the relief amplitude). For te and perturbation the jump angles move with the
design; the torsional model maps them to fixed integration angles so that AD sees their
motion (see :mod:`gearjax.models.torsional`). The 3D model's table knots are fixed at build
time: its te/perturbation derivatives with respect to the modifications miss that motion.
"""

from __future__ import annotations

import math

import diffrax
import equinox as eqx
import equinox.internal as eqxi
import jax
import jax.numpy as jnp
import numpy as np
from ..errors import SimulationError

__all__ = [
    "simulate",
    "SimulationResult",
    "Signals",
    "default_solver",
    "SimulationError",
    "PeriodicJumpController",
    "jump_density",
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
    """Separated jump angles per mesh period: jumps closer than 1e-3 of a mesh period count
    once (the cells of one 3D contact line engaging one after the other cost a few tiny
    steps together, not a cut of every step as the 240 spread-out helical jumps do)."""
    j = np.sort(np.asarray(model.jump_thetas, dtype=float))
    if j.size == 0:
        return 0.0
    n = 1 + int(np.sum(np.diff(j) > 1e-3 * model.mesh_period_rad))
    return n * model.mesh_period_rad / model.period_rad


def default_solver(formulation: str, jumps_per_mesh_period: float = 0.0):
    """(solver, rtol, atol) used when :func:`simulate` is given none.

    Reference: Tsit5, rtol 1e-7. te/perturbation: Dopri8, rtol 1e-7 -- unless the model
    has more than 20 separated jump angles per mesh period (:func:`jump_density`) (helical gears: every one of the 40 cells
    of a contact line enters and leaves the path, about 240 per mesh period), where the
    steps are cut at the jumps anyway and the cheaper stages of Tsit5 win: Tsit5 at rtol
    1e-8 (measured on the helical Table 1 pair, 8 speeds: 0.97 s and dynamic-factor error
    4e-8, against 1.6 s and 3e-8 for Dopri8 at rtol 1e-7). The 3D spur te model (5
    clusters of jumps, 23 jumps) at 700 rad/s: Dopri8 1e-7 34.8e3 steps, 2.0 s, error of
    the dynamic factor 1e-8; Tsit5 1e-8 121e3 steps, 3.6 s, 3e-9. ``atol = rtol / 100``; both act
    on the dimensionless state (lengths relative to the mean static approach). See the
    module docstring for the measurements.
    """
    name, rtol, atol = _DEFAULTS.get(formulation, _DEFAULTS["reference"])
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
    convergence : largest relative change of per-period extrema between the last two
        measured periods.
    converged : convergence <= tolerance and solver_ok.
    solver_ok : the integration succeeded with finite states.
    n_steps : accepted + rejected steps of all windows.
    transient_periods : excitation periods integrated before measuring.
    signals : :class:`Signals` or None.
    """

    speed_rad_s: jax.Array
    max_mesh_force_N: jax.Array
    min_mesh_force_N: jax.Array
    dynamic_factor: jax.Array
    dte_ptp_m: jax.Array
    accel_ptp_m_s2: jax.Array
    contact_loss: jax.Array
    convergence: jax.Array
    converged: jax.Array
    solver_ok: jax.Array
    n_steps: jax.Array
    transient_periods: jax.Array
    signals: Signals | None = None


class PeriodicJumpController(diffrax.AbstractAdaptiveStepSizeController):
    """A step-size controller (wrapping a PID controller) that steps to just before and
    restarts just after every ``jump_i + k * period`` (k integer), like
    ``diffrax.ClipStepSizeController(jump_ts=...)`` but for periodic jumps.

    ``ClipStepSizeController`` compares the step ends with *all* of its ``jump_ts`` at
    every step (O(n)), which for a steady state over 100+ periods with 6 (spur) to 240
    (helical) jumps per period costs more than the vector field. Here the next jump is
    found in O(1) from the position in the period (a ``searchsorted`` over one period's
    jumps and a handful of candidates compared in absolute time, so that round-off in
    ``t mod period`` can never skip a jump). Forward integration only.

    Attributes
    ----------
    controller : the wrapped adaptive controller (``diffrax.PIDController``).
    jumps : (n,) sorted jump positions in ``[0, period)``.
    period : the period (same time unit as the solve).
    """

    controller: diffrax.AbstractAdaptiveStepSizeController
    jumps: jax.Array
    period: float = eqx.field(static=True)

    @property
    def rtol(self):
        return self.controller.rtol

    @property
    def atol(self):
        return self.controller.atol

    @property
    def norm(self):
        return self.controller.norm

    def wrap(self, direction):
        return eqx.tree_at(lambda c: c.controller, self, self.controller.wrap(direction))

    def _next_jump(self, t):
        """Smallest jump time strictly greater than ``t``."""
        n = self.jumps.shape[0]
        k = jnp.floor(t / self.period)
        idx = jnp.searchsorted(self.jumps, t - k * self.period, side="right")
        js = jnp.clip(idx + jnp.array([-1, 0, 1]), 0, n - 1)
        js = jnp.concatenate([js, jnp.zeros(1, dtype=js.dtype)])
        ks = k + jnp.array([-1.0, 0.0, 1.0])
        cand = (ks[:, None] * self.period + self.jumps[js][None, :]).ravel()
        return jnp.min(jnp.where(cand > t, cand, jnp.inf))

    def _is_jump(self, t):
        return self._next_jump(eqxi.prevbefore(t)) == t

    def init(self, terms, t0, t1, y0, dt0, args, func, error_order):
        t1, inner = self.controller.init(terms, t0, t1, y0, dt0, args, func, error_order)
        t1 = jnp.minimum(t1, eqxi.prevbefore(self._next_jump(t0)))
        return t1, inner

    def adapt_step_size(self, t0, t1, y0, y1_candidate, args, y_error, error_order, state):
        keep, next_t0, next_t1, made_jump, inner, result = self.controller.adapt_step_size(
            t0, t1, y0, y1_candidate, args, y_error, error_order, state
        )
        # as ClipStepSizeController: a step that ended prevbefore(jump) restarts after it
        after = eqxi.nextafter(next_t0)
        jump1 = self._is_jump(after)
        jump2 = self._is_jump(next_t0)
        next_t0 = jnp.where(jump1, eqxi.nextafter(after), next_t0)
        next_t0 = jnp.where(jump2, after, next_t0)
        next_t1 = jnp.maximum(eqxi.nextafter(next_t0), next_t1)
        next_t1 = jnp.minimum(next_t1, eqxi.prevbefore(self._next_jump(next_t0)))
        return keep, next_t0, next_t1, made_jump | jump1 | jump2, inner, result


def _controller(rtol, atol, jumps=None, period=None):
    pid = diffrax.PIDController(rtol=rtol, atol=atol, pcoeff=0.0, icoeff=1.0)
    if jumps is None or len(jumps) == 0:
        return pid
    return PeriodicJumpController(pid, jnp.asarray(np.sort(np.asarray(jumps, dtype=float))),
                                  float(period))


def transient_start(model, omega):
    """Start of the transient at theta = 0: ``model.transient_start(omega)`` (see
    :meth:`gearjax.models.base.AbstractGearModel.transient_start`)."""
    return model.transient_start(omega)


def simulate(
    model,
    omega,
    n_transient_periods: int | None = None,
    n_measured_periods: int = 3,
    *,
    solver=None,
    rtol: float | None = None,
    atol: float | None = None,
    save_signals: bool = False,
    samples_per_mesh_period: int = 128,
    transient_decay: float = 1e-6,
    min_transient_mesh_periods: int = 8,
    max_transient_mesh_periods: int = 400,
    convergence_tol: float = 1e-3,
    max_steps: int = 2_000_000,
    adjoint=None,
    start: str = "auto",
    extrapolate: bool = True,
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
    convergence_tol : threshold on ``convergence`` for ``converged``.
    max_steps : step limit of each ``diffeqsolve`` (exceeded -> ``solver_ok=False``).
    adjoint : diffrax adjoint, default ``diffrax.ForwardMode()``.
    start : ``"auto"`` (:func:`transient_start`: modal models start their slow modes on
        the period mean of the quasi-static state) or ``"initial"``
        (``model.initial_state(omega)``).
    y0 : explicit start state at theta = 0 (overrides ``start``), e.g. a periodic orbit.
    extrapolate : for modal models, divide the convergence measure by ``|1 - mu|``, ``mu``
        the free-decay multiplier per period of the slowest mode the outputs see
        (:func:`slowest_output_mode`): an estimate of the distance to the steady state,
        not of the last change only.

    Returns
    -------
    SimulationResult

    Raises
    ------
    SimulationError
        for a concrete non-positive or non-finite speed or inconsistent configuration.
    """
    _check_config(n_transient_periods, n_measured_periods, samples_per_mesh_period,
                  transient_decay, min_transient_mesh_periods, max_transient_mesh_periods)
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
    jumps = np.asarray(model.jump_thetas, dtype=float)
    n_mesh = int(round(period / model.mesh_period_rad))
    n_samples = samples_per_mesh_period * n_mesh
    term = diffrax.ODETerm(lambda t, y, args: model.vector_field(t, y, args))

    # ---------------------------------------------------------------- one solve
    rate = model.decay_rate_per_rad(omega)
    if n_transient_periods is None:
        n_min = int(math.ceil(min_transient_mesh_periods / n_mesh))
        n_max = max(n_min, int(math.ceil(max_transient_mesh_periods / n_mesh)))
        n_auto = jnp.ceil(math.log(1.0 / transient_decay) / (rate * period))
        n_tr = jnp.clip(jnp.nan_to_num(n_auto, nan=n_max, posinf=n_max), n_min, n_max)
    else:
        n_max = int(n_transient_periods)
        n_tr = jnp.asarray(float(n_max))
    t_tr = n_tr * period
    t_end = t_tr + n_measured_periods * period
    # samples at mid-cells: never exactly on an engagement angle (spur engagement is at 0)
    ts = t_tr + (jnp.arange(n_measured_periods * n_samples) + 0.5) * (period / n_samples)
    ctrl = _controller(rtol, atol, jumps, period)
    if start not in ("auto", "initial"):
        raise SimulationError("start", start, 'must be "auto" or "initial"')
    if y0 is None:
        y0 = model.transient_start(omega) if start == "auto" else model.initial_state(omega)
    sol = diffrax.diffeqsolve(
        term, solver, t0=0.0, t1=t_end, dt0=None, y0=y0, args=omega,
        saveat=diffrax.SaveAt(ts=ts),
        stepsize_controller=ctrl,
        max_steps=max_steps, adjoint=adjoint, throw=False,
    )
    ys = sol.ys
    ok = (sol.result == diffrax.RESULTS.successful) & jnp.all(jnp.isfinite(ys))
    steps = sol.stats["num_steps"]
    out = jax.vmap(lambda t, yy: model.outputs(t, yy, omega))(ts, ys)
    per = lambda a: a.reshape(n_measured_periods, n_samples)  # noqa: E731
    fd, dte = per(out.mesh_force_N), per(out.dte_m)
    cols = [fd.max(1), fd.min(1), dte.max(1), dte.min(1)]
    acc = None if out.accel_m_s2 is None else per(out.accel_m_s2)
    if acc is not None:
        cols += [acc.max(1), acc.min(1)]
    ext = jnp.stack(cols, axis=1)  # (periods, extrema)
    sig = (ts, out.mesh_force_N, out.dte_m, out.accel_m_s2)
    f_s = model.static_force_N
    f_max = jnp.max(ext[:, 0])
    f_min = jnp.min(ext[:, 1])
    dte_ptp = jnp.max(ext[:, 2]) - jnp.min(ext[:, 3])
    has_acc = ext.shape[1] > 4
    acc_ptp = jnp.max(ext[:, 4]) - jnp.min(ext[:, 5]) if has_acc else jnp.asarray(jnp.nan)
    # convergence: last two periods; forces / F_S, DTE / DTE ptp, accel / accel ptp (ptp
    # floored at 1e-3 of the largest |value|, for signals that hardly vary)
    dte_s = jnp.maximum(dte_ptp, 1e-3 * jnp.max(jnp.abs(ext[:, 2:4])))
    acc_s = jnp.maximum(acc_ptp, 1e-3 * jnp.max(jnp.abs(ext[:, 4:6]))) if has_acc else None
    scales = [f_s, f_s, dte_s, dte_s] + ([acc_s, acc_s] if has_acc else [])
    scales = jnp.stack([jnp.maximum(jnp.abs(s), 1e-300) for s in scales])
    if n_measured_periods >= 2:
        conv = jnp.max(jnp.abs(ext[-1] - ext[-2]) / scales)
        # geometric extrapolation over the slowest mode the outputs see: a component
        # decaying like mu^k per period changes by |1 - mu| of what is left of it, so the
        # change between the last two periods divided by |1 - mu| bounds the distance to
        # the steady state (the change of faster components is over-counted: safe side)
        slow = model.slowest_output_mode()
        if slow is not None and extrapolate:
            w_s, z_s = slow
            arg = jnp.where(jnp.isfinite(w_s), w_s, 0.0) * period / omega
            wd = arg * jnp.sqrt(jnp.clip(1.0 - z_s**2, 0.0, 1.0))
            decay = jnp.exp(-z_s * arg)
            gap = jnp.sqrt((1.0 - decay * jnp.cos(wd)) ** 2 + (decay * jnp.sin(wd)) ** 2)
            factor = jnp.where(jnp.isfinite(w_s), 1.0 / jnp.clip(gap, 1e-12, 1.0), 1.0)
            conv = conv * factor
    else:
        conv = jnp.asarray(jnp.inf)
    finite = jnp.isfinite(f_max) & jnp.isfinite(f_min) & jnp.isfinite(dte_ptp)
    ok = ok & finite
    nan = jnp.asarray(jnp.nan)
    bad = lambda v: jnp.where(ok, v, nan)
    signals = None
    if save_signals:
        ts, fd, dte, acc = sig
        signals = Signals(
            theta_rad=ts.reshape(-1), mesh_force_N=fd.reshape(-1), dte_m=dte.reshape(-1),
            accel_m_s2=None if acc is None else acc.reshape(-1),
        )
    return SimulationResult(
        speed_rad_s=omega,
        max_mesh_force_N=bad(f_max),
        min_mesh_force_N=bad(f_min),
        dynamic_factor=bad(f_max / f_s),
        dte_ptp_m=bad(dte_ptp),
        accel_ptp_m_s2=bad(acc_ptp) if has_acc else nan,
        contact_loss=ok & (f_min <= 0.0),
        convergence=jnp.where(ok, conv, jnp.inf),
        # undamped (decay rate 0): the free response of the start never dies, so no
        # transient reaches the steady state -- never "converged" (see the docstring)
        converged=ok & (conv <= convergence_tol) & (rate > 0),
        solver_ok=ok,
        n_steps=steps,
        transient_periods=n_tr,
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
