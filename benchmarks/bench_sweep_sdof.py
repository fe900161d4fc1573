"""200-speed sdof sweep: compile time, run time, and the ratio to SciPy's solve_ivp.

Scenario: Baud & Velex spur pair (Table 1), short tip relief, 254.8 N m, damping ratio 0.03,
default (solid-cylinder) inertias, speeds 50-1500 rad/s, the three formulations.

* gearjax: :func:`gearjax.dynamics.sweep` (one jitted, vmapped call; compile time measured with
  ``lower().compile()`` on the chunk function, run time the median of repeated calls).
* SciPy: ``scipy.integrate.solve_ivp`` looping over the speeds with the *same* equations
  (the model's jitted vector field called from SciPy -- "JAX right-hand side + SciPy
  loop"), the same transient length per speed, the same jump handling (integration split
  at the jump angles), the solver of the same family (Dormand-Prince 5(4) ``RK45`` for the
  reference where gearjax uses Tsit5, ``DOP853`` where gearjax uses Dopri8) at the same
  rtol/atol on the same dimensionless state. It is timed on a subset of speeds spread over
  the range and scaled to 200 (printed as such); the largest difference of the dynamic
  factor between the two on that subset is printed to show the accuracy is the same. For
  te/perturbation a pure-NumPy right-hand side (the same Hermite table, no JAX dispatch) is
  timed too, as the fastest reasonable SciPy baseline.

Usage::

    python benchmarks/bench_sweep_sdof.py                  # sweep table (about 2 min)
    python benchmarks/bench_sweep_sdof.py --host-devices 2 # also shard over 2 CPU devices
    python benchmarks/bench_sweep_sdof.py --work-precision # solver/tolerance study
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time


def _args():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--speeds", type=int, default=200)
    ap.add_argument("--scipy-subset", type=int, default=8, help="speeds timed with SciPy")
    ap.add_argument("--host-devices", type=int, default=1,
                    help="also run sharded over this many XLA CPU devices (sets XLA_FLAGS)")
    ap.add_argument("--formulations", default="reference,te,perturbation")
    ap.add_argument("--work-precision", action="store_true",
                    help="solver/tolerance study instead of the sweep table")
    return ap.parse_args()


ARGS = _args() if __name__ == "__main__" else None
if ARGS is not None and ARGS.host_devices > 1:
    os.environ["XLA_FLAGS"] = (os.environ.get("XLA_FLAGS", "") +
                               f" --xla_force_host_platform_device_count={ARGS.host_devices}")

import diffrax  # noqa: E402
import equinox as eqx  # noqa: E402
import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

import gearjax  # noqa: E402,F401
import gearjax.dynamics.sweep as sweep_mod  # noqa: E402
from gearjax import Mesh, baud_velex_pair, table1_relief  # noqa: E402
from gearjax.models.torsional import TorsionalModel  # noqa: E402
from gearjax.dynamics.simulate import default_solver, jump_density, simulate  # noqa: E402
from gearjax.dynamics.sweep import sweep  # noqa: E402

ZETA = 0.03
SPEEDS = (50.0, 1500.0)


def build(formulation, relief="short"):
    return TorsionalModel.build(Mesh.build(baud_velex_pair(False)), table1_relief(relief),
                                formulation=formulation, damping_ratio=ZETA)


def _median_time(fn, repeats=3):
    ts = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        ts.append(time.perf_counter() - t0)
    return float(np.median(ts)), out


# ---------------------------------------------------------------------- SciPy baseline
def scipy_metrics(model, omega, n_transient, rhs="jax", n_measured=3, samples=128):
    """Same steady-state metrics with solve_ivp; returns (max F_D / F_S, seconds)."""
    from baselines import solve_ivp_piecewise  # benchmarks/ is on sys.path as the script dir

    mp = model
    name, rtol, atol = _scipy_method(model)
    period = model.period_rad
    jumps = np.asarray(mp.jump_thetas)
    w = float(omega)
    if rhs == "jax":
        vf = jax.jit(lambda t, y: mp.vector_field(t, y, w))
        f = lambda t, y: np.asarray(vf(t, y))  # noqa: E731
    else:
        f = _numpy_rhs(mp, w)
    t_tr = n_transient * period
    t_end = t_tr + n_measured * period
    grid = t_tr + (np.arange(n_measured * samples) + 0.5) * (period / samples)
    ys, dt = solve_ivp_piecewise(f, np.asarray(mp.initial_state(w)), period, jumps, t_tr, t_end,
                                 grid, name, rtol, atol)
    out = jax.vmap(lambda t, yy: mp.outputs(t, yy, w))(jnp.asarray(grid), jnp.asarray(ys))
    return float(jnp.max(out.mesh_force_N) / mp.static_force_N), dt


def _scipy_method(model):
    solver, rtol, atol = default_solver(model.formulation, jump_density(model))
    return ("DOP853" if isinstance(solver, diffrax.Dopri8) else "RK45"), rtol, atol


def _numpy_rhs(mp, omega):
    """Pure-NumPy right-hand side of the te/perturbation formulations (substitution-free
    case: NLTE = 0) with their contact law, reading the model's Hermite table."""
    if mp.formulation.name == "reference" or mp.nlte_terms:
        raise ValueError("NumPy RHS only for te/perturbation without NLTE terms")
    d = mp
    tab = d.table
    knots, vals, slopes = (np.asarray(tab.knots), np.asarray(tab.values), np.asarray(tab.slopes))
    origin, period = tab.origin, tab.period
    k_m, x_ref = float(d.k_m), float(d.x_ref)
    r = float(d.omega_n) / omega
    zeta = float(mp.damping_ratio)
    cos_b = mp.cos_bb
    f_s = float(mp.static_force_N)
    te = mp.formulation.name == "te"

    def rhs(t, y):
        s = origin + (t - origin) % period
        j = min(max(np.searchsorted(knots, s, side="right") - 1, 0), len(knots) - 2)
        t0, t1 = knots[j], knots[j + 1]
        w = max(t1 - t0, 1e-300)
        u = min(max((s - t0) / w, 0.0), 1.0)
        u2, u3 = u * u, u * u * u
        v = ((2 * u3 - 3 * u2 + 1) * vals[j] + (u3 - 2 * u2 + u) * w * slopes[j]
             + (-2 * u3 + 3 * u2) * vals[j + 1] + (u3 - u2) * w * slopes[j + 1])
        x_s, k_s = v[0], v[1]
        x = y[0] * x_ref
        stiff = k_s if te else k_m
        # contact law (gearjax.gears.contact.te_contact): no mesh force once it would be tensile
        resid = max(stiff * cos_b * (x - x_s) / f_s, -1.0)
        return np.array([r * y[1], -r * (resid + 2 * zeta * y[1])])

    return rhs


# ---------------------------------------------------------------------- sweep table
def sweep_table(args):
    speeds = np.linspace(*SPEEDS, args.speeds)
    print(f"# gearjax sdof sweep benchmark: {args.speeds} speeds {SPEEDS[0]:.0f}-{SPEEDS[1]:.0f} "
          f"rad/s, spur Table 1 short relief, zeta={ZETA}")
    print(f"# {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
          f"jax {jax.__version__}, diffrax {diffrax.__version__}, devices {len(jax.devices())}")
    print(f"{'formulation':13s} {'solver':7s} {'devices':>7s} {'compile [s]':>11s} {'run [s]':>8s} "
          f"{'ms/speed':>8s} {'max steps':>9s} {'unconv.':>7s} {'scipy-jax [s]':>13s} "
          f"{'ratio':>6s} {'scipy-np [s]':>12s} {'ratio':>6s} {'max |dDF|':>9s}")
    for form in args.formulations.split(","):
        model = build(form)
        kwargs = tuple()
        w = jnp.asarray(speeds)
        t0 = time.perf_counter()
        compiled = sweep_mod._batched.lower(model, w, kwargs).compile()
        compile_s = time.perf_counter() - t0
        del compiled
        sweep(model, speeds)  # warm the cache of the jitted function
        run_s, res = _median_time(lambda: sweep(model, speeds))
        rows = [(1, compile_s, run_s, res)]
        if args.host_devices > 1:
            devs = jax.devices()[: args.host_devices]
            t0 = time.perf_counter()
            sweep(model, speeds, devices=devs)
            first = time.perf_counter() - t0
            run2, res2 = _median_time(lambda: sweep(model, speeds, devices=devs))
            rows.append((len(devs), first - run2, run2, res2))
        # SciPy on a subset, scaled to all speeds
        sub = np.linspace(0, len(speeds) - 1, args.scipy_subset).round().astype(int)
        t_jax, t_np, ddf = [], [], []
        for i in sub:
            df, dt = scipy_metrics(model, speeds[i], int(res.transient_periods[i]), "jax")
            t_jax.append(dt)
            if res.converged[i]:
                ddf.append(abs(df - res.dynamic_factor[i]))
            if form != "reference":
                _, dtn = scipy_metrics(model, speeds[i], int(res.transient_periods[i]), "numpy")
                t_np.append(dtn)
        scale = len(speeds) / len(sub)
        sj = float(np.sum(t_jax) * scale)
        sn = float(np.sum(t_np) * scale) if t_np else float("nan")
        solver = {"DOP853": "Dopri8", "RK45": "Tsit5"}[_scipy_method(model)[0]]
        for n_dev, comp, run, r in rows:
            print(f"{form:13s} {solver:7s} {n_dev:7d} {comp:11.2f} {run:8.2f} "
                  f"{run / len(speeds) * 1e3:8.2f} {int(r.n_steps.max()):9d} "
                  f"{int((~r.converged).sum()):7d} {sj:13.1f} {sj / run:6.0f} "
                  f"{sn:12.1f} {sn / run:6.0f} {max(ddf) if ddf else float('nan'):9.1e}")
    print(f"# SciPy times: {args.scipy_subset} speeds timed, scaled x{len(speeds) / args.scipy_subset:.0f};"
          " 'scipy-jax' calls the jitted model RHS, 'scipy-np' a NumPy RHS (te/perturbation);"
          " max |dDF| = largest dynamic-factor difference gearjax vs SciPy on converged speeds")


# ---------------------------------------------------------------------- work precision
def work_precision(args):
    speeds = jnp.asarray(np.linspace(60.0, 1450.0, 16))
    stages = {"Tsit5": 6, "Dopri5": 6, "Dopri8": 13}
    print("# work-precision: 16 speeds 60-1450 rad/s, error vs Dopri8 rtol 1e-11 on converged "
          "speeds; cost = max steps over the batch x stages (lockstep)")
    print(f"{'formulation':13s} {'solver':7s} {'rtol':>6s} {'time [s]':>8s} {'max steps':>9s} "
          f"{'evals':>7s} {'err DF':>8s} {'err DTE':>8s}")
    for form in args.formulations.split(","):
        model = build(form)

        def run(solver, rtol):
            f = eqx.filter_jit(eqx.filter_vmap(
                lambda w: simulate(model, w, n_measured_periods=2, solver=solver, rtol=rtol,
                                   atol=rtol * 1e-2)))
            jax.block_until_ready(f(speeds))
            return _median_time(lambda: jax.block_until_ready(f(speeds)), 2)

        _, ref = run(diffrax.Dopri8(), 1e-11)
        ok = np.asarray(ref.converged)
        for solver in (diffrax.Tsit5(), diffrax.Dopri5(), diffrax.Dopri8()):
            for rtol in (1e-5, 1e-6, 1e-7, 1e-8):
                dt, r = run(solver, rtol)
                e1 = np.max(np.abs(np.asarray(r.dynamic_factor) - np.asarray(ref.dynamic_factor))[ok])
                e2 = np.max((np.abs(np.asarray(r.dte_ptp_m) - np.asarray(ref.dte_ptp_m))
                             / np.asarray(ref.dte_ptp_m))[ok])
                name = type(solver).__name__
                steps = int(np.max(r.n_steps))
                print(f"{form:13s} {name:7s} {rtol:6.0e} {dt:8.3f} {steps:9d} "
                      f"{steps * stages[name]:7d} {e1:8.1e} {e2:8.1e}", flush=True)


if __name__ == "__main__":
    if ARGS.work_precision:
        work_precision(ARGS)
    else:
        sweep_table(ARGS)
    sys.exit(0)
