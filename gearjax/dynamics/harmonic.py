"""Periodic steady state of the linear formulations in the frequency domain.

The te (Eq. (42), sdof Eq. (20)) and perturbation (Eq. (48a), sdof Eq. (47a)) formulations
are, while the mesh force stays compressive, ``y' = (A0 + c(theta) p w^T) y + b(theta)``
(Eq. (1) of :mod:`gearjax.dynamics.harmonic_split`, which reads the split from the model
once per model: :class:`~gearjax.dynamics.harmonic_split.HarmonicPlan`).

Harmonic balance (``H`` harmonics of the excitation period ``P``, ``nu = 2 pi / P``), in
the modal form of ``A0 = Q diag(lambda) Q^-1`` (``eta = Q^-1 y``; one mode of each complex
pair, the state being real), with ``g_h`` the receptance ``sum_k (w^T Q)_k (Q^-1 p)_k /
(i h nu - lambda_k)`` and ``f_h`` the response of ``sigma = w^T y`` to ``b`` alone::

    sigma_h - g_h (c * sigma)_h = f_h,          |h| <= H                          (2)

(``*`` the convolution of the coefficient sequences, applied by FFT: Hill's equation of
the scalar, solved by GMRES, :mod:`gearjax.dynamics.krylov`). ``k(theta)`` jumps (cell
engagement, active-set changes: ``model.jumps``), so ``b`` and ``c`` have Fourier
coefficients ``O(1/h)`` and a plain truncated series has Gibbs errors ``O(1)`` at the jumps
in the velocity and ``O(1/H)`` between them. Both are removed exactly: every function
that jumps is split into its jumps and kinks at the known angles times the periodic
Bernoulli functions ``S0, S1`` (a sawtooth and its zero-mean antiderivative, whose
Fourier coefficients are known), plus a ``C^1`` remainder sampled by DFT (aliasing
``O(N^-3)``); between two jump angles the jump part of the forcing is a quadratic in
theta, so each mode's periodic response to it is exact by the exponential integrator
(``phi_1..phi_3``, one turn around the period closed by periodicity: :func:`_jump_part`).
So the orbit is::

    eta_k(theta) = sum_|h|<=H gt_kh e^{i h nu theta} / (i h nu - lambda_k) + zeta_k(theta)

with ``gt`` the coefficients of the smooth remainder of the forcing ``p c sigma + b``.
The truncation error is ``O(H^-3)`` (``benchmarks/bench_harmonic.py --convergence``);
``error_estimate`` is the largest change, between ``H`` and ``H/2`` harmonics, of the
state at theta = 0 and of the state directions the outputs read on the output grid,
relative to their largest component, or the round-off bound of the jump part where larger
(:meth:`PeriodicSeries.rounding`). :func:`harmonics_for` chooses ``H`` from the top mode
of the model and the tolerance.

Metrics: the orbit is a function of theta (:class:`PeriodicSeries`), measured by
:func:`gearjax.dynamics.measure.measure_orbit`, the measure of every solver (the output
grid, both sides of every jump, the windows around the extremes and after the jumps, the
mesh orders), reading the orbit where an integrating solver re-integrates: no transient
and no ODE solve. The outputs read the state through a few directions only (the split's
``rows``), so the orbit is evaluated there and the measure reads the state ``R^T R y``,
whose outputs are those of ``y``. ``contact_holds`` (minimum linear mesh force over the
period > 0) says whether the linear regime holds; where it does not, the caller must
fall back to a nonlinear solver (shooting or transient). Stability: the periodic orbit of
an LTP system exists inside a parametric instability zone too; with ``floquet=True`` the
Floquet spectral radius of the monodromy matrix
(:func:`gearjax.dynamics.stability.monodromy`) decides, the small-gain bound of
:mod:`gearjax.dynamics.small_gain` proves it without one.
"""

from __future__ import annotations

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..errors import SimulationError
from ..models.base import LINEAR_FORMULATIONS, AbstractGearModel
from .batching import frequency_domain_sequential, over_speeds
from .harmonic_split import (HarmonicPlan, HarmonicSplit, harmonic_split, saw_coeffs,
                             small_gain_of, speed_samples, split_at)
from .krylov import gmres
from .measure import N_REFINE, measure_grid, measure_orbit
from .orders import N_MESH_ORDERS
from .stability import check_speeds, monodromy, spectral_radius_of

__all__ = ["PeriodicSeries", "HarmonicResult", "harmonic_steady_state",
           "harmonic_steady_states", "small_gain_bounds", "check_linear_model",
           "harmonics_for", "TRUNCATION_CONSTANT", "SMOOTHNESS_CONSTANT", "LINEAR_FORMULATIONS"]

_PHI_TERMS = 17  # Taylor terms of phi_3(z) for |z| < 1 (error 1/20! ~ 4e-19)


def _phi123(z):
    """e^z and phi_1, phi_2, phi_3 of the exponential integrators, ``phi_k(z) = sum_i
    z^i / (i + k)!`` (so ``int_0^x e^(lambda (x - s)) s^m ds = m! x^(m+1)
    phi_(m+1)(lambda x)``): for ``|z| < 1`` the Taylor series of ``phi_3`` and the stable
    recurrence ``phi_(k-1) = 1/(k-1)! + z phi_k`` up to ``e^z``; else ``e^z`` and
    ``phi_(k+1) = (phi_k - 1/k!) / z`` down from it."""
    small = jnp.abs(z) < 1.0
    zs = jnp.where(small, z, 0.0)
    acc = jnp.full_like(zs, 1.0 / math.factorial(_PHI_TERMS + 2))
    for i in range(_PHI_TERMS - 2, -1, -1):  # Horner: no complex powers
        acc = acc * zs + 1.0 / math.factorial(i + 3)
    s3 = acc
    s2 = 0.5 + zs * s3
    s1 = 1.0 + zs * s2
    zl = jnp.where(small, 1.0, z)
    ez = jnp.where(small, 1.0 + zs * s1, jnp.exp(z))
    p1 = (ez - 1.0) / zl
    p2 = (p1 - 1.0) / zl
    p3 = (p2 - 0.5) / zl
    return (ez, jnp.where(small, s1, p1), jnp.where(small, s2, p2),
            jnp.where(small, s3, p3))


# ---------------------------------------------------------------------- the orbit
class PeriodicSeries(eqx.Module):
    """A periodic orbit of Eq. (1) read through ``rows``: ``orbit(theta)`` is ``Re(rows
    eta(theta))`` at the simulation angle(s) ``theta`` (rad), shape ``theta.shape + (r,)``
    (``rows = qw``: the model's state; the split's ``rqw``: the state directions its
    outputs read).

    ``eta(theta) = sum_|h|<=H eta_h e^(i h nu theta) + zeta(theta)``: the truncated series
    of the smooth part (here read through ``rows`` and folded onto ``h >= 0``: ``coef``),
    and the modal responses ``zeta`` to the jumps and kinks of the forcing, which is a
    quadratic ``F0 + F1 x + F2 x^2`` in each segment between jump angles (``x`` from its
    start): ``zeta = P(x) + e^(lambda x) (zeta_0 - P(0))`` with the quadratic particular
    solution ``P = alpha + beta x + gamma x^2`` (``gamma = -F2 / lambda``, ``beta = (2 gamma
    - F1) / lambda``, ``alpha = (beta - F0) / lambda``) and the periodic values ``zeta_0``
    at the segment starts (:func:`_jump_part`).

    Attributes
    ----------
    coef : (H+1, r) complex coefficients: ``Re sum_h coef_h e^(i h nu theta)``.
    lam : (m,) eigenvalues of A0 at this speed (per rad).
    rows : (r, m) the modal components read (weights of conjugate pairs included).
    seg_start : (J,) sorted jump angles in [0, P) (rad), the segment starts.
    poly : (J, 3, m) ``alpha, beta, gamma`` of each segment.
    free : (J, m) ``zeta_0 - alpha`` of each segment.
    period : P (rad).
    """

    coef: jax.Array
    lam: jax.Array
    rows: jax.Array
    seg_start: jax.Array
    poly: jax.Array
    free: jax.Array
    period: float = eqx.field(static=True)

    def __call__(self, theta):
        theta = jnp.asarray(theta, dtype=float)
        th = jnp.mod(theta.reshape(-1), self.period)
        y = self._series(th)
        if self.seg_start.shape[0]:
            y = y + jnp.real(jax.vmap(self.modal_jumps)(th) @ self.rows.T)
        return y.reshape(theta.shape + (self.rows.shape[0],))

    def _series(self, th):
        """``Re sum_h coef_h e^(i h nu th)`` (N, r) at the angles ``th`` (N,): the powers
        ``e^(i h nu th)`` as products of two tables of ``_BLOCK`` and ``H / _BLOCK``
        exponentials (N (H / _BLOCK + _BLOCK) exponentials instead of N H)."""
        n_c, r = self.coef.shape
        blk = min(_BLOCK, n_c)
        n_hi = -(-n_c // blk)
        c = jnp.concatenate([self.coef, jnp.zeros((n_hi * blk - n_c, r), self.coef.dtype)])
        c = c.reshape(n_hi, blk, r)
        lo, hi = _exp_tables((2.0 * math.pi / self.period) * th, blk, n_hi)
        t = (lo @ c.transpose(1, 0, 2).reshape(blk, n_hi * r)).reshape(-1, n_hi, r)
        return jnp.real(jnp.einsum("na,nar->nr", hi, t))

    def modal_jumps(self, th):
        """``zeta`` (m,) at one angle ``th`` (rad)."""
        t = jnp.mod(th, self.period)
        a = jnp.searchsorted(self.seg_start, t, side="right") - 1
        x = jnp.where(a < 0, t + self.period - self.seg_start[-1], t - self.seg_start[a])
        c = self.poly[a]
        return c[0] + x * (c[1] + x * c[2]) + jnp.exp(self.lam * x) * self.free[a]

    def rounding(self):
        """(r,) bound of the round-off of the jump part read through ``rows``: the
        particular solution cancels against the free response where ``|lambda| x`` is
        small (a mode much slower than a segment)."""
        if not self.seg_start.shape[0]:
            return jnp.zeros(self.rows.shape[0])
        length = jnp.diff(jnp.concatenate([self.seg_start, self.seg_start[:1] + self.period]))
        ln = length[:, None]
        size = (jnp.abs(self.poly[:, 0]) + ln * jnp.abs(self.poly[:, 1])
                + ln**2 * jnp.abs(self.poly[:, 2]) + jnp.abs(self.free))  # (J, m)
        return 8.0 * jnp.finfo(float).eps * (jnp.abs(self.rows) @ jnp.max(size, axis=0))


_BLOCK = 32  # harmonics per block of the two exponential tables of PeriodicSeries


def _exp_tables(arg, blk: int, n_hi: int):
    """``e^(i arg k)`` for ``k = 0..blk-1`` and ``k = blk j``, ``j = 0..n_hi-1``: (N, blk)
    and (N, n_hi), whose products give every ``k < blk n_hi``."""
    return (jnp.exp(1j * arg[:, None] * jnp.arange(blk)[None, :]),
            jnp.exp(1j * arg[:, None] * (blk * jnp.arange(n_hi))[None, :]))


def _exp_harmonics(arg, n_h: int):
    """``e^(i arg h)`` (N, 2 n_h + 1) for ``h = -n_h..n_h`` from :func:`_exp_tables`."""
    if arg.shape[0] == 0:
        return jnp.zeros((0, 2 * n_h + 1), complex)
    blk = min(_BLOCK, n_h + 1)
    n_hi = -(-(n_h + 1) // blk)
    lo, hi = _exp_tables(arg, blk, n_hi)
    pos = (hi[:, :, None] * lo[:, None, :]).reshape(arg.shape[0], -1)[:, : n_h + 1]
    return jnp.concatenate([jnp.conj(pos[:, :0:-1]), pos], axis=1)


def _jump_part(lam, thj, dg0, dg1, period):
    """Segment data (zeta0, fpoly) of :class:`PeriodicSeries` for the modal jumps ``dg0``
    and slope jumps ``dg1`` (J, m) at the sorted angles ``thj``: the forcing
    ``sum_j dg0_j S0(theta - theta_j) + dg1_j S1(theta - theta_j)`` as a quadratic in
    each segment, and the periodic response at the segment starts (one turn of the
    exponential integrator, closed by ``zeta_0 = z_P / (1 - e^(lambda P))``)."""
    length = jnp.diff(jnp.concatenate([thj, thj[:1] + period]))  # (J,)
    tau = jnp.mod((thj[:, None] - thj[None, :]) / period, 1.0)  # (segment, jump)
    f0 = (0.5 - tau) @ dg0 - (period / 2) * (tau * tau - tau + 1.0 / 6.0) @ dg1
    f1 = -jnp.sum(dg0, axis=0)[None, :] / period - ((2.0 * tau - 1.0) / 2.0) @ dg1
    f2 = jnp.broadcast_to(-jnp.sum(dg1, axis=0) / (2.0 * period), f0.shape)
    fpoly = jnp.stack([f0, f1, f2], axis=1)  # (J, 3, m)
    ez, p1, p2, p3 = _phi123(lam[None, :] * length[:, None])
    ln = length[:, None]
    psi = ln * p1 * f0 + ln**2 * p2 * f1 + 2.0 * ln**3 * p3 * f2  # (J, m)

    def step(z, ep):
        e, ps = ep
        return e * z + ps, z

    z_end, z_starts = jax.lax.scan(step, jnp.zeros_like(lam), (ez, psi))
    zeta_first = z_end / -jnp.expm1(lam * period)
    zeta0 = z_starts + jnp.exp(lam[None, :] * (thj - thj[0])[:, None]) * zeta_first[None, :]
    return zeta0, fpoly


def _convolution(c_full, n_h):
    """``s -> (c * s)_h`` for |h| <= n_h: ``c_full`` (4 n_h + 1,) at -2n_h..2n_h, ``s``
    (2 n_h + 1,), by FFT (``c``'s transform computed once)."""
    m = 5 * n_h  # > 4H: no wrap-around into |h| <= H (sums span -3H..3H); 5 * 2^k: fast FFT

    def wrap(x, k):  # x at -k..k -> circular layout of length m
        return jnp.concatenate([x[k:], jnp.zeros(m - 2 * k - 1, x.dtype), x[:k]])

    fc = jnp.fft.fft(wrap(c_full, 2 * n_h))
    idx = jnp.arange(-n_h, n_h + 1) % m
    return lambda s: jnp.fft.ifft(fc * jnp.fft.fft(wrap(s, n_h)))[idx]


def _receptances(lam, h, nu):
    """``1 / (i h nu - lambda)`` (2H+1, m) in real arithmetic."""
    re = -jnp.real(lam)[None, :]
    im = (h * nu)[:, None] - jnp.imag(lam)[None, :]
    den = re * re + im * im
    return (re - 1j * im) / den


def _solve(split: HarmonicSplit, thj, sides, coeffs, omega, n_h: int, keep, period: float,
           gmres_tol, sig0=None):
    """Hill's equation (2) and the modal orbit with the harmonics ``|h| <= keep`` (traced,
    ``<= n_h``; those above are zero: the arrays keep their ``n_h`` shapes), from the
    sampled excitation at this speed (``sides`` (4, J, k + 1), ``coeffs`` (4H + 1, k + 1));
    GMRES from ``sig0`` (2H+1,) where given: (eta (2H+1, m), zeta0, fpoly, lam at this
    speed, GMRES relative residual, sigma_h).

    The modal forcing ``p c sigma + b`` and its jumps lie in the span of the ``k + 1``
    rows ``F = [Q^-1 p; (Q^-1 U)^T]``: they are assembled there and taken to the modes once
    (``(2H+1) (k+1) m`` operations, not ``(2H+1) J m``). A kept mode of a conjugate pair
    also stands for its conjugate, whose coefficient at ``h`` is the conjugate of its own
    at ``-h`` (a real forcing)."""
    nu = 2.0 * math.pi / period
    k = split.basis.shape[1]
    lam = split.speed_factor(omega) * split.lam
    h = jnp.arange(-n_h, n_h + 1)
    inside = jnp.abs(h) <= keep
    res = jnp.where(inside[:, None], _receptances(lam, h, nu), 0.0)
    pt, wt = split.pt, split.wt
    fr = jnp.concatenate([pt[None, :], split.ub])  # (k + 1, m)
    w1 = res @ (wt[None, :] * fr).T  # (2H+1, k+1): sigma's receptance to each row
    w2 = res @ ((wt * split.pair())[None, :] * fr).T  # the pairs' conjugates
    bh = coeffs[n_h: 3 * n_h + 1, :k]  # (2H+1, k) b_h in the forcing basis
    c_full = coeffs[:, k]
    g = w1[:, 0] + jnp.conj(w2[::-1, 0])  # receptance of sigma, Eq. (2)
    f = jnp.sum(bh * w1[:, 1:], axis=1) + jnp.conj(jnp.sum(bh[::-1] * w2[::-1, 1:], axis=1))
    conv = _convolution(c_full, n_h)
    x0 = f if sig0 is None else jnp.where(jnp.all(jnp.isfinite(sig0)),
                                          jnp.where(inside, sig0, 0.0), f)
    sig, gm_res = gmres(lambda s: s - g * conv(s), f, gmres_tol, x0=x0)
    qh = jnp.where(inside, conv(sig), 0.0)
    # jumps of the forcing p c sigma + b at theta_j, and of its slope, in the rows F
    lo, hi, dlo, dhi = sides
    e = _exp_harmonics(nu * thj, n_h)  # (J, 2H+1): e^{i h nu theta_j}
    sj = jnp.real(e @ sig)
    dsj = jnp.real(e @ (1j * h * nu * sig))  # mean of both one-sided slopes
    d0 = jnp.concatenate([((hi - lo)[:, k] * sj)[:, None], (hi - lo)[:, :k]], axis=1)
    dsig = jnp.real(d0 @ (fr @ (split.weight * wt)))  # jump of sigma' = w^T y'
    dcs = hi[:, k] * (dsj + dsig / 2) - lo[:, k] * (dsj - dsig / 2)
    d1 = jnp.concatenate([dcs[:, None], (dhi - dlo)[:, :k]], axis=1)
    s0, s1 = saw_coeffs(h, period)
    ph = jnp.conj(e).T  # (2H+1, J): e^{-i h nu theta_j}
    gam = (jnp.concatenate([qh[:, None], bh], axis=1) - (ph * s0[:, None]) @ d0
           - (ph * s1[:, None]) @ d1)  # (2H+1, k+1) smooth forcing in the rows F
    eta = res * (gam @ fr)
    if thj.shape[0]:
        zeta0, fpoly = _jump_part(lam, thj, d0 @ fr, d1 @ fr, period)
    else:
        m = lam.shape[0]
        zeta0, fpoly = jnp.zeros((0, m), lam.dtype), jnp.zeros((0, 3, m), lam.dtype)
    return eta, zeta0, fpoly, lam, gm_res, sig


def _series(eta, zeta0, fpoly, lam, rows, thj, n_h: int, period: float) -> PeriodicSeries:
    """The :class:`PeriodicSeries` of the modal orbit read through ``rows`` (r, m)."""
    gm = eta @ rows.T  # (2H+1, r) at -H..H
    coef = jnp.concatenate([gm[n_h:n_h + 1], gm[n_h + 1:] + jnp.conj(gm[:n_h][::-1])])
    f0, f1, f2 = fpoly[:, 0], fpoly[:, 1], fpoly[:, 2]
    gamma = -f2 / lam[None, :]
    beta = (2.0 * gamma - f1) / lam[None, :]
    alpha = (beta - f0) / lam[None, :]
    return PeriodicSeries(coef=coef, lam=lam, rows=rows, seg_start=thj,
                          poly=jnp.stack([alpha, beta, gamma], axis=1), free=zeta0 - alpha,
                          period=period)


def _state_at_zero(eta, series: PeriodicSeries, qw):
    """The model's state at theta = 0 (n,): ``Re(qw eta(0))``."""
    z = jnp.sum(eta, axis=0)
    if series.seg_start.shape[0]:
        z = z + series.modal_jumps(jnp.zeros(()))
    return jnp.real(qw @ z)


# ---------------------------------------------------------------------- one speed
class HarmonicResult(eqx.Module):
    """Steady state at one speed from the frequency domain (scalars; a leading speed
    axis after vmap).

    Attributes
    ----------
    orbit : :class:`PeriodicSeries`, the periodic state as a function of theta.
    y0 : the model's state at theta = 0 on the orbit (a periodic start for
        :func:`gearjax.dynamics.simulate.simulate` with ``y0=``).
    max_mesh_force_N, min_mesh_force_N, dynamic_factor, dte_ptp_m, accel_ptp_m_s2 :
        exact extrema over the period (:mod:`gearjax.dynamics.measure`, as
        :class:`~gearjax.dynamics.simulate.SimulationResult`).
    contact_holds : min mesh force > 0: the linear regime holds, the orbit is the model's.
    error_estimate : largest change of the state at 0 and of the outputs' state directions
        on the output grid between ``H`` and ``H/2`` harmonics over their largest
        component (an upper estimate for ``H/2``).
    rank_one_error : relative residual of the split of Eq. (1), of the forcing and output
        bases and of the eigendecomposition (round-off when valid).
    small_gain : the small-gain stability bound (:mod:`gearjax.dynamics.small_gain`; ``inf``
        if ``A0`` is not Hurwitz); below ``SMALL_GAIN_MARGIN`` the orbit is proven stable.
    spectral_radius : Floquet spectral radius (NaN when not computed).
    ok : finite results, GMRES converged.
    mesh_orders : (3, 5) amplitudes of mesh orders 1..5 of F_D (N), DTE (m), acceleration
        (m/s^2, NaN without one) (:mod:`gearjax.dynamics.orders`).
    """

    orbit: PeriodicSeries
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
    non-model, the nonlinear reference formulation, or te/perturbation with the per-cell
    contact law (its linear regime ends where a cell opens, which the mesh force does not
    show: :attr:`~gearjax.models.base.AbstractGearModel.mesh_level_contact`)."""
    if not isinstance(model, AbstractGearModel):
        raise SimulationError("model", type(model).__name__,
                              "must be a gear model (gearjax.models.base.AbstractGearModel)")
    if not model.formulation.linear:
        raise SimulationError(
            "formulation", model.formulation.name,
            "the frequency-domain solver needs a linear formulation (te, perturbation); the "
            "reference contact law is nonlinear: use gearjax.dynamics.steady (shooting) or "
            "simulate")
    if not model.mesh_level_contact:
        raise SimulationError(
            "model", "contact_law=CELLS",
            "the frequency-domain solver checks contact on the mesh force; with the per-cell "
            "contact law a cell may open while the mesh stays loaded: use the transient or "
            "the shooting (gearjax sweep --method transient or steady)")


def _check_harmonics(n_h) -> int:
    n_h = int(n_h)
    if n_h < 8 or n_h & (n_h - 1):
        raise SimulationError("n_harmonics", n_h, "must be a power of two >= 8")
    return n_h


def harmonic_steady_state(model, omega, n_harmonics: int = 256, *,
                          plan: HarmonicPlan | None = None,
                          samples_per_mesh_period: int = 128, n_refine: int = N_REFINE,
                          floquet: bool = False, gmres_tol: float = 1e-13) -> HarmonicResult:
    """Periodic steady state at pinion speed ``omega`` (rad/s) by harmonic balance with
    ``n_harmonics`` harmonics of the excitation period (module docstring). Jit- and
    vmap-compatible in ``omega`` and the model's arrays (on CPU, batch speeds with
    :func:`harmonic_steady_states`).

    ``plan``: the model's :func:`~gearjax.dynamics.harmonic_split.harmonic_plan` with
    ``n_harmonics`` harmonics (a speed-scaled model: valid at every speed); None: split
    and sampled at ``omega`` (an eigendecomposition per call). Static: ``n_harmonics`` (a
    power of two >= 8), ``samples_per_mesh_period`` and ``n_refine`` (output grid and
    windows of the measure, as in ``simulate``), ``floquet`` (also the Floquet spectral
    radius by :func:`gearjax.dynamics.stability.monodromy`, one period of ``n`` columns).

    Raises
    ------
    SimulationError
        for a model that is not a gear model, the reference formulation, a bad
        ``n_harmonics`` or a plan of another number of harmonics.
    """
    check_linear_model(model)
    n_h = _check_harmonics(n_harmonics)
    omega = jnp.asarray(omega, dtype=float)
    period = float(model.period_rad)
    if plan is None:
        split = split_at(model, omega)
        excitation = speed_samples(model, omega, split, n_h)
    else:
        split, excitation = plan.split, plan.excitation
        if excitation.n_harmonics != n_h:
            raise SimulationError("plan", f"{excitation.n_harmonics} harmonics",
                                  f"a plan for n_harmonics={n_h} is needed")
    thj = excitation.thj
    sides, coeffs, c_radius = excitation.at(omega)
    # H, then H/2 for the error estimate from H's sigma (one traced solve, scanned)
    def solve(sig0, keep):
        out = _solve(split, thj, sides, coeffs, omega, n_h, keep, period, gmres_tol, sig0)
        return out[-1], out[:5]

    f_start = jnp.full(2 * n_h + 1, jnp.nan, dtype=complex)  # NaN: GMRES from its default
    _, (eta, zeta0, fpoly, lam, gm_res) = jax.lax.scan(solve, f_start,
                                                       jnp.asarray([n_h, n_h // 2]))
    read = [_series(eta[i], zeta0[i], fpoly[i], lam[i], split.rqw, thj, n_h, period)
            for i in (0, 1)]
    mg = measure_grid(model, 2, samples_per_mesh_period, n_refine)
    t1 = mg.grid.offsets
    f_h, f_half = read[0](t1), read[1](t1)
    y0, y0_half = (_state_at_zero(eta[i], read[i], split.qw) for i in (0, 1))
    big = lambda a: jnp.maximum(jnp.max(jnp.abs(a)), 1e-300)  # noqa: E731
    err = jnp.maximum(jnp.max(jnp.abs(f_h - f_half)) / big(f_h),
                      jnp.max(jnp.abs(y0 - y0_half)) / big(y0))
    err = jnp.maximum(err, jnp.max(read[0].rounding()) / big(f_h))
    # the one measure, the state read through the outputs' directions: R^T (R y)
    meas = measure_orbit(model, omega, lambda t: read[0](t) @ split.rows, mg, contact=False)
    v_max, v_min = meas.maxima, meas.minima
    nan = jnp.asarray(jnp.nan)
    orders = jnp.concatenate([meas.orders, jnp.full((3 - meas.orders.shape[0], N_MESH_ORDERS),
                                                    nan)])
    f_s = model.static_force_N
    acc = v_max[2] - v_min[2] if v_max.shape[0] > 2 else nan
    ok = (jnp.all(jnp.isfinite(meas.vals)) & jnp.all(jnp.isfinite(y0))
          & jnp.isfinite(v_max[0]) & jnp.isfinite(v_min[0]) & (gm_res[0] < 1e-8))
    rho = spectral_radius_of(monodromy(model, omega)) if floquet else nan
    bad = lambda v: jnp.where(ok, v, nan)  # noqa: E731
    orbit = _series(eta[0], zeta0[0], fpoly[0], lam[0], split.qw, thj, n_h, period)
    return HarmonicResult(
        orbit=orbit, y0=bad(y0), max_mesh_force_N=bad(v_max[0]),
        min_mesh_force_N=bad(v_min[0]), dynamic_factor=bad(v_max[0] / f_s),
        dte_ptp_m=bad(v_max[1] - v_min[1]), accel_ptp_m_s2=bad(acc),
        contact_holds=ok & (v_min[0] > 0.0), error_estimate=jnp.where(ok, err, jnp.inf),
        rank_one_error=excitation.split_error, small_gain=small_gain_of(split, c_radius, omega),
        spectral_radius=rho, ok=ok, mesh_orders=bad(orders))


# ---------------------------------------------------------------------- batches
def harmonic_steady_states(model, speeds_rad_s, n_harmonics: int = 256, *,
                           plan: HarmonicPlan | None = None, samples_per_mesh_period: int = 128,
                           n_refine: int = N_REFINE, floquet: bool = False,
                           gmres_tol: float = 1e-13) -> HarmonicResult:
    """:func:`harmonic_steady_state` at each of ``speeds_rad_s`` (a 1-D array; the
    result has a leading speed axis), with its options. Jittable. Mapped or vmapped as
    :func:`gearjax.dynamics.batching.frequency_domain_sequential` decides (mapped on a
    CPU where each speed decomposes its own ``A0``: ``plan`` None)."""
    def one(w):
        return harmonic_steady_state(model, w, n_harmonics, plan=plan,
                                     samples_per_mesh_period=samples_per_mesh_period,
                                     n_refine=n_refine, floquet=floquet, gmres_tol=gmres_tol)

    return over_speeds(one, jnp.asarray(speeds_rad_s, dtype=float),
                       sequential=frequency_domain_sequential(plan is None))


def harmonics_for(model, split: HarmonicSplit, speeds_rad_s, rtol: float,
                  lo: int = 64, hi: int = 4096) -> int:
    """Harmonics ``H`` (a power of two in ``[lo, hi]``) for the speeds ``speeds_rad_s``
    (rad/s) at the relative accuracy ``rtol`` (host function): the truncation error falls
    like ``H^-3`` once the highest harmonic passes the top mode of ``A0`` (``|lambda|_max``
    at the lowest speed), measured ``~ C (|lambda|_max / (H nu))^3`` with ``C`` =
    :data:`TRUNCATION_CONSTANT` on the Baud-Velex rigs (``benchmarks/results/harmonic.md``),
    so ``H nu >= |lambda|_max (C / rtol)^(1/3)``; and at least ``(D / rtol)^(1/3)``
    (:data:`SMOOTHNESS_CONSTANT`) for the smooth part of the forcing at high speed."""
    s = split.speed_factor(jnp.asarray(float(np.min(speeds_rad_s))))
    top = float(np.max(np.abs(np.asarray(s * split.lam))))
    nu = 2.0 * math.pi / float(model.period_rad)
    r = float(rtol)
    need = max(top / nu * (TRUNCATION_CONSTANT / r) ** (1.0 / 3.0),
               (SMOOTHNESS_CONSTANT / r) ** (1.0 / 3.0), float(lo))
    return int(min(hi, 2 ** math.ceil(math.log2(need))))


TRUNCATION_CONSTANT = 2e-5  # error ~ C (|lambda|_max / (H nu))^3 (harmonics_for)
SMOOTHNESS_CONSTANT = 3.0  # error ~ D H^-3 of the smooth part (harmonics_for)


@eqx.filter_jit
def _bound_batch(model, speeds, split):
    def one(w):
        sp = split_at(model, w) if split is None else split
        exc = speed_samples(model, w, sp, 8)  # c's range only
        b = small_gain_of(sp, exc.at(w)[2], w)
        return jnp.where(exc.split_error <= _SPLIT_TOL, b, jnp.inf)

    return over_speeds(one, speeds, sequential=frequency_domain_sequential(split is None))


_SPLIT_TOL = 1e-6  # largest split residual for which small_gain_bounds uses the bound


def small_gain_bounds(model, speeds_rad_s) -> np.ndarray:
    """The small-gain stability bound (:mod:`gearjax.dynamics.small_gain`) of a linear
    formulation at each speed (rad/s), without an orbit or a monodromy: below
    ``SMALL_GAIN_MARGIN`` every Floquet multiplier is proven inside the unit circle;
    ``inf`` where ``A0`` is not Hurwitz (undamped) or the split's residual exceeds 1e-6."""
    check_linear_model(model)
    speeds = np.asarray(speeds_rad_s, dtype=float).reshape(-1)
    check_speeds(speeds)
    split = harmonic_split(model, float(np.median(speeds))) if model.speed_scaled_state else None
    return np.asarray(_bound_batch(model, jnp.asarray(speeds), split), dtype=float)
