"""Which periodic solver :class:`gearjax.Auto` picks, by measurement: every solver on every
formulation of the sdof and 3D Baud-Velex spur models at the README main job's speeds,
compilation apart from run time, error against a tight reference.

Cases: model {torsional, 3d} x formulation {te, perturbation, reference}; the main job's
scenario (short relief, damping 0.1, 45 speeds 20-900 rad/s; 3D cut-off as the command
line's default), the process set up as the command line sets up its main job
(:func:`gearjax.runtime.configure` with the legacy emitters).

Methods (each in a fresh process, so that no program compiled by another is reused):

* ``transient``: ``Transient()`` (every solver's defaults);
* ``shooting``: ``Fallback(Shooting(), Transient())``;
* ``harmonic``: ``Fallback(HarmonicBalance(), Transient())`` (te, perturbation);
* ``auto``: ``Auto()``, the rule under test;
* ``transient-hb-start`` (reference formulation): the transient started on the te
  formulation's frequency-domain orbit at each speed (``simulate(y0=...)``, the te orbit
  solved first, its time included), against ``transient`` from the quasi-static start: does
  the frequency-domain orbit shorten the reference's transient?

The tight reference of each case: the transient at ``tolerance_options(1e-10)`` (integrator
rtol 1e-10, periodicity 1e-5, transient decayed to 1e-10), an independent solver a thousand
times tighter than the defaults. Error: the largest difference over the speeds of the max
and min mesh force in units of F_S, and of the DTE and acceleration peak-to-peak relative
to their largest value (the README main job's criterion). Compile = first call minus
second (warm) call; run = the warm call, which includes the frequency domain's once-per-model
split and sampling (for ``harmonic`` also the frequency domain alone, warm, in the same
process: its share of the run). ``transient periods``: mean over speeds of the periods integrated
before the measurement.

Usage::

    python benchmarks/bench_auto.py                       # all cases, ~1 h on a loaded 2-core VM
    python benchmarks/bench_auto.py --models 3d --formulations te
    python benchmarks/bench_auto.py --out benchmarks/results/auto.md
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time

import numpy as np

FORMULATIONS = ("te", "perturbation", "reference")
MODELS = ("torsional", "3d")
METRICS = ("max_mesh_force_N", "min_mesh_force_N", "dte_ptp_m", "accel_ptp_m_s2")


def methods_for(formulation: str) -> tuple[str, ...]:
    linear = formulation != "reference"
    return (("transient", "shooting") + (("harmonic",) if linear else ("transient-hb-start",))
            + ("auto",))


def build(model: str, formulation: str, speeds):
    from gearjax import table1_relief
    from gearjax.models.cutoff import default_max_frequency_hz
    from gearjax.rigs import build_model, get_rig

    rig = get_rig("baud-velex-spur")
    kw = dict(model=model, formulation=formulation, damping_ratio=0.1)
    if model == "3d":
        kw.update(max_frequency_hz=default_max_frequency_hz(float(np.max(speeds)), rig.pair.z1),
                  moving_events=False)
    return build_model(rig, table1_relief("short"), **kw)


_RUNS: dict = {}


def hb_start_sweep(model, te, speeds):
    """The reference formulation's transient from the te formulation's (``te``)
    frequency-domain orbit at theta = 0 (same state as the reference model: the
    formulations differ in their mesh terms only); the quasi-static start where the te
    orbit has none."""
    import equinox as eqx
    import jax
    import jax.numpy as jnp

    from gearjax.dynamics.batching import over_speeds, sequential_for
    from gearjax.dynamics.harmonic_sweep import harmonic_sweep
    from gearjax.dynamics.simulate import simulate
    from gearjax.dynamics.sweep import Transient

    start = harmonic_sweep(te, speeds, floquet=False)
    options = tuple(sorted(Transient().simulate_options().items()))
    if "run" not in _RUNS:
        @eqx.filter_jit
        def run(m, w, y, opts):
            def one(wi, yi):
                r = simulate(m, wi, y0=yi, **dict(opts))
                return (r.max_mesh_force_N, r.min_mesh_force_N, r.dte_ptp_m,
                        r.accel_ptp_m_s2, r.transient_periods, r.converged)

            return over_speeds(one, w, y, sequential=sequential_for(m))

        _RUNS["run"] = run
    qs = jax.vmap(model.transient_start)(jnp.asarray(speeds))
    y0 = jnp.asarray(start.stats["y0"])
    y = jnp.where(jnp.isfinite(y0), y0, qs)
    out = jax.device_get(_RUNS["run"](model, jnp.asarray(speeds), y, options))
    return {k: np.asarray(v, dtype=float) for k, v in zip(
        METRICS + ("transient_periods", "converged"), out)}


def solver_of(name: str):
    from gearjax import Auto, Fallback, HarmonicBalance, Shooting, Transient
    from gearjax.dynamics.sweep import tolerance_options

    return {"transient": Transient(), "shooting": Fallback(Shooting(), Transient()),
            "harmonic": Fallback(HarmonicBalance(), Transient()), "auto": Auto(),
            "tight": Transient(**tolerance_options(1e-10))}[name]


def one(model_name: str, formulation: str, method: str, speeds, out_path: str,
        devices: int = 1) -> None:
    """Run one case in this process and write its JSON record; ``devices`` > 1: that many
    CPU devices, the speeds shared over them (``devices="all"``) as ``gearjax sweep`` does."""
    import gearjax as gj

    gj.runtime.configure(legacy_emitters=True, host_devices=devices if devices > 1 else None)
    dev = "all" if devices > 1 else None
    t0 = time.perf_counter()
    model = build(model_name, formulation, speeds)
    te = build(model_name, "te", speeds) if method == "transient-hb-start" else None
    t_build = time.perf_counter() - t0
    times, res = [], None
    for _ in range(2):
        t0 = time.perf_counter()
        if method == "transient-hb-start":
            res = hb_start_sweep(model, te, speeds)
        else:
            r = gj.sweep(model, speeds, solver_of(method), devices=dev)
            res = {k: np.asarray(getattr(r, k), dtype=float) for k in METRICS}
            res["transient_periods"] = np.asarray(r.transient_periods, dtype=float)
            res["converged"] = np.asarray(r.converged, dtype=float)
            res["solver"] = [str(s) for s in np.asarray(r.solver)]
        times.append(time.perf_counter() - t0)
    alone = None
    if method == "harmonic":  # the frequency domain alone (its Fallback's first), warm
        from gearjax.dynamics.harmonic_sweep import HarmonicBalance
        from gearjax.dynamics.solvers import SweepRun

        t0 = time.perf_counter()
        HarmonicBalance().sweep(model, speeds, SweepRun(devices=dev))
        alone = time.perf_counter() - t0
    rec = {"model": model_name, "formulation": formulation, "method": method,
           "build_s": t_build, "first_s": times[0], "run_s": times[1], "alone_s": alone,
           "static_force_N": float(model.static_force_N), "state_size": int(model.state_size)}
    rec.update({k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in res.items()})
    with open(out_path, "w") as fh:
        json.dump(rec, fh)


def error(rec, ref) -> dict:
    f_s = ref["static_force_N"]
    out = {}
    for k in ("max_mesh_force_N", "min_mesh_force_N"):
        out[k] = float(np.max(np.abs(np.asarray(rec[k]) - np.asarray(ref[k])))) / f_s
    for k in ("dte_ptp_m", "accel_ptp_m_s2"):
        a, b = np.asarray(rec[k], dtype=float), np.asarray(ref[k], dtype=float)
        if np.all(np.isnan(b)):
            continue
        out[k] = float(np.nanmax(np.abs(a - b)) / np.nanmax(np.abs(b)))
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--models", default=",".join(MODELS))
    ap.add_argument("--formulations", default=",".join(FORMULATIONS))
    ap.add_argument("--methods", default=None, help="comma-separated subset (default all)")
    ap.add_argument("--speeds", default="20:900:45", help="lo:hi:n (rad/s)")
    ap.add_argument("--out", default=None, help="write the Markdown table here")
    ap.add_argument("--no-reference", action="store_true",
                    help="skip the tight reference (times only; the error columns read '-')")
    ap.add_argument("--devices", type=int, default=1,
                    help="CPU devices of each case's process; above 1 the speeds are shared "
                         "over them, as gearjax sweep shares them (default 1)")
    ap.add_argument("--one", nargs=4, metavar=("MODEL", "FORMULATION", "METHOD", "JSON"),
                    help=argparse.SUPPRESS)
    args = ap.parse_args()
    lo, hi, n = args.speeds.split(":")
    speeds = np.linspace(float(lo), float(hi), int(n))
    if args.one:
        one(*args.one[:3], speeds, args.one[3], args.devices)
        return 0
    work = tempfile.mkdtemp(prefix="bench-auto-")
    rows = []
    for model in args.models.split(","):
        for form in args.formulations.split(","):
            recs = {}
            chosen = methods_for(form) if args.methods is None else [
                m for m in args.methods.split(",") if m in methods_for(form)]
            for method in (() if args.no_reference else ("tight",)) + tuple(chosen):
                path = os.path.join(work, f"{model}-{form}-{method}.json")
                cmd = [sys.executable, __file__, "--speeds", args.speeds,
                       "--devices", str(args.devices), "--one", model, form, method, path]
                t0 = time.perf_counter()
                subprocess.run(cmd, check=True, env=dict(os.environ))
                with open(path) as fh:
                    recs[method] = json.load(fh)
                print(f"{model} {form} {method}: {time.perf_counter() - t0:.1f} s "
                      f"(run {recs[method]['run_s']:.2f} s)", flush=True)
            for method in chosen:
                rec = recs[method]
                err = error(rec, recs["tight"]) if "tight" in recs else {}
                solvers = rec.get("solver")
                mix = ("" if solvers is None else ", ".join(
                    f"{s} {solvers.count(s)}" for s in sorted(set(solvers))))
                if rec.get("alone_s") is not None:
                    mix += f" (frequency domain alone {rec['alone_s']:.2f} s)"
                rows.append(dict(model=model, formulation=form, method=method,
                                 compile_s=rec["first_s"] - rec["run_s"], run_s=rec["run_s"],
                                 periods=float(np.mean(rec["transient_periods"])),
                                 mix=mix, **err))
    lines = ["| model | formulation | method | compile s | run s | transient periods | "
             "max F_D / F_S | min F_D / F_S | DTE ptp | accel ptp | solved by |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        acc, mx, mn, dte = (f"{r[k]:.1e}" if k in r else "-" for k in (
            "accel_ptp_m_s2", "max_mesh_force_N", "min_mesh_force_N", "dte_ptp_m"))
        lines.append(f"| {r['model']} | {r['formulation']} | {r['method']} | "
                     f"{r['compile_s']:.1f} | {r['run_s']:.2f} | {r['periods']:.1f} | "
                     f"{mx} | {mn} | {dte} | {acc} | {r['mix']} |")
    table = "\n".join(lines)
    print(table)
    if args.out:
        with open(args.out, "a") as fh:
            fh.write(f"\n`python benchmarks/bench_auto.py {' '.join(sys.argv[1:])}` on "
                     f"{platform.node()} (Python {platform.python_version()}), "
                     f"{time.strftime('%Y-%m-%d')}:\n\n{table}\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
