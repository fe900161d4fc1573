"""Designs as data: the notebook loop and the optimiser, compile time apart from run time.

Two measurements, each in a fresh process (empty in-memory caches; no persistent cache):

* ``notebook``: as a user in a notebook, ``build_model(relief A)`` -> ``sweep`` -> the
  same model swept again -> ``build_model(relief B)`` -> ... for four reliefs (te, zeta 0.1
  as the main job, 45 speeds 20-900 rad/s, the README's API): wall time, XLA compilations
  and their seconds, traces, per step. Goal (issue 51): after the first sweep, a rebuild
  with another relief and its sweep compile nothing (sdof <= 0.5 s in all, 3D <= 3 s).
  ``--max-frequency auto``: the 3D model at the command line's modal cut-off (default:
  every mode, ``build_model``'s default); ``--configure``: one CPU device per core and the
  speeds shared over them, as the command line.
* ``optimise``: the library calls of ``gearjax optimise`` with its defaults (sdof te,
  660-900 rad/s x 8, 4 starts in lockstep, 30 steps, the 7 x 7 Harris map refined once
  around its best points and the optima, the rebuilt check): wall time, compilations
  and their seconds, and the forward check of the optimum against the Table 1 reliefs by
  ``sweep`` (goal: <= 20 s cold, the optimum below both reliefs).
* ``evaluations``: one evaluation (value and gradient) of ``gearjax optimise``'s default
  objective (sdof te, zeta 0.03, 660-900 rad/s x 8, the three orbit starts) at five
  designs, by the transient (the default) and by the shooting with its implicit
  derivative: seconds per evaluation after the first call, the value, the value from
  each start. What an evaluation costs is what the optimiser's 20 s needs cut.

Run on a quiet machine (timings are meaningless while other work shares the cores)::

    python benchmarks/bench_design_loop.py notebook --model torsional
    python benchmarks/bench_design_loop.py notebook --model 3d
    python benchmarks/bench_design_loop.py notebook --model 3d --max-frequency auto --configure
    python benchmarks/bench_design_loop.py optimise
    python benchmarks/bench_design_loop.py evaluations

and record the output in ``benchmarks/results/design_loop.md``.
"""

from __future__ import annotations

import argparse
import collections
import sys
import time

import jax
import numpy as np

COUNTS = collections.Counter()
SECONDS = collections.Counter()
COMPILE = "/jax/core/compile/backend_compile_duration"
TRACE = "/jax/core/compile/jaxpr_trace_duration"


def _listen(event, duration, **kw):
    COUNTS[event] += 1
    SECONDS[event] += duration


class Step:
    """Wall time, compilations and traces of a block."""

    def __init__(self, label: str):
        self.label = label

    def __enter__(self):
        self.t0, self.c0 = time.perf_counter(), (COUNTS.copy(), SECONDS.copy())
        return self

    def __exit__(self, *exc):
        c, s = self.c0
        wall = time.perf_counter() - self.t0
        print(f"{self.label:38s} wall {wall:8.2f} s  compiles {COUNTS[COMPILE] - c[COMPILE]:3d} "
              f"({SECONDS[COMPILE] - s[COMPILE]:6.2f} s)  traces {COUNTS[TRACE] - c[TRACE]:3d} "
              f"({SECONDS[TRACE] - s[TRACE]:6.2f} s)", flush=True)


def notebook(model: str, cutoff: str, devices=None) -> None:
    import gearjax as gj
    from gearjax.models.cutoff import default_max_frequency_hz

    rig = gj.get_rig("baud-velex-spur")
    speeds = np.linspace(20.0, 900.0, 45)
    extra = {}
    if model == "3d" and cutoff == "auto":  # the command line's cut-off for these speeds
        extra["max_frequency_hz"] = default_max_frequency_hz(float(speeds.max()),
                                                             rig.pair.z1)
    print(f"# 3D cut-off: {extra.get('max_frequency_hz', 'all modes')}; devices "
          f"{jax.devices()}")
    for name, (a, e) in (("A short", (13.3e-6, 0.2)), ("B long", (13.3e-6, 0.5)),
                         ("C", (10e-6, 0.35)), ("D short", (16e-6, 0.15))):
        with Step(f"build {name}"):
            m = gj.build_model(rig, gj.ToothModifications.tip_relief(a, e), model=model,
                               formulation="te", damping_ratio=0.1, **extra)
            jax.block_until_ready(m)
        with Step(f"sweep {name}"):
            r = gj.sweep(m, speeds, devices=devices)
        print(f"    max force {np.nanmax(r.max_mesh_force_N):.6g} N, "
              f"{len(m.jump_thetas)} jumps, NLTE terms {m.nlte_terms}, "
              f"all converged {bool(np.all(r.converged))}")
        with Step(f"sweep {name} again"):
            gj.sweep(m, speeds, devices=devices)


def optimise() -> None:
    from gearjax import runtime

    runtime.configure()  # as the command line: XLA flags (no persistent cache is set here)
    import gearjax as gj
    from gearjax.design import (DynamicObjective, ReliefSpace, coarse_starts, harris_map,
                                multi_start)

    rig = gj.get_rig("baud-velex-spur")
    speeds = np.linspace(660.0, 900.0, 8)
    with Step("optimise (defaults) total"):
        mesh = gj.Mesh.build(rig.pair, "iso6336", pinion_torque_Nm=rig.pinion_torque_Nm)
        obj = DynamicObjective(mesh, ReliefSpace(), speeds, "peak-force", formulation="te",
                               orbits=("quasi-static", "separated"))
        with Step("  4 starts x 30 steps in lockstep"):
            best, runs = multi_start(obj, coarse_starts(obj.space, 2), max_iter=30,
                                     learning_rate=0.1)
        with Step("  rebuilt check"):
            rebuilt = obj.rebuilt(best.x)
        with Step("  Harris map 7 x 7, refined once"):
            hmap = harris_map(obj, np.linspace(2e-6, 30e-6, 7),
                              np.linspace(0.1, min(0.8, obj.space.upper[1]), 7), refine=1,
                              around=[r.x for r in runs])
    print(f"    optimum {best.x.tolist()}: {best.exact:.6g} N (rebuilt {rebuilt.exact:.6g}, "
          f"per orbit {rebuilt.per_orbit}); map there {hmap.value_at(best.x):.6g}, "
          f"map best {hmap.best()[1]:.6g}; model builds {obj.n_builds}")
    for r in runs:
        print(f"    start {r.x0.tolist()} -> {r.x.tolist()} {r.exact:.6g} N ({r.iterations} "
              f"steps, {r.stop_reason})")
    with Step("forward check by sweep"):
        worst = {}
        for name, x in (("optimum", best.x), ("short", (13.3e-6, 0.2)),
                        ("long", (13.3e-6, 0.5))):
            m = gj.build_model(rig, gj.ToothModifications.tip_relief(x[0], x[1]),
                               model="torsional", formulation="te")
            worst[name] = float(np.nanmax(gj.sweep(m, speeds).max_mesh_force_N))
    print(f"    forward sweeps, max force: {worst}")


def evaluations() -> None:
    from gearjax import runtime

    runtime.configure()
    import gearjax as gj
    from gearjax.design import DynamicObjective, ReliefSpace

    rig = gj.get_rig("baud-velex-spur")
    mesh = gj.Mesh.build(rig.pair, "iso6336", pinion_torque_Nm=rig.pinion_torque_Nm)
    designs = ((14.8e-6, 0.305), (13.3e-6, 0.2), (13.3e-6, 0.5), (20e-6, 0.45), (10e-6, 0.3))
    for solver in (gj.Transient(), gj.Shooting()):
        obj = DynamicObjective(mesh, ReliefSpace(), np.linspace(660.0, 900.0, 8),
                               "peak-force", formulation="te", solver=solver,
                               orbits=("quasi-static", "separated", "far"))
        name = type(solver).__name__
        for x in designs:
            with Step(f"{name} {x[0] * 1e6:.1f} um x {x[1]:.3f}, first call"):
                obj(np.asarray(x))
            t0 = time.perf_counter()
            ev = obj(np.asarray(x))
            print(f"    again {time.perf_counter() - t0:.2f} s: max force {ev.exact:.6g} N, "
                  f"per start {np.round(ev.per_orbit, 1).tolist()}, "
                  f"per speed {np.round(ev.per_case, 1).tolist()}", flush=True)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("what", choices=["notebook", "optimise", "evaluations"])
    p.add_argument("--model", default="torsional", choices=["torsional", "3d"])
    p.add_argument("--max-frequency", default="all", choices=["all", "auto"],
                   help="notebook, 3D: all modes (build_model's default) or the command "
                        "line's cut-off for the speeds (default_max_frequency_hz)")
    p.add_argument("--configure", action="store_true",
                   help="notebook: gearjax.runtime.configure() first with one CPU device "
                        "per core, the speeds shared over them (devices='all'), as "
                        "the command line (no persistent cache here)")
    args = p.parse_args(argv)
    devices = None
    if args.configure and args.what == "notebook":
        from gearjax import runtime

        runtime.configure(host_devices=runtime.host_device_count())
        devices = "all" if len(jax.devices()) > 1 else None
    jax.config.update("jax_enable_x64", True)
    jax.monitoring.register_event_duration_secs_listener(_listen)
    print(f"# bench_design_loop {args.what} ({args.model}), jax {jax.__version__}, "
          f"{jax.devices()[0].platform}")
    if args.what == "notebook":
        notebook(args.model, args.max_frequency, devices)
    elif args.what == "optimise":
        optimise()
    else:
        evaluations()
    return 0


if __name__ == "__main__":
    sys.exit(main())
