"""Tracing, lowering and XLA compilation of the README main job's programs, apart from
their run: the 3D model's build and the sweep program of each formulation, in a fresh
process each (no persistent cache), set up as the command line (legacy emitters, one CPU
device per core, equinox checks as NaN), on one or two checkouts alternately.

Usage::

    python benchmarks/bench_trace.py CHECKOUT [CHECKOUT ...] [--repeat 3]

Each checkout runs from its own source (``PYTHONPATH``) in this Python environment. Per
formulation and checkout: the build (wall, first build in the process), the sweep
program's trace + lowering (``gearjax.dynamics.sweep.lower_sweep``), its XLA compilation,
the sweep's run with the program compiled, and the largest relative difference of the
maximum mesh force against the first checkout's. Minimum and median over the repeats.
Record the output in ``benchmarks/results/`` with the command.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys

import numpy as np

CHILD = r"""
import json, sys, time
from gearjax import runtime
runtime.configure(legacy_emitters=True, host_devices=2)
runtime.use_cacheable_checks()
import jax, numpy as np
import gearjax as gj
from gearjax.models.cutoff import default_max_frequency_hz
from gearjax.dynamics.sweep import Auto, lower_sweep
form = sys.argv[1]
rig = gj.get_rig("baud-velex-spur")
speeds = np.linspace(20.0, 900.0, 45)
t0 = time.perf_counter()
m = gj.build_model(rig, gj.ToothModifications.tip_relief(13.3e-6, 0.2), model="3d",
                   formulation=form, damping_ratio=0.1, moving_events=False,
                   max_frequency_hz=default_max_frequency_hz(900.0, rig.pair.z1))
jax.block_until_ready(m)
t1 = time.perf_counter()
lowered = lower_sweep(m, speeds, Auto(), devices=jax.devices())
t2 = time.perf_counter()
lowered.compile()
t3 = time.perf_counter()
r = gj.sweep(m, speeds, devices="all")
t4 = time.perf_counter()
print(json.dumps(dict(build=t1 - t0, trace=t2 - t1, compile=t3 - t2, run=t4 - t3,
                      force=np.asarray(r.max_mesh_force_N).tolist())))
"""


def one(checkout: str, form: str) -> dict:
    env = dict(os.environ, PYTHONPATH=os.path.abspath(checkout))
    env.pop("JAX_COMPILATION_CACHE_DIR", None)
    out = subprocess.run([sys.executable, "-c", CHILD, form], env=env, check=True,
                         capture_output=True, text=True, cwd=os.path.abspath(checkout))
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("checkouts", nargs="+")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--formulations", default="reference,te")
    args = ap.parse_args()
    forms = args.formulations.split(",")
    runs = {(c, f): [] for c in args.checkouts for f in forms}
    for _ in range(args.repeat):
        for f in forms:
            for c in args.checkouts:
                runs[c, f].append(one(c, f))
    print("| formulation | checkout | build (s) | trace + lower (s) | compile (s) | run (s) "
          "| max force, rel. to the first |")
    print("|---|---|---|---|---|---|---|")
    for f in forms:
        ref = np.asarray(runs[args.checkouts[0], f][0]["force"])
        for c in args.checkouts:
            rs = runs[c, f]
            cell = lambda k: (f"{min(r[k] for r in rs):.2f} / "  # noqa: E731
                              f"{statistics.median(r[k] for r in rs):.2f}")
            diff = max(float(np.max(np.abs(np.asarray(r["force"]) - ref) / ref)) for r in rs)
            print(f"| {f} | `{c}` | {cell('build')} | {cell('trace')} | {cell('compile')} "
                  f"| {cell('run')} | {diff:.1e} |")
    print(f"\nmin / median of {args.repeat} fresh processes each, alternately")
    return 0


if __name__ == "__main__":
    sys.exit(main())
