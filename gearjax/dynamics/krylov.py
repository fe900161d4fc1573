"""Restarted GMRES for complex vectors in plain JAX (jit- and vmap-compatible), used by
the frequency-domain solver (:mod:`gearjax.dynamics.harmonic`) for Hill's equation of the
mesh deflection. Written out instead of ``lineax.GMRES`` because its small least-squares
solve must not call LAPACK: jaxlib 0.10.2's batched CPU LAPACK kernels wait on the
intra-op pool they run on, and two of them under vmap deadlock a 2-worker pool. The
least-squares problem of each cycle is kept triangular by Givens rotations applied as the
Arnoldi basis grows (Saad & Schultz 1986), so the residual is known after every step and
a cycle stops as soon as it meets the tolerance."""

from __future__ import annotations

import jax
import jax.numpy as jnp

__all__ = ["gmres", "hessenberg_lstsq"]


def _givens(a, b):
    """(c, s) with ``[[conj(c), conj(s)], [-s, c]] [a, b]^T = [r, 0]^T``."""
    nrm = jnp.sqrt(jnp.abs(a) ** 2 + jnp.abs(b) ** 2)
    safe = jnp.where(nrm > 0, nrm, 1.0)
    return jnp.where(nrm > 0, a / safe, 1.0), b / safe


def _rotate(c, s, x, y):
    return jnp.conj(c) * x + jnp.conj(s) * y, -s * x + c * y


def hessenberg_lstsq(hm, g):
    """``argmin |hm y - g|`` for the (m+1, m) upper Hessenberg ``hm`` of GMRES: Givens
    rotations and back substitution in plain jax (no LAPACK call: jaxlib 0.10.2's batched
    CPU LAPACK kernels wait on the intra-op pool they run on, and two of them under vmap
    deadlock a 2-worker pool, :mod:`gearjax.linalg`)."""
    m = hm.shape[1]

    def rotate(j, rg):
        r, g = rg
        c, s = _givens(r[j, j], r[j + 1, j])
        rj, rk = _rotate(c, s, r[j], r[j + 1])
        gj, gk = _rotate(c, s, g[j], g[j + 1])
        return r.at[j].set(rj).at[j + 1].set(rk), g.at[j].set(gj).at[j + 1].set(gk)

    r, g = jax.lax.fori_loop(0, m, rotate, (hm, g))
    return _back_substitute(r, g, m)


def _back_substitute(r, g, k):
    """``y`` (m,) with ``r[:k, :k] y[:k] = g[:k]`` (upper triangular), ``y[k:] = 0``."""
    m = r.shape[1]

    def back(i, y):
        j = m - 1 - i
        d = r[j, j]
        yj = (g[j] - r[j, :m] @ y) / jnp.where(d != 0, d, 1.0)
        return y.at[j].set(jnp.where((jnp.abs(d) > 0) & (j < k), yj, 0.0))

    return jax.lax.fori_loop(0, m, back, jnp.zeros(m, r.dtype))


def gmres(op, b, tol, restart: int = 30, max_cycles: int = 12, x0=None):
    """Restarted GMRES for ``op(x) = b`` (complex vectors) from ``x0`` (default ``b``):
    Arnoldi with classical Gram-Schmidt done twice, the Hessenberg matrix reduced by
    Givens rotations step by step, each cycle stopped once the residual is below
    ``tol |b|`` (or after ``restart`` steps). Returns (x, relative residual)."""
    n = b.shape[0]
    bn = jnp.maximum(jnp.linalg.norm(b), 1e-300)
    x_init = b if x0 is None else x0

    def cycle(x):
        r = b - op(x)
        beta = jnp.linalg.norm(r)
        v = jnp.zeros((restart + 1, n), b.dtype).at[0].set(r / jnp.maximum(beta, 1e-300))
        hm = jnp.zeros((restart + 1, restart), b.dtype)
        g = jnp.zeros(restart + 1, b.dtype).at[0].set(beta)
        cs = jnp.ones(restart, b.dtype)
        sn = jnp.zeros(restart, b.dtype)

        def go(c):
            j, _, _, g, _, _ = c
            return (j < restart) & (jnp.abs(g[j]) > tol * bn)

        def arnoldi(c):
            j, v, hm, g, cs, sn = c
            w = op(v[j])
            mask = (jnp.arange(restart + 1) <= j)[:, None]
            h1 = (jnp.conj(v) * mask) @ w
            w = w - v.T @ h1
            h2 = (jnp.conj(v) * mask) @ w
            w = w - v.T @ h2
            nw = jnp.linalg.norm(w)
            col = (h1 + h2).at[j + 1].set(nw)
            v = v.at[j + 1].set(jnp.where(nw > 0, w / jnp.where(nw > 0, nw, 1.0), 0.0))

            def old(i, col):  # the rotations of the earlier columns
                a, bb = _rotate(cs[i], sn[i], col[i], col[i + 1])
                keep = i < j
                return col.at[i].set(jnp.where(keep, a, col[i])).at[i + 1].set(
                    jnp.where(keep, bb, col[i + 1]))

            col = jax.lax.fori_loop(0, restart, old, col)
            c_, s_ = _givens(col[j], col[j + 1])
            top, _ = _rotate(c_, s_, col[j], col[j + 1])
            col = col.at[j].set(top).at[j + 1].set(0.0)
            gj, gk = _rotate(c_, s_, g[j], g[j + 1])
            return (j + 1, v, hm.at[:, j].set(col), g.at[j].set(gj).at[j + 1].set(gk),
                    cs.at[j].set(c_), sn.at[j].set(s_))

        k, v, hm, g, _, _ = jax.lax.while_loop(go, arnoldi, (0, v, hm, g, cs, sn))
        return x + v[:restart].T @ _back_substitute(hm, g, k)

    def cond(c):
        x, res, k = c
        return (res > tol) & (k < max_cycles)

    def body(c):
        x, _, k = c
        x = cycle(x)
        return x, jnp.linalg.norm(b - op(x)) / bn, k + 1

    x, res, _ = jax.lax.while_loop(cond, body, (x_init, jnp.linalg.norm(b - op(x_init)) / bn, 0))
    return x, res
