"""Test-only models written independently of gearjax (shared by several test files)."""

from __future__ import annotations

import math

import equinox as eqx
import jax.numpy as jnp

from gearjax.excitation.jumps import JumpSet
from gearjax.models.base import AbstractGearModel, ModelOutputs


class HarmonicOscillator(AbstractGearModel):
    """m x_tt + c x_t + k x = k a cos(n theta), theta = Omega t: a 'mesh' whose TE_S is a
    pure harmonic and whose stiffness is constant. State (x, x') with ' = d/dtheta,
    starting at x = a. ``forced=False`` drops the right-hand side: with damping_ratio 0
    the free vibration from x = a, energy k a^2 / 2 exactly conserved."""

    mass: float
    stiffness: float
    damping_ratio: float
    amplitude: float
    order: int = eqx.field(static=True)
    formulation: str = eqx.field(static=True)
    jumps: JumpSet
    forced: bool = eqx.field(static=True)
    structure_ok: bool = eqx.field(static=True)
    period_rad: float = eqx.field(static=True)

    def __init__(self, mass, stiffness, damping_ratio, amplitude, order,
                 formulation="perturbation", jump_thetas=(), forced=True):
        self.mass, self.stiffness = mass, stiffness
        self.damping_ratio, self.amplitude, self.order = damping_ratio, amplitude, order
        self.formulation, self.forced = formulation, forced
        self.structure_ok = True
        self.period_rad = 2 * math.pi / order
        self.jumps = JumpSet.from_angles(jump_thetas, self.period_rad)

    @property
    def mesh_period_rad(self):
        return self.period_rad

    @property
    def static_force_N(self):
        return 100.0 * self.stiffness * self.amplitude  # never a "contact loss"

    @property
    def omega_n(self):
        return math.sqrt(self.stiffness / self.mass)

    def _te_s(self, theta):
        return self.amplitude * jnp.cos(self.order * theta) if self.forced else 0.0

    @property
    def state_size(self):
        return 2

    def with_modifications(self, mods):
        return self

    def angle(self, s):
        return s, None

    def natural_frequency_rad_s(self):
        return self.omega_n

    def homogeneous_vector_field(self, theta, y, omega):
        c = 2 * self.damping_ratio * math.sqrt(self.stiffness * self.mass)
        return jnp.stack([y[1], (-self.stiffness * y[0] - omega * c * y[1]) / (omega**2 * self.mass)])

    def initial_state(self, omega, theta0=0.0):
        return jnp.stack([jnp.asarray(self.amplitude), jnp.zeros(())])

    def vector_field(self, theta, y, omega, contact: bool = True):  # linear: no contact law
        c = 2 * self.damping_ratio * math.sqrt(self.stiffness * self.mass)
        f = self.stiffness * (self._te_s(theta) - y[0])
        return jnp.stack([y[1], (f - omega * c * y[1]) / (omega**2 * self.mass)])

    def outputs(self, theta, y, omega, contact: bool = True):
        x_s = self._te_s(theta)
        return ModelOutputs(mesh_force_N=self.static_force_N + self.stiffness * (y[0] - x_s),
                            dte_m=y[0])

    def decay_rate_per_rad(self, omega):
        return self.damping_ratio * self.omega_n / omega
