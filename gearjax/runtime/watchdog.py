"""Stall watchdog: a long computation that makes no progress ends with a message.

A computation stuck inside the XLA runtime cannot be interrupted from Python (the main
thread waits in C++ for a result that never comes; issue 16 saw this on the CPU backend,
see ``benchmarks/results/soak_3d.md``). The watchdog is a daemon thread that the long
loops *feed*: :func:`progress` after every completed unit of work (a sweep chunk, an
optimiser step). When no progress arrives for ``timeout_s`` seconds it prints one line
to stderr naming the last progress point, runs the stall hooks (e.g. "results so far
are in results.csv") and ends the process with :data:`STALL_EXIT_CODE` through
``os._exit`` (a normal exit would wait for the stuck main thread).

The watchdog thread needs the GIL to wake up. A hang that holds it (a C call that never
releases it) would keep the thread asleep; the *backstop* (``backstop=True``, what the
``gearjax`` command uses) is a :func:`faulthandler.dump_traceback_later` timer, a C
thread that needs no GIL, armed :data:`BACKSTOP_GRACE_S` seconds after the watchdog's
own deadline and re-armed at every progress: it prints every thread's Python stack to
stderr (where it hung) and ends the process with exit status 1. faulthandler has one
such timer per process, so only the process's own command arms it (an in-process
caller, e.g. pytest's ``faulthandler_timeout``, keeps its own).

Usage (the CLI's ``--stall-timeout`` does this around every command)::

    from gearjax.runtime import HostProgressMeter, watchdog
    with watchdog.stall_guard(watchdog.DEFAULT_STALL_TIMEOUT_S, what="gearjax sweep"):
        # the host meter calls watchdog.progress() per chunk
        res = gj.sweep(model, speeds, progress=HostProgressMeter())

:func:`progress` is a no-op when no guard is active, so a meter may call it freely.
The first unit includes compilation (minutes for the 3D model on a small machine): keep
the timeout generous (default :data:`DEFAULT_STALL_TIMEOUT_S`).
"""

from __future__ import annotations

import contextlib
import faulthandler
import os
import sys
import threading
import time
from typing import Callable

__all__ = ["DEFAULT_STALL_TIMEOUT_S", "STALL_EXIT_CODE", "BACKSTOP_GRACE_S", "stall_guard",
           "progress", "add_stall_hook", "StallGuard"]

DEFAULT_STALL_TIMEOUT_S = 600.0
STALL_EXIT_CODE = 3
BACKSTOP_GRACE_S = 30.0  # the watchdog's hooks and message get this long before the backstop

_lock = threading.Lock()
_active: list["StallGuard"] = []


class StallGuard:
    """One watchdog thread: ends the process when :meth:`progress` is not called for
    ``timeout_s`` seconds between :meth:`start` and :meth:`stop`; with ``backstop``, also
    the faulthandler timer ``backstop_grace_s`` later (see the module docstring)."""

    def __init__(self, timeout_s: float, what: str = "computation", *,
                 exit_code: int = STALL_EXIT_CODE, stream=None, exit: Callable | None = None,
                 backstop: bool = False, backstop_grace_s: float = BACKSTOP_GRACE_S):
        self.timeout_s = float(timeout_s)
        self.what = what
        self.exit_code = exit_code
        self.stream = stream
        self._exit = os._exit if exit is None else exit
        self._hooks: list[Callable[[], str | None]] = []
        self._last = time.monotonic()
        self._allow = self.timeout_s
        self._where = "start"
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.backstop = backstop
        self.backstop_grace_s = float(backstop_grace_s)

    def progress(self, where: str | None = None, expect_s: float | None = None) -> None:
        self._last = time.monotonic()
        self._allow = self.timeout_s if expect_s is None else max(self.timeout_s, float(expect_s))
        if where is not None:
            self._where = where
        self._arm_backstop()

    def _arm_backstop(self) -> None:
        if self.backstop and not self._stop.is_set():  # re-arming replaces the last timer
            try:
                faulthandler.dump_traceback_later(self._allow + self.backstop_grace_s,
                                                  exit=True, file=sys.stderr)
            except (AttributeError, ValueError, OSError):  # a stderr without a file descriptor
                self.backstop = False

    def add_hook(self, fn: Callable[[], str | None]) -> None:
        self._hooks.append(fn)

    def start(self) -> "StallGuard":
        self._last = time.monotonic()
        self._thread = threading.Thread(target=self._run, name="gearjax-stall-watchdog",
                                        daemon=True)
        self._thread.start()
        self._arm_backstop()
        return self

    def stop(self) -> None:
        self._stop.set()
        if self.backstop:
            faulthandler.cancel_dump_traceback_later()

    def _run(self) -> None:
        while not self._stop.is_set():
            left = self._last + self._allow - time.monotonic()
            if left <= 0:
                self._stalled()
                return
            self._stop.wait(min(left, 1.0))

    def _stalled(self) -> None:
        stream = self.stream or sys.stderr
        idle = time.monotonic() - self._last
        lines = [f"gearjax: stalled: no progress for {idle:.0f} s in {self.what} "
                 f"(last progress: {self._where}); stopped by the stall watchdog "
                 f"(--stall-timeout {self.timeout_s:g}; 0 disables it)"]
        for hook in self._hooks:
            try:
                note = hook()
            except Exception as exc:  # noqa: BLE001 - a failing hook must not keep us alive
                note = f"stall hook failed: {exc}"
            if note:
                lines.append(f"gearjax: {note}")
        text = "\n".join(lines) + "\n"
        # the process's own stderr too when sys.stderr is replaced (pytest's capture, a
        # notebook): the capture is never read once the process ends, and an in-process
        # main() under a test runner would otherwise vanish without a word
        streams = [stream]
        if self.stream is None and sys.__stderr__ is not None and sys.__stderr__ is not stream:
            streams.append(sys.__stderr__)
        try:
            for s in streams:
                try:
                    s.write(text)
                    s.flush()
                except (OSError, ValueError):  # a closed or broken stream
                    pass
        finally:
            self._exit(self.exit_code)


@contextlib.contextmanager
def stall_guard(timeout_s: float | None = DEFAULT_STALL_TIMEOUT_S, what: str = "computation",
                **kwargs):
    """Watch the body: :func:`progress` must be called at least every ``timeout_s``
    seconds (``None`` or ``<= 0``: no watchdog). Yields the :class:`StallGuard` (or None)."""
    if timeout_s is None or timeout_s <= 0:
        yield None
        return
    guard = StallGuard(timeout_s, what, **kwargs).start()
    with _lock:
        _active.append(guard)
    try:
        yield guard
    finally:
        guard.stop()
        with _lock:
            _active.remove(guard)


def progress(where: str | None = None, expect_s: float | None = None) -> None:
    """Report progress (``where``: what just finished) to every active guard;
    ``expect_s``: the next unit is known to be long (one big vmapped call), allow it
    ``max(timeout, expect_s)`` seconds."""
    for g in tuple(_active):
        g.progress(where, expect_s)


def add_stall_hook(fn: Callable[[], str | None]) -> None:
    """Add ``fn`` to the innermost active guard (no-op without one): called in the
    watchdog thread on a stall, before the exit; its returned text is printed."""
    if _active:
        _active[-1].add_hook(fn)
