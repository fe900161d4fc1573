"""Strict numerics for every test: float64 and no silent rank promotion (as diffrax does)."""

import atexit
import os
import shutil
import tempfile

# equinox.error_if as NaN instead of a host callback, read at equinox's import (before any
# test module imports gearjax): JAX does not store executables with host callbacks in the
# persistent cache below, and diffrax's SaveAt checks put one in every simulate program,
# so without this no sweep program is shared between the workers. No test expects an
# equinox runtime error; a NaN from one fails the finite checks of every metric.
os.environ.setdefault("EQX_ON_ERROR", "nan")
# the command line's subprocesses on one CPU device, like the library calls of the tests:
# their programs then share the compilation cache below (one device per core is the
# command line's default, gearjax.runtime.host_device_count; the sharded sweep itself is
# tested in test_sweep.py with four fake devices)
os.environ.setdefault("GEARJAX_HOST_DEVICES", "1")


def _configure_the_test_process():
    """The host process as the command line configures its compile-bound commands, by the
    public runtime layer (:func:`gearjax.runtime.configure`): XLA's CPU workarounds and its
    legacy CPU emitters (jaxlib 0.10 only; a caller's ``XLA_FLAGS`` naming a flag wins,
    ``GEARJAX_XLA_DEFAULTS=0`` keeps XLA's defaults). Set before any JAX backend starts
    (importing gearjax starts none) and inherited through the environment by the workers,
    notebook kernels and CLI subprocesses, so every executable in the shared cache below is
    keyed and compiled alike (a flag set in a running process would not apply, yet would
    key its executables as if it had). The suite is compile-bound, and the legacy emitters
    compile faster; ``XLA_FLAGS=--xla_cpu_use_fusion_emitters=true`` runs it with XLA's
    default emitters, as library calls run."""
    from gearjax import runtime

    runtime.configure(legacy_emitters=True)


_configure_the_test_process()

import jax  # noqa: E402

jax.config.update("jax_enable_x64", True)
jax.config.update("jax_numpy_rank_promotion", "raise")


def _share_compilations_in_this_session():
    """One JAX persistent compilation cache for the whole test session: the pytest-xdist
    workers, the notebook kernels and the CLI subprocesses inherit its folder
    (JAX_COMPILATION_CACHE_DIR, set by the first process, the controller) and reuse each
    other's XLA executables of identical programs (e.g. the builds of the 3D te model,
    ~20 s of compilation in every fresh process, ~4 s from the cache). A fresh, empty
    folder per session, removed at its end: nothing carries over between runs, and no test
    checks compilation itself (trace counts are unaffected). A folder chosen by the
    caller is used as it is."""
    # every program, not only those that compile for a second or more (JAX's default): the
    # suite compiles ~6,300 programs per worker, most of them small (eager operations,
    # model builds), which the other worker and each CLI/notebook subprocess compiled
    # again (measured 2026-11-25 on 2 cores: the CLI and notebook tests 144 -> 127 s, the
    # sdof/3D/design files 281 -> 270 s)
    os.environ.setdefault("JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS", "0")
    jax.config.update("jax_persistent_cache_min_compile_time_secs",
                      float(os.environ["JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS"]))
    folder = os.environ.get("JAX_COMPILATION_CACHE_DIR")
    if not folder:
        folder = tempfile.mkdtemp(prefix="gearjax-tests-xla-cache-")
        os.environ["JAX_COMPILATION_CACHE_DIR"] = folder
        atexit.register(shutil.rmtree, folder, True)
    jax.config.update("jax_compilation_cache_dir", folder)


_share_compilations_in_this_session()


def _compile_for_tests():
    """XLA's expensive backend optimisations off for the whole session (the workers, and
    through the environment the notebook kernels and CLI subprocesses): the suite is
    compile-bound (most of its programs run well under a second after 5-10 s of
    compilation). Measured on 2 cores: the sdof test file 134 s -> 97 s, the 3D files
    unchanged (their longer runs eat the saving), the suite 13 min 28 s -> 11 min 34 s.
    Results change by rounding only; the main job and benchmarks keep the optimised
    compile. ``JAX_DISABLE_MOST_OPTIMIZATIONS=0`` runs the suite as users run the code."""
    os.environ.setdefault("JAX_DISABLE_MOST_OPTIMIZATIONS", "1")
    jax.config.update("jax_disable_most_optimizations",
                      os.environ["JAX_DISABLE_MOST_OPTIMIZATIONS"] not in ("0", "false", "False"))


_compile_for_tests()


import pytest  # noqa: E402

from gearjax.runtime import code_memory  # noqa: E402


@pytest.fixture(autouse=True)
def _release_compiled_code():
    """After every test, drop JAX's compiled programs once this worker holds more than half
    of the kernel's memory-map cap (:mod:`gearjax.runtime.code_memory`). Without it the
    long-lived workers crept up to the cap (58,600 and 64,600 of 65,530 maps measured in
    one run) and a worker that crossed it segfaulted inside XLA's compile or
    ``executable.serialize()`` (about one suite run in three, CI and local, until
    2026-11-25). Later tests reload what they need from the session's persistent cache."""
    yield
    code_memory.release_if_crowded(0.5)


@pytest.fixture(scope="session")
def torsional_cli_sweep(tmp_path_factory):
    """One ``gearjax sweep --model torsional`` run (te and reference at 40, 370 and 700 rad/s,
    signals at 300 rad/s, JSON summary) shared by tests/test_cli.py and
    tests/test_cli_dynamics.py, which check different parts of its output (the sdof sweep
    compiles and runs once per test worker instead of once per test).

    Returns ``(summary dict, output folder)``."""
    import contextlib
    import io
    import json

    from gearjax.cli.main import main

    out = tmp_path_factory.mktemp("torsional_cli") / "sw"
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        rc = main(["sweep", "--model", "torsional", "--speeds", "40:700:3",
                   "--formulations", "te,reference", "--signals", "300",
                   "--out", str(out), "--json"])
    assert rc == 0
    return json.loads(buf.getvalue()), out
