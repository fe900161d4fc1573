"""Structured against dense modal products in the 3D vector field (issue 14, item 5:
"diagonal modal stiffness used as such").

Scenario: the README main job's models (Baud-Velex spur rig, short relief, damping 0.1,
modes below the command line's default cut-off for 900 rad/s plus static corrections),
reference and te formulations. For each, the model as built (``kbar_r`` applied as its
diagonal, ``c_r`` as diagonal plus the static-correction block:
:func:`gearjax.models.geared3d_build.modal_structure`) against the same model with the dense products forced
(``dataclasses.replace(model, diagonal_stiffness=False, damping_split=0)``), in one run:

* right-hand side: one speed and 45 vmapped speeds (mean of repeated jitted calls);
* ``simulate`` vmapped over ``--speeds`` speeds 500-900 rad/s with a fixed transient of
  ``--periods`` excitation periods: compile (first call minus the second) and run time,
  steps, and the largest difference of the dynamic factor between the two (round-off and
  step sequence only: the products are equal to ~1e-11 of the largest rate).

Usage::

    python benchmarks/bench_modal_products.py [--speeds 45] [--periods 60] [--out FILE.md]
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import time

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

import gearjax  # noqa: F401
from gearjax.dynamics.simulate import simulate
from gearjax.models.geared3d import default_max_frequency_hz
from gearjax.rigs.factory import build_model
from gearjax.rigs.registry import get_rig

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from bench_work_precision import machine  # noqa: E402


def rhs_time(model, batch: int, repeats: int) -> float:
    """Seconds per jitted right-hand-side call over ``batch`` speeds."""
    rng = np.random.default_rng(0)
    y = jnp.asarray(rng.normal(size=(batch, model.state_size)) * 1e-3)
    w = jnp.linspace(20.0, 900.0, batch)
    f = jax.jit(jax.vmap(lambda s, yy, ww: model.vector_field(s, yy, ww), in_axes=(None, 0, 0)))
    f(0.1, y, w).block_until_ready()
    t = time.perf_counter()
    for i in range(repeats):
        out = f(0.1 + 1e-4 * i, y, w)
    out.block_until_ready()
    return (time.perf_counter() - t) / repeats


def sweep_time(model, speeds, periods: int):
    run = eqx.filter_jit(lambda m, ws: jax.vmap(
        lambda w: simulate(m, w, n_transient_periods=periods))(ws))
    t = time.perf_counter()
    jax.block_until_ready(run(model, speeds))
    first = time.perf_counter() - t
    t = time.perf_counter()
    res = jax.block_until_ready(run(model, speeds))
    second = time.perf_counter() - t
    return first - second, second, res


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--speeds", type=int, default=45)
    ap.add_argument("--periods", type=int, default=60)
    ap.add_argument("--out", default=os.path.join(HERE, "results", "modal_products.md"))
    args = ap.parse_args(argv)
    rig = get_rig("baud-velex-spur")
    hz = default_max_frequency_hz(900.0, rig.pair.z1)
    speeds = jnp.linspace(500.0, 900.0, args.speeds)
    lines = [f"# Structured vs dense modal products (`bench_modal_products.py --speeds "
             f"{args.speeds} --periods {args.periods}`)", "", f"Machine: {machine()}", "",
             "| formulation | products | RHS 1 speed (us) | RHS 45 speeds (us) | compile (s) "
             "| run (s) | max steps | max abs dDF vs dense |", "|---|---|---|---|---|---|---|---|"]
    for form in ("reference", "te"):
        built = build_model(rig, rig.modifications("short"), formulation=form,
                            damping_ratio=0.1, max_frequency_hz=hz)
        dense = dataclasses.replace(built, diagonal_stiffness=False, damping_split=0)
        out = {}
        for name, m in (("dense", dense), ("structured", built)):
            r1, r45 = rhs_time(m, 1, 2000), rhs_time(m, 45, 500)
            comp, run, res = sweep_time(m, speeds, args.periods)
            out[name] = res
            ddf = (float(np.max(np.abs(np.asarray(res.dynamic_factor)
                                       - np.asarray(out["dense"].dynamic_factor))))
                   if name == "structured" else 0.0)
            row = (f"| {form} | {name} | {r1 * 1e6:.1f} | {r45 * 1e6:.1f} | {comp:.1f} | "
                   f"{run:.2f} | {int(np.max(res.n_steps))} | {ddf:.1e} |")
            print(row, flush=True)
            lines.append(row)
    with open(args.out, "w") as fh:
        fh.write("\n".join(lines) + "\n")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
