"""The one integration in theta of gearjax: every transient, measured period, refinement
window, shooting period, monodromy and continuation restart is a call of :func:`integrate`,
under the model's jump-aware step-size controller (:func:`jump_controller`).

The right-hand side of a gear model jumps or kinks at speed-independent angles (cell
engagement, quasi-static active-set changes, NLTE kinks: ``model.jumps``, padded to a
static bound by repeating the last angle, which changes no step);
:class:`PeriodicJumpController` ends every step just before such an angle and restarts just
after it, in O(1) per step, so an explicit Runge-Kutta step never straddles a jump.
"""

from __future__ import annotations

import diffrax
import equinox as eqx
import equinox.internal as eqxi
import jax
import jax.numpy as jnp

__all__ = ["integrate", "jump_controller", "PeriodicJumpController"]


def integrate(vector_field, solver, controller, t0, t1, y0, omega, *, saveat: diffrax.SaveAt,
              max_steps: int, adjoint=None) -> diffrax.Solution:
    """``y' = vector_field(theta, y, omega)`` from ``t0`` to ``t1`` (rad of the model's
    simulation angle) with ``solver`` under ``controller`` (:func:`jump_controller` of the
    model: every caller passes it), saved at ``saveat``; ``adjoint`` default diffrax's.
    Never raises for a failed solve (``throw=False``): callers read ``result``."""
    kw = {} if adjoint is None else {"adjoint": adjoint}
    return diffrax.diffeqsolve(
        diffrax.ODETerm(vector_field), solver, t0=t0, t1=t1, dt0=None, y0=y0, args=omega,
        saveat=saveat, stepsize_controller=controller, max_steps=max_steps, throw=False, **kw)


def jump_controller(model, rtol, atol):
    """The step-size controller of every integration in theta (simulate, shooting,
    continuation): integral-only PID at ``rtol``/``atol``, whose steps end at the model's
    speed-independent jump angles (:class:`PeriodicJumpController`) where it has any."""
    pid = diffrax.PIDController(rtol=rtol, atol=atol, pcoeff=0.0, icoeff=1.0)
    jumps = model.jumps
    if jumps.bound == 0:
        return pid
    return PeriodicJumpController(pid, jumps.thetas, float(model.period_rad))



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
    jumps : (n,) sorted jump positions in ``[0, period)`` (repeated entries allowed).
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
