"""Stall watchdog (gearjax.runtime.watchdog, issue 16): a computation without progress
ends the process with one clear line and the stall exit code, never a silent hang.

Each case runs in a subprocess (the watchdog ends its process with os._exit) with a
1 s timeout and a fake stall: a Python sleep, and a jitted computation blocked inside
the XLA runtime (a host callback that sleeps), which is where the real hang sat."""

from __future__ import annotations

import subprocess
import sys
import textwrap
import time

from gearjax.runtime.watchdog import STALL_EXIT_CODE


def _run(code: str, timeout: float = 120.0):
    t0 = time.perf_counter()
    p = subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True,
                       text=True, timeout=timeout)
    return p, time.perf_counter() - t0


def test_stall_in_python_ends_with_message_and_hook():
    p, _ = _run("""
        import time
        from gearjax.runtime import watchdog
        with watchdog.stall_guard(1.0, what="fake sweep"):
            watchdog.add_stall_hook(lambda: "results so far are in out/results.csv")
            watchdog.progress("chunk 1/3")
            time.sleep(60)
        print("not reached")
    """)
    assert p.returncode == STALL_EXIT_CODE, (p.returncode, p.stderr)
    assert "not reached" not in p.stdout
    err = p.stderr.strip().splitlines()
    assert err[0].startswith("gearjax: stalled: no progress for 1 s in fake sweep "
                             "(last progress: chunk 1/3)"), err
    assert err[1] == "gearjax: results so far are in out/results.csv"
    assert "Traceback" not in p.stderr


def test_stall_inside_xla_execution():
    """The main thread waits in the XLA runtime (as in the hang) for a callback that
    never returns in time: the watchdog still ends the process promptly."""
    p, wall = _run("""
        import time, jax, jax.numpy as jnp
        from gearjax.runtime import watchdog
        def slow(x):
            time.sleep(60)
            return x
        f = jax.jit(lambda x: jax.pure_callback(slow, jax.ShapeDtypeStruct((), jnp.float32), x))
        with watchdog.stall_guard(1.0, what="fake XLA computation"):
            f(jnp.float32(1.0)).block_until_ready()
    """)
    assert p.returncode == STALL_EXIT_CODE, (p.returncode, p.stderr)
    assert "no progress for 1 s in fake XLA computation" in p.stderr
    assert wall < 50


def test_progress_keeps_it_alive_and_zero_disables():
    p, _ = _run("""
        import time
        from gearjax.runtime import watchdog
        with watchdog.stall_guard(1.0, what="steady work"):
            for i in range(6):
                time.sleep(0.4)
                watchdog.progress(f"step {i}")
        with watchdog.stall_guard(0, what="disabled") as g:
            assert g is None
            time.sleep(1.5)
        watchdog.progress("no guard: no-op")
        print("done")
    """)
    assert p.returncode == 0, p.stderr
    assert p.stdout.strip() == "done"


def test_cli_stall_timeout(tmp_path):
    """``gearjax optimise --stall-timeout 1`` with an optimiser that never finishes a step
    (patched to sleep) ends with the stall line and exit 3; a negative value is refused."""
    p, wall = _run(f"""
        import sys, time
        import gearjax.design
        from gearjax.cli.main import main
        gearjax.design.multi_start = lambda *a, **k: time.sleep(60)
        sys.exit(main(["optimise", "--stall-timeout", "1", "--out", {str(tmp_path / "o")!r}]))
    """)
    assert p.returncode == STALL_EXIT_CODE, (p.returncode, p.stderr)
    assert "gearjax: stalled: no progress for 1 s in gearjax optimise" in p.stderr, p.stderr
    assert "Traceback" not in p.stderr
    from gearjax.cli.main import main

    assert main(["optimise", "--stall-timeout", "-1", "--out", str(tmp_path / "o")]) == 2


_GIL_HANG = """
    import re
    from gearjax.runtime import watchdog
    with watchdog.stall_guard(1.0, what="GIL-holding hang", backstop={backstop},
                              backstop_grace_s=1.0):
        watchdog.progress("chunk 1/2")
        re.match(r"(a+)+$", "a" * 40 + "b")  # minutes in C, holding the GIL throughout
    print("not reached")
"""


def test_backstop_ends_a_hang_that_holds_the_gil():
    """A hang that never releases the GIL keeps the watchdog thread asleep (negative
    control: still running after 8 s, its 1 s timeout long past); the faulthandler
    backstop ends it 1 s after the watchdog's deadline with every thread's stack."""
    import pytest

    with pytest.raises(subprocess.TimeoutExpired):
        _run(_GIL_HANG.format(backstop=False), timeout=8.0)
    p, wall = _run(_GIL_HANG.format(backstop=True))
    assert p.returncode == 1, (p.returncode, p.stderr)
    assert "not reached" not in p.stdout
    assert "Timeout (0:00:02)!" in p.stderr, p.stderr
    assert '"<string>", line 7' in p.stderr, p.stderr  # where it hung
    assert wall < 30


def test_stall_message_reaches_the_process_stderr_under_capture():
    """An in-process command whose sys.stderr is a capture (pytest's capsys, a notebook)
    still leaves the stall line on the process's real stderr: the capture dies with the
    process (a slow test once ended its pytest worker this way without a word)."""
    p, _ = _run("""
        import io, sys, time
        from gearjax.runtime import watchdog
        sys.stderr = io.StringIO()
        with watchdog.stall_guard(1.0, what="captured optimise"):
            watchdog.progress("optimiser step 3")
            time.sleep(60)
    """)
    assert p.returncode == STALL_EXIT_CODE, (p.returncode, p.stderr)
    assert "no progress for 1 s in captured optimise (last progress: optimiser step 3)" in p.stderr
