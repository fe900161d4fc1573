"""Test-only models written independently of gearjax (shared by several test files)."""

from __future__ import annotations

import math

import equinox as eqx
import jax.numpy as jnp

from gearjax.models.torsional import ModelOutputs


class HarmonicOscillator(eqx.Module):
    """m x_tt + c x_t + k x = k a cos(n theta), theta = Omega t: a 'mesh' whose TE_S is a
    pure harmonic and whose stiffness is constant. State (x, x') with ' = d/dtheta,
    starting at x = a. ``forced=False`` drops the right-hand side: with damping_ratio 0
    the free vibration from x = a, energy k a^2 / 2 exactly conserved."""

    mass: float
    stiffness: float
    damping_ratio: float
    amplitude: float
    order: int = eqx.field(static=True)
    formulation: str = eqx.field(static=True, default="perturbation")
    jump_thetas: tuple = eqx.field(static=True, default=())
    forced: bool = eqx.field(static=True, default=True)

    @property
    def period_rad(self):
        return 2 * math.pi / self.order

    mesh_period_rad = period_rad

    @property
    def static_force_N(self):
        return 100.0 * self.stiffness * self.amplitude  # never a "contact loss"

    @property
    def omega_n(self):
        return math.sqrt(self.stiffness / self.mass)

    def _te_s(self, theta):
        return self.amplitude * jnp.cos(self.order * theta) if self.forced else 0.0

    def initial_state(self, omega):
        return jnp.stack([jnp.asarray(self.amplitude), jnp.zeros(())])

    def vector_field(self, theta, y, omega):
        c = 2 * self.damping_ratio * math.sqrt(self.stiffness * self.mass)
        f = self.stiffness * (self._te_s(theta) - y[0])
        return jnp.stack([y[1], (f - omega * c * y[1]) / (omega**2 * self.mass)])

    def outputs(self, theta, y, omega):
        x_s = self._te_s(theta)
        return ModelOutputs(mesh_force_N=self.static_force_N + self.stiffness * (y[0] - x_s),
                            dte_m=y[0])

    def decay_rate_per_rad(self, omega):
        return self.damping_ratio * self.omega_n / omega
