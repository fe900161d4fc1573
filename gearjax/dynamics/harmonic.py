"""Periodic steady state of the linear formulations in the frequency domain.

The te (Eq. (42), sdof Eq. (20)) and perturbation (Eq. (48a), sdof Eq. (47a))
formulations are, wherever the mesh force stays compressive, linear time-periodic systems
in the angle ``theta = Omega1 t`` (rad)::

    y' = A(theta) y + b(theta),     A(theta) = A0 + c(theta) p w^T,              (1)

with a *rank-one* parametric part: the mesh stiffness fluctuation ``k(theta) - k_m`` acts
along the mesh vector only (``(k - k_m) V V^T`` in Eq. (42); ``k(theta)/k_m`` in the
single row of Eq. (20)); ``c = 0`` for Eq. (48a)/(47a). Only the scalar ``sigma = w^T y``
(the mesh deflection) is parametrically coupled.

What the solver asks of the model: nothing but the interface of
:class:`gearjax.models.base.AbstractGearModel`. ``A0, p, w, c(theta)`` and ``b(theta)``
are read from ``model.vector_field`` by forward-mode linearisation about the quasi-static
state ``model.initial_state(omega, theta)`` (in contact, so that the split stays valid for
a contact law that clips tensile forces): ``A(theta) xi`` for a probe ``xi`` at every
sample shows the varying direction ``p``; the difference of two Jacobians gives ``w``;
every forcing term the model contains (TE_S, NLTE and its derivatives after the models'
substitutions, eccentricity) is in ``b`` without naming it. The split is verified on all
samples (``rank_one_error``); an angle map of a moved design, for instance, breaks it and
is reported, not silently solved.

Harmonic balance (``H`` harmonics of the excitation period ``P``, ``nu = 2 pi / P``),
modal form of ``A0 = Q diag(lambda) Q^-1`` (one eigendecomposition per speed; ``eta =
Q^-1 y``), with ``g_h`` the receptance ``sum_k (w^T Q)_k (Q^-1 p)_k / (i h nu -
lambda_k)`` and ``f_h`` the response of ``sigma`` to ``b`` alone::

    sigma_h - g_h (c * sigma)_h = f_h,          |h| <= H                          (2)

(``*`` the convolution of the coefficient sequences, applied by FFT: Hill's equation of
the scalar, solved by GMRES). ``k(theta)`` jumps (cell engagement, active-set changes:
``model.jumps``), so ``b`` and ``c`` have Fourier coefficients ``O(1/h)`` and a
plain truncated series has Gibbs errors ``O(1)`` at the jumps in the velocity and
``O(1/H)`` between them. Both are removed exactly: every function that jumps is split
into its jumps and kinks at the known angles (the one-sided values and slopes there, by
forward-mode AD) times the periodic Bernoulli functions ``S0, S1`` (a sawtooth and its
zero-mean antiderivative, whose Fourier coefficients are known), plus a ``C^1``
remainder. The remainder is sampled (DFT, aliasing ``O(N^-3)``); between two jump
angles the jump part of the forcing is a quadratic in theta, so each mode's periodic
response to it is exact by the exponential integrator (``phi_1..phi_3``, one turn
around the period closed by periodicity: :func:`_jump_part`). So the orbit is::

    eta_k(theta) = sum_|h|<=H gt_kh e^{i h nu theta} / (i h nu - lambda_k) + zeta_k(theta)

with ``gt`` the coefficients of the smooth remainder of the forcing ``p c sigma + b``
(``b`` kept in a basis of its few directions: :func:`_forcing_basis`). The truncation
error is ``O(H^-3)`` (``benchmarks/bench_harmonic.py --convergence``);
:func:`gearjax.dynamics.harmonic_sweep.harmonic_sweep` raises
``H`` until ``error_estimate`` (the largest change of the state on the output grid
between ``H`` and ``H/2``, relative to its largest component) is below ``rtol``.

Metrics: the orbit is a callable of theta, so the exact extrema of
:mod:`gearjax.dynamics.metrics` (both sides of every jump, refined between grid points)
read it directly instead of an integration: no transient and no ODE solve at all.
``contact_holds`` (minimum mesh force over the period > 0) says whether the linear
regime holds; where it does not, the caller must fall back to a nonlinear solver
(shooting or transient). Stability: the periodic orbit of an LTP system exists inside a
parametric instability zone too; with ``floquet=True`` the Floquet spectral radius of
the monodromy matrix (:func:`gearjax.dynamics.stability.monodromy`) sets ``stable``.
"""

from __future__ import annotations

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..errors import SimulationError
from ..models.base import LINEAR_FORMULATIONS, AbstractGearModel
from . import grid as grids
from .batching import on_cpu, over_speeds
from .krylov import gmres
from .metrics import (MAX_JUMP_WINDOWS, NEAR_EXTREME_WINDOWS, jump_window_extrema,
                      refine_windows, ringing_length, window_extrema)
from .orders import N_MESH_ORDERS
from .small_gain import small_gain_bound
from .stability import check_speeds, monodromy
from .steady import spectral_radius_of

__all__ = ["HarmonicOrbit", "HarmonicResult", "harmonic_steady_state",
           "harmonic_steady_states", "small_gain_bounds", "check_linear_model",
           "LINEAR_FORMULATIONS"]

_JUMP_SIDE = 1e-9  # one-sided evaluation at theta_j -/+ _JUMP_SIDE * period
_N_REFINE = 64  # points per grid interval in the refinement windows (parabolic vertex)
_FORCING_RANK = 48  # columns kept for the forcing b (its rank: a few; checked)
_SPLIT_TOL = 1e-6  # largest split residual for which small_gain_bounds uses the bound
_PHI_TERMS = 18  # Taylor terms of phi_k(z) for |z| < 1 (error 1/19! ~ 8e-18)


def _phi123(z):
    """phi_1, phi_2, phi_3 of the exponential integrators, ``phi_k(z) = sum_i z^i /
    (i + k)!`` (so ``int_0^x e^(lambda (x - s)) s^m ds = m! x^(m+1) phi_(m+1)(lambda x)``):
    Taylor series for ``|z| < 1``, else the recurrence ``phi_(k+1) = (phi_k - 1/k!) / z``
    from ``phi_0 = e^z``. Returns (e^z, phi_1, phi_2, phi_3)."""
    small = jnp.abs(z) < 1.0
    zs = jnp.where(small, z, 0.0)
    ser = []
    for k in (1, 2, 3):  # Horner: no complex powers (a log and an exp each)
        acc = jnp.full_like(zs, 1.0 / math.factorial(_PHI_TERMS - 1 + k))
        for i in range(_PHI_TERMS - 2, -1, -1):
            acc = acc * zs + 1.0 / math.factorial(i + k)
        ser.append(acc)
    zl = jnp.where(small, 1.0, z)
    ez = jnp.exp(z)
    p1 = jnp.expm1(zl) / zl
    p2 = (p1 - 1.0) / zl
    p3 = (p2 - 0.5) / zl
    return (ez, jnp.where(small, ser[0], p1), jnp.where(small, ser[1], p2),
            jnp.where(small, ser[2], p3))


def _saw(x, period):
    """(S0, S1) at angles ``x`` (rad): unit sawtooth and its zero-mean antiderivative."""
    t = jnp.mod(x / period, 1.0)
    return 0.5 - t, -period * (t * t - t + 1.0 / 6.0) / 2.0


def _saw_coeffs(h, period):
    """Fourier coefficients of S0, S1 at harmonics ``h`` (integers, any shape)."""
    hs = jnp.where(h == 0, 1, h)
    s0 = jnp.where(h == 0, 0.0, 1.0 / (2j * jnp.pi * hs))
    s1 = jnp.where(h == 0, 0.0, s0 / (1j * hs * (2.0 * jnp.pi / period)))
    return s0, s1


# ---------------------------------------------------------------------- the linear split
class _Split(eqx.Module):
    """``A0`` (n, n) and the unit vectors ``p``, ``w`` (n,) of Eq. (1) at one speed, the
    basis (n, k) of the forcing ``b`` (:func:`_forcing_basis`), the largest relative
    residual of the split and of that basis over the samples (round-off if valid), and
    the radius of ``c``: ``A0`` holds the midpoint of the range of the parametric
    coefficient, so ``|c(theta)| <= c_radius`` (:mod:`gearjax.dynamics.small_gain`)."""

    a0: jax.Array
    p: jax.Array
    w: jax.Array
    basis: jax.Array
    rank_one_error: jax.Array
    c_radius: jax.Array  # max |c(theta)| over the samples (c centred on its range)


def _forcing_basis(b):
    """Orthonormal basis ``U`` (n, k) of the span of the forcing samples ``b`` (N, n),
    ``k = min(n, _FORCING_RANK)``, and the relative residual of ``b ~ (b U) U^T``. The
    forcing of the models is a few fixed vectors times functions of theta (3D: the mesh
    vector, E and C E from NLTE, eccentricity vectors), so the modal transforms of its
    coefficients cost ``k`` columns instead of ``n``; found by a seeded random sketch."""
    n = b.shape[1]
    if n <= _FORCING_RANK:
        return jnp.eye(n), jnp.zeros(())
    sketch = jax.random.normal(jax.random.PRNGKey(0), (n, _FORCING_RANK), dtype=b.dtype)
    qn, _ = jnp.linalg.qr(b @ sketch)  # range of the samples
    _, _, vt = jnp.linalg.svd(qn.T @ b, full_matrices=False)
    basis = vt.T
    res = jnp.max(jnp.abs(b - (b @ basis) @ basis.T))
    return basis, res / jnp.maximum(jnp.max(jnp.abs(b)), 1e-300)


def _field(model, omega):
    return lambda th, y: model.vector_field(th, y, omega)


def _reference(model, omega):
    """theta -> a state in contact at theta, about which the vector field is linearised:
    the quasi-static state (``model.initial_state``); for a model whose initial state is
    already its periodic orbit (``periodic_start``, computed in the frequency domain at
    each call), that orbit's state at theta = 0."""
    if model.periodic_start:
        y0 = model.initial_state(omega)
        return lambda th: y0
    return lambda th: model.initial_state(omega, th)


def _prepare(model, omega, n_h: int):
    """The split of Eq. (1) from the model's vector field (module docstring) and the
    data of the harmonic balance: jump angles, one-sided values and slopes of ``(U^T b,
    c)`` there, and the jump-corrected Fourier coefficients of ``(U^T b, c)`` at -2H..2H
    (``(4H+1, k+1)``, from ``4H`` samples; ``U`` the forcing basis). Every evaluation of the model is batched in
    three vmapped calls (probe, two Jacobians, ``(b, c)`` everywhere)."""
    period = float(model.period_rad)
    nu = 2.0 * math.pi / period
    n, n_s = model.state_size, 4 * n_h
    th = (jnp.arange(n_s) + 0.5) * (period / n_s)
    thj, use = _distinct_jumps(model.jumps, period)
    d = _JUMP_SIDE * period
    # one-sided slopes by differences over ``step`` (< a quarter of the closest jumps)
    step = 1e-6 * period
    if thj.shape[0]:
        u = jnp.sort(jnp.where(use, thj, jnp.inf))  # the angles that count, then inf
        i, n_use = jnp.arange(u.shape[0]), jnp.sum(use)
        gaps = jnp.where(i + 1 < n_use, jnp.roll(u, -1) - u, u[0] + period - u)
        step = jnp.minimum(step, 0.25 * jnp.min(jnp.where(i < n_use, gaps, period)))
    t_all = jnp.concatenate([th, thj - d - step, thj - d, thj + d, thj + d + step])
    f = _field(model, omega)
    ref = jax.vmap(_reference(model, omega))(t_all)

    def a_dot(t, yr, v):
        return jax.jvp(lambda y: f(t, y), (yr,), (v,))[1]

    xi = jnp.cos(1.7 * jnp.arange(n) + 0.3)  # a probe without structure
    g = jax.vmap(a_dot, in_axes=(0, 0, None))(th, ref[:n_s], xi)
    dev = g - jnp.mean(g, axis=0)[None, :]
    norms = jnp.sqrt(jnp.sum(dev * dev, axis=1))
    m1 = jnp.argmax(norms)
    p = dev[m1] / jnp.maximum(norms[m1], 1e-300)
    m2 = jnp.argmin(dev @ p)
    idx = jnp.concatenate([jnp.full(n, m1), jnp.full(n, m2)])
    jacs = jax.vmap(a_dot, out_axes=1)(th[idx], ref[idx], jnp.concatenate([jnp.eye(n)] * 2))
    j1 = jacs[:, :n]
    row = p @ (j1 - jacs[:, n:])
    w = row / jnp.maximum(jnp.sqrt(jnp.sum(row * row)), 1e-300)
    p = jnp.where(jnp.any(row != 0), p, 0.0)

    def bc(t, yr):  # (b, c) with A0 = j1, c shifted below (b does not change)
        fr, aw = jax.jvp(lambda y: f(t, y), (yr,), (w,))
        c = p @ (aw - j1 @ w)
        return jnp.concatenate([fr - j1 @ yr - c * p * (w @ yr), c[None]])

    v = jax.vmap(bc)(t_all, ref)
    # A0 takes the midpoint of c's range (one-sided values at the jumps included), so c
    # varies in [-c_radius, c_radius]: the smallest radius for the small-gain bound
    c_all = v[:, n]
    cbar = 0.5 * (jnp.max(c_all) + jnp.min(c_all))
    resid = g - (j1 @ xi)[None, :] - v[:n_s, n][:, None] * p[None, :] * (w @ xi)
    err = jnp.max(jnp.abs(resid)) / jnp.maximum(jnp.max(jnp.abs(g)), 1e-300)
    basis, b_err = _forcing_basis(v[:, :n])
    split = _Split(a0=j1 + cbar * jnp.outer(p, w), p=p, w=w, basis=basis,
                   rank_one_error=jnp.maximum(err, b_err),
                   c_radius=0.5 * (jnp.max(c_all) - jnp.min(c_all)))
    v = jnp.concatenate([v[:, :n] @ basis, v[:, n:] - cbar], axis=1)  # (.., k + 1)
    n_j = thj.shape[0]
    vl2, vl1, vr1, vr2 = (v[n_s + i * n_j: n_s + (i + 1) * n_j] for i in range(4))
    dl, dr = (vl1 - vl2) / step, (vr2 - vr1) / step
    lo, hi = vl1 + d * dl, vr1 - d * dr  # one-sided limits at theta_j
    # padding and merged entries of the jump set jump by nothing
    hi, dr = jnp.where(use[:, None], hi, lo), jnp.where(use[:, None], dr, dl)
    j0, j1s = hi - lo, dr - dl
    s0, s1 = _saw(th[:, None] - thj[None, :], period)  # (N, J)
    smooth = v[:n_s] - s0 @ j0 - s1 @ j1s  # C^1 remainder
    k = jnp.arange(-2 * n_h, 2 * n_h + 1)
    dft = jnp.fft.fft(smooth, axis=0)[k % n_s] / n_s
    dft = dft * jnp.exp(-1j * jnp.pi * k / n_s)[:, None]  # samples at (m + 1/2) P / N
    c0, c1 = _saw_coeffs(k, period)
    ph = jnp.exp(-1j * nu * jnp.outer(k, thj))  # (4H+1, J)
    coeffs = dft + (ph * c0[:, None]) @ j0 + (ph * c1[:, None]) @ j1s
    return split, (thj, (lo, hi, dl, dr), coeffs)


def _distinct_jumps(jumps, period: float, rtol: float = 1e-9):
    """The jump set's angles (sorted, padded) and which of them count: the valid ones,
    less any within ``rtol * period`` of the one before it or, for the last, of the first
    one period on (:func:`gearjax.excitation.events.distinct_angles`' merging, traced)."""
    thj, valid = jumps.thetas, jumps.valid
    if thj.shape[0] == 0:
        return thj, valid
    close = jnp.concatenate([jnp.zeros(1, bool), jnp.diff(thj) <= rtol * period])
    use = valid & ~close
    n = jnp.sum(valid)
    last = jnp.arange(thj.shape[0]) == n - 1
    use = use & ~(last & (n > 1) & (thj[0] + period - thj <= rtol * period))
    return thj, use


def _modal_form(a0):
    """``(lambda, Q, Q^-1)`` of ``A0 = Q diag(lambda) Q^-1`` (complex)."""
    lam, q = jnp.linalg.eig(a0)
    return lam, q, jnp.linalg.solve(q, jnp.eye(q.shape[0], dtype=q.dtype))


# ---------------------------------------------------------------------- the orbit
class HarmonicOrbit(eqx.Module):
    """The periodic orbit of Eq. (1) at one speed: ``orbit(theta)`` is the model's state
    at the simulation angle(s) ``theta`` (rad), shape ``theta.shape + (n,)``.

    ``y = Re[sum_|h|<=H Y_h e^(i h nu theta) + Q zeta(theta)]``: the truncated series of
    the smooth part, and the modal responses ``zeta`` to the jumps and kinks of the
    forcing (piecewise quadratic between the jump angles), exact by the exponential
    integrator from the periodic values ``zeta_a`` at the jump angles.

    Attributes
    ----------
    lam, q : eigenvalues and eigenvectors of A0 (theta units).
    coef : (H+1, n) coefficients of the smooth part, harmonics 0..H (those of -h are
        their conjugates: ``y = Re sum_h coef_h e^(i h nu theta)``, doubled for h > 0).
    seg_start : (J,) sorted jump angles in [0, P) (rad), the segment starts.
    zeta0 : (J, n) modal jump responses at the segment starts.
    fpoly : (J, 3, n) modal forcing of each segment, ``F0 + F1 x + F2 x^2`` (x from its
        start).
    period : P (rad).
    """

    lam: jax.Array
    q: jax.Array
    coef: jax.Array
    seg_start: jax.Array
    zeta0: jax.Array
    fpoly: jax.Array
    period: float = eqx.field(static=True)

    def __call__(self, theta):
        theta = jnp.asarray(theta, dtype=float)
        th = theta.reshape(-1)
        # the series of a real orbit from its harmonics h >= 0: cos / sin and two GEMMs
        h = jnp.arange(self.coef.shape[0])
        ph = (2.0 * math.pi / self.period) * th[:, None] * h[None, :]
        y = jnp.cos(ph) @ jnp.real(self.coef) - jnp.sin(ph) @ jnp.imag(self.coef)
        if self.seg_start.shape[0]:
            y = y + jax.vmap(self._jumps)(th)
        return y.reshape(theta.shape + (self.q.shape[0],))

    def _jumps(self, th):
        t = jnp.mod(th, self.period)
        a = jnp.searchsorted(self.seg_start, t, side="right") - 1
        x = jnp.where(a < 0, t + self.period - self.seg_start[-1], t - self.seg_start[a])
        ez, p1, p2, p3 = _phi123(self.lam * x)
        f = self.fpoly[a]
        zeta = ez * self.zeta0[a] + x * p1 * f[0] + x**2 * p2 * f[1] + 2.0 * x**3 * p3 * f[2]
        return jnp.real(self.q @ zeta)


def _jump_part(lam, thj, dg0, dg1, period):
    """Segment data (zeta0, fpoly) of :class:`HarmonicOrbit` for the modal jumps ``dg0``
    and slope jumps ``dg1`` (J, n) at the sorted angles ``thj``: the forcing
    ``sum_j dg0_j S0(theta - theta_j) + dg1_j S1(theta - theta_j)`` as a quadratic in
    each segment, and the periodic response at the segment starts (one turn of the
    exponential integrator, closed by ``zeta_0 = z_P / (1 - e^(lambda P))``)."""
    length = jnp.diff(jnp.concatenate([thj, thj[:1] + period]))  # (J,)
    tau = jnp.mod((thj[:, None] - thj[None, :]) / period, 1.0)  # (segment, jump)
    f0 = (0.5 - tau) @ dg0 - (period / 2) * (tau * tau - tau + 1.0 / 6.0) @ dg1
    f1 = -jnp.sum(dg0, axis=0)[None, :] / period - ((2.0 * tau - 1.0) / 2.0) @ dg1
    f2 = jnp.broadcast_to(-jnp.sum(dg1, axis=0) / (2.0 * period), f0.shape)
    fpoly = jnp.stack([f0, f1, f2], axis=1)  # (J, 3, n)
    ez, p1, p2, p3 = _phi123(lam[None, :] * length[:, None])
    ln = length[:, None]
    psi = ln * p1 * f0 + ln**2 * p2 * f1 + 2.0 * ln**3 * p3 * f2  # (J, n)

    def step(z, ep):
        e, ps = ep
        return e * z + ps, z

    z_end, z_starts = jax.lax.scan(step, jnp.zeros_like(lam), (ez, psi))
    zeta_first = z_end / -jnp.expm1(lam * period)
    zeta0 = z_starts + jnp.exp(lam[None, :] * (thj - thj[0])[:, None]) * zeta_first[None, :]
    return zeta0, fpoly


def _conv(c_full, s, n_h):
    """(c * s)_h for |h| <= n_h: ``c_full`` (4 n_h + 1,) at -2n_h..2n_h, ``s`` (2 n_h + 1,)."""
    m = 5 * n_h  # > 4H: no wrap-around into |h| <= H (sums span -3H..3H); 5 * 2^k: fast FFT

    def wrap(x, k):  # x at -k..k -> circular layout of length m
        return jnp.concatenate([x[k:], jnp.zeros(m - 2 * k - 1, x.dtype), x[:k]])

    a, b = wrap(c_full, 2 * n_h), wrap(s, n_h)
    out = jnp.fft.ifft(jnp.fft.fft(a) * jnp.fft.fft(b))
    return out[jnp.arange(-n_h, n_h + 1) % m]


def _orbit(model, omega, n_h: int, keep, data, split, modal, gmres_tol):
    """HarmonicOrbit with the harmonics ``|h| <= keep`` (traced, ``<= n_h``) from the
    sampled (b, c) data and the eigendecomposition ``modal = (lambda, Q, Q^-1)`` of A0;
    the harmonics above ``keep`` are zero (so that one compiled function serves ``H`` and
    the error estimate at ``H/2``)."""
    period = float(model.period_rad)
    nu = 2.0 * math.pi / period
    thj, (lo, hi, dlo, dhi), coeffs = data  # coeffs: (4H+1, k+1) at -2H..2H
    n, k = model.state_size, split.basis.shape[1]
    h = jnp.arange(-n_h, n_h + 1)
    inside = jnp.abs(h) <= keep
    lam, q, qinv = modal
    pt, wt, ub = qinv @ split.p, q.T @ split.w, (qinv @ split.basis).T  # ub: (k, n)
    res = jnp.where(inside[:, None], 1.0 / (1j * h[:, None] * nu - lam[None, :]), 0.0)
    g = res @ (wt * pt)  # receptance of sigma to the parametric force, Eq. (2)
    beta = coeffs[n_h: 3 * n_h + 1, :k] @ ub  # (2H+1, n) modal b_h
    c_full = coeffs[:, k]
    f = jnp.sum(res * beta * wt[None, :], axis=1)
    sig, gm_res = gmres(lambda s: s - g * _conv(c_full, s, n_h), f, gmres_tol)
    qh = jnp.where(inside, _conv(c_full, sig, n_h), 0.0)
    gam = pt[None, :] * qh[:, None] + beta  # modal forcing coefficients
    # jumps of the forcing p c sigma + b at theta_j, and of its slope
    e = jnp.exp(1j * nu * jnp.outer(thj, h))  # (J, 2H+1)
    sj = jnp.real(e @ sig)
    dsj = jnp.real(e @ (1j * h * nu * sig))  # mean of both one-sided slopes
    dg0 = (hi - lo)[:, k][:, None] * sj[:, None] * pt[None, :] + (hi - lo)[:, :k] @ ub
    dsig = dg0 @ wt  # jump of sigma' = w^T y'
    dcs = hi[:, k] * (dsj + dsig / 2) - lo[:, k] * (dsj - dsig / 2)
    dg1 = dcs[:, None] * pt[None, :] + (dhi - dlo)[:, :k] @ ub
    s0, s1 = _saw_coeffs(h, period)
    ph = jnp.conj(e).T  # (2H+1, J): e^{-i h nu theta_j}
    gam = gam - (ph * s0[:, None]) @ dg0 - (ph * s1[:, None]) @ dg1
    coef = ((res * gam) @ q.T)[n_h:] * jnp.where(h[n_h:] > 0, 2.0, 1.0)[:, None]  # h >= 0
    if thj.shape[0]:
        zeta0, fpoly = _jump_part(lam, thj, dg0, dg1, period)
    else:
        zeta0, fpoly = jnp.zeros((0, n), lam.dtype), jnp.zeros((0, 3, n), lam.dtype)
    return HarmonicOrbit(lam=lam, q=q, coef=coef, seg_start=thj, zeta0=zeta0, fpoly=fpoly,
                         period=period), gm_res


# ---------------------------------------------------------------------- one speed
class HarmonicResult(eqx.Module):
    """Steady state at one speed from the frequency domain (scalars; a leading speed
    axis after vmap).

    Attributes
    ----------
    orbit : :class:`HarmonicOrbit`, the periodic state as a function of theta.
    y0 : the model's state at theta = 0 on the orbit (a periodic start for
        :func:`gearjax.dynamics.simulate.simulate` with ``y0=``).
    max_mesh_force_N, min_mesh_force_N, dynamic_factor, dte_ptp_m, accel_ptp_m_s2 :
        exact extrema over the period (as :class:`~gearjax.dynamics.simulate.SimulationResult`).
    contact_holds : min mesh force > 0: the linear regime holds, the orbit is the model's.
    error_estimate : largest change of the state on the output grid between ``H`` and
        ``H/2`` harmonics over its largest component (an upper estimate for ``H/2``).
    rank_one_error : relative residual of the split of Eq. (1) and of the forcing basis
        over the samples (round-off when valid).
    small_gain : the small-gain stability bound (:mod:`gearjax.dynamics.small_gain`; ``inf``
        if ``A0`` is not Hurwitz); below ``SMALL_GAIN_MARGIN`` the orbit is proven stable.
    spectral_radius : Floquet spectral radius (NaN when not computed).
    ok : finite results.
    mesh_orders : (3, 5) amplitudes of mesh orders 1..5 of F_D (N), DTE (m), acceleration
        (m/s^2, NaN without one) (:mod:`gearjax.dynamics.orders`).
    """

    orbit: HarmonicOrbit
    y0: jax.Array
    max_mesh_force_N: jax.Array
    min_mesh_force_N: jax.Array
    dynamic_factor: jax.Array
    dte_ptp_m: jax.Array
    accel_ptp_m_s2: jax.Array
    contact_holds: jax.Array
    error_estimate: jax.Array
    rank_one_error: jax.Array
    small_gain: jax.Array
    spectral_radius: jax.Array
    ok: jax.Array
    mesh_orders: jax.Array


def check_linear_model(model):
    """Refuse (:class:`SimulationError`) what the frequency-domain solver cannot solve: a
    non-model or the nonlinear reference formulation."""
    if not isinstance(model, AbstractGearModel):
        raise SimulationError("model", type(model).__name__,
                              "must be a gear model (gearjax.models.base.AbstractGearModel)")
    if model.formulation not in LINEAR_FORMULATIONS:
        raise SimulationError(
            "formulation", model.formulation,
            "the frequency-domain solver needs a linear formulation (te, perturbation); the "
            "reference contact law is nonlinear: use gearjax.dynamics.steady (shooting) or "
            "simulate")


def harmonic_steady_state(model, omega, n_harmonics: int = 256, *,
                          samples_per_mesh_period: int = 128, floquet: bool = False,
                          gmres_tol: float = 1e-13) -> HarmonicResult:
    """Periodic steady state at pinion speed ``omega`` (rad/s) by harmonic balance with
    ``n_harmonics`` harmonics of the excitation period (module docstring). Jit- and
    vmap-compatible in ``omega`` and the model's arrays (on CPU, batch speeds with
    :func:`harmonic_steady_states`, not vmap); ``n_harmonics`` (a power of two
    >= 8), ``samples_per_mesh_period`` (output grid of the metrics, as in ``simulate``)
    and ``floquet`` (also compute the Floquet spectral radius by
    :func:`gearjax.dynamics.stability.monodromy`, one period of ``n`` columns) are static.
    :func:`gearjax.dynamics.harmonic_sweep.harmonic_sweep` chooses ``n_harmonics`` for a tolerance.

    Raises
    ------
    SimulationError
        for a model that is not a gear model, the reference formulation, or a bad
        ``n_harmonics``.
    """
    check_linear_model(model)
    n_h = int(n_harmonics)
    if n_h < 8 or n_h & (n_h - 1):
        raise SimulationError("n_harmonics", n_harmonics, "must be a power of two >= 8")
    omega = jnp.asarray(omega, dtype=float)
    period = float(model.period_rad)
    split, data = _prepare(model, omega, n_h)
    lam, q, qinv = modal = _modal_form(split.a0)
    # H and H/2 in one batch (no LAPACK call inside): the error estimate costs no second
    # compilation
    both, gm_res = jax.vmap(
        lambda k: _orbit(model, omega, n_h, k, data, split, modal, gmres_tol))(
        jnp.asarray([n_h, n_h // 2]))
    orbit = jax.tree_util.tree_map(lambda a: a[0], both)
    half = jax.tree_util.tree_map(lambda a: a[1], both)

    n_mesh = int(round(period / model.mesh_period_rad))
    # the output grid of simulate (mid-cell samples, both sides of every jump) over one
    # period, closed by the periodic neighbours of its ends so that every point is interior
    # (gearjax.dynamics.grid: the padding after the closing point)
    n_samples = samples_per_mesh_period * n_mesh
    pg = grids.period_grid(period, n_samples, model.jumps)
    per, nv, offs = pg.per_period, pg.n_valid, pg.offsets
    k = jnp.arange(per + 2)
    ts = jnp.where(k == 0, offs[nv - 1] - period,
                   jnp.where(k <= nv, offs[jnp.clip(k - 1, 0, per - 1)], offs[0] + period))
    # the windows after the jumps, as in simulate (metrics, rule 3); ts[i + 1] is offs[i]
    cl = grids.jump_clusters(pg, period, n_samples, model.jumps)
    cl = grids.Clusters(cl.before + 1, cl.after + 1, cl.count)
    ring = ringing_length(omega, model.natural_frequency_rad_s(), period / n_samples)
    ys = orbit(ts)
    err = jnp.max(jnp.abs(ys - half(ts))) / jnp.maximum(jnp.max(jnp.abs(ys)), 1e-300)

    nan = jnp.asarray(jnp.nan)

    def observed(t, y):  # the linear orbit's own force: tensile where contact is lost
        o = model.outputs(t, y, omega, contact=False)
        cols = [o.mesh_force_N, o.dte_m] + ([] if o.accel_m_s2 is None else [o.accel_m_s2])
        return jnp.stack(cols)

    # the orbit is the flow: the refinement windows read it instead of integrating
    # (gearjax.dynamics.metrics.refined_extrema on the traced grid)
    vals = jax.vmap(observed)(ts, ys)
    n_valid = nv + 2
    j0, tf = refine_windows(vals, ts, _N_REFINE, n_valid)
    cols = jnp.repeat(jnp.arange(vals.shape[1]), 2)
    wvals = jax.vmap(lambda c, t: jax.vmap(observed)(t, orbit(t))[:, c])(cols, tf)
    v_max, v_min = window_extrema(vals, ts, j0, wvals, n_valid)
    n_jw = min(MAX_JUMP_WINDOWS + 2 * vals.shape[1] * NEAR_EXTREME_WINDOWS, model.jumps.bound)
    if n_jw:
        jj, tj = grids.jump_windows(vals, ts, cl, n_valid, 1, n_jw, ring, 2 * _N_REFINE)
        wj = jax.vmap(lambda t: jax.vmap(observed)(t, orbit(t)))(tj)
        j_max, j_min = jump_window_extrema(vals, ts, jj, tj, wj)
        v_max, v_min = jnp.maximum(v_max, j_max), jnp.minimum(v_min, j_min)
    orders = grids.order_amplitudes(pg, model.jumps, period, model.mesh_period_rad,
                                    n_samples, vals[None, 1:per + 1], N_MESH_ORDERS)
    orders = jnp.concatenate([orders, jnp.full((3 - orders.shape[0], N_MESH_ORDERS), nan)])
    f_s = model.static_force_N
    acc = v_max[2] - v_min[2] if v_max.shape[0] > 2 else nan
    ok = (jnp.all(jnp.isfinite(ys)) & jnp.isfinite(v_max[0]) & jnp.isfinite(v_min[0])
          & (gm_res[0] < 1e-8))
    rho = spectral_radius_of(monodromy(model, omega)) if floquet else nan
    bad = lambda v: jnp.where(ok, v, nan)  # noqa: E731
    return HarmonicResult(
        orbit=orbit, y0=bad(orbit(jnp.zeros(()))), max_mesh_force_N=bad(v_max[0]),
        min_mesh_force_N=bad(v_min[0]), dynamic_factor=bad(v_max[0] / f_s),
        dte_ptp_m=bad(v_max[1] - v_min[1]), accel_ptp_m_s2=bad(acc),
        contact_holds=ok & (v_min[0] > 0.0), error_estimate=jnp.where(ok, err, jnp.inf),
        rank_one_error=split.rank_one_error,
        small_gain=small_gain_bound(lam, (q.T @ split.w) * (qinv @ split.p), split.c_radius),
        spectral_radius=rho, ok=ok, mesh_orders=bad(orders))


# ---------------------------------------------------------------------- batches
def harmonic_steady_states(model, speeds_rad_s, n_harmonics: int = 256,
                           **kwargs) -> HarmonicResult:
    """:func:`harmonic_steady_state` at each of ``speeds_rad_s`` (a 1-D array; the
    result has a leading speed axis). Jittable. On the CPU backend the speeds are mapped
    one after the other, elsewhere vmapped (:mod:`gearjax.dynamics.batching`): vmapped on
    a CPU, its LAPACK kernels would be batched, and two batched kernels at once deadlock
    jaxlib 0.10.2's 2-worker intra-op pool."""
    one = lambda w: harmonic_steady_state(model, w, n_harmonics, **kwargs)  # noqa: E731
    return over_speeds(one, jnp.asarray(speeds_rad_s, dtype=float), sequential=on_cpu())


@eqx.filter_jit
def _bound_batch(model, speeds):
    def one(w):
        split, _ = _prepare(model, w, 8)  # the split only: its Fourier data is not used
        lam, q, qinv = _modal_form(split.a0)
        b = small_gain_bound(lam, (q.T @ split.w) * (qinv @ split.p), split.c_radius)
        return jnp.where(split.rank_one_error <= _SPLIT_TOL, b, jnp.inf)

    return over_speeds(one, speeds, sequential=on_cpu())  # no batched LAPACK on a CPU


def small_gain_bounds(model, speeds_rad_s) -> np.ndarray:
    """The small-gain stability bound (:mod:`gearjax.dynamics.small_gain`) of a linear
    formulation at each speed (rad/s), without an orbit or a monodromy: below
    ``SMALL_GAIN_MARGIN`` every Floquet multiplier is proven inside the unit circle;
    ``inf`` where ``A0`` is not Hurwitz (undamped) or the split's residual exceeds 1e-6."""
    check_linear_model(model)
    speeds = np.asarray(speeds_rad_s, dtype=float).reshape(-1)
    check_speeds(speeds)
    return np.asarray(_bound_batch(model, jnp.asarray(speeds)), dtype=float)
