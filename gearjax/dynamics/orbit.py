"""What a periodic solver finds at one speed, and how every solver's orbit is measured.

:class:`Orbit`: the periodic state at ``theta = 0`` (the model's dimensionless state), the
period in excitation periods, the last residual, the Floquet radius where the solver knows
it, and a :class:`RESULTS` status, as diffrax's ``RESULTS`` says why a solve ended.
:func:`measure`: the metrics of an orbit, read by
:func:`gearjax.dynamics.simulate.simulate` over measured periods started on it (no
transient): the output grid of :mod:`gearjax.dynamics.metrics` with exact extrema on both
sides of every stiffness jump, the jump and refinement windows, the mesh orders. The
shooting, the continuation and the frequency domain's fallback measure their orbits with
it; the transient measures its own end state with the same legs, inside ``simulate``.
"""

from __future__ import annotations

import enum

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

__all__ = ["RESULTS", "Orbit", "measure", "status_message", "metric_status"]


class RESULTS(enum.IntEnum):
    """Why a periodic solve at one speed ended (stored as int codes in
    :class:`Orbit.status` and :attr:`gearjax.dynamics.SweepResult.status`).

    ``successful``: a periodic orbit, stable where stability is known, measured;
    ``not_periodic``: the measured periods differ by more than the convergence tolerance
    (a transient not yet settled, or a response of another period);
    ``integration_failed``: diffrax stopped (step limit, non-finite state);
    ``newton_failed``: the shooting residual stayed above its tolerance;
    ``unstable``: the orbit's Floquet radius is >= 1 (it exists but repels);
    ``contact_lost``: the solver's equations assume contact on the whole orbit and the
    orbit's mesh force is not compressive (the frequency domain), so it is not the model's.
    """

    successful = 0
    not_periodic = 1
    integration_failed = 2
    newton_failed = 3
    unstable = 4
    contact_lost = 5


_MESSAGES = {
    RESULTS.successful: "periodic orbit found and measured",
    RESULTS.not_periodic: "the measured periods are not periodic to the convergence tolerance",
    RESULTS.integration_failed: "the integration stopped (step limit or non-finite state)",
    RESULTS.newton_failed: "the shooting Newton iteration did not converge",
    RESULTS.unstable: "the periodic orbit is unstable (Floquet radius >= 1)",
    RESULTS.contact_lost: "contact is lost on the orbit of equations that assume contact",
}


def status_message(code) -> str:
    """The sentence of a :class:`RESULTS` code."""
    return _MESSAGES[RESULTS(int(code))]


def metric_status(solver_ok, converged, spectral_radius=None) -> np.ndarray:
    """Per speed, the :class:`RESULTS` code of measured metrics (host arrays):
    ``integration_failed`` where the solve failed, else ``unstable`` where the Floquet
    ``spectral_radius`` (NaN: unknown) is >= 1, else ``not_periodic`` where not
    ``converged``, else ``successful``."""
    ok = np.asarray(solver_ok, dtype=bool)
    conv = np.asarray(converged, dtype=bool)
    out = np.where(conv, RESULTS.successful, RESULTS.not_periodic).astype(np.int8)
    if spectral_radius is not None:
        out = np.where(np.asarray(spectral_radius, dtype=float) >= 1.0, RESULTS.unstable, out)
    return np.where(ok, out, RESULTS.integration_failed).astype(np.int8)


class Orbit(eqx.Module):
    """A periodic orbit at one pinion speed (scalars / (n,) arrays; a leading speed axis
    after vmap).

    state : (n,) model state at ``theta = 0`` on the orbit (the model's dimensionless state).
    omega : pinion speed Omega1 (rad/s).
    period_multiple : the orbit's period in excitation periods (1 for a shooting orbit).
    residual : the solver's last residual (shooting: the norm of the last Newton step, in
        the dimensionless state).
    floquet_radius : largest modulus of the Floquet multipliers (NaN where the solver does
        not compute the monodromy).
    status : a :class:`RESULTS` code.
    n_steps : integration steps the solver took.
    """

    state: jax.Array
    omega: jax.Array
    period_multiple: jax.Array
    residual: jax.Array
    floquet_radius: jax.Array
    status: jax.Array
    n_steps: jax.Array

    @property
    def found(self) -> jax.Array:
        """The solver found the orbit (``status`` is not a failure to solve: an unstable
        orbit is found)."""
        return (self.status == RESULTS.successful) | (self.status == RESULTS.unstable)


def measure(model, orbit: Orbit, transient):
    """The metrics of ``orbit`` (:class:`gearjax.dynamics.simulate.SimulationResult`):
    :func:`~gearjax.dynamics.simulate.simulate` over ``transient.n_measured_periods``
    periods started on ``orbit.state`` with no transient (``transient``: a
    :class:`~gearjax.dynamics.sweep.Transient` whose measuring options are used:
    tolerances, samples per mesh period, convergence tolerance, step limit). Where the
    solver has no state (``integration_failed``) the measurement starts from the
    quasi-static state instead (its metrics are then not those of an orbit; the status
    says so).
    Jit/vmap-compatible in ``orbit`` and the model's arrays."""
    from .simulate import simulate

    omega = jnp.asarray(orbit.omega, dtype=float)
    y0 = jnp.where(orbit.status != RESULTS.integration_failed, orbit.state,
                   model.initial_state(omega))
    return simulate(model, omega, y0=y0, n_transient_periods=0,
                    n_measured_periods=transient.n_measured_periods, rtol=transient.rtol,
                    atol=transient.atol, samples_per_mesh_period=transient.samples_per_mesh_period,
                    convergence_tol=transient.convergence_tol, max_steps=transient.max_steps,
                    start="auto", extrapolate=transient.extrapolate,
                    accelerate=transient.accelerate)
