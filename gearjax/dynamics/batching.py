"""How one program runs a solver at many speeds (or designs): one after the other on a CPU
(``jax.lax.map``), vmapped on an accelerator.

Every batched solve of :mod:`gearjax.dynamics` and :mod:`gearjax.design` goes through
:func:`over_speeds`, so the choice is made in one place. Why the CPU maps:

* A vmapped adaptive integration advances in lockstep: every speed of a batch takes as
  many steps as its slowest one, and a ``lax.cond`` under ``vmap`` becomes a ``select``
  that evaluates both branches. On XLA:CPU a batch gains nothing in return: the 3D model's
  292 states are too few for wider kernels to pay, and one program runs on one thread.
  Measured 2026-11-25/27 on the 2-core VM (one device, 24 speeds of the README main job's
  models, compile apart): te 20-480 rad/s 1.10 s mapped against 3.38 s vmapped, te
  300-480 rad/s 0.92 against 1.65 s, reference 20-480 rad/s 0.96 against 2.65 s; the
  compile 7.7-12.1 s against 10.7-15.4 s. The README main job went 31.4 -> 19.6 s.
* jaxlib 0.10.2's CPU LAPACK kernels (eig, solve, qr) split a batch over the intra-op
  thread pool and wait for it from inside that pool, so two batched kernels running at
  once deadlock a 2-worker pool (reproduced: two vmapped ``jnp.linalg.solve`` in one
  program hang; unbatched they do not). Mapped, no LAPACK kernel is batched.

On an accelerator one kernel serves every speed of a batch, which is what pays there
(``benchmarks/results/accelerator_h100.md``).
"""

from __future__ import annotations

import jax

__all__ = ["sequential_on", "over_speeds"]


def sequential_on(platform: str) -> bool:
    """Whether a batch runs one element after the other on a device of ``platform``
    (``"cpu"``, ``"gpu"``, ``"tpu"``, ...): on a CPU (module docstring)."""
    return platform == "cpu"


def over_speeds(one, *xs, sequential: bool | None = None):
    """``one`` at every element of the leading axis of ``xs`` (arrays, or pytrees of
    arrays, of one length), results stacked on a leading axis: ``jax.lax.map`` where
    ``sequential`` (default: :func:`sequential_on` JAX's default backend, read when
    traced), else ``jax.vmap``. Jittable and differentiable either way (``jacfwd`` and
    ``jacrev`` through a map are those of a scan)."""
    if sequential is None:
        sequential = sequential_on(jax.default_backend())
    if sequential:
        return jax.lax.map(lambda a: one(*a), xs)
    return jax.vmap(one)(*xs)
