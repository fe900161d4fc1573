"""Periodic steady state without transients: shooting with the monodromy matrix.

The te (Eq. (42) / sdof Eq. (20)) and perturbation (Eq. (48a) / sdof Eq. (47a))
formulations are linear time-periodic systems in the angle ``theta = Omega1 t``::

    y' = A(theta) y + b(theta),      A, b periodic with the excitation period P,

so one period fixes the steady state. With ``y_p`` the solution from the start ``y_s``
(``model.initial_state``) and ``Phi`` the monodromy matrix (``Phi' = A Phi``, ``Phi(0) = I``)::

    (I - Phi) y* = y_p(P) - Phi y_s                                   (shooting)

``Phi`` and ``y_p`` come from *one* ``diffeqsolve`` over one period of the augmented state
``(y, Phi)``, ``Phi' = (df/dy) Phi`` by forward-mode linearisation of the model's
``vector_field`` (exact for an affine vector field; the same matrix as
:func:`gearjax.dynamics.stability.monodromy`), with one error control and the model's jump
angles (:func:`gearjax.dynamics.integrate.integrate`). Where the linear orbit's
force turns tensile, the contact law (:func:`gearjax.gears.contact.te_contact`) makes te
and perturbation piecewise linear like the reference.

The reference formulation (Eq. (14) / (16)) is piecewise linear in ``y``: the same
step is a Newton iteration ``y <- y + (I - Phi(y))^-1 (y_P(y) - y)`` on the periodicity
residual (quadratic convergence while the set of loaded cells along the orbit stays the
same; ``max_newton`` iterations, stopped when the step is below ``newton_tol`` on the
dimensionless state). Where teeth separate the orbit found may be unstable or not the one
a transient reaches: :func:`steady_sweep` recomputes those speeds with
:func:`gearjax.dynamics.simulate.simulate` from the quasi-static start, as ``sweep`` does.

Metrics: ``y*`` is measured by :func:`gearjax.dynamics.simulate.simulate` with no
transient, so every metric means what it means there and ``convergence`` measures how
periodic ``y*`` is. ``converged`` also requires the Floquet spectral radius
``rho = max |mu(Phi)| < 1`` (an unstable orbit is never what a transient shows) and, for the
reference, the Newton iteration to have converged. ``rho`` is estimated by normalised
squaring of ``Phi`` (``log rho = lim 2^-m log ||Phi^(2^m)||``), matrix products only.

Shooting rather than harmonic balance for jumping stiffness: ``k(theta)`` of a spur pair is
a square wave whose Fourier coefficients decay like 1/h (Gibbs errors of O(1/H) in the peak
force), while shooting integrates across the jumps exactly, with an error of the
integration tolerance times ``1/(1 - rho)``, at the cost of ``n + 1`` columns over one period.
"""

from __future__ import annotations

import math
import time

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..linalg import solve as dense_solve
from .progress import AbstractProgressMeter, NoProgressMeter, check_meter
from .batching import over_speeds, sequential_for
from .results import FLAG_FIELDS, METRIC_FIELDS, SweepResult, empty_metrics
from .integrate import integrate, jump_controller
from .orbit import RESULTS, Orbit, measure, metric_status
from .simulate import SimulationError, SimulationResult
from .solvers import AbstractOrbitSolver, Fallback, SweepRun
from .sweep import Transient, sweep
from .stability import check_speeds, spectral_radius_of  # noqa: F401 (re-exported)

__all__ = [
    "periodic_state",
    "period_and_monodromy",
    "period_end",
    "PeriodicState",
    "steady_state",
    "SteadyStateResult",
    "steady_sweep",
    "orbit_of",
    "spectral_radius_of",
    "Shooting",
    "period_map",
    "shooting_solver",
]

# Shooting solver: Dopri8 at rtol 1e-9 (benchmarks/bench_work_precision.py: the periodic
# start is amplified by 1/(1 - rho), so the single period is integrated tighter than a
# transient needs).
_SHOOT_DEFAULT = ("dopri8", 1e-9, 1e-11)
# a looser requested accuracy keeps these (Shooting.for_transient)
_SHOOT_RTOL, _SHOOT_ATOL = _SHOOT_DEFAULT[1:]
# default chunk of steady_sweep: speeds x n^2 monodromy entries per chunk (3D rig: 2 speeds)
_CHUNK_ELEMENTS = 80_000


class PeriodicState(eqx.Module):
    """Periodic start of the steady response at one speed (scalars / (n,) arrays; a
    leading speed axis after vmap).

    Attributes
    ----------
    y0 : (n,) model state at theta = 0 on the periodic orbit (the model's dimensionless
        state).
    spectral_radius : max |Floquet multiplier| of the monodromy matrix at ``y0``
        (< 1: the periodic orbit attracts; >= 1: parametric instability).
    residual : norm of the last shooting step (dimensionless state).
    newton_iterations : shooting steps taken (te/perturbation while contact holds: 2, one
        to solve and one to verify).
    ok : the period integrations succeeded and ``y0`` is finite.
    n_steps : integration steps of all shooting solves.
    """

    y0: jax.Array
    spectral_radius: jax.Array
    residual: jax.Array
    newton_iterations: jax.Array
    ok: jax.Array
    n_steps: jax.Array


class SteadyStateResult(eqx.Module):
    """:class:`gearjax.dynamics.simulate.SimulationResult` of the periodic orbit plus the
    :class:`~gearjax.dynamics.orbit.Orbit` it was measured on (``orbit``)."""

    result: SimulationResult
    orbit: Orbit


def _one_period(model, omega, y_start, solver, rtol, atol, max_steps):
    """(y(P), Phi(P), ok, steps): the state and the monodromy matrix of the linearised
    flow after one excitation period from ``y_start`` (one diffeqsolve)."""
    return period_map(model, omega, y_start, solver=solver, rtol=rtol, atol=atol,
                      max_steps=max_steps)


def period_map(model, omega, y_start, *, solver, rtol, atol, max_steps,
               speed_column: bool = False, jacobian: bool = True):
    """``(y(P), J, ok, steps)``: the state after one excitation period ``P`` from
    ``y_start`` at pinion speed ``omega`` (rad/s) and its Jacobian, by one diffeqsolve of
    the state with its variational equations (forward-mode linearisation of the model's
    ``vector_field``: ``Phi' = (df/dy) Phi``, ``Phi(0) = I``). ``J`` is the monodromy
    ``Phi(P) = dy(P)/dy(0)`` (n, n), or with ``speed_column`` the (n, n + 1) matrix
    ``[Phi(P) | dy(P)/dOmega]`` whose last column (s/rad per unit of state) obeys
    ``s' = (df/dy) s + df/dOmega``, ``s(0) = 0``: the shooting residual's derivative in speed
    for pseudo-arclength continuation (:mod:`gearjax.dynamics.arclength`); without
    ``jacobian``, ``J`` is None and only the state is integrated. All columns share the
    state's error control and the model's jump angles (``solver``, ``rtol``, ``atol``,
    ``max_steps`` as :func:`periodic_state`). ``ok``: the solve succeeded with finite
    values; ``steps``: its steps."""
    if not jacobian:
        sol = integrate(lambda t, y, args: model.vector_field(t, y, args), solver,
                        jump_controller(model, rtol, atol), 0.0, float(model.period_rad),
                        y_start, omega, saveat=diffrax.SaveAt(t1=True), max_steps=max_steps)
        y_p = sol.ys[-1]
        return y_p, None, (sol.result == diffrax.RESULTS.successful) & jnp.all(
            jnp.isfinite(y_p)), sol.stats["num_steps"]
    n = y_start.shape[0]
    k = n + 1 if speed_column else n
    dw = jnp.zeros(k, dtype=y_start.dtype).at[n].set(1.0) if speed_column else None

    def vf(t, state, args):
        y, jac = state
        if speed_column:
            fy, lin = jax.linearize(lambda yy, ww: model.vector_field(t, yy, ww), y, args)
            return fy, jax.vmap(lin, in_axes=(1, 0), out_axes=1)(jac, dw)
        fy, lin = jax.linearize(lambda yy: model.vector_field(t, yy, args), y)
        return fy, jax.vmap(lin, in_axes=1, out_axes=1)(jac)

    jac0 = jnp.eye(n, k, dtype=y_start.dtype)
    sol = integrate(vf, solver, jump_controller(model, rtol, atol), 0.0,
                    float(model.period_rad), (y_start, jac0), omega,
                    saveat=diffrax.SaveAt(t1=True), max_steps=max_steps,
                    adjoint=diffrax.ForwardMode())
    y_p, jac = sol.ys[0][-1], sol.ys[1][-1]
    ok = (sol.result == diffrax.RESULTS.successful) & jnp.all(jnp.isfinite(jac)) & jnp.all(
        jnp.isfinite(y_p))
    return y_p, jac, ok, sol.stats["num_steps"]


def shooting_solver(solver=None, rtol=None, atol=None):
    """``(solver, rtol, atol)`` of a shooting period integration: the given ones, None
    replaced by the shooting's defaults (Dopri8, 1e-9, 1e-11)."""
    name, d_rtol, d_atol = _SHOOT_DEFAULT
    solver = diffrax.Dopri8() if solver is None else solver
    return solver, (d_rtol if rtol is None else rtol), (d_atol if atol is None else atol)


def periodic_state(model, omega, *, solver=None, rtol: float | None = None,
                   atol: float | None = None, max_newton: int = 8, newton_tol: float = 1e-10,
                   max_steps: int = 1_000_000, y_start=None) -> PeriodicState:
    """Periodic start ``y*`` of the steady response at pinion speed ``omega`` (rad/s) by
    shooting (module docstring). Jit/vmap-compatible in ``omega`` and the model's arrays.

    Parameters
    ----------
    model : a model with the simulation interface of :mod:`gearjax.dynamics.simulate`.
    omega : pinion speed Omega1 (rad/s).
    solver, rtol, atol : diffrax solver and tolerances of the period integration (default
        Dopri8, 1e-9, 1e-11 on the model's dimensionless state).
    max_newton, newton_tol : Newton iterations on the periodicity residual (te and
        perturbation converge in one step while contact holds on the orbit; a second step
        verifies it).
    max_steps : step limit of each period integration.
    y_start : (n,) first Newton iterate (default the quasi-static state
        ``model.initial_state(omega)``); e.g. the periodic orbit at a neighbouring speed,
        for continuation (:mod:`gearjax.dynamics.continuation`).
    """
    solver, rtol, atol = shooting_solver(solver, rtol, atol)
    omega = jnp.asarray(omega, dtype=float)
    y_s = model.initial_state(omega) if y_start is None else jnp.asarray(y_start, dtype=float)
    n = y_s.shape[0]
    eye = jnp.eye(n, dtype=y_s.dtype)

    def step(y):
        y_p, phi, ok, steps = _one_period(model, omega, y, solver, rtol, atol, max_steps)
        dy = dense_solve(eye - phi, y_p - y)  # vmapped: gearjax.linalg
        # a period wholly out of contact has a free rigid-body motion: Phi has the
        # multiplier 1, I - Phi is singular and dy infinite. Stop there, and keep the last
        # finite iterate: under vmap a stopped speed's body still runs in lockstep, and a
        # period from an infinite start runs to max_steps (the 1,000-speed stall)
        finite = jnp.all(jnp.isfinite(dy))
        return (jnp.where(finite, y + dy, y), phi, ok & finite, steps,
                jnp.sqrt(jnp.sum(dy * dy)))

    y1, phi, ok, steps, res = step(y_s)
    it = jnp.ones((), dtype=jnp.int32)
    # every formulation iterates: te/perturbation converge in one step while contact holds
    # (the second step verifies it), and are piecewise linear like the reference where the
    # contact law cuts their force
    if max_newton > 1:
        def cond(c):
            y, phi, ok, steps, res, it = c
            return ok & (res > newton_tol * (1.0 + jnp.sqrt(jnp.sum(y * y)))) & (it < max_newton)

        def body(c):
            y, _, ok, steps, _, it = c
            y2, phi2, ok2, st2, res2 = step(y)
            return y2, phi2, ok & ok2, steps + st2, res2, it + 1

        y1, phi, ok, steps, res, it = jax.lax.while_loop(cond, body, (y1, phi, ok, steps, res, it))
    ok = ok & jnp.all(jnp.isfinite(y1))
    rho = spectral_radius_of(jnp.where(ok, phi, 0.0))
    nan = jnp.asarray(jnp.nan)
    return PeriodicState(
        y0=jnp.where(ok, y1, nan), spectral_radius=jnp.where(ok, rho, nan),
        residual=jnp.where(ok, res, nan), newton_iterations=it, ok=ok, n_steps=steps,
    )


def orbit_of(model, omega, ps: PeriodicState, newton_tol: float) -> Orbit:
    """The :class:`~gearjax.dynamics.orbit.Orbit` of a shooting's :class:`PeriodicState`:
    ``integration_failed`` where a period integration failed, else ``newton_failed`` where
    the last Newton step exceeds ``newton_tol (1 + |y*|)``, else ``unstable`` where the
    Floquet radius is >= 1, else ``successful``."""
    newton_ok = ps.residual <= newton_tol * (1.0 + jnp.sqrt(jnp.sum(ps.y0**2)))
    status = jnp.where(~ps.ok, RESULTS.integration_failed,
                       jnp.where(~newton_ok, RESULTS.newton_failed,
                                 jnp.where(ps.spectral_radius >= 1.0, RESULTS.unstable,
                                           RESULTS.successful))).astype(jnp.int8)
    return Orbit(state=ps.y0, omega=jnp.asarray(omega, dtype=float),
                 period_multiple=jnp.ones((), jnp.int32), residual=ps.residual,
                 floquet_radius=ps.spectral_radius, status=status, n_steps=ps.n_steps)


def period_and_monodromy(model, omega, y_start, *, solver=None, rtol: float | None = None,
                         atol: float | None = None, max_steps: int = 1_000_000):
    """``(y(P), Phi(P), ok, steps)``: the state after one excitation period from
    ``y_start`` and the monodromy matrix of the linearised flow there (the shooting's
    augmented period, one diffeqsolve; solver options as :func:`periodic_state`'s)."""
    solver, rtol, atol = shooting_solver(solver, rtol, atol)
    return _one_period(model, jnp.asarray(omega, dtype=float), y_start, solver, rtol, atol,
                       max_steps)


def period_end(model, omega, y_start, *, solver=None, rtol: float | None = None,
               atol: float | None = None, max_steps: int = 1_000_000):
    """``(y(P), ok)``: the state after one excitation period from ``y_start``, integrated
    as the shooting integrates its period (solver options as :func:`periodic_state`'s)
    without the monodromy: forward-mode derivatives of ``y(P)`` at the cost of the state
    alone."""
    solver, rtol, atol = shooting_solver(solver, rtol, atol)
    sol = integrate(model.vector_field, solver, jump_controller(model, rtol, atol), 0.0,
                    float(model.period_rad), y_start, jnp.asarray(omega, dtype=float),
                    saveat=diffrax.SaveAt(t1=True), max_steps=max_steps,
                    adjoint=diffrax.ForwardMode())
    y_p = sol.ys[-1]
    return y_p, (sol.result == diffrax.RESULTS.successful) & jnp.all(jnp.isfinite(y_p))


def steady_state(model, omega, shooting: "Shooting | None" = None, *,
                 y_start=None, periodic: PeriodicState | None = None) -> SteadyStateResult:
    """Steady-state metrics at one speed from the periodic orbit (no transient, no
    continuation: see :func:`steady_sweep` for that). Jit/vmap-compatible.

    The orbit is ``shooting``'s (:meth:`Shooting.orbit`, default :class:`Shooting`,
    from ``y_start``, default the quasi-static state); the metrics are
    :func:`~gearjax.dynamics.orbit.measure`'s over ``shooting.n_measured_periods`` periods
    started on it. ``converged`` = the measured periods are periodic to
    ``convergence_tol`` and the orbit's status is ``successful`` (found, Newton converged,
    Floquet radius < 1); where a period integration failed the metrics are NaN.
    ``periodic``: the orbit's :class:`PeriodicState` where the caller has it already (e.g.
    with its own derivative rule, :mod:`gearjax.design.orbits`; its status read by
    :func:`orbit_of`), else the shooting's.
    """
    shooting = Shooting() if shooting is None else shooting
    orbit = (shooting.orbit(model, omega, y_start=y_start) if periodic is None
             else orbit_of(model, omega, periodic, shooting.newton_tol))
    res = measure(model, orbit, shooting.measured())
    good = (orbit.status != RESULTS.integration_failed) & res.solver_ok
    nan = jnp.asarray(jnp.nan)
    bad = lambda v: jnp.where(good, v, nan)  # noqa: E731
    converged = res.converged & good & (orbit.status == RESULTS.successful)
    res = eqx.tree_at(
        lambda r: (r.max_mesh_force_N, r.min_mesh_force_N, r.dynamic_factor, r.dte_ptp_m,
                   r.accel_ptp_m_s2, r.converged, r.period_multiple, r.solver_ok,
                   r.contact_loss, r.back_contact, r.n_steps, r.mesh_force_orders_N,
                   r.dte_orders_m, r.accel_orders_m_s2),
        res,
        (bad(res.max_mesh_force_N), bad(res.min_mesh_force_N), bad(res.dynamic_factor),
         bad(res.dte_ptp_m), bad(res.accel_ptp_m_s2), converged,
         jnp.where(converged, 1, 0).astype(res.period_multiple.dtype), good,
         res.contact_loss & good, res.back_contact & good, res.n_steps + orbit.n_steps,
         bad(res.mesh_force_orders_N),
         bad(res.dte_orders_m), bad(res.accel_orders_m_s2)),
    )
    return SteadyStateResult(result=res, orbit=orbit)


# ---------------------------------------------------------------------- sweeps
@eqx.filter_jit
def _steady_batch(model, speeds, shooting):
    def one(w):
        out = steady_state(model, w, shooting)
        r = out.result
        return tuple(getattr(r, f) for f in METRIC_FIELDS) + (out.orbit.floquet_radius,
                                                               out.orbit.status)
    return over_speeds(one, speeds, sequential=sequential_for(model))


def steady_sweep(model, speeds_rad_s, shooting: "Shooting | None" = None, *,
                 chunk_size: int | None = None,
                 progress: AbstractProgressMeter = NoProgressMeter(),
                 continuation: Transient | None = Transient()) -> SweepResult:
    """Steady state over pinion speeds by shooting, the speeds it does not solve by the
    transient: :func:`gearjax.dynamics.sweep.sweep` with
    ``Fallback(shooting, continuation)`` (``shooting`` None: :class:`Shooting`'s defaults;
    ``continuation`` None: the shooting alone), kept as the name earlier versions exported.

    A speed is handed on where the periodic orbit shows contact loss, is unstable
    (``spectral_radius >= 1``) or was not found (:func:`orbit_solved`): the transient from
    the quasi-static start then gives exactly what ``sweep`` computes there (after contact
    loss several attractors can coexist; a continuation started on the unstable orbit
    reached another one). ``chunk_size``: speeds per compiled call of the shooting
    (:meth:`Shooting.sweep`)."""
    shooting = Shooting() if shooting is None else shooting
    solver = shooting if continuation is None else Fallback(shooting, continuation)
    return sweep(model, speeds_rad_s, solver, chunk_size=chunk_size, progress=progress)


def _shooting_sweep(model, speeds_rad_s, shooting: "Shooting", chunk_size: int | None,
                    progress: AbstractProgressMeter) -> SweepResult:
    """:meth:`Shooting.sweep`: the periodic orbit and its metrics at every speed, chunk by
    chunk (one compilation per chunk shape; the speeds of a chunk mapped on a CPU, vmapped
    elsewhere: :mod:`gearjax.dynamics.batching`). ``chunk_size`` default: a chunk holds
    about 80 000 monodromy entries (sdof: all speeds; the 3D rig with 182 states: 2
    speeds), as large batched monodromy solves are memory-bound
    (``benchmarks/results/code_notes.md``, section gearjax.dynamics.steady); on a CPU, where
    the speeds are mapped, it sets how often progress is reported. ``transient_periods`` is
    0; ``n_steps`` counts shooting and measuring steps."""
    speeds = np.asarray(speeds_rad_s, dtype=float).reshape(-1)
    check_speeds(speeds)  # and float64
    model.require_structure()
    if chunk_size is None:
        # the batched monodromy (chunk x n x n per stage) must stay cache-sized
        # (benchmarks/results/code_notes.md, section gearjax.dynamics.steady)
        n = int(model.state_size)
        chunk = int(min(speeds.size, max(1, _CHUNK_ELEMENTS // (n * n))))
    else:
        chunk = int(chunk_size)
    if chunk < 1:
        raise SimulationError("chunk_size", chunk_size, "must be a positive integer")
    n_chunks = int(math.ceil(speeds.size / chunk))
    order = np.argsort(speeds, kind="stable")
    padded = np.concatenate([order, np.full(n_chunks * chunk - speeds.size, order[-1])])
    out = empty_metrics(speeds.size)
    rho = np.full(speeds.size, np.nan)
    orbit_status = np.zeros(speeds.size, dtype=np.int8)
    task = f"steady-state sweep {model.formulation}"
    check_meter(progress).start(task, speeds.size, f"{n_chunks} chunk(s) of {chunk} speed(s)")
    t_start = time.perf_counter()
    for c in range(n_chunks):
        sel = padded[c * chunk:(c + 1) * chunk]
        t0 = time.perf_counter()
        res = jax.device_get(_steady_batch(model, jnp.asarray(speeds[sel]), shooting))
        for f, v in zip(METRIC_FIELDS, res[:len(METRIC_FIELDS)]):
            out[f][sel] = np.asarray(v, dtype=float)
        rho[sel] = np.asarray(res[-2], dtype=float)
        orbit_status[sel] = np.asarray(res[-1])
        progress.update(task, min(speeds.size, (c + 1) * chunk), speeds.size,
                        f"chunk {c + 1}/{n_chunks}: {len(set(sel.tolist()))} speeds in "
                        f"{time.perf_counter() - t0:.2f} s", elapsed_s=time.perf_counter() - t_start)
    out["transient_periods"][:] = 0.0
    formulation = model.formulation.name
    for f in FLAG_FIELDS:
        out[f] = out[f] > 0
    out["n_steps"] = out["n_steps"].astype(np.int64)
    measured = metric_status(out["solver_ok"], out["converged"])
    status = np.where(orbit_status == RESULTS.successful, measured, orbit_status)
    return SweepResult(**out, formulation=formulation, spectral_radius=rho,
                       status=status.astype(np.int8),
                       solver=np.full(speeds.size, "steady"))


def orbit_solved(contact_loss, spectral_radius, converged) -> np.ndarray:
    """Per speed, whether a shooting orbit is the model's steady state: contact kept, stable
    (Floquet ``spectral_radius < 1``) and converged; :func:`steady_sweep` continues the
    other speeds by the transient, as :class:`Shooting` hands them on in a ``Fallback``."""
    stable = np.asarray(spectral_radius, dtype=float) < 1.0
    return ~np.asarray(contact_loss, dtype=bool) & stable & np.asarray(converged, dtype=bool)


class Shooting(AbstractOrbitSolver):
    """Newton shooting on the periodicity residual ``y(P) - y(0)`` (module docstring),
    then :func:`~gearjax.dynamics.simulate.simulate` over ``n_measured_periods`` from the
    periodic state: :func:`steady_sweep` without its continuation. A speed is solved where
    the orbit keeps contact, is stable (Floquet radius < 1) and converged; compose with
    :class:`~gearjax.dynamics.solvers.Fallback` to hand the others to the transient.

    ``rtol``/``atol``: the shooting period's tolerances (None: 1e-9 / 1e-11, Dopri8);
    ``measure_rtol``/``measure_atol``: the measured periods' (None: ``simulate``'s);
    ``max_newton``, ``newton_tol``, ``convergence_tol``, ``n_measured_periods``,
    ``samples_per_mesh_period``, ``max_steps``: as :func:`steady_state` and ``simulate``.
    :meth:`for_transient` reads a transient's tolerances the one way every command does.
    """

    rtol: float | None = None
    atol: float | None = None
    measure_rtol: float | None = None
    measure_atol: float | None = None
    max_newton: int = 8
    newton_tol: float = 1e-10
    convergence_tol: float = 1e-3
    n_measured_periods: int = 2
    samples_per_mesh_period: int = 128
    max_steps: int = 2_000_000

    def __check_init__(self):
        if self.n_measured_periods < 2:
            raise SimulationError("n_measured_periods", self.n_measured_periods,
                                  "need >= 2 periods to measure periodicity")

    @classmethod
    def for_transient(cls, transient) -> "Shooting":
        """The shooting at the accuracy of a :class:`~gearjax.dynamics.sweep.Transient`:
        the one reading of ``--rtol`` with the shooting (``sweep``, ``optimise``,
        ``harris-map``). The transient's ``rtol``/``atol`` become the measured periods'
        (``measure_*``); the shooting's period integration takes them only where they are
        tighter than its own 1e-9 / 1e-11: its error reaches the periodic start amplified by
        1 / (1 - rho) (an oscillator at resonance, zeta 0.005, rho 0.969: 1.1e-3 error in
        the peak-to-peak with the shooting at rtol 1e-4, 2.1e-5 with it at 1e-9 and the
        measured periods at 1e-4; ``tests/test_steady.py``). The measuring options
        (periods, samples, convergence tolerance, step limit) pass unchanged; the
        transient's own (its length, decay, start) do not apply."""
        t = transient
        tighter = lambda v, own: v if v is not None and v < own else None  # noqa: E731
        return cls(rtol=tighter(t.rtol, _SHOOT_RTOL), atol=tighter(t.atol, _SHOOT_ATOL),
                   measure_rtol=t.rtol, measure_atol=t.atol,
                   convergence_tol=t.convergence_tol, n_measured_periods=t.n_measured_periods,
                   samples_per_mesh_period=t.samples_per_mesh_period, max_steps=t.max_steps)

    def orbit(self, model, omega, y_start=None) -> Orbit:
        """The periodic orbit at ``omega`` (rad/s) by Newton shooting from ``y_start``
        (default the quasi-static state): :func:`periodic_state` with these options, its
        status as :func:`orbit_of` reads it. Jit/vmap-compatible."""
        ps = periodic_state(model, omega, rtol=self.rtol, atol=self.atol,
                            max_newton=self.max_newton, newton_tol=self.newton_tol,
                            y_start=y_start)
        return orbit_of(model, omega, ps, self.newton_tol)

    def measured(self) -> Transient:
        """The measuring options of this shooting as a
        :class:`~gearjax.dynamics.sweep.Transient` (for :func:`~gearjax.dynamics.orbit.measure`)."""
        return Transient(n_measured_periods=self.n_measured_periods, rtol=self.measure_rtol,
                         atol=self.measure_atol, samples_per_mesh_period=self.samples_per_mesh_period,
                         convergence_tol=self.convergence_tol, max_steps=self.max_steps)

    def orbit_metrics(self, model, omega, adjoint=None) -> SimulationResult:
        """The metrics at one speed ``omega`` (rad/s) from the periodic orbit
        (:func:`steady_state`); jit-, vmap- and differentiable in forward mode only.
        Raises :class:`~gearjax.errors.SimulationError` for a reverse-mode ``adjoint``."""
        if isinstance(adjoint, diffrax.RecursiveCheckpointAdjoint):
            raise SimulationError("adjoint", type(adjoint).__name__,
                                  "the shooting differentiates in forward mode only")
        return steady_state(model, omega, self).result

    def solved(self, result: SweepResult) -> np.ndarray:
        return orbit_solved(result.contact_loss, result.spectral_radius, result.converged)

    def sweep(self, model, speeds: np.ndarray, run: SweepRun) -> SweepResult:
        if run.devices is not None or jax.process_count() > 1:
            raise SimulationError("devices", run.devices, "shooting runs on one device of one "
                                  "process; use Transient() to shard over devices or hosts")
        res = _shooting_sweep(model, speeds, self, run.chunk_size, run.progress)
        if run.sink is not None:
            run.sink(res)
        return res
