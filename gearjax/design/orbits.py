"""Which periodic orbits a dynamic design objective measures (:class:`OrbitSet`), and the
implicit derivative of a shooting orbit (:func:`implicit_steady_metrics`).

Orbit sets (robust objectives)
------------------------------
With the contact law of Section 6.2 the te formulation (Eqs. (20)/(42)) is piecewise
linear: in and near the contact-loss band up to three periodic orbits coexist (sdof te,
zeta 0.03), and which one a transient from the quasi-static state reaches can switch with
the design, so an objective measured on that one orbit jumps, and an optimiser that
follows it settles wherever a start happened to land. An :class:`OrbitSet` measures the
steady state from each of an explicit set of starts at every speed and takes the largest
value (the peak force over the orbits those starts reach):

* ``"quasi-static"``: the model's transient start (:meth:`~gearjax.models.base.
  AbstractGearModel.transient_start`, the state every forward ``sweep`` starts from);
* ``"separated"`` and ``"far"``: the quasi-static state with its displacements scaled by
  -1 (the static deflection of the mesh mirrored: teeth apart by the static approach) and
  by -3, velocities kept (:meth:`~gearjax.models.base.AbstractGearModel.deflected_start`):
  starts with the energy of a high, contact-losing orbit where one coexists. Their basins
  of attraction are fragmented, so a set of starts finds more of the coexisting orbits than
  one start, never certainly all of them (measurements: ``benchmarks/results/
  code_notes.md``, section gearjax.design.orbits).

Implicit derivative of a shooting orbit
---------------------------------------
The periodic orbit ``y*`` of the shooting solves ``y(P; y*, p) - y* = 0`` (``P`` the
excitation period, ``p`` the design). By the implicit function theorem
``dy*/dp = (I - Phi)^-1 dy(P)/dp`` with ``Phi = dy(P)/dy`` the monodromy matrix at
``y*``. :func:`implicit_steady_metrics` finds ``y*`` by Newton on the model with its
derivative cut (``stop_gradient``: the iterations carry no tangents), takes ``Phi`` there,
and forms ``y* + (I - Phi)^-1 (y(P; y*, p) - y*)``: its value is one more Newton step
(``y*`` to the shooting's tolerance), its forward derivative the implicit one, at the cost of
one period of the state alone; the metrics are then measured from it as
:func:`gearjax.dynamics.steady.steady_state` measures them.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp

from ..dynamics.simulate import SimulationResult, simulate
from ..dynamics.steady import (PeriodicState, Shooting, period_and_monodromy, period_end,
                               periodic_state, steady_state)
from ..dynamics.sweep import Transient
from ..errors import DesignError
from ..linalg import solve as dense_solve

__all__ = ["ORBIT_STARTS", "OrbitSet", "implicit_steady_metrics"]

ORBIT_STARTS = ("quasi-static", "separated", "far")
# the factor on the quasi-static displacements of each start but the first
# (AbstractGearModel.deflected_start)
_FACTORS = {"separated": -1.0, "far": -3.0}


class OrbitSet(eqx.Module):
    """The starts from which a dynamic objective measures the steady state at every
    speed (module docstring); the objective takes, per speed and metric, the largest
    value over them.

    Attributes
    ----------
    starts : names from :data:`ORBIT_STARTS` (static), default the quasi-static state alone.
    """

    starts: tuple = eqx.field(static=True, default=("quasi-static",))

    def __check_init__(self):
        if not self.starts or any(s not in ORBIT_STARTS for s in self.starts):
            raise DesignError("orbits", self.starts, f"starts must be among {ORBIT_STARTS}")
        if len(set(self.starts)) != len(self.starts):
            raise DesignError("orbits", self.starts, "each start once")

    @property
    def label(self) -> str:
        """The starts joined by ``+`` (what a report names)."""
        return "+".join(self.starts)

    def start_states(self, model, omega, transient: bool = True):
        """(n_starts, n) states at theta = 0 of the starts at pinion speed ``omega``
        (rad/s), derivatives cut (where an orbit starts does not change the orbit); the
        quasi-static start is the model's transient start (``transient``, a transient's
        ``start="auto"``) or its quasi-static state (a shooting's first iterate)."""
        out = []
        for name in self.starts:
            if name == "quasi-static":
                out.append(model.transient_start(omega) if transient
                           else model.initial_state(omega))
            else:
                out.append(model.deflected_start(omega, _FACTORS[name]))
        return jax.lax.stop_gradient(jnp.stack(out))

    def metrics(self, solver, model, omega, adjoint=None, implicit: bool = True):
        """The metrics of ``solver`` (a :class:`~gearjax.Transient` or
        :class:`~gearjax.Shooting`) at ``omega`` from every start, one solve vmapped over
        the starts: a :class:`~gearjax.dynamics.simulate.SimulationResult` whose fields
        have a leading start axis. ``implicit``: a shooting orbit differentiated by
        :func:`implicit_steady_metrics`."""
        auto = isinstance(solver, Transient) and solver.start == "auto"
        y0s = self.start_states(model, omega, transient=auto)
        if isinstance(solver, Shooting):
            if implicit:
                return jax.vmap(lambda y0: implicit_steady_metrics(model, omega, solver, y0))(y0s)

            def one(y0):
                ps = periodic_state(model, omega, y_start=y0, **_shooting_newton(solver))
                return steady_state(model, omega, solver, periodic=ps).result

            return jax.vmap(one)(y0s)
        if isinstance(solver, Transient):
            opts = solver.simulate_options()
            opts.pop("start")
            return jax.vmap(lambda y0: simulate(model, omega, adjoint=adjoint, y0=y0,
                                                **opts))(y0s)
        raise DesignError("solver", type(solver).__name__, "Transient or Shooting")


def _shooting_newton(shooting: Shooting) -> dict:
    """:func:`periodic_state`'s options of a :class:`Shooting`."""
    return dict(rtol=shooting.rtol, atol=shooting.atol, max_newton=shooting.max_newton,
                newton_tol=shooting.newton_tol)


def implicit_steady_metrics(model, omega, shooting: Shooting, y_start=None) -> SimulationResult:
    """:func:`gearjax.dynamics.steady.steady_state`'s metrics at pinion speed ``omega``
    (rad/s) with the periodic orbit differentiated implicitly (module docstring): forward
    mode through one period of the state and the measured periods, not through the Newton
    iterations. ``y_start``: the first Newton iterate (default the quasi-static state)."""
    opts = _shooting_newton(shooting)
    omega = jnp.asarray(omega, dtype=float)
    frozen = jax.lax.stop_gradient(model)
    ps = periodic_state(frozen, omega, y_start=y_start, **opts)
    y_s = jnp.where(ps.ok, ps.y0, frozen.initial_state(omega))
    y_s = jax.lax.stop_gradient(y_s)
    _, phi, ok_phi, _ = period_and_monodromy(frozen, omega, y_s, rtol=opts["rtol"],
                                             atol=opts["atol"])
    phi = jax.lax.stop_gradient(phi)
    y_p, ok_p = period_end(model, omega, y_s, rtol=opts["rtol"], atol=opts["atol"])
    eye = jnp.eye(y_s.shape[0], dtype=y_s.dtype)
    step = dense_solve(eye - jnp.where(ok_phi, phi, 0.0), y_p - y_s)
    good = ps.ok & ok_phi & ok_p & jnp.all(jnp.isfinite(step))
    y_star = jnp.where(good, y_s + step, y_s)
    periodic = PeriodicState(y0=jnp.where(ps.ok, y_star, jnp.nan),
                             spectral_radius=ps.spectral_radius, residual=ps.residual,
                             newton_iterations=ps.newton_iterations, ok=ps.ok & good,
                             n_steps=ps.n_steps)
    return steady_state(model, omega, shooting, periodic=periodic).result
