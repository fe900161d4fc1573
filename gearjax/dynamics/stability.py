"""Floquet stability of the linear time-periodic gear equations (parametric excitation).

The te formulation (Eq. (20), ``k(theta) = (sum k_i)^S`` the loaded quasi-static stiffness)
is linear with theta-periodic coefficients; its free response obeys the homogeneous
equation ``Omega^2 m_eq x'' + Omega c x' + k(theta) cos^2(b_b) x = 0``. Over one excitation
period P the state is mapped by the monodromy matrix ``Phi(P)``; its eigenvalues (Floquet
multipliers) decide stability: every steady response of Eq. (20) is bounded and attracts
the others iff the spectral radius ``rho = max |mu| < 1``. Inside a parametric instability
zone (mesh frequency near ``2 omega_n / n``) ``rho > 1`` and the time integration grows
like ``rho^(theta / P)``.

``Phi(P)`` is computed by integrating the variational (here: the homogeneous matrix)
equation ``Phi' = A(theta) Phi``, ``Phi(0) = I``, with diffrax (all columns under the same
error control; steps end at the jumps of ``k(theta)``: :func:`gearjax.dynamics.integrate.
jump_controller`). For a linear system this
*is* the Jacobian of the flow map, without the pitfall of ``jax.jacfwd`` through an
adaptive solve, whose step sizes would be chosen for one primal trajectory only.

Models provide ``homogeneous_vector_field(theta, y, omega)`` (linear in ``y``),
``period_rad`` and ``jump_thetas`` (:class:`gearjax.models.base.AbstractGearModel`). For
:class:`gearjax.models.torsional.TorsionalModel` the reference formulation is linearised
about the quasi-static contact (same equation as te, valid while no cell changes contact),
and the perturbation formulation has constant coefficients
(``rho = exp(-zeta omega_n T)``, a check).
"""

from __future__ import annotations

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..errors import SimulationError, check_float64
from ..models.base import AbstractGearModel
from .batching import over_speeds, sequential_for
from .integrate import integrate, jump_controller

__all__ = ["monodromy", "floquet_multipliers", "spectral_radius", "spectral_radius_of",
           "check_speeds"]


def spectral_radius_of(phi, squarings: int = 40):
    """Spectral radius of a square matrix by normalised repeated squaring (matrix
    products only): ``log rho ~ sum_j 2^-j log s_j + 2^-m log ||B_m||`` with
    ``A_0 = phi``, ``s_j = ||A_j||_F``, ``A_{j+1} = (A_j / s_j)^2``. Error
    ``O(2^-m log cond)`` plus the ratio of the two largest moduli to the power ``2^m``."""
    def body(carry, _):
        a, acc, w = carry
        s = jnp.sqrt(jnp.sum(a * a))
        s = jnp.where(s > 0, s, 1.0)
        b = a / s
        return (b @ b, acc + w * jnp.log(s), w / 2), None

    (a, acc, w), _ = jax.lax.scan(body, (phi, jnp.zeros((), phi.dtype), jnp.ones((), phi.dtype)),
                                  None, length=squarings)
    s = jnp.sqrt(jnp.sum(a * a))
    return jnp.exp(acc + w * jnp.log(jnp.maximum(s, 1e-300)))


def monodromy(model, omega, *, solver=None, rtol: float = 1e-10, atol: float = 1e-12,
              max_steps: int = 1_000_000):
    """Monodromy matrix of the homogeneous linear equation over one excitation period.

    Parameters
    ----------
    model : model with ``homogeneous_vector_field`` (see module docstring).
    omega : pinion speed Omega1 (rad/s), > 0 (traceable: jit/vmap friendly).
    solver, rtol, atol, max_steps : diffrax options (default Dopri8, 1e-10, 1e-12 on the
        model's dimensionless state).

    Returns
    -------
    (n, n) array ``Phi(P)`` in the model's (scaled) state coordinates; NaN if the
    integration failed.
    """
    if not isinstance(model, AbstractGearModel):
        raise SimulationError(
            "model", type(model).__name__,
            "must be a gear model (gearjax.models.base.AbstractGearModel, which declares "
            "homogeneous_vector_field, period_rad and jump_thetas)")
    solver = diffrax.Dopri8() if solver is None else solver
    omega = jnp.asarray(omega, dtype=float)
    period = float(model.period_rad)
    n = model.state_size

    def vf(t, phi, args):
        return jax.vmap(lambda col: model.homogeneous_vector_field(t, col, args), in_axes=1,
                        out_axes=1)(phi)

    sol = integrate(vf, solver, jump_controller(model, rtol, atol), 0.0, period, jnp.eye(n),
                    omega, saveat=diffrax.SaveAt(t1=True), max_steps=max_steps,
                    adjoint=diffrax.ForwardMode())
    ok = sol.result == diffrax.RESULTS.successful
    return jnp.where(ok, sol.ys[-1], jnp.nan)


def floquet_multipliers(model, omega, *, rtol: float = 1e-10, atol: float = 1e-12,
                        max_steps: int = 1_000_000):
    """Floquet multipliers (complex eigenvalues of :func:`monodromy`, integrated at
    ``rtol``/``atol`` within ``max_steps``) at one speed, sorted by decreasing modulus
    (NumPy, concrete ``omega``)."""
    check_speeds(np.atleast_1d(np.asarray(omega, dtype=float)))
    phi = np.asarray(eqx.filter_jit(monodromy)(model, jnp.asarray(float(omega)), rtol=rtol,
                                               atol=atol, max_steps=max_steps))
    if not np.all(np.isfinite(phi)):
        raise SimulationError("omega", float(omega), "monodromy integration failed (step limit)")
    mu = np.linalg.eigvals(phi)
    return mu[np.argsort(-np.abs(mu))]


@eqx.filter_jit
def _rho(model, speeds, rtol: float, atol: float, max_steps: int):
    def one(w):
        phi = monodromy(model, w, rtol=rtol, atol=atol, max_steps=max_steps)
        return jnp.max(jnp.abs(jnp.linalg.eigvals(phi)))

    return over_speeds(one, speeds, sequential=sequential_for(model))


def spectral_radius(model, speeds_rad_s, *, rtol: float = 1e-10, atol: float = 1e-12,
                    max_steps: int = 1_000_000) -> np.ndarray:
    """Spectral radius ``max |mu|`` of the monodromy matrix at each speed (mapped or
    vmapped by :func:`gearjax.dynamics.batching.over_speeds`, one
    compilation per model structure and number of speeds).

    ``rho < 1``: asymptotically stable steady response; ``rho > 1``: parametric instability
    (the linear te response grows like ``rho`` per period). NaN where the integration
    failed. ``rtol``, ``atol``, ``max_steps``: :func:`monodromy`'s integration.
    """
    speeds = np.asarray(speeds_rad_s, dtype=float).reshape(-1)
    check_speeds(speeds)
    return np.asarray(_rho(model, jnp.asarray(speeds), float(rtol), float(atol),
                           int(max_steps)))


def check_speeds(speeds):
    """Raise a SimulationError naming ``speeds_rad_s`` unless ``speeds`` (1-D array) holds
    at least one speed and all are finite and > 0 (rad/s); and unless JAX computes in
    float64 (:func:`gearjax.errors.check_float64`)."""
    check_float64()
    bad = ~(np.isfinite(speeds) & (speeds > 0))
    if speeds.size == 0 or np.any(bad):
        raise SimulationError(
            "speeds_rad_s", speeds[bad][:5].tolist() if speeds.size else [],
            "need at least one finite pinion speed > 0 (rad/s)",
        )
