"""Up and down speed sweeps by continuation of the periodic orbit: coexisting branches,
jumps and the hysteresis band of contact loss (Velex & Ajmi, Section 6.3.1, Fig. 8).

Near a tooth critical speed with contact loss the response is *softening*: where the
teeth separate the mesh stiffness drops out of Eqs. (16)/(14) (and out of (20)/(42),
(47a)/(48a) by the contact law of Section 6.2), so the resonance leans towards low speeds
and, over a band of speeds, a low orbit (contact kept) and a high orbit (contact lost)
are both stable: sweeping up stays on the low branch until it ends and jumps up, sweeping
down stays on the high branch to *its* end and jumps down. ``gearjax.dynamics.sweep``
solves every speed independently from the quasi-static start; this module follows one
branch in one direction (the whole curve, unstable parts and folds included, is
:func:`gearjax.dynamics.arclength.trace_speed`'s).

Continuation (natural parameter, a Python loop over the compiled steps of
:mod:`gearjax.dynamics.corrector`, shared with the arclength continuation): at each speed
the periodic start ``y*`` is found by Newton shooting at fixed speed
(:func:`gearjax.dynamics.corrector.correct`) from the neighbour's ``y*``. The state is the
model's dimensionless ``y = (z / x_ref, (dz/dt) / (omega_n x_ref))`` at ``theta = 0`` (sdof;
the 3D modal state alike): position and *time* velocity, so the orbit at one speed is the
natural first iterate at the next. Where Newton fails (the branch ended at a fold) or
converges onto an unstable orbit (``spectral_radius >= 1``, kept in the ``unstable_*``
fields), a transient from the neighbour's orbit (``transient_decay``, as
:func:`gearjax.dynamics.simulate.simulate`'s) settles onto the attractor at the new speed,
as a slow run-up on a rig does, and Newton refines it (``restarted``). The first speed
starts from ``model.initial_state``.

Stability: the Floquet multipliers are the eigenvalues of the monodromy ``Phi``
integrated with the orbit (:func:`gearjax.dynamics.steady.period_map`). The contact laws
are continuous in the state (``k_i max(0, .)`` per cell, the force cut of
:func:`gearjax.gears.contact.te_contact`): only ``df/dy`` jumps where contact changes, so
the saltation matrix there is the identity and ``Phi`` needs no correction. For the sdof
model the trace of ``df/dy`` is ``-2 zeta omega_n / Omega`` whatever the contact, so ``det
Phi = exp(-2 zeta omega_n T)`` (Liouville) and complex multipliers have ``rho =
exp(-zeta omega_n T)``, ``T = P / Omega`` (a check used in the tests): an sdof orbit loses
stability only through a real multiplier (:mod:`gearjax.dynamics.bifurcation`).

Jumps (:func:`branch_jumps`): between neighbouring speeds, a change of the followed orbit's
maximum mesh force larger than ``threshold`` (:data:`JUMP_THRESHOLD`) times the smaller of
the two maxima, with whether the continuation failed there (``restarted``; measurements:
``benchmarks/results/code_notes.md``, section gearjax.dynamics.continuation).
"""

from __future__ import annotations

import math
import time

import jax
import jax.numpy as jnp
import numpy as np

from ..errors import SimulationError
from .bifurcation import multipliers
from .corrector import CorrectorOptions, correct, measure, settle
from .progress import AbstractProgressMeter, NoProgressMeter, check_meter
from .orbit import metric_status
from .results import FLAG_FIELDS, METRIC_FIELDS, SweepResult, empty_metrics
from .stability import check_speeds

__all__ = ["continuation_sweep", "BRANCH_STATS", "branch_jumps", "hysteresis_band",
           "forces_differ", "DIRECTIONS", "JUMP_THRESHOLD"]

DIRECTIONS = ("up", "down")
JUMP_THRESHOLD = 0.2  # relative change of the max mesh force between neighbours (see above)


BRANCH_STATS = ("stable", "restarted", "newton_iterations", "y0",
                "unstable_max_mesh_force_N", "unstable_dte_ptp_m", "unstable_spectral_radius",
                "unstable_y0")
"""The ``stats`` of a :func:`continuation_sweep` result (one branch), per speed:

stable : ``spectral_radius < 1`` and the Newton shooting converged.
restarted : the Newton from the neighbour's orbit found no stable orbit, so a transient
    from it settled first (a jump, or the first speed without a quasi-static orbit).
newton_iterations : shooting steps of the last Newton solve.
y0 : (n_speeds, n) periodic start at theta = 0 (model's dimensionless state).
unstable_max_mesh_force_N, unstable_dte_ptp_m, unstable_spectral_radius : an unstable
    periodic orbit the Newton from the neighbour converged onto before the restart (NaN
    where none was found; only orbits met this way are found).
unstable_y0 : (n_speeds, n) its start (NaN where none).
"""


def _orbit(model, omega, y_start, options: CorrectorOptions, convergence_tol: float):
    """Newton shooting at fixed speed from ``y_start`` (the corrector of
    :func:`gearjax.dynamics.corrector.correct` with the speed fixed) and the metrics of
    the orbit found (of ``y_start`` where none): ``(found, spectral radius, Newton
    iterations, y0, metrics)`` on the host."""
    y_start = jnp.asarray(y_start, dtype=float)
    n = y_start.shape[0]
    border = jnp.zeros(n + 1).at[n].set(1.0)
    c = jax.device_get(correct(model, y_start, omega, jnp.concatenate([y_start, omega[None]]),
                               border, 1.0, options))
    found = bool(c.converged)
    y0 = np.asarray(c.y) if found else np.asarray(y_start)
    met = jax.device_get(measure(model, omega, jnp.asarray(y0), convergence_tol))
    found = found and bool(met[METRIC_FIELDS.index("solver_ok")])
    rho = float(np.max(np.abs(multipliers(c.phi)))) if found else float("nan")
    return found, rho, int(c.iterations), y0, met


def continuation_sweep(model, speeds_rad_s, direction: str = "up", *, max_newton: int = 12,
                       newton_tol: float = 1e-10, convergence_tol: float = 1e-3,
                       transient_decay: float = 1e-6, min_transient_mesh_periods: int = 8,
                       max_transient_mesh_periods: int = 400,
                       progress: AbstractProgressMeter = NoProgressMeter()) -> SweepResult:
    """Follow the periodic orbit over ``speeds_rad_s`` (rad/s) in ``direction`` (``"up"``:
    increasing speed, ``"down"``: decreasing), each speed's Newton shooting started from
    its neighbour's orbit (module docstring: restarts, stability, the unstable orbits).

    Parameters
    ----------
    model : any :class:`gearjax.models.base.AbstractGearModel` (sdof or 3D, every
        formulation; the contact loss that makes branches coexist needs the reference
        formulation or the contact law of te/perturbation).
    speeds_rad_s : distinct pinion speeds Omega1 > 0 (rad/s), any order; the closer, the
        surer the continuation (15 rad/s on the sdof spur rig).
    max_newton, newton_tol : Newton shooting at fixed speed
        (:func:`gearjax.dynamics.corrector.correct`: a step below ``newton_tol (1 + |y|)``;
        the 3D model's period integration at the shooting's tolerances does not reach the
        default's: give it 1e-8, as ``gearjax sweep --direction`` does,
        ``benchmarks/results/code_notes.md``).
    convergence_tol : periodicity threshold of the metrics' ``converged`` (as simulate).
    transient_decay, min/max_transient_mesh_periods : the restart transient.
    progress : the meter told of every speed done (default none).

    Returns
    -------
    The :class:`~gearjax.dynamics.results.SweepResult` of the orbit followed at each speed
    (caller's order; metrics measured over two periods from ``y0``, as
    :func:`gearjax.dynamics.steady.steady_state`; ``spectral_radius`` the followed orbit's
    max |Floquet multiplier|), its ``stats`` :data:`BRANCH_STATS`.
    """
    if direction not in DIRECTIONS:
        raise SimulationError("direction", direction, f"must be one of {', '.join(DIRECTIONS)}")
    speeds = np.asarray(speeds_rad_s, dtype=float).reshape(-1)
    check_speeds(speeds)  # and float64
    if np.unique(speeds).size != speeds.size:
        raise SimulationError("speeds_rad_s", speeds[:5].tolist(),
                              "speeds must be distinct (a branch visits each once)")
    model.require_structure()
    options = CorrectorOptions(max_newton=int(max_newton), newton_tol=float(newton_tol))
    settle_cfg = (float(transient_decay), int(min_transient_mesh_periods),
                  int(max_transient_mesh_periods))
    order = np.argsort(speeds, kind="stable")
    if direction == "down":
        order = order[::-1]
    n, k = speeds.size, int(model.state_size)
    out = empty_metrics(n)
    extra = {name: np.full(n, np.nan) for name in
             ("spectral_radius", "newton_iterations", "unstable_max_mesh_force_N",
              "unstable_dte_ptp_m", "unstable_spectral_radius")}
    stable, restarted = np.zeros(n, bool), np.zeros(n, bool)
    y0s, uy0s = np.full((n, k), np.nan), np.full((n, k), np.nan)
    carry = None
    task = f"continuation {model.formulation} {direction}"
    check_meter(progress).start(task, n)
    t_start = time.perf_counter()
    for j, i in enumerate(order):
        w = jnp.asarray(speeds[i])
        start = model.initial_state(w) if carry is None else carry
        found, rho, it, y, met = _orbit(model, w, start, options, float(convergence_tol))
        ok = found and rho < 1.0
        if bool(found) and not ok:  # an unstable orbit: keep it, then settle elsewhere
            extra["unstable_max_mesh_force_N"][i] = met[METRIC_FIELDS.index("max_mesh_force_N")]
            extra["unstable_dte_ptp_m"][i] = met[METRIC_FIELDS.index("dte_ptp_m")]
            extra["unstable_spectral_radius"][i] = rho
            uy0s[i] = y
        if not ok:
            restarted[i] = True
            settled = settle(model, w, start, *settle_cfg)
            found, rho, it, y, met = _orbit(model, w, settled, options, float(convergence_tol))
            ok = found and rho < 1.0
        for f, v in zip(METRIC_FIELDS, met):
            out[f][i] = v
        extra["spectral_radius"][i], extra["newton_iterations"][i] = rho, it
        stable[i] = ok
        y0s[i] = y
        carry = jnp.asarray(y) if np.all(np.isfinite(y)) else carry
        progress.update(task, j + 1, n, f"{speeds[i]:9.4g} rad/s: DF "
                        f"{out['dynamic_factor'][i]:.3f}, rho {float(rho):.4f}"
                        f"{', restarted' if restarted[i] else ''}"
                        f"{'' if ok else ', NO stable orbit'}",
                        elapsed_s=time.perf_counter() - t_start)
    for f in FLAG_FIELDS:
        out[f] = out[f] > 0
    out["converged"] = out["converged"] & stable
    out["n_steps"] = np.nan_to_num(out["n_steps"]).astype(np.int64)
    extra["newton_iterations"] = np.nan_to_num(extra["newton_iterations"]).astype(np.int64)
    rho = extra.pop("spectral_radius")
    return SweepResult(**out, formulation=model.formulation, solver=np.full(n, "continuation"),
                       spectral_radius=rho,
                       status=metric_status(out["solver_ok"], out["converged"], rho),
                       stats=dict(stable=stable, restarted=restarted, y0=y0s, unstable_y0=uy0s,
                                  **extra))


def forces_differ(f_a, f_b, threshold: float = JUMP_THRESHOLD):
    """The jump criterion (module docstring): max mesh forces ``f_a``, ``f_b`` (N, arrays
    broadcast) differing by more than ``threshold`` times the smaller one."""
    return np.abs(np.asarray(f_b) - np.asarray(f_a)) > threshold * np.minimum(f_a, f_b)


def branch_jumps(branch: SweepResult, direction: str,
                 threshold: float = JUMP_THRESHOLD) -> list[dict]:
    """Jumps of one branch (a :func:`continuation_sweep` result), in the order the sweep in
    ``direction`` met them: neighbouring speeds (in that direction) where the max mesh force changes by more than ``threshold`` times
    the smaller of the two (module docstring). Each jump: ``from_rad_s``, ``to_rad_s``,
    ``max_mesh_force_before_N``, ``max_mesh_force_after_N``, ``restarted``."""
    if not (math.isfinite(threshold) and threshold > 0):
        raise SimulationError("threshold", threshold, "must be a finite relative change > 0")
    w = np.asarray(branch.speed_rad_s, dtype=float)
    f = np.asarray(branch.max_mesh_force_N, dtype=float)
    order = np.argsort(w, kind="stable")
    if direction not in DIRECTIONS:
        raise SimulationError("direction", direction, f"must be one of {', '.join(DIRECTIONS)}")
    if direction == "down":
        order = order[::-1]
    jumps = []
    for a, b in zip(order[:-1], order[1:]):
        fa, fb = f[a], f[b]
        if not (np.isfinite(fa) and np.isfinite(fb)):
            continue
        if forces_differ(fa, fb, threshold):
            jumps.append({"from_rad_s": float(w[a]), "to_rad_s": float(w[b]),
                          "max_mesh_force_before_N": float(fa),
                          "max_mesh_force_after_N": float(fb),
                          "restarted": bool(branch.stats["restarted"][b])})
    return jumps


def hysteresis_band(up: SweepResult, down: SweepResult,
                    threshold: float = JUMP_THRESHOLD) -> list[float] | None:
    """``[lowest, highest]`` speed (rad/s) at which the up and the down sweeps both hold a
    stable orbit and their max mesh forces differ by more than ``threshold`` times the
    smaller one (two coexisting stable orbits found); None where they agree everywhere.
    Both sweeps must cover the same speeds."""
    wu, wd = np.asarray(up.speed_rad_s, float), np.asarray(down.speed_rad_s, float)
    iu, idn = np.argsort(wu), np.argsort(wd)
    if not np.array_equal(wu[iu], wd[idn]):
        raise SimulationError("speeds_rad_s", wu[:5].tolist(),
                              "the up and down sweeps must cover the same speeds")
    fu = np.asarray(up.max_mesh_force_N, float)[iu]
    fd = np.asarray(down.max_mesh_force_N, float)[idn]
    both = np.asarray(up.stats["stable"], bool)[iu] & np.asarray(down.stats["stable"], bool)[idn]
    differ = both & forces_differ(fu, fd, threshold)
    if not differ.any():
        return None
    return [float(wu[iu][differ].min()), float(wu[iu][differ].max())]
