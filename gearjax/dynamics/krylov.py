"""Restarted GMRES for complex vectors in plain JAX (jit- and vmap-compatible), used by
the frequency-domain solver (:mod:`gearjax.dynamics.harmonic`) for Hill's equation of the
mesh deflection. Written out instead of ``lineax.GMRES`` because its small least-squares
solve must not call LAPACK: jaxlib 0.10.2's batched CPU LAPACK kernels wait on the
intra-op pool they run on, and two of them under vmap deadlock a 2-worker pool."""

from __future__ import annotations

import jax
import jax.numpy as jnp

__all__ = ["gmres", "hessenberg_lstsq"]


def hessenberg_lstsq(hm, g):
    """``argmin |hm y - g|`` for the (m+1, m) upper Hessenberg ``hm`` of GMRES: Givens
    rotations and back substitution in plain jax (no LAPACK call: jaxlib 0.10.2's batched
    CPU LAPACK kernels wait on the intra-op pool they run on, and two of them under vmap
    deadlock a 2-worker pool, :mod:`gearjax.linalg`)."""
    m = hm.shape[1]

    def rotate(j, rg):
        r, g = rg
        a, b = r[j, j], r[j + 1, j]
        nrm = jnp.sqrt(jnp.abs(a) ** 2 + jnp.abs(b) ** 2)
        c, s = jnp.where(nrm > 0, a / jnp.where(nrm > 0, nrm, 1.0), 1.0), b / jnp.where(
            nrm > 0, nrm, 1.0)
        rj, rk = r[j], r[j + 1]
        r = r.at[j].set(jnp.conj(c) * rj + jnp.conj(s) * rk).at[j + 1].set(-s * rj + c * rk)
        gj, gk = g[j], g[j + 1]
        return r, g.at[j].set(jnp.conj(c) * gj + jnp.conj(s) * gk).at[j + 1].set(-s * gj + c * gk)

    r, g = jax.lax.fori_loop(0, m, rotate, (hm, g))

    def back(i, y):
        j = m - 1 - i
        d = r[j, j]
        yj = (g[j] - r[j, :m] @ y) / jnp.where(d != 0, d, 1.0)
        return y.at[j].set(jnp.where(jnp.abs(d) > 0, yj, 0.0))

    return jax.lax.fori_loop(0, m, back, jnp.zeros(m, hm.dtype))


def gmres(op, b, tol, restart: int = 30, max_cycles: int = 12):
    """Restarted GMRES for ``op(x) = b`` (complex vectors): Arnoldi with classical
    Gram-Schmidt done twice, a small least-squares solve per cycle, stopped when the
    residual is below ``tol |b|``. Returns (x, relative residual)."""
    n = b.shape[0]
    bn = jnp.maximum(jnp.linalg.norm(b), 1e-300)

    def cycle(x):
        r = b - op(x)
        beta = jnp.linalg.norm(r)
        v = jnp.zeros((restart + 1, n), b.dtype).at[0].set(r / jnp.maximum(beta, 1e-300))
        hm = jnp.zeros((restart + 1, restart), b.dtype)

        def arnoldi(j, vh):
            v, hm = vh
            w = op(v[j])
            mask = (jnp.arange(restart + 1) <= j)[:, None]
            h1 = (jnp.conj(v) * mask) @ w
            w = w - v.T @ h1
            h2 = (jnp.conj(v) * mask) @ w
            w = w - v.T @ h2
            nw = jnp.linalg.norm(w)
            hm = hm.at[:, j].set(h1 + h2).at[j + 1, j].set(nw)
            v = v.at[j + 1].set(jnp.where(nw > 0, w / jnp.where(nw > 0, nw, 1.0), 0.0))
            return v, hm

        v, hm = jax.lax.fori_loop(0, restart, arnoldi, (v, hm))
        e1 = jnp.zeros(restart + 1, b.dtype).at[0].set(beta)
        return x + v[:restart].T @ hessenberg_lstsq(hm, e1)

    def cond(c):
        x, res, k = c
        return (res > tol) & (k < max_cycles)

    def body(c):
        x, _, k = c
        x = cycle(x)
        return x, jnp.linalg.norm(b - op(x)) / bn, k + 1

    x, res, _ = jax.lax.while_loop(cond, body, (b, jnp.linalg.norm(b - op(b)) / bn, 0))
    return x, res
