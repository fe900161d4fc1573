"""Progress meters of the host process: text on a stream, and the command line's meter that
also feeds the stall watchdog and releases compiled code between tasks.

Library loops report through :class:`gearjax.dynamics.progress.AbstractProgressMeter`
(default: nothing); these are the meters that act on the process.
"""

from __future__ import annotations

import sys
from typing import TextIO

from ..dynamics.progress import AbstractProgressMeter, NoProgressMeter
from . import code_memory, watchdog

__all__ = ["TextProgressMeter", "HostProgressMeter", "command_meter"]

_BAR = 20  # characters of the progress bar


class TextProgressMeter(AbstractProgressMeter):
    """One line per event on ``stream`` (default: the process's ``sys.stderr`` at the
    time of the call): ``[gearjax] TASK [bar] DONE/TOTAL done: DETAIL (elapsed S s)``."""

    stream: TextIO | None = None

    def _write(self, text: str) -> None:
        out = sys.stderr if self.stream is None else self.stream
        print(f"[gearjax] {text}", file=out, flush=True)

    def start(self, task: str, total: int, detail: str = "") -> None:
        self._write(f"{task}: {total} to do{': ' + detail if detail else ''}")

    def update(self, task: str, done: int, total: int, detail: str = "", *,
               elapsed_s: float = 0.0, next_unit_s: float | None = None) -> None:
        del next_unit_s
        bar = "#" * round(_BAR * done / max(total, 1))
        self._write(f"{task} [{bar:<{_BAR}s}] {done}/{total} done"
                    f"{': ' + detail if detail else ''} (elapsed {elapsed_s:.1f} s)")

    def note(self, task: str, message: str) -> None:
        self._write(f"{task}: {message}")


class HostProgressMeter(AbstractProgressMeter):
    """The command line's meter: forwards every event to ``inner`` and

    * at :meth:`start` and :meth:`update` (between compilations) releases JAX's compiled
      code when the process nears the kernel's memory-map cap
      (:func:`code_memory.release_if_crowded`: only then, so a loop's program is compiled
      again, or loaded from the persistent cache, only where the process would otherwise
      crash);
    * at :meth:`update` feeds the stall watchdog (:func:`watchdog.progress`; a no-op
      without an active :func:`watchdog.stall_guard`)."""

    inner: AbstractProgressMeter = NoProgressMeter()

    def start(self, task: str, total: int, detail: str = "") -> None:
        code_memory.release_if_crowded()
        self.inner.start(task, total, detail)

    def update(self, task: str, done: int, total: int, detail: str = "", *,
               elapsed_s: float = 0.0, next_unit_s: float | None = None) -> None:
        watchdog.progress(f"{task} {done}/{total}", expect_s=next_unit_s)
        code_memory.release_if_crowded()
        self.inner.update(task, done, total, detail, elapsed_s=elapsed_s,
                          next_unit_s=next_unit_s)

    def note(self, task: str, message: str) -> None:
        self.inner.note(task, message)


def command_meter(text: bool) -> HostProgressMeter:
    """The command line's meter: :class:`HostProgressMeter` around a
    :class:`TextProgressMeter` on stderr (``text``) or around nothing (e.g. ``--json``)."""
    return HostProgressMeter(TextProgressMeter() if text else NoProgressMeter())
