"""Speed sweeps: :func:`sweep`, the one entry point of the periodic solvers
(:mod:`gearjax.dynamics.solvers`), :class:`Auto` (the rule that picks one) and
:class:`Transient`, whose sweep is one jitted :func:`gearjax.dynamics.simulate.simulate`
per chunk of speeds, its speeds one after the other (a 3D model on a CPU) or vmapped (the
sdof model on a CPU, every model on an accelerator): :mod:`gearjax.dynamics.batching`.

* The speeds are the only batched input, so a new set of speeds (same chunk size) never
  recompiles: the model's array data (its design, jump angles and tables included) and the
  speeds are traced, only its static structure (formulation, which terms exist, the bounds
  of its jump set) and the simulation options are compiled in.
  Chunks are padded to ``chunk_size``: vmapped, by repeating the last speed (a lane in
  lockstep); mapped, by NaN speeds, which the program skips.
* Progress is reported per chunk to the ``progress`` meter
  (:class:`~gearjax.dynamics.progress.AbstractProgressMeter`, default none); rows are
  appended to ``out_csv`` as chunks complete (a header is written when the file is new or
  empty).
* With several JAX devices the batch is split across them with ``jax.shard_map`` over a
  1-D device mesh (each device runs its own share of the chunk, mapped or vmapped as above;
  no cross-device synchronisation inside the solver loop). Speeds are padded to a multiple of
  ``chunk_size`` (itself a multiple of the device count) and *interleaved*: the speeds are
  sorted by estimated cost (low speeds cost more per period) and dealt round-robin, so every
  device gets a similar mix, then the results are put back in the caller's order.
* Several hosts: after ``jax.distributed.initialize(...)`` (or ``gearjax sweep
  --distributed``) every process calls ``sweep`` with the same arguments (SPMD); the device
  mesh spans every device of every process (``jax.devices()``), each process feeds and
  runs its own devices' speeds, and the results are gathered on all processes
  (``multihost_utils.process_allgather``). Only process 0 reports progress and writes
  ``out_csv``. Without ``devices`` a multi-process run uses all devices (each host would
  otherwise repeat the whole sweep).
* ``programs`` (:class:`~gearjax.dynamics.exported.ProgramStore`): the chunk programs (and
  the frequency domain's) come from a folder where an earlier run exported them, instead
  of being traced again; a multi-process sweep traces its own.
"""

from __future__ import annotations

import dataclasses
import math
import os
import time
from functools import partial
from typing import Callable, NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..errors import check_float64
from .exported import AbstractProgramStore, NoProgramStore
from .batching import over_speeds, sequential_on
from .progress import AbstractProgressMeter, NoProgressMeter, check_meter

from .harmonic_sweep import HarmonicBalance
from .solvers import AbstractOrbitSolver, AbstractPeriodicSolver, Fallback, SweepRun
from .orders import N_MESH_ORDERS
from .results import (CSV_COLUMNS, FLAG_FIELDS, METRIC_FIELDS, ORDER_COLUMNS, ORDER_FIELDS,
                      SweepResult, append_rows, empty_metrics)
from .orbit import metric_status
from .simulate import SimulationError, SimulationResult, simulate

__all__ = ["sweep", "Transient", "Auto", "SweepResult", "CSV_COLUMNS", "tolerance_options",
           "lower_sweep", "default_chunk_size", "memory_chunk", "planned_chunk",
           "FREQUENCY_DOMAIN_MIN_STATES", "FREQUENCY_DOMAIN_MIN_SPEEDS"]


def _over_speeds(model, speeds, solver, sequential: bool):
    """The metrics of ``solver`` (a :class:`Transient`, static) at every speed of
    ``speeds``, mapped or vmapped (:func:`gearjax.dynamics.batching.over_speeds`). Mapped,
    each metric is a float and a NaN speed (a padding slot of the chunk, :func:`_plan`) is
    not integrated: its metrics are NaN (a ``lax.cond`` under ``lax.map`` runs one branch;
    under ``vmap`` it would run both)."""
    if not sequential:
        return over_speeds(lambda w: _metrics_only(solver.orbit_metrics(model, w)), speeds,
                           sequential=False)

    def one(w):
        return tuple(jnp.asarray(v, float) for v in
                     _metrics_only(solver.orbit_metrics(model, w)))

    def padding(w):
        return tuple(jnp.full((N_MESH_ORDERS,) if f in ORDER_FIELDS else (), jnp.nan)
                     for f in METRIC_FIELDS)

    return over_speeds(lambda w: jax.lax.cond(jnp.isnan(w), padding, one, w), speeds,
                       sequential=True)


@partial(eqx.filter_jit, donate="none")
def _batched(model, speeds, solver):
    return _over_speeds(model, speeds, solver, sequential=False)


@partial(eqx.filter_jit, donate="none")
def _sequential(model, speeds, solver):
    return _over_speeds(model, speeds, solver, sequential=True)


def _metrics_only(res: SimulationResult):
    return tuple(getattr(res, f) for f in METRIC_FIELDS)


def _make_sharded(devices, sequential: bool):
    """A jitted function running ``_batched``'s (or ``_sequential``'s) body under
    shard_map over ``devices``."""
    from jax.sharding import Mesh as DeviceMesh
    from jax.sharding import PartitionSpec as P

    dmesh = DeviceMesh(np.asarray(devices), ("speed",))

    @partial(eqx.filter_jit, donate="none")
    def run(model, speeds, solver):
        dyn, static = eqx.partition(model, eqx.is_array)

        def body(dyn_, w):
            return _over_speeds(eqx.combine(dyn_, static), w, solver, sequential)

        f = jax.shard_map(
            body, mesh=dmesh, in_specs=(P(), P("speed")), out_specs=P("speed"), check_vma=False
        )
        return f(dyn, speeds)

    return run


_SHARDED_CACHE: dict = {}


def _global_speeds(w: np.ndarray, devices):
    """The chunk's speeds as one array sharded over ``devices`` (which may belong to several
    processes: each process fills only its own devices' shards, from the same ``w``)."""
    from jax.sharding import Mesh as DeviceMesh
    from jax.sharding import NamedSharding, PartitionSpec

    sharding = NamedSharding(DeviceMesh(np.asarray(devices), ("speed",)), PartitionSpec("speed"))
    return jax.make_array_from_callback(w.shape, sharding, lambda idx: w[idx])


def _cost_order(speeds):
    """Indices of the speeds in cost order. The cost is monotonic in speed (with the
    automatic transient it grows slowly with speed; with a fixed transient it falls like
    1/speed), so sorting by speed is sorting by cost: contiguous chunks hold similar costs
    (good for lockstep), and dealing each chunk round-robin to the devices balances them."""
    return np.argsort(speeds, kind="stable")


class Transient(AbstractOrbitSolver):
    """:func:`gearjax.dynamics.simulate.simulate` at every speed: diffrax from the model's
    quasi-static start (:meth:`~gearjax.models.base.AbstractGearModel.transient_start`)
    through a transient to the periodic steady state, then measured over
    ``n_measured_periods`` periods. Any model and formulation, contact loss included; the
    only solver that shares speeds over several processes and writes rows chunk by chunk.

    The fields are :func:`~gearjax.dynamics.simulate.simulate`'s options of the same names
    (``rtol``/``atol``: None for :func:`~gearjax.dynamics.simulate.default_solver`'s;
    ``n_transient_periods``: None for the automatic transient of its module docstring).
    """

    n_transient_periods: int | None = None
    n_measured_periods: int = 2
    rtol: float | None = None
    atol: float | None = None
    samples_per_mesh_period: int = 128
    transient_decay: float = 1e-6
    min_transient_mesh_periods: int = 8
    max_transient_mesh_periods: int = 400
    convergence_tol: float = 1e-3
    max_steps: int = 2_000_000
    start: str = "auto"
    extrapolate: bool = True
    accelerate: bool = True

    def simulate_options(self) -> dict:
        """The keyword arguments of :func:`~gearjax.dynamics.simulate.simulate` (static)."""
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}

    def orbit_metrics(self, model, omega, adjoint=None) -> SimulationResult:
        """The metrics at one speed ``omega`` (rad/s): :func:`~gearjax.dynamics.simulate.
        simulate` with these options; jit-, vmap- and differentiable (``adjoint``: diffrax's,
        default forward mode)."""
        return simulate(model, omega, adjoint=adjoint, **self.simulate_options())

    def solved(self, result: SweepResult) -> np.ndarray:
        return np.ones(np.shape(result.speed_rad_s), dtype=bool)  # the last resort

    def sweep(self, model, speeds: np.ndarray, run: SweepRun) -> SweepResult:
        progress, sink = run.progress, run.sink
        multi_process = jax.process_count() > 1
        lead = jax.process_index() == 0  # the process that reports and writes
        plan = _plan(model, speeds, run.chunk_size, run.devices, self)
        chunk, n_chunks, padded_idx, pad = plan.chunk, plan.n_chunks, plan.padded_idx, plan.pad
        programs = NoProgramStore() if multi_process else run.programs
        total = n_chunks * chunk
        formulation = model.formulation.name

        results = empty_metrics(total)
        if not lead:
            sink, progress = None, NoProgressMeter()
        task = f"sweep {formulation}"
        progress.start(task, speeds.size, f"chunk 1/{n_chunks}: "
                       f"{int(np.sum(~pad[:chunk]))} speeds "
                       f"{speeds[padded_idx[:chunk]].min():.4g}-"
                       f"{speeds[padded_idx[:chunk]].max():.4g} rad/s: compiling if new, "
                       "then integrating")
        t_start = time.perf_counter()
        n_done = n_unconverged = 0  # so far, as the progress line says
        for c in range(n_chunks):
            sel = padded_idx[c * chunk:(c + 1) * chunk]
            t0 = time.perf_counter()
            out = programs.call(plan.fn, plan.compiled, plan.chunk_speeds(c), self)
            if multi_process and plan.n_dev > 1:
                from jax.experimental import multihost_utils

                out = multihost_utils.process_allgather(out, tiled=True)
            out = jax.device_get(out)
            dt = time.perf_counter() - t0
            for f, v in zip(METRIC_FIELDS, out):
                results[f][c * chunk:(c + 1) * chunk] = np.asarray(v, dtype=float)
            # rows of the real (non-padding) speeds of this chunk, in sorted-speed order
            real = np.flatnonzero(~pad[c * chunk:(c + 1) * chunk])
            real_rows = sorted((c * chunk + real).tolist(), key=lambda k: padded_idx[k])
            if sink is not None:
                sink(_gather(results, formulation, real_rows))
            n_done += real.size
            conv = np.asarray(out[METRIC_FIELDS.index("converged")], dtype=float) == 1.0
            n_unconverged += int(np.sum(~conv[real]))
            progress.update(
                task, n_done, speeds.size,
                f"chunk {c + 1}/{n_chunks}: {real.size} speeds {speeds[sel].min():.4g}-"
                f"{speeds[sel].max():.4g} rad/s in {dt:.2f} s"
                f"{' incl. compile if new' if c == 0 else ''}, {n_unconverged} not converged",
                elapsed_s=time.perf_counter() - t_start)
        # back to the caller's order: the one real slot of each speed
        where = np.empty(speeds.size, dtype=int)
        where[padded_idx[~pad]] = np.flatnonzero(~pad)
        res = _gather(results, formulation, where)
        failed = ~res.solver_ok.astype(bool)
        if np.any(failed):
            progress.note(task, f"integration failed (step limit or non-finite state) at "
                          f"{int(failed.sum())} speed(s): {speeds[failed][:10].tolist()} "
                          "rad/s; their metrics are NaN and converged=False")
        return res


class Auto(AbstractPeriodicSolver):
    """The cheapest exact solver for the model and the number of speeds (:meth:`choose`),
    chosen from the model's declared capabilities by measurement, at the relative accuracy
    ``rtol`` of the metrics (:func:`tolerance_options`; None: every solver's defaults).

    The rule (``benchmarks/bench_auto.py``, ``benchmarks/results/auto.md``: compilation and
    run time of each solver against a tight reference, sdof and 3D, each formulation):

    * the te formulation (linear while the mesh force stays compressive,
      ``model.formulation.linear``) of a model whose state is speed-scaled
      (:attr:`~gearjax.models.base.AbstractGearModel.speed_scaled_state`: the frequency
      domain decomposes it once for every speed), large enough that a speed of the
      transient costs more than one of the frequency domain
      (``model.state_size >= FREQUENCY_DOMAIN_MIN_STATES``), swept over enough speeds that
      the frequency domain's cheaper speeds repay its compilation
      (``n_speeds >= FREQUENCY_DOMAIN_MIN_SPEEDS``): the frequency domain, exact there, its
      speeds with contact loss, not converged or not proven stable handed to the transient
      (``Fallback(HarmonicBalance(), Transient())``);
    * every other case: the transient (the shooting measured costlier), from the periodic
      start where the model has one
      (:attr:`~gearjax.models.base.AbstractGearModel.periodic_start`: the 3D perturbation
      model starts on its frequency-domain orbit already, so its transient only verifies
      and measures it)."""

    rtol: float | None = None

    def transient(self, model) -> Transient:
        """The transient at ``rtol`` for ``model`` (from its periodic start where it has
        one)."""
        options = tolerance_options(self.rtol)
        if model.periodic_start:
            options.update(n_transient_periods=0, start="initial")
        return Transient(**options)

    def harmonic(self) -> HarmonicBalance:
        """The frequency-domain solver at ``rtol`` (its truncation tolerance)."""
        return HarmonicBalance() if self.rtol is None else HarmonicBalance(rtol=self.rtol)

    def choose(self, model, n_speeds: int) -> AbstractPeriodicSolver:
        """The solver :meth:`sweep` uses for ``n_speeds`` speeds of ``model`` (class
        docstring)."""
        if (model.formulation.linear and not model.periodic_start
                and model.speed_scaled_state
                and model.state_size >= FREQUENCY_DOMAIN_MIN_STATES
                and n_speeds >= FREQUENCY_DOMAIN_MIN_SPEEDS):
            return Fallback(self.harmonic(), self.transient(model))
        return self.transient(model)

    def solved(self, result: SweepResult) -> np.ndarray:
        return np.ones(np.shape(result.speed_rad_s), dtype=bool)

    def sweep(self, model, speeds: np.ndarray, run: SweepRun) -> SweepResult:
        """:meth:`choose`'s solver; where it refuses the model (a
        :class:`~gearjax.errors.SimulationError` on ``model``, e.g. a vector field the
        frequency-domain split does not fit) or the run (several devices or processes:
        ``devices``), every speed by the transient."""
        chosen = self.choose(model, speeds.size)
        try:
            return chosen.sweep(model, speeds, run)
        except SimulationError as exc:
            if exc.field not in ("model", "devices") or isinstance(chosen, Transient):
                raise
            run.progress.note(f"sweep {model.formulation}", f"{type(chosen).__name__} not "
                              f"applicable ({exc}); every speed by the transient solver")
            return self.transient(model).sweep(model, speeds, run)


# smallest state, and fewest speeds, from which Auto solves te in the frequency domain
# (Auto): measured, benchmarks/results/auto.md
FREQUENCY_DOMAIN_MIN_STATES = 16
FREQUENCY_DOMAIN_MIN_SPEEDS = 5000


def sweep(
    model,
    speeds_rad_s,
    solver: AbstractPeriodicSolver = Auto(),
    *,
    chunk_size: int | None = None,
    progress: AbstractProgressMeter = NoProgressMeter(),
    out_csv: str | os.PathLike | None = None,
    orders_csv: str | os.PathLike | None = None,
    devices=None,
    programs: AbstractProgramStore = NoProgramStore(),
) -> SweepResult:
    """Steady-state response over pinion speeds: the one entry point of every periodic
    solver (:mod:`gearjax.dynamics.solvers`).

    Parameters
    ----------
    model : a gear model (:class:`gearjax.models.base.AbstractGearModel`).
    speeds_rad_s : (n,) pinion speeds Omega1 (rad/s), finite and > 0.
    solver : :class:`Auto` (default), :class:`Transient`,
        :class:`gearjax.dynamics.steady.Shooting`,
        :class:`gearjax.dynamics.harmonic_sweep.HarmonicBalance`, or a
        :class:`gearjax.dynamics.solvers.Fallback` of them (e.g. the frequency domain where
        contact holds, the transient elsewhere).
    chunk_size : speeds per compiled call (default: the solver's rule; for the transient
        :func:`default_chunk_size`: on a CPU 16-64 speeds per device by the model's size, on
        accelerators as many as :func:`memory_chunk` allows in the device's own memory).
        Chunks are padded so that every call has the same shape (one compilation).
    progress : the meter told of the sweep's start and of every chunk done
        (:class:`~gearjax.dynamics.progress.AbstractProgressMeter`; default none; e.g.
        :class:`gearjax.TextProgressMeter`).
    out_csv : append one row per speed (columns :data:`CSV_COLUMNS`) as speeds finish.
    orders_csv : append one row per speed of mesh-order amplitudes (columns
        :data:`gearjax.dynamics.results.ORDER_COLUMNS`) before ``out_csv`` gets it.
    devices : list of JAX devices to shard the speed axis over (the transient, and the
        frequency domain in one process; the shooting refuses them);
        ``None`` uses one device (the default device), ``"all"`` every device of the
        default backend.
    programs : where the compiled programs come from
        (:class:`~gearjax.dynamics.exported.ProgramStore`: exported into a folder by an
        earlier run, not traced again); default :class:`~gearjax.dynamics.exported.
        NoProgramStore`, traced in this process.

    Returns
    -------
    SweepResult (NumPy arrays, caller's order; ``solver`` names the solver per speed).

    Raises
    ------
    SimulationError
        for empty, non-finite or non-positive speeds, a bad chunk size, or a model the
        solver cannot take.
    """
    check_float64()
    speeds = np.asarray(speeds_rad_s, dtype=float).reshape(-1)
    if speeds.size == 0:
        raise SimulationError("speeds_rad_s", speeds_rad_s, "no speeds given")
    bad = ~(np.isfinite(speeds) & (speeds > 0))
    if np.any(bad):
        raise SimulationError(
            "speeds_rad_s", speeds[bad][:5].tolist(), "pinion speeds must be finite and > 0 (rad/s)"
        )
    if not isinstance(solver, AbstractPeriodicSolver):
        raise SimulationError("solver", solver, "must be a periodic solver "
                              "(gearjax.dynamics.solvers.AbstractPeriodicSolver: Auto(), "
                              "Transient(), Shooting(), HarmonicBalance(), Fallback(...))")
    check_meter(progress)
    model.require_structure()

    def write(finished: SweepResult) -> None:  # rows in speed order
        order = np.argsort(np.asarray(finished.speed_rad_s), kind="stable")
        if orders_csv is not None:  # before results.csv, which --resume reads
            rows = finished.order_rows()
            append_rows(orders_csv, ORDER_COLUMNS, [rows[i] for i in order])
        if out_csv is not None:
            rows = finished.rows()
            append_rows(out_csv, CSV_COLUMNS, [rows[i] for i in order])

    sink = write if (out_csv is not None or orders_csv is not None) else None
    if not isinstance(programs, AbstractProgramStore):
        raise SimulationError("programs", programs, "must be a program store "
                              "(gearjax.dynamics.exported.ProgramStore or NoProgramStore)")
    run = SweepRun(chunk_size=chunk_size, devices=devices, progress=progress, sink=sink,
                   programs=programs)
    return solver.sweep(model, speeds, run)


# share of the machine's memory that one chunk's saved states may take (memory_chunk)
CHUNK_MEMORY_FRACTION = 0.4
# bytes per saved state entry (output grid point x state component) of one speed: XLA's
# temporary memory (compile-time memory_analysis) of simulate vmapped over 8 and 14 speeds
# of the helical rig with pitch errors (17,076 grid points, n = 294) grows by 0.75 GB per
# speed, 149 bytes per entry (the measured states, the solver's saves, the windows'
# output evaluations on the grid and the batched loop's copies of them); 20 doubles
_BYTES_PER_ENTRY = 20 * 8


def _chunking(model, n_speeds: int, chunk_size, devices, solver: Transient):
    """``(devices, n_dev, first device, chunk)`` of a transient sweep of ``n_speeds``."""
    if devices is None and jax.process_count() > 1:
        devices = "all"
    if devices == "all":
        devices = jax.devices()
    n_dev = 1 if devices is None else len(devices)
    if n_dev < 1:
        raise SimulationError("devices", devices, "need at least one device")
    first = devices[0] if devices else jax.devices()[0]
    if chunk_size is None:
        chunk_size = default_chunk_size(model, n_speeds, n_dev, solver.simulate_options(),
                                        first.platform, device_memory_bytes(first))
    if int(chunk_size) != chunk_size or chunk_size < 1:
        raise SimulationError("chunk_size", chunk_size, "must be a positive integer")
    return devices, n_dev, first, int(math.ceil(int(chunk_size) / n_dev) * n_dev)


def planned_chunk(model, n_speeds: int, solver: AbstractPeriodicSolver = Auto(),
                  devices=None) -> int | None:
    """The speeds per compiled call that :func:`sweep` takes for ``n_speeds`` speeds of
    ``model`` with ``solver`` (:class:`Auto` resolved) and ``devices`` and no
    ``chunk_size``, or None where the solver is not a :class:`Transient`: a later sweep
    given it as ``chunk_size`` runs the same compiled program (e.g. the added speeds of
    :mod:`gearjax.dynamics.refine`)."""
    if isinstance(solver, Auto):
        solver = solver.choose(model, int(n_speeds))
    if not isinstance(solver, Transient):
        return None
    return _chunking(model, int(n_speeds), None, devices, solver)[3]


class _Plan(NamedTuple):
    """How a :class:`Transient` runs a sweep's speeds (:func:`_plan`)."""

    fn: Callable  # the compiled function of one chunk (mapped, vmapped or sharded)
    compiled: object  # the model it takes (``model.compiled_form()``)
    devices: object  # the devices (None: the default one)
    n_dev: int
    chunk: int  # slots per call
    n_chunks: int
    padded_idx: np.ndarray  # per slot, an index into the speeds (padded, cost-sorted)
    pad: np.ndarray  # per slot, whether it is padding
    slot_speeds: np.ndarray  # per slot, its speed (NaN in a mapped padding slot)

    def chunk_speeds(self, c: int):
        """The speeds of chunk ``c`` as its program takes them (shared over the devices)."""
        slots = self.slot_speeds[c * self.chunk:(c + 1) * self.chunk]
        return _global_speeds(slots, self.devices) if self.n_dev > 1 else jnp.asarray(slots)


def _plan(model, speeds, chunk_size, devices, solver: Transient) -> _Plan:
    """How ``solver`` (a :class:`Transient`) runs ``speeds``: the compiled function, the
    model it takes, the devices, the chunk, the speeds' padded, cost-sorted order (an index
    into ``speeds`` per slot), which slots are padding, and the speed of every slot (NaN
    in a padding slot where the speeds are mapped: :func:`_over_speeds` skips it)."""
    devices, n_dev, first, chunk = _chunking(model, speeds.size, chunk_size, devices, solver)
    sequential = sequential_on(first.platform, model.state_size)
    n_chunks = int(math.ceil(speeds.size / chunk))
    total = n_chunks * chunk
    compiled = model.compiled_form()  # 3D te and perturbation: one program for both

    # order: the whole sweep sorted by cost (speed), chunks of consecutive speeds, each chunk
    # dealt round-robin to the devices
    order = _cost_order(speeds)
    padded_idx = np.concatenate([order, np.full(total - speeds.size, order[-1])])
    pad = np.arange(total) >= speeds.size
    if n_dev > 1:
        per = chunk // n_dev
        # chunk c, device d, slot s <- sorted position (c * per + s) * n_dev + d
        pos = np.arange(total).reshape(n_chunks * per, n_dev)  # row: interleaved group
        layout = np.empty((n_chunks, n_dev, per), dtype=int)
        for c in range(n_chunks):
            for dv in range(n_dev):
                layout[c, dv] = pos[c * per:(c + 1) * per, dv]
        padded_idx, pad = padded_idx[layout.reshape(-1)], pad[layout.reshape(-1)]
        key = (tuple(devices), sequential)
        if key not in _SHARDED_CACHE:
            _SHARDED_CACHE[key] = _make_sharded(devices, sequential)
        fn = _SHARDED_CACHE[key]
    else:
        fn = _sequential if sequential else _batched
    slot_speeds = np.where(pad & sequential, np.nan, speeds[padded_idx])
    return _Plan(fn, compiled, devices, n_dev, chunk, n_chunks, padded_idx, pad, slot_speeds)


def lower_sweep(model, speeds_rad_s, solver: AbstractPeriodicSolver = Transient(),
                chunk_size: int | None = None, devices=None,
                programs: AbstractProgramStore = NoProgramStore()):
    """The program that ``sweep(model, speeds_rad_s, solver, chunk_size=chunk_size,
    devices=devices, programs=programs)`` will call, traced (or loaded from ``programs``)
    and lowered but not compiled (a
    ``jax.stages.Lowered``): its ``compile()`` releases the GIL, so a thread can compile the
    next formulation's program while another sweep traces, compiles and integrates (the
    command line's te program during the reference sweep). The executable reaches that
    later call through JAX's compilation caches (in memory, and the persistent cache where
    one is set). ``solver``: a :class:`Transient`, or :class:`Auto` (its choice)."""
    speeds = np.asarray(speeds_rad_s, dtype=float).reshape(-1)
    if isinstance(solver, Auto):
        solver = solver.choose(model, speeds.size)
    if not isinstance(solver, Transient):
        raise SimulationError("solver", solver, "only the transient's program is lowered ahead")
    plan = _plan(model, speeds, chunk_size, devices, solver)
    if jax.process_count() > 1:
        programs = NoProgramStore()
    return programs.lower(plan.fn, plan.compiled, plan.chunk_speeds(0), solver)


def memory_chunk(model, simulate_kwargs: dict | None = None,
                 budget_bytes: float | None = None) -> int:
    """Most speeds per vmapped ``simulate`` call whose saved states fit in ``budget_bytes``
    (default :data:`CHUNK_MEMORY_FRACTION` of the machine's memory, of 16 GiB where
    unknown).

    Each speed keeps its states on the output grid (mid-cell samples and both sides of
    every jump, per measured period) through the legs of
    :func:`gearjax.dynamics.simulate.simulate` (:mod:`gearjax.dynamics.legs`):
    :data:`_BYTES_PER_ENTRY` bytes per grid point and state component. The spur 3D rig:
    16 MB per speed; the helical rig with pitch errors (a pinion revolution of 26 mesh
    periods, 240 jumps per mesh period): 0.8 GB."""
    from .simulate import (DEFAULT_MEASURED_PERIODS, DEFAULT_SAMPLES_PER_MESH_PERIOD,
                           grid_size)

    kw = dict(simulate_kwargs or {})
    n_meas = int(kw.get("n_measured_periods", DEFAULT_MEASURED_PERIODS))
    _, per_period, _ = grid_size(
        model, n_meas, int(kw.get("samples_per_mesh_period", DEFAULT_SAMPLES_PER_MESH_PERIOD)))
    per_speed = float(_BYTES_PER_ENTRY) * n_meas * per_period * int(model.state_size)
    if budget_bytes is None:
        try:
            total = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
        except (ValueError, OSError, AttributeError):
            total = 16 * 2**30
        budget_bytes = CHUNK_MEMORY_FRACTION * total
    return max(1, int(budget_bytes // per_speed))


# Speeds per device and compiled call on a CPU: at most CPU_CHUNK_STATE_ENTRIES / state size,
# clipped to CPU_CHUNK_SPEEDS. Vmapped speeds advance in lockstep (a wide chunk waits for its
# slowest speed) and a chunk's solver stages must stay in the core's cache (16 speeds x 266
# states x 8 bytes x the 13 stages of Dopri8: ~0.5 MB); a chunk also pays a fixed dispatch
# cost, hence the lower bound. Where a model's speeds are mapped (gearjax.dynamics.batching)
# the chunk only sets how often rows are written. Measurements:
# benchmarks/results/code_notes.md, section gearjax.dynamics.sweep.
CPU_CHUNK_STATE_ENTRIES = 4096
CPU_CHUNK_SPEEDS = (16, 64)


def device_memory_bytes(device) -> int | None:
    """Memory of an accelerator ``device`` in bytes (its allocator's ``bytes_limit``), or
    None where the backend does not say (CPU devices share the host's memory)."""
    try:
        stats = device.memory_stats()
    except (AttributeError, NotImplementedError, RuntimeError):  # backends without them
        return None
    limit = (stats or {}).get("bytes_limit")
    return int(limit) if limit else None


def default_chunk_size(model, n_speeds: int, n_devices: int = 1,
                       simulate_kwargs: dict | None = None, platform: str = "cpu",
                       device_bytes: int | None = None) -> int:
    """Speeds per compiled call of :func:`sweep` when ``chunk_size`` is None: as many as
    the saved states fit in memory (:func:`memory_chunk`: per device on accelerators, of
    ``device_bytes`` each where given (:func:`device_memory_bytes`), else of the host's
    memory; for all devices together on a CPU, whose devices share the host's memory)
    and, on a CPU, at
    most :data:`CPU_CHUNK_STATE_ENTRIES` / ``model.state_size`` per device (clipped to
    :data:`CPU_CHUNK_SPEEDS`; see there for the measurements); accelerators take every
    speed that memory holds in one batch. The speeds are split into equal chunks (no
    chunk of padding copies)."""
    on_device = platform != "cpu" and device_bytes
    per_device = memory_chunk(model, simulate_kwargs, CHUNK_MEMORY_FRACTION * device_bytes
                              if on_device else None)
    if platform == "cpu":  # CPU devices share the host's memory
        per_device = max(1, per_device // int(n_devices))
        lo, hi = CPU_CHUNK_SPEEDS
        per_device = min(per_device, max(lo, min(hi, CPU_CHUNK_STATE_ENTRIES
                                                 // int(model.state_size))))
    cap = max(1, per_device * int(n_devices))
    n_chunks = math.ceil(int(n_speeds) / cap)
    return max(1, math.ceil(int(n_speeds) / n_chunks))


def tolerance_options(rtol: float | None) -> dict:
    """:func:`sweep` options for one requested relative accuracy ``rtol`` of the metrics
    (the command line's ``--rtol``; None: every solver's own defaults): the integrators'
    ``rtol`` (``atol = rtol / 100`` on the dimensionless state), the frequency-domain
    solver's truncation estimate, the transient's decay of the slowest mode (at most
    ``rtol``, so a tighter request integrates a longer transient) and its periodicity test
    ``convergence_tol = min(1e-3, 1e5 rtol)`` (the extrema's change between two periods
    carries the integration noise, which a contact loss raises: 2.3e-6 measured at rtol
    1e-10 on the sdof reference at 700 rad/s; models without per-mode extrapolation
    multiply it by the slowest output mode's ``1 / |1 - mu|``, up to ~1e3 for slow rig
    modes; the default pair is rtol 1e-7, tol 1e-3)."""
    if rtol is None:
        return {}
    r = float(rtol)
    if not (math.isfinite(r) and 1e-13 <= r <= 1e-2):
        raise SimulationError("rtol", rtol, "must lie in [1e-13, 1e-2]")
    return dict(rtol=r, atol=r / 100, transient_decay=min(1e-6, r),
                convergence_tol=min(1e-3, 1e5 * r))


def _gather(results, formulation, idx):
    idx = np.asarray(idx, dtype=int)
    kw = {f: results[f][idx] for f in METRIC_FIELDS}
    for f in FLAG_FIELDS:
        kw[f] = kw[f].astype(bool)
    kw["n_steps"] = kw["n_steps"].astype(np.int64)
    return SweepResult(**kw, formulation=formulation, solver=np.full(idx.size, "transient"),
                       spectral_radius=np.full(idx.size, np.nan),
                       status=metric_status(kw["solver_ok"], kw["converged"]))
