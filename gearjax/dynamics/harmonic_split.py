"""The linear split of the te/perturbation equations that the frequency-domain solver
(:mod:`gearjax.dynamics.harmonic`) solves, read once per model and sampled for it.

While the mesh force stays compressive, Eq. (42) (sdof Eq. (20)) and Eq. (48a) (sdof
Eq. (47a)) are, in the angle ``theta = Omega1 t`` (rad)::

    y' = A(theta) y + b(theta),     A(theta) = A0 + c(theta) p w^T,                 (1)

with a *rank-one* parametric part: the mesh stiffness fluctuation ``k(theta) - k_m`` acts
along the mesh vector only (``(k - k_m) V V^T`` in Eq. (42); ``k(theta)/k_m`` in the single
row of Eq. (20)); ``c = 0`` for Eqs. (48a)/(47a).

What is asked of the model: its :meth:`~gearjax.models.base.AbstractGearModel.vector_field`
without the contact law (affine in ``y``), its ``outputs`` and, declared,
:attr:`~gearjax.models.base.AbstractGearModel.speed_scaled_state`. ``A0, p, w`` are read
by forward-mode linearisation: ``A(theta) xi`` for a probe ``xi`` at every sample shows the
varying direction ``p``; the difference of two Jacobians gives ``w``; ``A0`` takes the
midpoint of the range of ``c`` (so ``|c| <= c_radius``, the smallest radius for the
small-gain bound). Every forcing term the model contains (TE_S, NLTE and its derivatives
after the models' substitutions, eccentricity) is in ``b = f(theta, 0)`` without naming it.

:class:`HarmonicSplit` holds the eigendecomposition ``A0 = Q diag(lambda) Q^-1`` (one mode
of each complex-conjugate pair kept, weighted 2), the modal forms of ``p``, ``w``, an
orthonormal basis ``U`` of the few directions of ``b`` and an orthonormal basis ``R`` of
the state directions the outputs read (their Jacobians' rows: mesh vector, encoder
vector, ...), so that the outputs of the state ``R^T R y`` are those of ``y``.
:class:`Excitation` holds the sampled ``(U^T b, c)`` of the harmonic balance: the one-sided
values and slopes at the jump angles and the jump-corrected Fourier coefficients.

A speed-scaled model (the models' states ``(z / x, z' / (r x))``, ``r = omega / Omega``)
has ``A(theta; Omega) = Omega^-1 A_1(theta)``, so one split serves every speed (``lambda``
scales with ``Omega_r / Omega``, the eigenvectors stay), and ``(U^T b, c)`` is
``sum_p Omega^p V_p(theta)``, ``p = -1, 0, 1`` (the excitation terms over ``Omega``, the
substituted NLTE' terms, the inertial ones times ``Omega``): :func:`harmonic_plan` reads
it at three speeds, checks the split and that form at a fourth and keeps the Fourier data
of each ``V_p`` (:class:`HarmonicPlan`), so that a speed costs no sampling at all
(host function, ranks read from the singular values). A model whose state is not
speed-scaled gets its split and samples at every speed (:func:`split_at`,
:func:`speed_samples`; jittable). ``split_error`` is the largest relative residual of
these checks: round-off where the split holds.
"""

from __future__ import annotations

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .exported import AbstractProgramStore, NoProgramStore
from .measure import observer
from .small_gain import small_gain_bound

__all__ = ["HarmonicSplit", "Excitation", "HarmonicPlan", "harmonic_split", "harmonic_plan",
           "split_at", "speed_samples", "small_gain_of", "saw_coeffs", "JUMP_SIDE",
           "FORCING_RANK", "OUTPUT_RANK", "SPEED_POWERS"]

JUMP_SIDE = 1e-9  # one-sided evaluation at theta_j -/+ JUMP_SIDE * period
FORCING_RANK = 48  # most directions of the forcing b (the models': a few; checked)
OUTPUT_RANK = 48  # most state directions the outputs read (the models': a few; checked)
SPEED_POWERS = (-1, 0, 1)  # powers of Omega in the sampled forcing of a speed-scaled model
_FIT_SPEEDS = (0.5, 1.0, 2.0)  # fitting speeds / Omega_r, and the check speed below
_CHECK_SPEED = 3.0
_SPLIT_SAMPLES = 256  # samples per excitation period that find the split and the bases
_RANK_TOL = 1e-13  # singular values kept, relative to the largest (bases U and R)
_PAIR_TOL = 1e-12  # |Im lambda| / |lambda| below which an eigenvalue counts as real


class HarmonicSplit(eqx.Module):
    """The split (1) at the speed ``omega_ref`` (module docstring); ``m`` modes kept (one
    per conjugate pair), ``k`` forcing directions, ``n_o`` output directions.

    omega_ref : the speed (rad/s) of ``lam``; at ``Omega`` the eigenvalues are
        ``lam * omega_ref / Omega`` where ``scaled``.
    lam, weight : (m,) eigenvalues of A0 (per rad) and weights (2: the mode stands for its
        conjugate pair too, 1: real or unpaired).
    qw : (n, m) eigenvectors times their weights: the state is ``Re(qw eta)``.
    pt, wt : (m,) modal ``Q^-1 p`` and ``Q^T w``.
    p, w : (n,) the unit vectors of the rank-one part; ``a0w``, ``a0xi`` : (n,) ``A0 w`` and
        ``A0 xi`` (``xi`` the probe).
    basis : (n, k) orthonormal basis of the forcing; ``ub`` : (k, m) its modal form.
    rows : (n_o, n) orthonormal basis of the outputs' state directions; ``rqw`` : (n_o, m)
        ``rows @ qw``.
    gain : ``sup_chi |w^T (i chi - A0)^-1 p|`` (inf where A0 is not Hurwitz).
    error : largest relative residual of the split's own checks (eigendecomposition,
        probe, bases at its samples).
    scaled : the model's state is speed-scaled (static).
    """

    omega_ref: jax.Array
    lam: jax.Array
    weight: jax.Array
    qw: jax.Array
    pt: jax.Array
    wt: jax.Array
    p: jax.Array
    w: jax.Array
    a0w: jax.Array
    a0xi: jax.Array
    basis: jax.Array
    ub: jax.Array
    rows: jax.Array
    rqw: jax.Array
    gain: jax.Array
    error: jax.Array
    scaled: bool = eqx.field(static=True)

    def speed_factor(self, omega):
        """``omega_ref / Omega``: A0 at ``omega`` is this times the split's A0."""
        return self.omega_ref / omega if self.scaled else jnp.ones_like(omega)

    def pair(self):
        """(m,) bool: the mode stands for a conjugate pair."""
        return self.weight > 1.5


class Excitation(eqx.Module):
    """``(U^T b, c)`` of the harmonic balance with ``H`` harmonics, as the sum over the
    speed powers ``p`` of ``powers`` of ``Omega^p`` times the stored data (one power, 0,
    for the samples of one speed).

    thj : (J,) the sorted jump angles (rad) in [0, P) of the model's padded jump set
        (padding and merged entries jump by nothing: zero-length segments).
    sides : (P, 4, J, k + 1) the one-sided values (lo, hi) and slopes (dlo, dhi) there.
    coeffs : (P, 4H + 1, k + 1) the jump-corrected Fourier coefficients at -2H..2H.
    c_samples : (P, N) ``c`` on the samples (its range: the small-gain bound).
    omega_unit : the speed (rad/s) the powers are taken of: ``(Omega / omega_unit)^p``.
    split_error : see the module docstring.
    powers : the powers of Omega (static).
    """

    thj: jax.Array
    sides: jax.Array
    coeffs: jax.Array
    c_samples: jax.Array
    omega_unit: jax.Array
    split_error: jax.Array
    powers: tuple = eqx.field(static=True)

    @property
    def n_harmonics(self) -> int:
        """``H``."""
        return (self.coeffs.shape[1] - 1) // 4

    def at(self, omega):
        """(sides (4, J, k + 1), coeffs (4H + 1, k + 1), max |c|) at pinion speed
        ``omega`` (rad/s)."""
        x = omega / self.omega_unit
        wp = jnp.stack([x ** p for p in self.powers])
        return (jnp.tensordot(wp, self.sides, axes=1), jnp.tensordot(wp, self.coeffs, axes=1),
                jnp.max(jnp.abs(wp @ self.c_samples)))


class HarmonicPlan(eqx.Module):
    """The split and the sampled excitation of a speed-scaled model, valid at every speed
    (:func:`harmonic_plan`)."""

    split: HarmonicSplit
    excitation: Excitation


def _probe(n):
    return jnp.cos(1.7 * jnp.arange(n) + 0.3)  # a probe without structure


def _field(model, omega):
    return lambda th, y: model.vector_field(th, y, omega, contact=False)


def _row_basis(a, cap: int, xp):
    """Orthonormal rows (cap, n) spanning the rows of ``a`` (N, n) (a fixed pseudo-random
    sketch, QR, SVD; ``xp``: numpy or jax.numpy), their singular values (cap,) and the
    relative residual of ``a``."""
    n = a.shape[1]
    cap = min(cap, n)
    sketch = xp.cos(1.3 * xp.outer(xp.arange(n), xp.arange(1, cap + 1)) + 0.7)
    u, _, _ = xp.linalg.svd(a @ sketch, full_matrices=False)  # range of the rows' images
    _, sv, vt = xp.linalg.svd(u.T @ a, full_matrices=False)
    res = xp.max(xp.abs(a - (a @ vt.T) @ vt))
    return vt, sv, res / xp.maximum(xp.max(xp.abs(a)), 1e-300)


def _split_samples(model):
    period = float(model.period_rad)
    th = (jnp.arange(_SPLIT_SAMPLES) + 0.5) * (period / _SPLIT_SAMPLES)
    thj = model.jumps.thetas  # padding repeats an angle: the same samples again
    d = JUMP_SIDE * period
    return jnp.concatenate([th, thj - d, thj + d])


def _linear_parts(model, omega_ref, n_forcing: int, output_rows: bool):
    """What the split reads of the model at ``omega_ref`` (jittable, no LAPACK): ``A(theta)
    xi`` at the samples, the varying direction ``p``, two Jacobians (``j1`` where the
    probe's response is farthest from its mean, ``j2`` opposite along ``p``), ``w``,
    ``c(theta)``, the forcing at ``omega_ref`` and twice it (where ``n > n_forcing``) and,
    with ``output_rows``, each output's normalised state direction at both speeds."""
    n = model.state_size
    ts = _split_samples(model)
    f = _field(model, omega_ref)
    xi = _probe(n)
    zero = jnp.zeros(n)

    def a_dot(t, v):
        return jax.jvp(lambda y: f(t, y), (zero,), (v,))[1]

    g = jax.vmap(a_dot, in_axes=(0, None))(ts, xi)
    dev = g - jnp.mean(g, axis=0)[None, :]
    norms = jnp.sqrt(jnp.sum(dev * dev, axis=1))
    m1 = jnp.argmax(norms)
    p = dev[m1] / jnp.maximum(norms[m1], 1e-300)
    m2 = jnp.argmin(dev @ p)
    jac = lambda t: jax.jacfwd(lambda y: f(t, y))(zero)  # noqa: E731
    j1, j2 = jac(ts[m1]), jac(ts[m2])
    row = p @ (j1 - j2)
    w = row / jnp.maximum(jnp.sqrt(jnp.sum(row * row)), 1e-300)
    p = jnp.where(jnp.any(row != 0), p, 0.0)
    c = jax.vmap(lambda t: p @ (a_dot(t, w) - j1 @ w))(ts)
    out = dict(g=g, p=p, w=w, j1=j1, c=c, xi=xi)
    if n > n_forcing:  # the forcing at two speeds: its directions, whatever their speed law
        out["b"] = jnp.concatenate([jax.vmap(lambda t: _field(model, s * omega_ref)(t, zero))(
            ts) for s in (1.0, 2.0)])
    if output_rows:
        t_o = jnp.concatenate([ts[:_SPLIT_SAMPLES:8], ts[_SPLIT_SAMPLES:]])  # and the jumps

        def out_rows(w_):  # each output's state direction at each sample, normalised
            jo = jax.vmap(lambda t: jax.jacrev(lambda y: observer(model, w_, False)(t, y))(
                zero))(t_o).reshape(-1, n)
            return jo / jnp.maximum(jnp.linalg.norm(jo, axis=1), 1e-300)[:, None]

        out["jo"] = jnp.concatenate([out_rows(omega_ref), out_rows(2.0 * omega_ref)])
    return out


def _decompose(parts, n_forcing: int, xp):
    """The split from :func:`_linear_parts` (``xp``: numpy on the host, jax.numpy when
    traced): A0 at the midpoint of ``c``'s range, the probe's residual, the
    eigendecomposition and its residual, the forcing and output bases (identity without
    their samples) with their singular values, the small-gain ``sup |g|``."""
    g, p, w, j1, c, xi = (parts[k] for k in ("g", "p", "w", "j1", "c", "xi"))
    n = j1.shape[0]
    cbar = 0.5 * (xp.max(c) + xp.min(c))
    a0 = j1 + cbar * xp.outer(p, w)
    resid = g - (a0 @ xi)[None, :] - (c - cbar)[:, None] * p[None, :] * (w @ xi)
    err = xp.max(xp.abs(resid)) / xp.maximum(xp.max(xp.abs(g)), 1e-300)
    lam, q = xp.linalg.eig(a0)
    lam, q = lam.astype(complex), q.astype(complex)  # numpy: real where every one is
    qinv = xp.linalg.solve(q, xp.eye(n, dtype=q.dtype))
    eig_err = xp.max(xp.abs((q * lam[None, :]) @ qinv - a0)) / xp.maximum(
        xp.max(xp.abs(a0)), 1e-300)
    if "b" in parts:
        vt, b_sv, b_err = _row_basis(parts["b"], n_forcing, xp)
        basis = vt.T
    else:
        basis, b_sv, b_err = xp.eye(n), xp.ones(n), 0.0 * err
    if "jo" in parts:
        rows, r_sv, r_err = _row_basis(parts["jo"], OUTPUT_RANK, xp)
    else:
        rows, r_sv, r_err = xp.eye(n), xp.ones(n), 0.0 * err
    gain = small_gain_bound(lam, (q.T @ w) * (qinv @ p), 1.0, xp)
    return dict(lam=lam, q=q, qinv=qinv, p=p, w=w, a0w=a0 @ w, a0xi=a0 @ xi, basis=basis,
                b_sv=b_sv, rows=rows, r_sv=r_sv, gain=gain,
                error=xp.maximum(xp.maximum(err, eig_err), xp.maximum(b_err, r_err)))


def _assemble(raw, omega_ref, keep, weight, k: int, n_o: int, scaled: bool) -> HarmonicSplit:
    lam, q, qinv = raw["lam"][keep], raw["q"][:, keep], raw["qinv"][keep]
    basis, rows = raw["basis"][:, :k], raw["rows"][:n_o]
    qw = q * weight[None, :]
    return HarmonicSplit(
        omega_ref=jnp.asarray(omega_ref, dtype=float), lam=lam, weight=weight, qw=qw,
        pt=qinv @ raw["p"], wt=q.T @ raw["w"], p=raw["p"], w=raw["w"], a0w=raw["a0w"],
        a0xi=raw["a0xi"], basis=basis, ub=(qinv @ basis).T, rows=rows, rqw=rows @ qw,
        gain=raw["gain"], error=raw["error"], scaled=scaled)


def split_at(model, omega) -> HarmonicSplit:
    """The split at the speed ``omega`` (rad/s), every mode kept and the outputs read
    from the whole state (jittable; calls LAPACK: map, do not vmap, on a CPU)."""
    raw = _decompose(_linear_parts(model, jnp.asarray(omega, dtype=float), FORCING_RANK,
                                   False), FORCING_RANK, jnp)
    n = model.state_size
    k = min(n, FORCING_RANK)
    return _assemble(raw, omega, jnp.arange(n), jnp.ones(n), k, n, False)


def _rank(sv) -> int:
    sv = np.asarray(sv, dtype=float)
    if sv.size == 0 or not np.isfinite(sv).all() or sv[0] <= 0:
        return max(1, sv.size)
    return max(1, int(np.sum(sv > _RANK_TOL * sv[0])))


def _kept_modes(lam):
    """(indices, weights) of one mode per conjugate pair (weight 2) and every real one
    (weight 1); every mode (weight 1) where the pairs do not match."""
    lam = np.asarray(lam)
    tol = _PAIR_TOL * np.maximum(np.abs(lam), 1e-300)
    up, down = lam.imag > tol, lam.imag < -tol
    if up.sum() != down.sum() or not np.allclose(np.sort_complex(lam[up]),
                                                 np.sort_complex(np.conj(lam[down])),
                                                 rtol=1e-8, atol=0.0):
        return np.arange(lam.size), np.ones(lam.size)
    keep = np.flatnonzero(~down)
    return keep, np.where(up[keep], 2.0, 1.0)


def harmonic_split(model, omega_ref: float,
                   programs: AbstractProgramStore = NoProgramStore()) -> HarmonicSplit:
    """The split of ``model`` at ``omega_ref`` (rad/s; host function): with one mode per
    conjugate pair and the bases cut to their numerical rank where
    ``model.speed_scaled_state`` (valid at every speed); else :func:`split_at`.
    ``programs``: where its compiled program and its value come from
    (:mod:`gearjax.dynamics.exported`)."""
    if not model.speed_scaled_state:
        return programs.value(_split_at_jit, model, jnp.asarray(float(omega_ref)))
    raw = jax.device_get(programs.value(_raw_split_jit, model, jnp.asarray(float(omega_ref)),
                                        FORCING_RANK))
    keep, weight = _kept_modes(raw["lam"])
    n = model.state_size
    k = min(n, _rank(raw["b_sv"]))
    return _assemble({key: jnp.asarray(v) for key, v in raw.items()}, float(omega_ref),
                     jnp.asarray(keep), jnp.asarray(weight), k, _rank(raw["r_sv"]), True)


_split_at_jit = eqx.filter_jit(split_at)


@eqx.filter_jit
def _raw_split_jit(model, omega_ref, n_forcing: int):
    """The split of :func:`harmonic_split` before its rank truncation (one program: XLA's
    single-threaded LAPACK kernels on the CPU)."""
    return _decompose(_linear_parts(model, omega_ref, n_forcing, True), n_forcing, jnp)


# ---------------------------------------------------------------------- the samples
def saw(x, period):
    """(S0, S1) at angles ``x`` (rad): unit sawtooth and its zero-mean antiderivative."""
    t = jnp.mod(x / period, 1.0)
    return 0.5 - t, -period * (t * t - t + 1.0 / 6.0) / 2.0


def saw_coeffs(h, period):
    """Fourier coefficients of S0, S1 at harmonics ``h`` (integers, any shape)."""
    hs = jnp.where(h == 0, 1, h)
    s0 = jnp.where(h == 0, 0.0, 1.0 / (2j * jnp.pi * hs))
    s1 = jnp.where(h == 0, 0.0, s0 / (1j * hs * (2.0 * jnp.pi / period)))
    return s0, s1


def _angles(model, n_h: int):
    """(mid-cell samples (4H,), jump angles (J,) of the model's padded jump set, which of
    them count (:meth:`~gearjax.excitation.jumps.JumpSet.distinct`: the others jump by
    nothing), all sample angles, step, delta)."""
    period = float(model.period_rad)
    n_s = 4 * n_h
    th = (jnp.arange(n_s) + 0.5) * (period / n_s)
    thj, use = model.jumps.thetas, model.jumps.distinct()
    d = JUMP_SIDE * period
    # one-sided slopes by differences over ``step`` (< a quarter of the closest jumps)
    step = jnp.asarray(1e-6 * period)
    if thj.shape[0]:
        u = jnp.sort(jnp.where(use, thj, jnp.inf))  # the angles that count, then inf
        i, n_use = jnp.arange(u.shape[0]), jnp.sum(use)
        gaps = jnp.where(i + 1 < n_use, jnp.roll(u, -1) - u, u[0] + period - u)
        step = jnp.minimum(step, 0.25 * jnp.min(jnp.where(i < n_use, gaps, period)))
    t_all = jnp.concatenate([th, thj - d - step, thj - d, thj + d, thj + d + step])
    return th, (thj, use), t_all, step, d


def _sample(model, omega, split: HarmonicSplit, t_all, n_s: int):
    """``(U^T b, c)`` (N, k + 1) at pinion speed ``omega`` on the angles ``t_all`` (the
    first ``n_s`` mid-cell samples), and the relative residual of the split, the forcing
    basis and the outputs' basis there."""
    n = model.state_size
    f = _field(model, omega)
    s = split.speed_factor(omega)
    zero, xi = jnp.zeros(n), _probe(n)

    def sample(t):
        b, aw = jax.jvp(lambda y: f(t, y), (zero,), (split.w,))
        axi = jax.jvp(lambda y: f(t, y), (zero,), (xi,))[1]
        c = split.p @ (aw - s * split.a0w)
        resid = axi - s * split.a0xi - c * split.p * (split.w @ xi)
        return b, c, jnp.max(jnp.abs(resid)), jnp.max(jnp.abs(axi))

    b, c, r_res, r_scale = jax.vmap(sample)(t_all)
    err = jnp.max(r_res) / jnp.maximum(jnp.max(r_scale), 1e-300)
    bb = b @ split.basis
    b_err = jnp.max(jnp.abs(b - bb @ split.basis.T)) / jnp.maximum(jnp.max(jnp.abs(b)), 1e-300)
    # the outputs read the state through ``rows`` only (at the jump sides and 32 samples)
    observed = observer(model, omega, False)
    proj = split.rows.T @ (split.rows @ xi)
    t_chk = jnp.concatenate([t_all[: n_s: max(1, n_s // 32)], t_all[n_s:]])
    o0 = jax.vmap(lambda t: observed(t, zero))(t_chk)
    o1 = jax.vmap(lambda t: observed(t, xi))(t_chk) - o0
    o2 = jax.vmap(lambda t: observed(t, proj))(t_chk) - o0
    o_err = jnp.max(jnp.max(jnp.abs(o1 - o2), axis=0) / jnp.maximum(
        jnp.max(jnp.abs(o1), axis=0), 1e-300))
    v = jnp.concatenate([bb, c[:, None]], axis=1)
    return v, jnp.maximum(jnp.maximum(err, b_err), o_err)


def _fourier(v, th, jumps, step: float, d: float, period: float, n_h: int):
    """One-sided values and slopes at the jumps (4, J, k + 1) and the jump-corrected
    Fourier coefficients at -2H..2H (4H + 1, k + 1) of the samples ``v`` (the layout of
    :func:`_angles`): the jumps and kinks removed exactly (sawtooth ``S0`` and its
    antiderivative ``S1``, whose coefficients are known), the ``C^1`` remainder by DFT.
    Linear in ``v``."""
    nu = 2.0 * math.pi / period
    thj, use = jumps  # (angles, which count) of :func:`_angles`
    n_s, n_j = th.shape[0], thj.shape[0]
    vl2, vl1, vr1, vr2 = (v[n_s + i * n_j: n_s + (i + 1) * n_j] for i in range(4))
    dl, dr = (vl1 - vl2) / step, (vr2 - vr1) / step
    lo, hi = vl1 + d * dl, vr1 - d * dr  # one-sided limits at theta_j
    # padding and merged entries of the jump set jump by nothing
    hi, dr = jnp.where(use[:, None], hi, lo), jnp.where(use[:, None], dr, dl)
    j0, j1 = hi - lo, dr - dl
    s0, s1 = saw(th[:, None] - thj[None, :], period)  # (N, J)
    smooth = v[:n_s] - s0 @ j0 - s1 @ j1  # C^1 remainder
    k = jnp.arange(-2 * n_h, 2 * n_h + 1)
    dft = jnp.fft.fft(smooth, axis=0)[k % n_s] / n_s
    dft = dft * jnp.exp(-1j * jnp.pi * k / n_s)[:, None]  # samples at (m + 1/2) P / N
    c0, c1 = saw_coeffs(k, period)
    ph = jnp.exp(-1j * nu * jnp.outer(k, thj))  # (4H+1, J)
    coeffs = dft + (ph * c0[:, None]) @ j0 + (ph * c1[:, None]) @ j1
    return jnp.stack([lo, hi, dl, dr]), coeffs


def speed_samples(model, omega, split: HarmonicSplit, n_h: int) -> Excitation:
    """The :class:`Excitation` of one speed ``omega`` (rad/s; power 0) on ``4 n_h``
    samples and both sides of every jump, and the split's residual there (jittable)."""
    period = float(model.period_rad)
    th, thj, t_all, step, d = _angles(model, n_h)
    v, err = _sample(model, omega, split, t_all, th.shape[0])
    sides, coeffs = _fourier(v, th, thj, step, d, period, n_h)
    return Excitation(thj=thj[0], sides=sides[None], coeffs=coeffs[None],
                      c_samples=v[None, :, -1], omega_unit=jnp.asarray(omega, dtype=float),
                      split_error=jnp.maximum(err, split.error), powers=(0,))


def _plan_excitation(model, split: HarmonicSplit, n_h: int) -> Excitation:
    """The :class:`Excitation` of a speed-scaled model over :data:`SPEED_POWERS`: sampled
    at ``_FIT_SPEEDS`` times the split's speed, each ``V_p`` fitted, the fit and the split
    checked at ``_CHECK_SPEED`` times it (jittable)."""
    period = float(model.period_rad)
    th, thj, t_all, step, d = _angles(model, n_h)
    n_s = th.shape[0]
    ratios = jnp.asarray(_FIT_SPEEDS + (_CHECK_SPEED,))
    vs, errs = jax.vmap(lambda r: _sample(model, split.omega_ref * r, split, t_all, n_s))(ratios)
    # in powers of Omega / Omega_r (a well-conditioned Vandermonde matrix)
    vand = np.array([[r ** p for p in SPEED_POWERS] for r in _FIT_SPEEDS])  # (3, P)
    vp = jnp.tensordot(jnp.asarray(np.linalg.inv(vand)), vs[:3], axes=1)
    pred = jnp.tensordot(jnp.asarray([_CHECK_SPEED ** p for p in SPEED_POWERS]), vp, axes=1)
    # relative to the forcing's size (its columns together) and, for c, to A0's (c is
    # round-off where the stiffness is constant: Eq. (48a))
    big = jnp.max(jnp.abs(vs), axis=(0, 1))
    scale = jnp.concatenate([jnp.full(big.shape[0] - 1, jnp.max(big[:-1])), jnp.maximum(
        big[-1:], jnp.max(jnp.abs(split.a0w)) / min(_FIT_SPEEDS))])
    fit_err = jnp.max(jnp.max(jnp.abs(pred - vs[3]), axis=0) / jnp.maximum(scale, 1e-300))
    sides, coeffs = jax.vmap(lambda v: _fourier(v, th, thj, step, d, period, n_h))(vp)
    return Excitation(thj=thj[0], sides=sides, coeffs=coeffs, c_samples=vp[:, :, -1],
                      omega_unit=split.omega_ref,
                      split_error=jnp.maximum(jnp.max(errs), jnp.maximum(fit_err, split.error)),
                      powers=SPEED_POWERS)


_plan_excitation_jit = eqx.filter_jit(_plan_excitation)


def harmonic_plan(model, split: HarmonicSplit, n_h: int,
                  programs: AbstractProgramStore = NoProgramStore()) -> HarmonicPlan:
    """The :class:`HarmonicPlan` of a speed-scaled ``model`` with ``n_h`` harmonics, from
    its ``split`` (:func:`harmonic_split`): one sampling for every speed (host function;
    ``programs``: where its compiled program and its value come from)."""
    return HarmonicPlan(split=split, excitation=programs.value(_plan_excitation_jit, model,
                                                               split, int(n_h)))


def small_gain_of(split: HarmonicSplit, c_radius, omega):
    """The small-gain bound (:mod:`gearjax.dynamics.small_gain`) at ``omega`` (rad/s): the
    split's ``sup |g|`` at its speed scaled to this one (``g`` scales as ``Omega /
    omega_ref``) times ``c_radius = max |c|`` at this speed; inf where A0 is not Hurwitz."""
    bound = split.gain / split.speed_factor(omega) * c_radius
    return jnp.where(jnp.isinf(split.gain), jnp.inf, bound)
