"""Small-gain stability bound of the linear time-periodic gear equations, without a
monodromy.

The te (Eq. (42), sdof Eq. (20)) and perturbation (Eq. (48a), sdof Eq. (47a))
formulations are, while contact holds, ``y' = (A0 + c(theta) p w^T) y + b(theta)``
(:mod:`gearjax.dynamics.harmonic`, Eq. (1)): the LTI system ``A0`` closed by the
time-varying scalar gain ``c(theta)`` through ``sigma = w^T y``, so that ``sigma = g *
(c sigma)`` with the transfer function ``g(s) = w^T (s - A0)^-1 p = sum_k pw_k / (s -
lambda_k)`` (``lambda_k`` the eigenvalues of ``A0``, ``pw_k`` the products of the modal
components of ``w`` and ``p``). By the small-gain theorem, if ``A0`` is Hurwitz and
``sup_chi |g(i chi)| * max|c| < 1``, the loop is exponentially stable for *every* gain
history within that bound, periodic ones included: every Floquet multiplier lies inside
the unit circle, with no monodromy integration. Sufficient, not necessary (it ignores
the frequency content of ``c``; values on the Baud-Velex rig:
``benchmarks/results/code_notes.md``, section gearjax.dynamics.small_gain). The
perturbation formulation has ``c = 0``: bound 0.

The sup is sampled at :data:`SMALL_GAIN_GRID` frequencies across each mode's half-power
band (and zero); a bound below :data:`SMALL_GAIN_MARGIN` proves stability (the margin
covers the sampling). Used by :func:`gearjax.dynamics.harmonic_sweep.harmonic_sweep` (speeds it
proves need no Floquet radius) and ``gearjax stability --method harmonic``
(:func:`gearjax.dynamics.harmonic.small_gain_bounds`).
"""

from __future__ import annotations

import jax.numpy as jnp

__all__ = ["SMALL_GAIN_GRID", "SMALL_GAIN_MARGIN", "small_gain_bound"]

SMALL_GAIN_GRID = 25  # frequencies per mode over +-3 half-power bandwidths (H-inf norm)
SMALL_GAIN_MARGIN = 0.95  # bound below which stability is proven (covers the sampling)


def small_gain_bound(lam, pw, c_radius, xp=jnp):
    """``sup |g(i chi)| * c_radius`` (module docstring) for the eigenvalues ``lam`` (n,)
    of ``A0``, the modal products ``pw`` (n,) and the radius of ``c``; ``inf`` if ``A0``
    is not Hurwitz. Jittable; ``xp=numpy`` computes it on the host."""
    t = xp.linspace(-3.0, 3.0, SMALL_GAIN_GRID)
    chi = xp.abs(xp.imag(lam))[:, None] + xp.abs(xp.real(lam))[:, None] * t[None, :]
    chi = xp.concatenate([xp.zeros(1), chi.reshape(-1)])
    g = xp.sum(pw[None, :] / (1j * chi[:, None] - lam[None, :]), axis=1)
    hurwitz = xp.max(xp.real(lam)) < 0.0
    return xp.where(hurwitz, xp.max(xp.abs(g)) * c_radius, xp.inf)
