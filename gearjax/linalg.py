"""Dense linear solves inside traced code that cannot deadlock the CPU backend.

jaxlib 0.10.2's CPU LAPACK kernels (``getrf``, ``trsm``, ...) split a *batch* of matrices
over XLA's intra-op thread pool and then wait for the pieces from inside that same pool
(``jax::ParallelBatchMap``). When as many batched kernels run at once as the pool has
threads (on a 2-thread pool, two independent ``jnp.linalg.solve`` under ``vmap`` in one
program), every worker waits for a worker and the program hangs at 0 % CPU;
``--xla_cpu_multi_thread_eigen=false`` does not prevent it (where it was seen:
``benchmarks/results/code_notes.md``, section gearjax.linalg).

:func:`solve` is LU with partial pivoting written in plain jax (``fori_loop`` over the
columns; no LAPACK call, so batching it with ``vmap`` gives element-wise XLA ops), wrapped
in :func:`jax.lax.custom_linear_solve` so that derivatives (forward and reverse, with
respect to the matrix and the right-hand side) are the implicit ones, ``A^-1`` applied to
the tangent, and never differentiate the elimination loop. Meant for the small and
medium systems of the models (contact sets, reduced structures, Newton steps of a few
hundred states); large unbatched solves may use :func:`jax.numpy.linalg.solve`.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

__all__ = ["lu_factor", "lu_solve", "solve"]


def lu_factor(a):
    """``(lu, perm)`` of the square ``a`` (n, n): ``a[perm] = L U`` with ``L`` unit lower
    (below the diagonal of ``lu``) and ``U`` upper (on and above it), by Gaussian
    elimination with partial pivoting (the largest modulus of each column below the
    diagonal). A singular ``a`` gives a zero on ``U``'s diagonal (and infinite solves, as
    LAPACK's)."""
    n = a.shape[-1]
    rows = jnp.arange(n)

    def column(k, carry):
        m, perm = carry
        mag = jnp.where(rows >= k, jnp.abs(m[:, k]), -1.0)
        p = jnp.argmax(mag)
        m = m.at[jnp.stack([k, p])].set(m[jnp.stack([p, k])])
        perm = perm.at[jnp.stack([k, p])].set(perm[jnp.stack([p, k])])
        piv = m[k, k]
        below = rows > k  # rows below the pivot; as a column mask, right of it
        f = jnp.where(below, m[:, k] / jnp.where(piv == 0, 1.0, piv), 0.0)
        m = m - f[:, None] * jnp.where(below, m[k], 0.0)[None, :]
        m = m.at[:, k].set(jnp.where(below, f, m[:, k]))
        return m, perm

    return jax.lax.fori_loop(0, n, column, (a, rows))


def lu_solve(lu, perm, b, trans: bool = False):
    """``x`` with ``a x = b`` (or ``a^T x = b`` when ``trans``; the plain transpose, also
    for complex ``a``) from :func:`lu_factor`; ``b`` is (n,) or (n, k)."""
    n = lu.shape[-1]
    vec = b.ndim == 1
    rhs = (b[:, None] if vec else b).astype(jnp.result_type(lu, b))
    lower = jnp.tril(lu, -1) + jnp.eye(n, dtype=lu.dtype)
    upper = jnp.triu(lu)

    def substitute(t, r, unit, reverse):
        """x with t x = r, t triangular (lower: forward, upper: ``reverse``)."""
        def body(j, x):
            i = n - 1 - j if reverse else j
            xi = r[i] - t[i] @ x  # x is still zero at i and beyond it
            return x.at[i].set(xi if unit else xi / t[i, i])
        return jax.lax.fori_loop(0, n, body, jnp.zeros_like(r))

    if not trans:  # L U x = b[perm]
        y = substitute(lower, rhs[perm], True, False)
        x = substitute(upper, y, False, True)
    else:  # a^T = U^T L^T P: U^T y = b, L^T z = y, x[perm] = z
        y = substitute(upper.T, rhs, False, False)
        z = substitute(lower.T, y, True, True)
        x = jnp.zeros_like(z).at[perm].set(z)
    return x[:, 0] if vec else x


def solve(a, b):
    """``x`` with ``a x = b``: ``a`` (..., n, n), ``b`` (..., n) or (..., n, k) with the same
    leading (batch) axes, real or complex; the module docstring says why not
    :func:`jax.numpy.linalg.solve`. Differentiable in ``a`` and ``b`` (implicitly)."""
    a = jnp.asarray(a)
    b = jnp.asarray(b)
    if a.ndim < 2 or a.shape[-1] != a.shape[-2]:
        raise ValueError(f"solve: a must be (..., n, n), got shape {a.shape}")
    if a.ndim > 2:
        vec = b.ndim == a.ndim - 1
        sig = "(n,n),(n)->(n)" if vec else "(n,n),(n,k)->(n,k)"
        return jnp.vectorize(solve, signature=sig)(a, b)
    dtype = jnp.result_type(a, b)
    a = a.astype(dtype)
    b = b.astype(dtype)
    lu, perm = lu_factor(jax.lax.stop_gradient(a))
    return jax.lax.custom_linear_solve(
        lambda x: a @ x, b,
        solve=lambda _, r: lu_solve(lu, perm, r),
        transpose_solve=lambda _, r: lu_solve(lu, perm, r, trans=True))
