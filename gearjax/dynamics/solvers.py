"""Periodic-orbit solvers as typed objects, in the way of diffrax's solvers: an abstract
base, final solvers whose options are fields, and :class:`Fallback` to compose them (as
optax's ``chain`` composes transformations).

A solver finds the periodic steady state of a model at many pinion speeds and measures it
(:class:`gearjax.dynamics.results.SweepResult`). The final solvers live beside their
numerics: :class:`gearjax.dynamics.sweep.Transient` (diffrax from the quasi-static start,
any model), :class:`gearjax.dynamics.steady.Shooting` (Newton on ``y(P) - y(0)``, monodromy
by forward-mode linearisation) and :class:`gearjax.dynamics.harmonic_sweep.HarmonicBalance`
(the linear te/perturbation equations in the frequency domain);
:class:`gearjax.dynamics.sweep.Auto` picks one. :func:`gearjax.dynamics.sweep.sweep` is the
one entry point.
"""

from __future__ import annotations

import abc
import dataclasses
from typing import Callable

import equinox as eqx
import numpy as np

from .exported import AbstractProgramStore, NoProgramStore
from .progress import AbstractProgressMeter, NoProgressMeter
from .results import SweepResult, merge_results

__all__ = ["AbstractPeriodicSolver", "AbstractOrbitSolver", "SweepRun", "Fallback"]


class SweepRun(eqx.Module):
    """How a solver runs a sweep, besides the model, speeds and its own options.

    chunk_size : speeds per compiled call (None: the solver's rule).
    devices : JAX devices to share the speeds over (None: one): the transient's and the
        frequency domain's speeds (one process for the latter); the shooting refuses them.
    progress : the meter told of the sweep's progress.
    sink : called with a :class:`SweepResult` of the speeds a solver has finished (its
        rows are final), as they finish; None: nothing is written.
    programs : where the solver's compiled programs come from
        (:class:`~gearjax.dynamics.exported.ProgramStore`: a folder of exported programs;
        default: traced in this process).
    """

    chunk_size: int | None = None
    devices: object = None
    progress: AbstractProgressMeter = NoProgressMeter()
    sink: Callable[[SweepResult], None] | None = None
    programs: AbstractProgramStore = NoProgramStore()


class AbstractPeriodicSolver(eqx.Module):
    """Finds and measures the periodic steady state of a model over pinion speeds."""

    @abc.abstractmethod
    def sweep(self, model, speeds: np.ndarray, run: SweepRun) -> SweepResult:
        """Metrics at every speed of ``speeds`` (rad/s, checked finite and positive, in the
        caller's order); ``solver`` names the solver of each speed. The rows of finished
        speeds go to ``run.sink``.

        Raises :class:`gearjax.errors.SimulationError` for a model or option the solver
        cannot take."""

    @abc.abstractmethod
    def solved(self, result: SweepResult) -> np.ndarray:
        """Per speed of ``result`` (this solver's), whether its orbit is the model's
        steady state as far as the solver can tell; :class:`Fallback` hands the others on."""


class AbstractOrbitSolver(AbstractPeriodicSolver):
    """A solver whose one-speed solve is a pure function of the model and the speed
    (jit-, vmap- and differentiable): what a design objective differentiates."""

    @abc.abstractmethod
    def orbit_metrics(self, model, omega, adjoint=None):
        """The :class:`~gearjax.dynamics.simulate.SimulationResult` at pinion speed
        ``omega`` (rad/s, traceable); ``adjoint``: diffrax's, where the solver integrates
        with one (None: forward mode)."""


class Fallback(AbstractPeriodicSolver):
    """``first`` at every speed, then ``then`` at the speeds that ``first`` did not solve
    (:meth:`AbstractPeriodicSolver.solved`: contact lost by a linear orbit, stability not
    proven, not converged). The result names per speed which solver gave it; where
    ``then`` solved a speed, ``spectral_radius`` and ``status`` are its own, and why
    ``first`` handed the speed on stays in ``stats``: ``first_status`` (its
    :class:`~gearjax.dynamics.orbit.RESULTS` code, as a float) and
    ``first_spectral_radius`` (the Floquet radius of its orbit, e.g. > 1 for an unstable
    one) at every speed (the innermost ``Fallback``'s where they nest)."""

    first: AbstractPeriodicSolver
    then: AbstractPeriodicSolver

    def sweep(self, model, speeds: np.ndarray, run: SweepRun) -> SweepResult:
        res = self.first.sweep(model, speeds, dataclasses.replace(run, sink=None))
        ok = np.asarray(self.first.solved(res), dtype=bool)
        first = {"first_status": np.asarray(res.status, dtype=float),
                 "first_spectral_radius": np.asarray(res.spectral_radius, dtype=float)}
        if run.sink is not None and ok.any():
            run.sink(res.take(ok))
        if ok.all():
            return dataclasses.replace(res, stats={**first, **res.stats})
        rest = ~ok
        n_rest = int(rest.sum())
        chunk = None if run.chunk_size is None else min(int(run.chunk_size), n_rest)
        run_rest = dataclasses.replace(run, chunk_size=chunk)
        run.progress.note(f"{type(self.first).__name__} {model.formulation}",
                          f"{n_rest} of {speeds.size} speed(s) to "
                          f"{type(self.then).__name__}")
        merged = merge_results(res, self.then.sweep(model, speeds[rest], run_rest), rest)
        return dataclasses.replace(merged, stats={**first, **merged.stats})

    def solved(self, result: SweepResult) -> np.ndarray:
        return np.asarray(self.then.solved(result), dtype=bool)
