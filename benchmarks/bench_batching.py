"""Speeds of a chunk on one CPU device: mapped (``jax.lax.map``, one after the other) against
vmapped (lockstep), by the model's state size (:mod:`gearjax.dynamics.batching`).

Scenario: the README main job's case (Baud & Velex spur rig, Table 1 short relief, damping
0.1), te formulation, one chunk of ``--speeds`` speeds spread over ``--range`` rad/s, one
CPU device (the default of this script: no ``GEARJAX_HOST_DEVICES``). Models: the sdof
model (2 states) and the 3D model at several modal cut-offs (``--cutoffs`` Hz; the state
is twice the kept modes plus the static-correction block). Each program is compiled first
(``lower(...).compile()``, timed apart), then run ``--repeat`` times; the best run is kept.
The metrics of the two programs are compared (largest relative difference of the maximum
mesh force).

Usage (writes ``benchmarks/results/batching.md``)::

    python benchmarks/bench_batching.py
    python benchmarks/bench_batching.py --cutoffs 1000,3000 --speeds 16 --no-write
"""

from __future__ import annotations

import argparse
import datetime
import os
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np

from gearjax import table1_relief
from gearjax.dynamics import sweep as sweep_mod
from gearjax.dynamics.results import METRIC_FIELDS
from gearjax.rigs import baud_velex_rig, build_model

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from bench_work_precision import machine  # noqa: E402


def models(cutoffs):
    rig = baud_velex_rig(False)
    mods = table1_relief("short")
    yield "sdof", build_model(rig, mods, model="torsional", formulation="te",
                              damping_ratio=0.1)
    for fc in cutoffs:
        yield f"3D < {fc:g} Hz", build_model(rig, mods, formulation="te", damping_ratio=0.1,
                                             max_frequency_hz=fc)


def timed(fn, model, w, repeat):
    t0 = time.perf_counter()
    exe = fn.lower(model, w, sweep_mod.Transient()).compile()
    compile_s = time.perf_counter() - t0
    best, out = np.inf, None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = jax.block_until_ready(exe(model, w, sweep_mod.Transient()))
        best = min(best, time.perf_counter() - t0)
    return compile_s, best, np.asarray(out[METRIC_FIELDS.index("max_mesh_force_N")])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cutoffs", default="1000,2000,4000,8000,16759",
                    help="3D modal cut-offs (Hz); 16759 is the main job's default")
    ap.add_argument("--speeds", type=int, default=24)
    ap.add_argument("--range", default="20:480", help="A:B rad/s")
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--no-write", action="store_true")
    a = ap.parse_args(argv)
    lo, hi = (float(v) for v in a.range.split(":"))
    w = jnp.asarray(np.linspace(lo, hi, a.speeds))
    rows = []
    for name, m in models([float(c) for c in a.cutoffs.split(",")]):
        cm = m.compiled_form()
        cs, rs, fs = timed(sweep_mod._sequential, cm, w, a.repeat)
        cv, rv, fv = timed(sweep_mod._batched, cm, w, a.repeat)
        diff = float(np.max(np.abs(fs - fv) / np.abs(fv)))
        rows.append((name, int(m.state_size), cs, rs, cv, rv, rv / rs, diff))
        print(f"{name:14s} states {m.state_size:4d}  mapped: compile {cs:6.2f} s run "
              f"{rs:6.3f} s   vmapped: compile {cv:6.2f} s run {rv:6.3f} s   "
              f"vmapped/mapped run {rv / rs:5.2f}   max force rel. diff {diff:.1e}", flush=True)
    lines = [
        "# Mapped against vmapped speeds on one CPU device, by state size",
        "",
        f"`python benchmarks/bench_batching.py --cutoffs {a.cutoffs} --speeds {a.speeds} "
        f"--range {a.range} --repeat {a.repeat}`, {datetime.date.today()}, {machine()}.",
        "",
        f"te formulation, one chunk of {a.speeds} speeds {lo:g}-{hi:g} rad/s; run: best of "
        f"{a.repeat} after the compile.",
        "",
        "| model | states | mapped compile [s] | mapped run [s] | vmapped compile [s] | "
        "vmapped run [s] | vmapped / mapped run | max force rel. diff |",
        "|---|---|---|---|---|---|---|---|",
    ]
    lines += [f"| {n} | {s} | {cs:.2f} | {rs:.3f} | {cv:.2f} | {rv:.3f} | {r:.2f} | {d:.1e} |"
              for n, s, cs, rs, cv, rv, r, d in rows]
    if not a.no_write:
        with open(os.path.join(HERE, "results", "batching.md"), "w") as fh:
            fh.write("\n".join(lines) + "\n")
    return rows


if __name__ == "__main__":
    main()
