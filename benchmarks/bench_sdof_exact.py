"""Issue 14's sdof acceptance case: 2000 speeds of the TE-based sdof model (Eq. (20)) with
perfect spur teeth, the ``uniform`` stiffness law and damping 0.1, against the exact
periodic orbit and against a SciPy ``solve_ivp`` DOP853 loop, whole command.

* gearjax: the command a user types, timed from the shell as a subprocess with empty
  compilation caches (Python start, import, build, compile, run, CSV and figure):
  ``gearjax sweep --model torsional --stiffness uniform --relief none --damping 0.1
  --formulations te --speeds 50:1500:2000``.
* Exact: :func:`gearjax.dynamics.closed_form.piecewise_oscillator_orbit` (the square-wave
  stiffness makes Eq. (20) a piecewise-constant oscillator; its extrema written out). The
  criterion is the max mesh force within 2e-4 F_S at every speed where contact holds on the
  exact orbit (min force > 0).
* SciPy: the script an engineer writes today: per speed, ``solve_ivp(method="DOP853")``
  segment by segment of the stiffness square wave (restarted at every jump, so both sides
  are exact), mesh period after mesh period until the state repeats (``|z(T) - z(0)|`` below
  1e-6 of the static deflection, like the state-change test that ends gearjax's
  accelerated transient), then one period
  sampled 128 times plus the jump sides. Same equations (m, c, k1, k2, F_S taken from the
  gearjax model). Timed on ``--scipy-subset`` speeds spread over the range and scaled to
  all; its own error against the exact orbit is printed beside gearjax's. A second,
  generic script reads k(t) inside its right-hand side instead (one ``solve_ivp`` per mesh
  period, the jump left to DOP853's step rejection, 128 samples).

Usage::

    python benchmarks/bench_sdof_exact.py                 # 2000 speeds (26 s on 2 cores)
    python benchmarks/bench_sdof_exact.py --speeds 200 --scipy-subset 10
"""

from __future__ import annotations

import argparse
import csv
import math
import os
import platform
import subprocess
import sys
import tempfile
import time

import numpy as np

SPEEDS = (50.0, 1500.0)
ZETA = 0.1
SAMPLES = 128


def _args():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--speeds", type=int, default=2000)
    ap.add_argument("--scipy-subset", type=int, default=40, help="speeds timed with SciPy")
    ap.add_argument("--scipy-rtol", type=float, default=1e-9)
    return ap.parse_args()


def exact_inputs():
    """The closed form's inputs read from the CLI's model (same factory, same mesh)."""
    from gearjax import Mesh, ToothModifications
    from gearjax.rigs.factory import build_model
    from gearjax.rigs.registry import get_rig

    rig = get_rig("baud-velex-spur")
    mesh = Mesh.build(rig.pair, "uniform", pinion_torque_Nm=rig.pinion_torque_Nm)
    model = build_model(rig, ToothModifications.none(), model="torsional", mesh=mesh,
                        formulation="te", damping_ratio=ZETA)
    pair = rig.pair
    p, eps = pair.mesh_period_rad, pair.transverse_contact_ratio
    k2 = float(mesh.stiffness(0.5 * (eps - 1) * p))
    k1 = float(mesh.stiffness(0.5 * (eps - 1) * p + 0.5 * p))
    m = float(model.equivalent_mass_kg)
    k_m = (eps - 1) * k2 + (2 - eps) * k1
    c = 2 * ZETA * math.sqrt(k_m * m)
    return dict(m=m, c=c, k1=k1, k2=k2, eps=eps, mesh_period_rad=p,
                f_s=float(model.static_force_N))


def exact(ex, omega):
    from gearjax.dynamics.closed_form import piecewise_oscillator_orbit, square_wave_segments

    segs = square_wave_segments(ex["eps"], ex["mesh_period_rad"] / omega, ex["k1"], ex["k2"])
    return piecewise_oscillator_orbit(ex["m"], ex["c"], segs, ex["f_s"])


def scipy_speed(ex, omega, rtol, restarts=True, max_periods=2000):
    """(max force N, min force N, mesh periods, seconds) by the SciPy script described
    above. ``restarts=False``: the generic script, one ``solve_ivp`` per mesh period with
    k(t) read inside the right-hand side (the jump left to DOP853's step rejection), the
    measured period sampled 128 times."""
    from scipy.integrate import solve_ivp

    from gearjax.dynamics.closed_form import square_wave_segments

    m, c, f = ex["m"], ex["c"], ex["f_s"]
    segs = square_wave_segments(ex["eps"], ex["mesh_period_rad"] / omega, ex["k1"], ex["k2"])
    period = sum(tau for _, tau in segs)
    x_s = f / (0.5 * (ex["k1"] + ex["k2"]))
    v_s = x_s * 2 * math.pi / period
    atol = [1e-3 * rtol * x_s, 1e-3 * rtol * v_s]
    if restarts:
        pieces = [((lambda t, z, k=k: [z[1], (f - c * z[1] - k * z[0]) / m]), k, tau)
                  for k, tau in segs]
    else:
        (k2, tau2), (k1, _) = segs

        def rhs(t, z):
            k = k2 if t < tau2 else k1
            return [z[1], (f - c * z[1] - k * z[0]) / m]
        pieces = [(rhs, None, period)]
    t0 = time.perf_counter()
    z = np.array([x_s, 0.0])
    for n in range(max_periods):
        z_start = z
        for fun, _, tau in pieces:
            z = solve_ivp(fun, (0.0, tau), z, method="DOP853", rtol=rtol, atol=atol).y[:, -1]
        if abs(z[0] - z_start[0]) <= 1e-6 * x_s and abs(z[1] - z_start[1]) <= 1e-6 * v_s:
            break
    forces = []
    for fun, k, tau in pieces:
        if k is None:  # 128 samples, k read where they fall
            ts = (np.arange(SAMPLES) + 0.5) * period / SAMPLES
            ks = np.where(ts < segs[0][1], segs[0][0], segs[1][0])
        else:          # both ends of each segment (the jump sides) and samples between
            ts = np.linspace(0.0, tau, max(2, int(round(SAMPLES * tau / period)) + 1))
            ks = k
        sol = solve_ivp(fun, (0.0, tau), z, method="DOP853", rtol=rtol, atol=atol, t_eval=ts)
        forces.append(ks * sol.y[0])
        z = sol.y[:, -1]
    forces = np.concatenate(forces)
    return float(forces.max()), float(forces.min()), n + 1, time.perf_counter() - t0


def run_cli(n_speeds, out):
    env = dict(os.environ)
    cache = tempfile.mkdtemp(prefix="gearjax-bench-cache-")
    env.update(XDG_CACHE_HOME=cache, JAX_COMPILATION_CACHE_DIR=os.path.join(cache, "jax"))
    cmd = ["gearjax", "sweep", "--model", "torsional", "--stiffness", "uniform", "--relief",
           "none", "--damping", str(ZETA), "--formulations", "te",
           "--speeds", f"{SPEEDS[0]:g}:{SPEEDS[1]:g}:{n_speeds}", "--out", out]
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        sys.exit(f"gearjax sweep failed ({proc.returncode}):\n{proc.stderr[-3000:]}")
    return " ".join(cmd[:-2]), wall, proc.stderr


def main():
    args = _args()
    import jax

    import gearjax  # noqa: F401  (float64)
    ex = exact_inputs()
    out = tempfile.mkdtemp(prefix="gearjax-bench-")
    cmd, wall, log = run_cli(args.speeds, out)
    with open(os.path.join(out, "results.csv")) as fh:
        rows = [r for r in csv.DictReader(fh) if r["formulation"] == "te"]
    speeds = np.array([float(r["speed_rad_s"]) for r in rows])
    fmax = np.array([float(r["max_mesh_force_N"]) for r in rows])
    fmin = np.array([float(r["min_mesh_force_N"]) for r in rows])
    conv = np.array([r["converged"] == "True" for r in rows])
    loss = np.array([r["contact_loss"] == "True" for r in rows])
    f_s = ex["f_s"]
    t0 = time.perf_counter()
    ref = [exact(ex, w) for w in speeds]
    t_exact = time.perf_counter() - t0
    holds = np.array([o.min_force_N > 0.0 for o in ref])
    err_max = np.abs(fmax - np.array([o.max_force_N for o in ref])) / f_s
    err_min = np.abs(fmin - np.array([o.min_force_N for o in ref])) / f_s
    worst = int(np.argmax(np.where(holds, err_max, -1.0)))

    sub = np.linspace(0, len(speeds) - 1, args.scipy_subset).round().astype(int)
    scipy_rows = {}
    for restarts in (True, False):
        t_sc, e_sc, periods = [], [], []
        for i in sub:
            smax, _, n, dt = scipy_speed(ex, speeds[i], args.scipy_rtol, restarts)
            t_sc.append(dt)
            periods.append(n)
            if holds[i]:
                e_sc.append(abs(smax - ref[i].max_force_N) / f_s)
        scipy_rows[restarts] = (float(np.sum(t_sc)) * len(speeds) / len(sub), max(e_sc),
                                min(periods), max(periods))

    print(f"# sdof exact case (issue 14): te Eq. (20), uniform stiffness, perfect spur teeth, "
          f"zeta {ZETA}, {len(speeds)} speeds {SPEEDS[0]:g}-{SPEEDS[1]:g} rad/s")
    print(f"# {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
          f"jax {jax.__version__}, python {platform.python_version()}")
    print(f"gearjax whole command: {wall:.1f} s  `{cmd}` (empty compilation cache)")
    for line in log.splitlines():
        if ("chunk" in line and " in " in line) or "built" in line:
            print(f"    {line.strip()}")
    for restarts, label in ((True, "restarted at the jumps"), (False, "k(t) in the RHS")):
        t_scipy, e_scipy, p0, p1 = scipy_rows[restarts]
        print(f"SciPy DOP853 loop, {label}: {t_scipy:.1f} s = {t_scipy / wall:.1f}x gearjax's "
              f"whole command ({len(sub)} speeds timed, x{len(speeds) / len(sub):.0f}; rtol "
              f"{args.scipy_rtol:g}; {p0}-{p1} mesh periods; its max |F_max - exact| / F_S "
              f"{e_scipy:.1e})")
    print(f"closed form, all speeds: {t_exact:.2f} s")
    print(f"contact holds on the exact orbit at {int(holds.sum())} / {len(speeds)} speeds; "
          f"gearjax flags contact loss at {int(loss.sum())}, unconverged {int((~conv).sum())}")
    print(f"gearjax max |F_max - exact| / F_S where contact holds: {err_max[holds].max():.2e} "
          f"(at {speeds[worst]:.1f} rad/s; criterion 2e-4), median {np.median(err_max[holds]):.1e}; "
          f"max |F_min - exact| / F_S {err_min[holds].max():.2e}")
    agree = np.array_equal(loss, ~holds)
    print(f"contact-loss flags equal the exact orbit's: {agree}"
          + ("" if agree else f" (differ at {speeds[loss != ~holds]})"))


if __name__ == "__main__":
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    main()
