"""Release of compiled code before the kernel's memory-map cap (gearjax.runtime.code_memory).

The crash itself (a compile at ``vm.max_map_count`` segfaults in jaxlib 0.10.2) needs a
lowered sysctl to reproduce in reasonable time, i.e. root; these tests check what the
guard relies on: that compiled programs hold memory maps, that the release gives them
back, that the jitted functions still work afterwards, and that below the threshold
nothing is released."""

import sys

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from gearjax.runtime import code_memory

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="counts /proc/self/maps")


def _compiled_programs(n):
    """n distinct jitted programs, each compiled once and kept alive."""
    x = jnp.linspace(0.0, 1.0, 8)
    fns = [jax.jit(lambda x, k=k: jnp.sin(k * x) + jnp.cumsum(x)) for k in range(n)]
    for f in fns:
        f(x).block_until_ready()
    return fns, x


def test_map_count_reads_proc_and_the_cap_is_positive():
    with open("/proc/self/maps") as f:
        lines = sum(1 for _ in f)
    n = code_memory.map_count()
    assert n is not None and abs(n - lines) <= 5  # the read itself may map a buffer
    assert code_memory.max_map_count() > 0


def test_release_gives_the_maps_back_and_functions_still_work():
    fns, x = _compiled_programs(200)
    before = code_memory.map_count()
    # threshold above the current count: nothing happens
    assert not code_memory.release_if_crowded(0.5, max_maps=4 * before)
    assert code_memory.map_count() >= before - 5
    # threshold below it: JAX's caches dropped, and with them the programs' code maps
    assert code_memory.release_if_crowded(0.5, max_maps=before)
    after = code_memory.map_count()
    assert before - after >= 2 * 200, (before, after)  # at least text + data per program
    # the jitted functions compile again on their next call and compute the same
    for k in (0, 7, 199):
        np.testing.assert_allclose(fns[k](x), np.sin(k * np.asarray(x)) + np.cumsum(np.asarray(x)),
                                   rtol=1e-15, atol=1e-15)


def test_optimise_releases_between_iterations(monkeypatch):
    """An optimisation whose objective compiles a new program at every evaluation (as a
    dynamic objective does after each structure change, when it rebuilds its model) stays
    below the cap: :func:`gearjax.design.optimise` given the command line's meter
    (:class:`gearjax.runtime.HostProgressMeter`) releases before every evaluation, not
    only before its first (the slow CLI optimise test's worker crashed at the cap)."""
    from gearjax.design import ReliefSpace, optimise
    from gearjax.design.objectives import Evaluation
    from gearjax.runtime import HostProgressMeter

    class Recompiling:
        space = ReliefSpace()
        programs = []  # kept alive, as JAX's caches keep a live model's programs

        def __call__(self, x, grad=True):
            k = len(self.programs)
            f = jax.jit(lambda v: jnp.sum(jnp.sin(v + k)) + jnp.sum((v / self.space.upper) ** 2))
            self.programs.append(f)
            v = jnp.asarray(x)
            val = float(f(v))
            g = np.asarray(jax.grad(f)(v))
            return Evaluation(np.asarray(x), val, val, g, np.asarray([val]))

    x0 = np.array([10e-6, 0.5])
    optimise(Recompiling(), x0, max_iter=2)  # compiles the optimiser's own eager steps
    start = code_memory.map_count()
    cap = int((start + 100) / code_memory.DEFAULT_FRACTION)  # release above start + 100
    monkeypatch.setattr(code_memory, "max_map_count", lambda: cap)
    seen = []
    res = optimise(Recompiling(), x0, max_iter=20, patience=10**6, step_tol=0.0,
                   callback=lambda h: seen.append(code_memory.map_count()),
                   progress=HostProgressMeter())  # the command line's meter
    assert res.iterations == 20 and len(Recompiling.programs) == 3 + 21
    # measured ~15 maps per evaluation (the program and its gradient's), i.e. ~start + 310
    # at the end without the releases; with them the count never passes the threshold by
    # more than one evaluation's programs
    assert max(seen) < start + 100 + 40, (start, seen)
    assert min(seen[5:]) < max(seen)  # released at least once
