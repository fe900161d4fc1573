"""The compiled steps of the continuations in speed (:mod:`gearjax.dynamics.continuation`,
natural parameter; :mod:`gearjax.dynamics.arclength`, pseudo-arclength): the Newton
corrector on the bordered shooting system, the measurement of an orbit and the transient
that settles onto an attractor. Each is one compiled program per model (speeds, states and
the border are arrays), called from a host loop over points.

Bordered shooting system. The unknowns are the periodic start ``y`` (the model's
dimensionless state at ``theta = 0``) and the speed as ``p = Omega / Omega_s``
(``Omega_s``: the speed scale, rad/s, that weighs speed against state in the arclength
norm). With ``phi(y, Omega)`` the state after one excitation period ``P`` (a fixed angle:
the speed enters the vector field only) and a border row ``c`` with its predictor ``u_p``::

    G(y, p) = phi(y, p Omega_s) - y = 0                        (periodicity, n equations)
    c . ((y, p) - u_p) = 0                                     (one more)

Newton on both: ``[[Phi - I, Omega_s dphi/dOmega], [c]] du = -(G, c . (u - u_p))`` with
``Phi`` the monodromy and ``dphi/dOmega`` integrated with the orbit
(:func:`gearjax.dynamics.steady.period_map`, ``speed_column``; forward-mode linearisation
of the vector field in state and speed), solved by :func:`gearjax.linalg.solve`. With
``c = (0, ..., 0, 1)`` the speed is fixed (natural parameter: the Newton shooting of
:func:`gearjax.dynamics.steady.periodic_state`, step for step); with ``c`` the unit tangent
at the last point and ``u_p`` that point plus a step along it, pseudo-arclength (Keller).
Stops when the step is below ``newton_tol (1 + |y|)``, as the shooting does. The tangent of
the solution curve at the result solves ``[[Phi - I, Omega_s dphi/dOmega], [c]] t = (0, 1)``
(Jacobian of the last iterate), normalised: ``t . c > 0`` keeps the direction of travel.
"""

from __future__ import annotations

import math

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..errors import SimulationError
from ..linalg import lu_factor, lu_solve
from ..linalg import solve as dense_solve
from .integrate import integrate, jump_controller
from .results import METRIC_FIELDS
from .orbit import RESULTS, Orbit
from .orbit import measure as orbit_measure
from .simulate import default_solver, jump_density, transient_periods
from .steady import period_map, shooting_solver
from .sweep import Transient

__all__ = ["CorrectorOptions", "Correction", "correct", "Linearisation", "linearise",
           "tangent", "Chord", "chord", "measure", "settle"]


class CorrectorOptions(eqx.Module):
    """Options of :func:`correct`.

    ``max_newton``: Newton iterations; ``newton_tol``: stop when the step norm (state and
    ``p``) is below ``newton_tol (1 + |y|)`` (both data: changing them compiles nothing);
    ``rtol``, ``atol``: the period integration (None: the shooting's Dopri8 at 1e-9 /
    1e-11); ``max_steps``: its step limit.
    """

    max_newton: int = 8
    newton_tol: float = 1e-10
    rtol: float | None = None
    atol: float | None = None
    max_steps: int = 200_000

    def __check_init__(self):
        if int(self.max_newton) != self.max_newton or self.max_newton < 1:
            raise SimulationError("max_newton", self.max_newton, "must be an integer >= 1")
        if not (math.isfinite(self.newton_tol) and self.newton_tol > 0):
            raise SimulationError("newton_tol", self.newton_tol, "must be a finite number > 0")


class Correction(eqx.Module):
    """What :func:`correct` returns (arrays).

    Attributes
    ----------
    y : (n,) periodic start at theta = 0 (last iterate).
    omega : pinion speed Omega1 (rad/s) of the last iterate.
    phi : (n, n) monodromy matrix at the previous iterate (its Floquet multipliers).
    tangent : (n + 1,) unit tangent ``(dy, dp)`` of the solution curve, ``tangent . c > 0``.
    residual : norm of the last Newton step.
    iterations : Newton iterations done.
    converged : the integrations succeeded, the values are finite and the last step met
        the tolerance.
    n_steps : integration steps of all iterations.
    """

    y: jax.Array
    omega: jax.Array
    phi: jax.Array
    tangent: jax.Array
    residual: jax.Array
    iterations: jax.Array
    converged: jax.Array
    n_steps: jax.Array


def correct(model, y_start, omega_start, u_predictor, border, speed_scale,
            options: CorrectorOptions = CorrectorOptions()) -> Correction:
    """Newton on the bordered shooting system (module docstring) from ``(y_start,
    omega_start)`` (rad/s).

    Parameters
    ----------
    model : an :class:`~gearjax.models.base.AbstractGearModel`.
    y_start, omega_start : first iterate: (n,) state at theta = 0 and speed (rad/s).
    u_predictor : (n + 1,) the border's predictor ``(y, p)``, ``p = Omega / speed_scale``.
    border : (n + 1,) the border row ``c``; ``(0, ..., 0, 1)`` fixes the speed at
        ``u_predictor[-1] * speed_scale``.
    speed_scale : ``Omega_s`` (rad/s).
    options : :class:`CorrectorOptions`.
    """
    return _correct(model, jnp.asarray(y_start, dtype=float),
                    jnp.asarray(omega_start, dtype=float), jnp.asarray(u_predictor, dtype=float), jnp.asarray(border, dtype=float),
                    jnp.asarray(speed_scale, dtype=float), jnp.asarray(options.max_newton, dtype=int),
                    jnp.asarray(options.newton_tol, dtype=float),
                    (options.rtol, options.atol, options.max_steps))


@eqx.filter_jit
def _correct(model, y_start, omega_start, u_predictor, border, s, max_newton, newton_tol,
             static) -> Correction:
    rtol, atol, max_steps = static
    solver, rtol, atol = shooting_solver(None, rtol, atol)
    n = y_start.shape[0]
    eye = jnp.eye(n, dtype=float)

    def jacobian(u):
        y_p, jac, ok, steps = period_map(model, u[n] * s, u[:n], solver=solver, rtol=rtol,
                                         atol=atol, max_steps=max_steps,
                                         speed_column=True)
        a = jnp.concatenate([jac[:, :n] - eye, jac[:, n:] * s], axis=1)  # (n, n + 1)
        return y_p - u[:n], a, jac[:, :n], ok, steps

    def step(u):
        g, a, phi, ok, steps = jacobian(u)
        m = jnp.concatenate([a, border[None, :]], axis=0)
        r = jnp.concatenate([g, (border @ (u - u_predictor))[None]])
        du = dense_solve(m, -r)
        u_new = u + du
        good = ok & jnp.all(jnp.isfinite(du)) & (u_new[n] > 0)
        # a failed step keeps the last finite iterate (a period from an infinite start
        # would run to max_steps)
        return jnp.where(good, u_new, u), a, phi, good, steps, jnp.sqrt(jnp.sum(du * du))

    def small(u, res):
        return res <= newton_tol * (1.0 + jnp.sqrt(jnp.sum(u[:n] ** 2)))

    u0 = jnp.concatenate([y_start, omega_start[None] / s])
    u, a, phi, ok, steps, res = step(u0)
    it = jnp.ones((), dtype=jnp.int32)

    def cond(c):
        u, _, _, ok, _, res, it = c
        return ok & ~small(u, res) & (it < max_newton)

    def body(c):
        u, _, _, _, steps, _, it = c
        u2, a2, phi2, ok2, st2, res2 = step(u)
        return u2, a2, phi2, ok2, steps + st2, res2, it + 1

    u, a, phi, ok, steps, res, it = jax.lax.while_loop(
        cond, body, (u, a, phi, ok, steps, res, it))
    rhs = jnp.zeros(n + 1, dtype=float).at[n].set(1.0)
    t = dense_solve(jnp.concatenate([a, border[None, :]], axis=0), rhs)
    t = t / jnp.sqrt(jnp.sum(t * t))
    converged = ok & small(u, res) & jnp.all(jnp.isfinite(t))
    return Correction(y=u[:n], omega=u[n] * s, phi=phi, tangent=t, residual=res,
                      iterations=it, converged=converged, n_steps=steps)


class Linearisation(eqx.Module):
    """The bordered system's rows at one point (:func:`linearise`; arrays).

    Attributes
    ----------
    residual : (n,) ``G = y(P) - y``.
    jacobian : (n, n + 1) ``[Phi - I | Omega_s dy(P)/dOmega]``.
    phi : (n, n) the monodromy matrix (its eigenvalues: the Floquet multipliers).
    ok : the integration succeeded with finite values.
    n_steps : its steps.
    """

    residual: jax.Array
    jacobian: jax.Array
    phi: jax.Array
    ok: jax.Array
    n_steps: jax.Array


def linearise(model, y, omega, speed_scale, options: CorrectorOptions = CorrectorOptions()
              ) -> Linearisation:
    """The residual and Jacobian of the bordered system at ``(y, omega)`` (rad/s): one
    period of the state with its ``n + 1`` variational columns."""
    return _linearise(model, jnp.asarray(y, dtype=float), jnp.asarray(omega, dtype=float),
                      jnp.asarray(speed_scale, dtype=float),
                      (options.rtol, options.atol, options.max_steps))


@eqx.filter_jit
def _linearise(model, y, omega, s, static) -> Linearisation:
    rtol, atol, max_steps = static
    solver, rtol, atol = shooting_solver(None, rtol, atol)
    n = y.shape[0]
    y_p, jac, ok, steps = period_map(model, omega, y, solver=solver, rtol=rtol, atol=atol,
                                     max_steps=max_steps, speed_column=True)
    a = jnp.concatenate([jac[:, :n] - jnp.eye(n), jac[:, n:] * s], axis=1)
    return Linearisation(residual=y_p - y, jacobian=a, phi=jac[:, :n], ok=ok, n_steps=steps)


def tangent(jacobian, orientation):
    """The unit tangent ``t`` of the solution curve: ``jacobian t = 0`` with
    ``orientation . t > 0`` (solves ``[jacobian; orientation] t = (0, ..., 0, 1)``; host
    NumPy). NaN where the bordered matrix is singular."""
    a = np.asarray(jacobian, dtype=float)
    m = np.concatenate([a, np.asarray(orientation, dtype=float)[None, :]], axis=0)
    rhs = np.zeros(m.shape[0])
    rhs[-1] = 1.0
    try:
        t = np.linalg.solve(m, rhs)
    except np.linalg.LinAlgError:
        return np.full(m.shape[0], np.nan)
    return t / np.linalg.norm(t)


class Chord(eqx.Module):
    """What :func:`chord` returns: ``y``, ``omega`` (rad/s) of the last iterate, the norm
    of its last step (``residual``), ``iterations``, ``converged`` and the integration
    steps ``n_steps``."""

    y: jax.Array
    omega: jax.Array
    residual: jax.Array
    iterations: jax.Array
    converged: jax.Array
    n_steps: jax.Array


def chord(model, y_start, omega_start, u_predictor, border, jacobian, speed_scale,
          options: CorrectorOptions = CorrectorOptions(), contraction: float = 0.7) -> Chord:
    """The chord (simplified Newton) corrector of the bordered system (module docstring)
    with a fixed ``jacobian`` (n, n + 1) (e.g. the last point's, :func:`linearise`): each
    iteration integrates the state alone over one period and solves with the one LU of
    ``[jacobian; border]``. Converges linearly, at a rate that shrinks with the step; stops
    (not converged) after ``options.max_newton`` iterations, or where a step is not at
    most ``contraction`` times the previous one (the predictor too far for the Jacobian).
    """
    return _chord(model, jnp.asarray(y_start, dtype=float), jnp.asarray(omega_start, dtype=float),
                  jnp.asarray(u_predictor, dtype=float), jnp.asarray(border, dtype=float),
                  jnp.asarray(jacobian, dtype=float), jnp.asarray(speed_scale, dtype=float),
                  jnp.asarray(options.max_newton, dtype=int),
                  jnp.asarray(options.newton_tol, dtype=float),
                  jnp.asarray(contraction, dtype=float),
                  (options.rtol, options.atol, options.max_steps))


@eqx.filter_jit
def _chord(model, y_start, omega_start, u_predictor, border, jac, s, max_iter, tol, rate,
           static) -> Chord:
    rtol, atol, max_steps = static
    solver, rtol, atol = shooting_solver(None, rtol, atol)
    n = y_start.shape[0]
    lu, perm = lu_factor(jnp.concatenate([jac, border[None, :]], axis=0))

    def step(u):
        y_p, _, ok, steps = period_map(model, u[n] * s, u[:n], solver=solver, rtol=rtol,
                                       atol=atol, max_steps=max_steps, jacobian=False)
        r = jnp.concatenate([y_p - u[:n], (border @ (u - u_predictor))[None]])
        du = -lu_solve(lu, perm, r)
        u_new = u + du
        good = ok & jnp.all(jnp.isfinite(du)) & (u_new[n] > 0)
        return jnp.where(good, u_new, u), good, steps, jnp.sqrt(jnp.sum(du * du))

    def small(u, res):
        return res <= tol * (1.0 + jnp.sqrt(jnp.sum(u[:n] ** 2)))

    u0 = jnp.concatenate([y_start, omega_start[None] / s])
    u, ok, steps, res = step(u0)
    c0 = (u, ok, steps, res, jnp.asarray(jnp.inf), jnp.ones((), dtype=jnp.int32))

    def cond(c):
        u, ok, _, res, prev, it = c
        return ok & ~small(u, res) & (it < max_iter) & (res <= rate * prev)

    def body(c):
        u, _, steps, res, _, it = c
        u2, ok2, st2, res2 = step(u)
        return u2, ok2, steps + st2, res2, res, it + 1

    u, ok, steps, res, _, it = jax.lax.while_loop(cond, body, c0)
    return Chord(y=u[:n], omega=u[n] * s, residual=res, iterations=it,
                 converged=ok & small(u, res), n_steps=steps)


def measure(model, omega, y0, convergence_tol: float = 1e-3) -> tuple:
    """The metrics (:data:`gearjax.dynamics.results.METRIC_FIELDS`, in that order) of the
    orbit started at ``y0`` at speed ``omega`` (rad/s), measured the one way every solver's
    orbit is (:func:`gearjax.dynamics.orbit.measure`: two periods from ``y0`` at
    :class:`~gearjax.dynamics.sweep.Transient`'s measuring options, exact extrema at the
    stiffness jumps, :mod:`gearjax.dynamics.metrics`)."""
    return _measure(model, jnp.asarray(omega, dtype=float), jnp.asarray(y0, dtype=float),
                    Transient(convergence_tol=float(convergence_tol)))


@eqx.filter_jit
def _measure(model, omega, y0, transient):
    orbit = Orbit(state=y0, omega=omega, period_multiple=jnp.ones((), jnp.int32),
                  residual=jnp.zeros(()), floquet_radius=jnp.asarray(jnp.nan),
                  status=jnp.asarray(RESULTS.successful, jnp.int8),
                  n_steps=jnp.zeros((), jnp.int32))
    r = orbit_measure(model, orbit, transient)
    return tuple(getattr(r, f) for f in METRIC_FIELDS)


def settle(model, omega, y_start, transient_decay: float = 1e-6,
           min_transient_mesh_periods: int = 8, max_transient_mesh_periods: int = 400):
    """State at theta = k P after a transient from ``y_start`` at speed ``omega`` (rad/s),
    ``k`` from the decay rate of the slowest free mode as simulate's automatic transient
    (:func:`gearjax.dynamics.simulate.transient_periods`): where a branch ends, the
    attractor a slow run-up (or run-down) reaches."""
    return _settle(model, jnp.asarray(omega, dtype=float), jnp.asarray(y_start, dtype=float),
                   (float(transient_decay), int(min_transient_mesh_periods),
                    int(max_transient_mesh_periods)))


@eqx.filter_jit
def _settle(model, omega, y_start, static):
    transient_decay, min_transient_mesh_periods, max_transient_mesh_periods = static
    period = float(model.period_rad)
    k = transient_periods(model, omega, transient_decay, min_transient_mesh_periods,
                          max_transient_mesh_periods)
    solver, rtol, atol = default_solver(model.formulation, jump_density(model))
    sol = integrate(lambda t, y, args: model.vector_field(t, y, args), solver,
                    jump_controller(model, rtol, atol), 0.0, k * period, y_start, omega,
                    saveat=diffrax.SaveAt(t1=True), max_steps=2_000_000)
    return sol.ys[-1]
