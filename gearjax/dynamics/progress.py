"""Progress of long host-side loops, as an object passed in (diffrax's
``AbstractProgressMeter`` for our speed sweeps, shooting and continuation).

A solver that loops over chunks of speeds calls :meth:`AbstractProgressMeter.start` once,
before anything compiles, :meth:`~AbstractProgressMeter.update` after every completed unit
of work, and :meth:`~AbstractProgressMeter.note` for something the user should know that is
not an error. The library's default is :class:`NoProgressMeter`: it does nothing, so the
library has no side effects of its own. Meters that print, feed the command line's stall
watchdog or release compiled code live in the host layer (:mod:`gearjax.runtime.progress`).
"""

from __future__ import annotations

import abc

import equinox as eqx

from ..errors import SimulationError

__all__ = ["AbstractProgressMeter", "NoProgressMeter", "check_meter"]


class AbstractProgressMeter(eqx.Module):
    """What a long loop reports. Every method receives everything it needs (meters keep no
    state), so one meter may serve several loops, one after the other or nested."""

    @abc.abstractmethod
    def start(self, task: str, total: int, detail: str = "") -> None:
        """``task`` (e.g. ``"sweep te"``) begins ``total`` units of work (speeds, steps);
        called before its first compilation. ``detail``: what the first unit holds."""

    @abc.abstractmethod
    def update(self, task: str, done: int, total: int, detail: str = "", *,
               elapsed_s: float = 0.0, next_unit_s: float | None = None) -> None:
        """``done`` of ``total`` units of ``task`` have finished, ``elapsed_s`` seconds
        after :meth:`start`; ``detail``: what the last unit was. ``next_unit_s``: the next
        unit is known to take about this long (e.g. a batch that compiles again), or None."""

    @abc.abstractmethod
    def note(self, task: str, message: str) -> None:
        """Something about ``task`` the user should know that is not an error (a speed
        handed to another solver, a method not applicable)."""


class NoProgressMeter(AbstractProgressMeter):
    """Reports nothing: the library's default."""

    def start(self, task: str, total: int, detail: str = "") -> None:
        del task, total, detail

    def update(self, task: str, done: int, total: int, detail: str = "", *,
               elapsed_s: float = 0.0, next_unit_s: float | None = None) -> None:
        del task, done, total, detail, elapsed_s, next_unit_s

    def note(self, task: str, message: str) -> None:
        del task, message


def check_meter(progress) -> AbstractProgressMeter:
    """``progress`` if it is a meter; raises :class:`~gearjax.errors.SimulationError` on
    ``progress`` otherwise (e.g. the boolean earlier versions took)."""
    if not isinstance(progress, AbstractProgressMeter):
        raise SimulationError("progress", progress, "must be a progress meter: "
                              "gearjax.NoProgressMeter() (the default: nothing reported) or "
                              "gearjax.TextProgressMeter() (a line per chunk on stderr)")
    return progress
