"""100-speed 3D sweep (issue #4): compile time, run time, the ratio to SciPy's solve_ivp,
and transient (``sweep``) against shooting (``steady_sweep``) with their accuracy.

Scenario: ``build_model(baud_velex_rig(helical), short relief, formulation, damping_ratio=0.1,
max_frequency_hz=6000)`` (the paper's 3D rig, cell structure vectors, modes to 6 kHz plus
static corrections), speeds linearly spaced in ``--range``.

* gearjax transient: :func:`gearjax.dynamics.sweep.sweep` (default solver, automatic transient from
  :func:`gearjax.dynamics.simulate.transient_start`); compile time from ``lower().compile()`` of the
  chunk function, run time of one call (all speeds in one vmapped call).
* gearjax steady: :func:`gearjax.dynamics.steady.steady_sweep` (shooting, default tolerances); its
  run time is a second call of the compiled chunk function (same shape), its compile
  time the first call minus that.
* accuracy: on ``--check`` speeds spread over the range, both against a tight reference
  (shooting at rtol 1e-10, measuring at rtol 1e-10), error of the dynamic factor and
  relative error of the DTE peak-to-peak.
* SciPy: ``solve_ivp`` (``DOP853`` where gearjax uses Dopri8, ``RK45`` for Tsit5) at the
  same rtol/atol on the same dimensionless state, the model's jitted JAX right-hand side,
  the same start, transient length (the plain transient's ``transient_periods`` per speed,
  ``simulate(accelerate=False)``; the accelerated default is its own row) and jump
  splitting, timed on ``--scipy-subset`` speeds and scaled to all speeds (printed as
  such), its error against the same reference printed next to gearjax's.

Usage::

    python benchmarks/bench_sweep_3d.py                       # spur te, 100 speeds
    python benchmarks/bench_sweep_3d.py --helical --speeds 8  # helical te, 8 speeds
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

import gearjax  # noqa: F401
import gearjax.dynamics.steady  # noqa: F401
import gearjax.dynamics.sweep  # noqa: F401
from gearjax.rigs import baud_velex_rig, build_model
from gearjax.rigs.registry import get_rig
from gearjax.dynamics.simulate import default_solver, jump_density, transient_start
from gearjax.dynamics.steady import steady_sweep
from gearjax.dynamics.sweep import Transient, sweep

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from baselines import solve_ivp_piecewise  # noqa: E402
from bench_work_precision import machine  # noqa: E402

sweep_mod = sys.modules["gearjax.dynamics.sweep"]
steady_mod = sys.modules["gearjax.dynamics.steady"]


def scipy_run(model, w, n_transient, n_measured=3, samples=128):
    """(DF, DTE ptp, seconds) with solve_ivp, split at the jump angles."""
    import diffrax
    mp = model  # born complete: the excitation table is built with the model
    solver, rtol, atol = default_solver(model.formulation, jump_density(model))
    name = "DOP853" if isinstance(solver, diffrax.Dopri8) else "RK45"
    period = model.period_rad
    n_mesh = int(round(period / model.mesh_period_rad))
    jumps = np.asarray(mp.jump_thetas)
    vf = jax.jit(lambda t, y: mp.vector_field(t, y, w))
    f = lambda t, y: np.asarray(vf(t, y))  # noqa: E731
    y = np.asarray(eqx.filter_jit(transient_start)(mp, jnp.asarray(w)))
    f(0.0, y)  # compile the RHS outside the timing
    t_tr = n_transient * period
    t_end = t_tr + n_measured * period
    n_s = samples * n_mesh
    grid = t_tr + (np.arange(n_measured * n_s) + 0.5) * (period / n_s)
    ys, dt = solve_ivp_piecewise(f, y, period, jumps, t_tr, t_end, grid, name, rtol, atol)
    out = jax.vmap(lambda t, yy: mp.outputs(t, yy, w))(jnp.asarray(grid), jnp.asarray(ys))
    dte = np.asarray(out.dte_m)
    return float(jnp.max(out.mesh_force_N) / mp.static_force_N), float(dte.max() - dte.min()), dt, name


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--helical", action="store_true")
    ap.add_argument("--formulation", default="te")
    ap.add_argument("--speeds", type=int, default=100)
    ap.add_argument("--range", default="200:1500")
    ap.add_argument("--check", type=int, default=4, help="speeds checked against the reference")
    ap.add_argument("--scipy-subset", type=int, default=2)
    ap.add_argument("--skip-transient", action="store_true")
    args = ap.parse_args()
    lo, hi = (float(v) for v in args.range.split(":"))
    speeds = np.linspace(lo, hi, args.speeds)
    rig = get_rig("baud-velex-helical" if args.helical else "baud-velex-spur")
    say = lambda s="": print(s, flush=True)  # noqa: E731
    say(f"# 3D sweep benchmark: {'helical' if args.helical else 'spur'} {args.formulation}, "
        f"{args.speeds} speeds {lo:.0f}-{hi:.0f} rad/s, zeta 0.1, modes to 6 kHz")
    say(f"machine: {machine()}; load average at start {os.getloadavg()[0]:.1f}")
    t0 = time.perf_counter()
    model = build_model(baud_velex_rig(args.helical), rig.modifications("short"),
                                     formulation=args.formulation, damping_ratio=0.1,
                                     max_frequency_hz=6000.0)
    say(f"build {time.perf_counter() - t0:.1f} s, {model.n_reduced} modal coordinates, "
        f"{len(model.jump_thetas)} jump angles per period")
    rows = {}
    if not args.skip_transient:
        w = jnp.asarray(speeds)
        # plain: one transient of the automatic count (what the SciPy loop integrates too);
        # accelerated: simulate's default, periodic estimate after every period
        for name, kw in (("transient (plain)", (("accelerate", False),)), ("transient", ())):
            t0 = time.perf_counter()
            sweep_mod._batched.lower(model, w, Transient(**dict(kw))).compile()
            comp = time.perf_counter() - t0
            t0 = time.perf_counter()
            tr = sweep(model, speeds, Transient(**dict(kw)))
            # lower().compile() does not fill jit's cache: the call compiles again; run time =
            # call - compile (the first-call time is printed too)
            first_tr = time.perf_counter() - t0
            run = max(first_tr - comp, 0.0)
            rows[name] = (tr, comp, run)
            say(f"{name} sweep: first call {first_tr:.1f} s, compile {comp:.1f} s, run {run:.1f} s "
                f"({run / speeds.size:.2f} s/speed), converged {int(tr.converged.sum())}/{speeds.size}, "
                f"steps/speed median {np.median(tr.n_steps):.0f}, transient periods "
                f"{tr.transient_periods.min():.0f}-{tr.transient_periods.max():.0f}")
    t0 = time.perf_counter()
    st = steady_sweep(model, speeds)
    first = time.perf_counter() - t0
    t0 = time.perf_counter()
    jax.block_until_ready(steady_mod._steady_batch(model, jnp.asarray(speeds), steady_mod.Shooting()))  # cached
    run_st = time.perf_counter() - t0
    rows["steady"] = (st, max(first - run_st, 0.0), run_st)
    say(f"steady sweep: compile {max(first - run_st, 0.0):.1f} s, run {run_st:.1f} s "
        f"({run_st / speeds.size:.2f} s/speed), converged {int(st.converged.sum())}/{speeds.size}, "
        f"spectral radius {np.nanmin(st.spectral_radius):.4f}-{np.nanmax(st.spectral_radius):.4f}")

    idx = np.unique(np.round(np.linspace(0, speeds.size - 1, args.check)).astype(int))
    t0 = time.perf_counter()
    ref = steady_sweep(model, speeds[idx], steady_mod.Shooting(
        rtol=1e-10, atol=1e-12, measure_rtol=1e-10, measure_atol=1e-12))
    say(f"reference (shooting rtol 1e-10) at {speeds[idx].round(1).tolist()} rad/s in "
        f"{time.perf_counter() - t0:.1f} s")
    say("\n| method | speeds | compile s | run s | s/speed | max err DF | max rel err DTE ptp | converged |")
    say("|---|---|---|---|---|---|---|---|")
    for name, (r, comp, run) in rows.items():
        e_df = np.max(np.abs(r.dynamic_factor[idx] - ref.dynamic_factor))
        e_d = np.max(np.abs(r.dte_ptp_m[idx] / ref.dte_ptp_m - 1))
        say(f"| gearjax {name} | {speeds.size} | {comp:.1f} | {run:.1f} | {run / speeds.size:.3f} | "
            f"{e_df:.1e} | {e_d:.1e} | {int(r.converged.sum())}/{speeds.size} |")
    if args.scipy_subset > 0 and "transient (plain)" in rows:
        tr = rows["transient (plain)"][0]
        sub = idx[np.unique(np.round(np.linspace(0, idx.size - 1, args.scipy_subset)).astype(int))]
        tot, e_df, e_d = 0.0, 0.0, 0.0
        for i in sub:
            df, dte, dt, name = scipy_run(model, float(speeds[i]), int(tr.transient_periods[i]))
            j = int(np.flatnonzero(idx == i)[0])
            e_df = max(e_df, abs(df - ref.dynamic_factor[j]))
            e_d = max(e_d, abs(dte / ref.dte_ptp_m[j] - 1))
            tot += dt
            say(f"  scipy {name} at {speeds[i]:.1f} rad/s: {dt:.1f} s")
        scaled = tot / sub.size * speeds.size
        say(f"| scipy solve_ivp {name} loop (timed on {sub.size} speeds, scaled x{speeds.size / sub.size:.0f}) "
            f"| {speeds.size} | 0 | {scaled:.0f} | {tot / sub.size:.2f} | {e_df:.1e} | {e_d:.1e} | - |")
        for name, (r, comp, run) in rows.items():
            say(f"ratio scipy / gearjax {name}: {scaled / run:.1f}x run time, "
                f"{scaled / (run + comp):.1f}x including compile")


if __name__ == "__main__":
    main()
