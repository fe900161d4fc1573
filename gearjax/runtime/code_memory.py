"""Compiled code of a long-lived process: release it before the kernel's map limit.

Every program XLA compiles for the CPU keeps its machine code in memory maps of its own
(LLVM's section memory manager: about six per small program), held for as long as JAX
caches the executable. Linux caps the maps of a process at ``vm.max_map_count`` (65,530 by
default). A process that compiles many distinct programs -- the test workers, a notebook
running sweeps of many models, ``gearjax paper`` -- reaches the cap, and then the next
compilation fails and jaxlib 0.10.2 *segfaults* in ``backend_compile_and_load`` (or in
``executable.serialize()``) instead of raising (``benchmarks/results/code_notes.md``,
section gearjax.runtime.code_memory).

:func:`release_if_crowded` drops JAX's compilation caches (``jax.clear_caches()``) when the
process holds more than a fraction of the cap: the executables are freed and their maps
unmapped, and the jitted functions stay usable; a function called again compiles again,
or loads its program from the persistent compilation cache when one is configured. The
command line's progress meter (:class:`gearjax.runtime.HostProgressMeter`) calls it between
compilations, the test suite after every test. Results never change; only the cost of a
recompile.

Where ``/proc`` is absent (macOS, Windows) nothing is counted and nothing released.
"""

from __future__ import annotations

import gc

import jax

#: fraction of ``vm.max_map_count`` above which :func:`release_if_crowded` releases (a
#: sweep of the 3D rig adds a few thousand maps, so a release comes before the cap; the
#: test suite releases after every test above 0.5, so that no release falls between two
#: calls of one test, e.g. a check that a second sweep does not trace again)
DEFAULT_FRACTION = 0.75
#: ``vm.max_map_count`` of a default Linux kernel (used when the sysctl cannot be read)
DEFAULT_MAX_MAP_COUNT = 65530


def map_count() -> int | None:
    """Number of memory maps this process holds (lines of ``/proc/self/maps``), or None
    where there is no ``/proc``."""
    try:
        with open("/proc/self/maps", "rb") as f:
            return sum(block.count(b"\n") for block in iter(lambda: f.read(1 << 20), b""))
    except OSError:
        return None


def max_map_count() -> int:
    """The kernel's cap on a process's memory maps (``vm.max_map_count``)."""
    try:
        with open("/proc/sys/vm/max_map_count") as f:
            return int(f.read().strip())
    except (OSError, ValueError):
        return DEFAULT_MAX_MAP_COUNT


def release_if_crowded(fraction: float = DEFAULT_FRACTION, *, max_maps: int | None = None) -> bool:
    """``jax.clear_caches()`` (and a garbage collection) when this process holds more than
    ``fraction`` of ``max_maps`` memory maps (default: the kernel's ``vm.max_map_count``).
    Returns whether it released. Cheap (one read of ``/proc/self/maps``): call it between
    compilations, never inside a traced function."""
    n = map_count()
    if n is None:
        return False
    cap = max_map_count() if max_maps is None else int(max_maps)
    if n <= fraction * cap:
        return False
    jax.clear_caches()
    gc.collect()
    return True
