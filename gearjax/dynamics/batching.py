"""How one program runs a solver at many speeds (or designs): one after the other
(``jax.lax.map``) or vmapped (in lockstep).

Every batched solve of :mod:`gearjax.dynamics` and :mod:`gearjax.design` goes through
:func:`over_speeds`; :func:`sequential_on` decides, from the device's platform and the
model's state size:

* A vmapped adaptive integration advances in lockstep: every speed of a batch takes as
  many steps as its slowest one, and a ``lax.cond`` under ``vmap`` becomes a ``select``
  that evaluates both branches. On XLA:CPU a batch of a large model gains nothing in
  return (one thread; a few hundred states are too few for wider kernels to pay), while a
  tiny model's step is loop overhead that a batch shares
  (``benchmarks/bench_batching.py``, ``benchmarks/results/batching.md``).
* On an accelerator one kernel serves every speed of a batch, which is what pays there
  (``benchmarks/results/accelerator_h100.md``).
* jaxlib 0.10.2's CPU LAPACK kernels (eig, solve, qr) split a batch over the intra-op
  thread pool and wait for it from inside that pool, so two batched kernels running at
  once deadlock a 2-worker pool (reproduced: two vmapped ``jnp.linalg.solve`` in one
  program hang; unbatched they do not). Solvers that call LAPACK per speed (the frequency
  domain) map on every CPU: :func:`on_cpu`.
"""

from __future__ import annotations

import jax

__all__ = ["MAPPED_MIN_STATES", "sequential_on", "sequential_for", "on_cpu", "over_speeds",
           "frequency_domain_sequential", "shard_speeds"]

# Smallest state (first-order unknowns) whose speeds a CPU runs one after the other; the
# sdof model (2) is vmapped, every 3D model (38 states and up) mapped (module docstring).
MAPPED_MIN_STATES = 16


def sequential_on(platform: str, state_size: int) -> bool:
    """Whether a batch of a model with ``state_size`` states runs one speed after the other
    on a device of ``platform`` (``"cpu"``, ``"gpu"``, ``"tpu"``, ...): on a CPU, from
    :data:`MAPPED_MIN_STATES` states (module docstring)."""
    return platform == "cpu" and int(state_size) >= MAPPED_MIN_STATES


def sequential_for(model) -> bool:
    """:func:`sequential_on` JAX's default backend (read when traced) for ``model``'s
    state size."""
    return sequential_on(jax.default_backend(), model.state_size)


def on_cpu() -> bool:
    """Whether JAX's default backend is the CPU (read when traced): where a solver that
    calls LAPACK per speed maps its speeds whatever the model's size (module docstring)."""
    return jax.default_backend() == "cpu"


def frequency_domain_sequential(lapack_per_speed: bool) -> bool:
    """Whether the frequency-domain solver (:mod:`gearjax.dynamics.harmonic`) maps its
    speeds: on a CPU always -- where each speed decomposes its own ``A0``
    (``lapack_per_speed``) a vmapped batch would run batched LAPACK kernels (module
    docstring), and mapped speeds skip the windows after the jumps where the grid resolves
    the ringing (a ``lax.cond`` under ``vmap`` runs both branches); vmapped on
    accelerators unless ``lapack_per_speed``."""
    return on_cpu() or bool(lapack_per_speed)


def over_speeds(one, *xs, sequential: bool):
    """``one`` at every element of the leading axis of ``xs`` (arrays, or pytrees of
    arrays, of one length), results stacked on a leading axis: ``jax.lax.map`` where
    ``sequential``, else ``jax.vmap``. Jittable and differentiable either way (``jacfwd``
    and ``jacrev`` through a map are those of a scan)."""
    if sequential:
        return jax.lax.map(lambda a: one(*a), xs)
    return jax.vmap(one)(*xs)


def shard_speeds(body, devices):
    """``f(shared, speeds)``: ``body(shared, share)`` on each of ``devices`` (one process),
    each with its share of ``speeds`` (a leading axis, a multiple of ``len(devices)``
    long), ``shared`` (a pytree of arrays) replicated, the results stacked back along the
    speeds (``jax.shard_map`` over a 1-D device mesh ``"speed"``; no communication). Each
    CPU device runs on its own thread: the speeds of a program share the cores."""
    import numpy as np
    from jax.sharding import Mesh, PartitionSpec

    mesh = Mesh(np.asarray(devices), ("speed",))
    return jax.shard_map(body, mesh=mesh, in_specs=(PartitionSpec(), PartitionSpec("speed")),
                         out_specs=PartitionSpec("speed"), check_vma=False)
