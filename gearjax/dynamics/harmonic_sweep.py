"""Speed sweeps of the frequency-domain solver of :mod:`gearjax.dynamics.harmonic`:
:func:`harmonic_sweep` reads the model's split once
(:func:`gearjax.dynamics.harmonic_split.harmonic_plan`), solves every speed in one compiled
program with the number of harmonics that the model's top mode and the tolerance ask for
(:func:`gearjax.dynamics.harmonic.harmonics_for`), then proves stability by the small-gain
bound (:mod:`gearjax.dynamics.small_gain`) or the Floquet radius of the monodromy
(:func:`gearjax.dynamics.stability.monodromy`); its
:class:`gearjax.dynamics.results.SweepResult` carries the solver's diagnostics in ``stats``
(:data:`HARMONIC_STATS`). How the speeds of the program are batched:
:func:`gearjax.dynamics.batching.frequency_domain_sequential`."""

from __future__ import annotations

import math
import time

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..errors import SimulationError
from .exported import AbstractProgramStore, NoProgramStore
from .progress import AbstractProgressMeter, NoProgressMeter, check_meter
from .harmonic import check_linear_model, harmonic_steady_states, harmonics_for
from .harmonic_split import harmonic_plan, harmonic_split
from .batching import shard_speeds
from .measure import N_REFINE
from .orbit import RESULTS
from .orders import N_MESH_ORDERS
from .results import SweepResult
from .solvers import AbstractPeriodicSolver, SweepRun
from .small_gain import SMALL_GAIN_MARGIN
from .stability import check_speeds, monodromy, spectral_radius_of

__all__ = ["harmonic_sweep", "HARMONIC_STATS", "HarmonicBalance",
           "HARMONIC_FLOQUET_MAX_STATES"]


HARMONIC_STATS = ("n_harmonics", "error_estimate", "contact_holds", "stable",
                  "stability_known", "small_gain", "y0")
"""The ``stats`` of a :func:`harmonic_sweep` result, per speed:

n_harmonics : harmonics used (those of :func:`~gearjax.dynamics.harmonic.harmonics_for`,
    or more where the estimate did not meet ``rtol``).
error_estimate : see :class:`~gearjax.dynamics.harmonic.HarmonicResult`.
contact_holds : the linear mesh force stays compressive over the period (else the orbit is
    not the model's: fall back to shooting / transient).
stable, stability_known : proven stable (small-gain bound below 0.95, or ``spectral_radius
    < 1``); whether either was established (False only with ``floquet=False``).
small_gain : the small-gain bound (:mod:`gearjax.dynamics.small_gain`).
y0 : (n_speeds, n) periodic state at theta = 0 (a start for ``simulate(y0=...)``).
"""


_FIELDS = ("max_mesh_force_N", "min_mesh_force_N", "dynamic_factor", "dte_ptp_m",
           "accel_ptp_m_s2", "contact_holds", "error_estimate", "rank_one_error",
           "small_gain", "ok", "y0", "mesh_orders")


@eqx.filter_jit
def _hb_batch(model, speeds, n_h, plan, samples_per_mesh_period, n_refine):
    r = harmonic_steady_states(model, speeds, n_h, plan=plan,
                               samples_per_mesh_period=samples_per_mesh_period,
                               n_refine=n_refine)
    return tuple(getattr(r, f) for f in _FIELDS)


@eqx.filter_jit
def _hb_sharded(model, speeds, n_h, plan, samples_per_mesh_period, n_refine, devices):
    dyn, static = eqx.partition((model, plan), eqx.is_array)

    def body(dyn_, w):
        m, p = eqx.combine(dyn_, static)
        r = harmonic_steady_states(m, w, n_h, plan=p,
                                   samples_per_mesh_period=samples_per_mesh_period,
                                   n_refine=n_refine)
        return tuple(getattr(r, f) for f in _FIELDS)

    return shard_speeds(body, devices)(dyn, speeds)


def _solve_batch(model, speeds, n_h, plan, samples_per_mesh_period, n_refine, devices,
                 programs: AbstractProgramStore):
    """The batch of ``speeds`` on one device, or shared over ``devices`` (padded with the
    last speed to a multiple of their number, handed to the program sharded over them:
    the devices it runs on); ``programs``: where the program comes from."""
    if devices is None or len(devices) < 2:
        return programs.call(_hb_batch, model, jnp.asarray(speeds), n_h, plan,
                             samples_per_mesh_period, n_refine)
    n_dev = len(devices)
    pad = -speeds.size % n_dev
    w = np.concatenate([speeds, np.full(pad, speeds[-1])])
    mesh = jax.sharding.Mesh(np.asarray(devices), ("speed",))
    w = jax.device_put(w, jax.sharding.NamedSharding(mesh, jax.sharding.PartitionSpec("speed")))
    out = programs.call(_hb_sharded, model, w, n_h, plan,
                        samples_per_mesh_period, n_refine, tuple(devices))
    return tuple(np.asarray(v)[: speeds.size] for v in jax.device_get(out))


@eqx.filter_jit
def _rho_batch(model, speeds):
    return jax.vmap(lambda w: spectral_radius_of(monodromy(model, w)))(speeds)


def harmonic_sweep(model, speeds_rad_s, *, rtol: float = 1e-6,
                   harmonics: int | None = None, max_harmonics: int = 4096,
                   floquet: bool = True, samples_per_mesh_period: int = 128,
                   n_refine: int = N_REFINE,
                   progress: AbstractProgressMeter = NoProgressMeter(),
                   rank_one_tol: float | None = None, devices=None,
                   programs: AbstractProgramStore = NoProgramStore()) -> SweepResult:
    """Steady state of a linear formulation (te, perturbation; sdof or 3D) over pinion
    speeds (rad/s) in the frequency domain (module docstring): one plan of the model
    (:func:`~gearjax.dynamics.harmonic_split.harmonic_plan`, at the median speed), one
    compiled program for every speed. Returns a
    :class:`~gearjax.dynamics.results.SweepResult` (``convergence`` is the error estimate,
    ``contact_loss`` is ``not contact_holds``, ``back_contact`` False: where contact holds
    no back flank is reached, ``n_steps`` and ``transient_periods`` 0: nothing is
    integrated; ``spectral_radius`` NaN where the bound proved stability or ``floquet`` is
    False) whose ``stats`` are :data:`HARMONIC_STATS`.

    ``harmonics``: the number ``H`` of harmonics (a power of two >= 8; None:
    :func:`~gearjax.dynamics.harmonic.harmonics_for` the speeds and ``rtol``). The speeds
    whose ``error_estimate`` exceeds ``rtol`` are solved again with the power of two that
    the ``H^-3`` decay of the estimate predicts for the worst of them (at least twice as
    many; a compilation each), up to ``max_harmonics``;
    ``converged`` = that estimate met, the orbit finite and not known to be unstable.
    Stability: the small-gain bound (:mod:`gearjax.dynamics.small_gain`, free) proves it
    where it can; with ``floquet`` the Floquet ``spectral_radius`` decides at the other
    speeds (one monodromy period of ``n`` columns each: cheap for the sdof model, costly for
    the 3D rig, see ``benchmarks/results/code_notes.md``, section
    gearjax.dynamics.harmonic_sweep). Inside a parametric instability zone the periodic
    orbit exists but a transient never reaches it. Where ``contact_holds`` is False the
    linear orbit has a tensile mesh force: exact for the linear equations, not for a
    contact law that clips it. ``samples_per_mesh_period``, ``n_refine``: the measure's
    grid and windows (:mod:`gearjax.dynamics.measure`).
    ``rank_one_tol`` (default ``max(1e-8, rtol / 10)``): the largest relative residual of
    the rank-one split accepted (it perturbs the orbit by about as much; round-off of the
    3D long-relief te model's optimised compile reached 1.2e-8). ``devices``: the devices
    of this process to share the speeds over (a list, ``"all"`` or None: the default one;
    :func:`gearjax.dynamics.batching.shard_speeds`). ``programs``: where the compiled
    programs come from (:mod:`gearjax.dynamics.exported`; default: traced here).

    Raises
    ------
    SimulationError
        for a non-model, the reference formulation, bad speeds or options, or a model
        whose varying part is not rank one (e.g. a design whose switching angles moved:
        its angle map scales the whole vector field).
    """
    check_linear_model(model)
    speeds = np.asarray(speeds_rad_s, dtype=float).reshape(-1)
    check_speeds(speeds)
    model.require_structure()
    devices = jax.devices() if devices == "all" else devices
    if not (0.0 < rtol < 1.0):
        raise SimulationError("rtol", rtol, "must lie in (0, 1)")
    if rank_one_tol is None:  # the split's residual moves the orbit by about as much
        rank_one_tol = max(1e-8, 0.1 * rtol)
    hi = int(max_harmonics)
    for name, v in (("harmonics", harmonics), ("max_harmonics", hi)):
        if v is not None and (int(v) < 8 or int(v) & (int(v) - 1)):
            raise SimulationError(name, v, "must be a power of two >= 8")
    if harmonics is not None and int(harmonics) > hi:
        raise SimulationError("max_harmonics", hi, f"must be >= harmonics={harmonics}")
    # te and perturbation of a 3D build: one program (gearjax.models.base.compiled_form)
    compiled = model.compiled_form()
    scaled = model.speed_scaled_state  # one split and one sampling for every speed
    split = harmonic_split(compiled, float(np.median(speeds)) if scaled
                           else float(np.min(speeds)), programs)
    n_h = (int(harmonics) if harmonics is not None else
           harmonics_for(model, split, speeds, rtol, hi=hi))
    n = model.state_size
    out = {f: np.full(speeds.size, np.nan) for f in _FIELDS}
    out["y0"], out["mesh_orders"] = np.full((speeds.size, n), np.nan), np.full(
        (speeds.size, 3, N_MESH_ORDERS), np.nan)
    n_used = np.zeros(speeds.size, dtype=np.int64)
    todo = np.arange(speeds.size)
    task = f"harmonic balance {model.formulation}"
    check_meter(progress).start(task, speeds.size, f"H={n_h}")
    t0 = time.perf_counter()
    while todo.size:
        t_batch = time.perf_counter()
        plan = harmonic_plan(compiled, split, n_h, programs) if scaled else None
        res = jax.device_get(_solve_batch(compiled, speeds[todo], n_h, plan,
                                          int(samples_per_mesh_period), int(n_refine),
                                          devices, programs))
        for f, v in zip(_FIELDS, res):
            out[f][todo] = np.asarray(v, dtype=float)
        n_used[todo] = n_h
        if np.any(out["rank_one_error"][todo] > rank_one_tol):
            raise SimulationError(
                "model", f"rank_one_error={np.max(out['rank_one_error'][todo]):.1e}",
                "the parametric part of the vector field is not rank one, its forcing "
                "spans more than 48 directions or its state is not speed-scaled as it "
                "declares (a design whose switching angles moved?): use "
                "gearjax.dynamics.steady (shooting)")
        batch = todo.size
        todo = todo[~(out["error_estimate"][todo] <= rtol)]
        # the next batch doubles H at least (and compiles again): allow it 4x this one
        progress.update(task, speeds.size - todo.size, speeds.size,
                        f"{batch} speed(s) at H={n_h}", elapsed_s=time.perf_counter() - t0,
                        next_unit_s=4.0 * (time.perf_counter() - t_batch))
        if n_h >= hi or not todo.size:
            break
        # the estimate falls like H^-3 (bench_harmonic.py --convergence): jump to
        # the power of two predicted for the worst speed (one compilation, not a ladder)
        est = out["error_estimate"][todo]
        worst = float(np.max(est[np.isfinite(est)], initial=rtol))
        need = n_h * 1.2 * (worst / rtol) ** (1.0 / 3.0)
        n_h = int(min(hi, max(2 * n_h, 2 ** math.ceil(math.log2(need)))))
    proven = out["small_gain"] < SMALL_GAIN_MARGIN
    rho = np.full(speeds.size, np.nan)
    need = np.flatnonzero(~proven)
    if floquet and need.size:
        rho[need] = np.asarray(programs.call(_rho_batch, model, jnp.asarray(speeds[need])),
                               dtype=float)
        progress.note(task, f"Floquet radius at {need.size} speed(s) the small-gain bound "
                      f"leaves open: {time.perf_counter() - t0:.2f} s")
    ok = out["ok"] > 0
    stable = proven | (rho < 1.0)
    known = proven | np.isfinite(rho)
    holds = out["contact_holds"] > 0
    zero = np.zeros(speeds.size)
    conv = ok & (out["error_estimate"] <= rtol) & (stable | ~known)
    return SweepResult(
        speed_rad_s=speeds, max_mesh_force_N=out["max_mesh_force_N"],
        min_mesh_force_N=out["min_mesh_force_N"], dynamic_factor=out["dynamic_factor"],
        dte_ptp_m=out["dte_ptp_m"], accel_ptp_m_s2=out["accel_ptp_m_s2"],
        contact_loss=ok & ~holds, back_contact=np.zeros(speeds.size, bool),
        convergence=out["error_estimate"],
        converged=conv, period_multiple=np.where(conv, 1, 0), solver_ok=ok,
        n_steps=zero.astype(np.int64), transient_periods=zero, formulation=model.formulation.name,
        spectral_radius=rho,
        status=_status(ok, holds, known & ~stable, out["error_estimate"] <= rtol),
        stats=dict(n_harmonics=n_used, error_estimate=out["error_estimate"],
                   contact_holds=holds, stable=stable, stability_known=known,
                   small_gain=out["small_gain"], y0=out["y0"]),
        mesh_force_orders_N=out["mesh_orders"][:, 0],
        dte_orders_m=out["mesh_orders"][:, 1], accel_orders_m_s2=out["mesh_orders"][:, 2],
        solver=np.full(speeds.size, "harmonic"))


def _status(ok, holds, unstable, converged) -> np.ndarray:
    """Per speed, the :class:`~gearjax.dynamics.orbit.RESULTS` code of a frequency-domain
    orbit: failed solve, else contact lost, else unstable, else not converged in the
    harmonics, else successful."""
    out = np.where(converged, RESULTS.successful, RESULTS.not_periodic)
    out = np.where(unstable, RESULTS.unstable, out)
    out = np.where(holds, out, RESULTS.contact_lost)
    return np.where(ok, out, RESULTS.integration_failed).astype(np.int8)


HARMONIC_FLOQUET_MAX_STATES = 32  # above: the transient is cheaper than a monodromy


class HarmonicBalance(AbstractPeriodicSolver):
    """The periodic orbit of the linear te/perturbation equations in the frequency domain
    (:func:`harmonic_sweep`; no integration). A speed is solved where that orbit is the
    model's: contact holds over the period, the harmonics converged to ``rtol``, and
    stability is proven by the small-gain bound or the Floquet radius; compose with
    :class:`~gearjax.dynamics.solvers.Fallback` to hand the others to the transient.

    ``floquet``: compute the Floquet radius where the bound leaves stability open (None:
    for models of at most :data:`HARMONIC_FLOQUET_MAX_STATES` states, above which the
    transient is the cheaper judge). The other fields are :func:`harmonic_sweep`'s.
    Raises :class:`~gearjax.errors.SimulationError` for the reference formulation or a
    model whose parametric part is not rank one."""

    rtol: float = 1e-6
    harmonics: int | None = None
    max_harmonics: int = 4096
    floquet: bool | None = None
    samples_per_mesh_period: int = 128
    n_refine: int = N_REFINE
    rank_one_tol: float | None = None

    def solved(self, result: SweepResult) -> np.ndarray:
        st = result.stats
        return np.asarray(result.converged, dtype=bool) & np.asarray(st["contact_holds"]) \
            & np.asarray(st["stable"]) & np.asarray(st["stability_known"])

    def sweep(self, model, speeds: np.ndarray, run: SweepRun) -> SweepResult:
        if jax.process_count() > 1:
            raise SimulationError("devices", run.devices, "the frequency domain runs in one "
                                  "process; use Transient() to share speeds over hosts")
        floquet = (model.state_size <= HARMONIC_FLOQUET_MAX_STATES if self.floquet is None
                   else bool(self.floquet))
        res = harmonic_sweep(model, speeds, rtol=self.rtol, harmonics=self.harmonics,
                             max_harmonics=self.max_harmonics, floquet=floquet,
                             samples_per_mesh_period=self.samples_per_mesh_period,
                             n_refine=self.n_refine, progress=run.progress,
                             rank_one_tol=self.rank_one_tol, devices=run.devices,
                             programs=run.programs)
        if run.sink is not None:
            run.sink(res)
        return res
