"""3D sweep on one accelerator (issue #14 "Accelerators": 3D, 3 formulations, 4,500 speeds,
target <= 10 s after compile), per chunk size: the README main job's scenario (Baud &
Velex spur rig, short relief, damping 0.1, default modal cut-off) at ``--speeds`` speeds
from 20 to 900 rad/s, each formulation swept with ``chunk_size`` speeds per vmapped call.

Per formulation and chunk size it reports the compile time (``lower_sweep(...).compile()``,
so the sweep after it runs the compiled program), XLA's memory estimate of that program
(temporaries + arguments + outputs), the sweep's time after compile, and the largest
difference of the dynamic factor from the first chunk size's (vmapped speeds advance in
lockstep with their own step sizes, so chunking must not change a result beyond rounding).
A chunk whose estimate exceeds the device's memory is skipped and said so. Rows are
printed and appended to ``--out`` (JSON lines) as they come.

Runs on any backend (``JAX_PLATFORMS=cpu`` for a dry run with few speeds)::

    python benchmarks/bench_accelerator.py --speeds 4500 --chunks 1500,2250,4500
"""

from __future__ import annotations

import argparse
import json
import os
import time

# equinox's runtime checks as NaN, as the command line sets them
# (gearjax.runtime.use_cacheable_checks): the default raises through a host callback,
# a device-to-host round trip on an accelerator
os.environ.setdefault("EQX_ON_ERROR", "nan")

import numpy as np  # noqa: E402

import gearjax  # noqa: F401,E402  (float64)
import jax
from gearjax.cli.solvers import periodic_start_options
from gearjax.models.geared3d import default_max_frequency_hz
from gearjax.rigs.factory import build_model
from gearjax.rigs.registry import get_rig
from gearjax.dynamics.sweep import Transient, device_memory_bytes, lower_sweep, sweep


def models(damping: float):
    """reference, te and perturbation models of the main job (te and perturbation share
    one build and one compiled program, as in the command line)."""
    rig = get_rig("baud-velex-spur")
    mods = rig.modifications("short", None, None, "linear", False)
    hz = default_max_frequency_hz(900.0, rig.pair.z1)
    kw = dict(model="3d", law="iso6336", damping_ratio=damping, encoder_position=1,
              max_frequency_hz=hz, nlte_reaction="drive", moving_events=False)
    ref = build_model(rig, mods, formulation="reference", **kw)
    te = build_model(rig, mods, formulation="te", **kw)
    return {"reference": ref, "te": te, "perturbation": te.with_formulation("perturbation")}


def memory_bytes(compiled) -> int | None:
    try:
        m = compiled.memory_analysis()
    except (AttributeError, NotImplementedError, RuntimeError):
        return None
    if isinstance(m, (list, tuple)):  # one per device on some backends
        m = m[0] if m else None
    if m is None:
        return None
    return int(m.temp_size_in_bytes + m.argument_size_in_bytes + m.output_size_in_bytes)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--speeds", type=int, default=4500)
    ap.add_argument("--chunks", default="1500,4500")
    ap.add_argument("--formulations", default="reference,te,perturbation")
    ap.add_argument("--damping", type=float, default=0.1)
    ap.add_argument("--out", default=os.path.join(os.environ.get("OUT", "."), "accelerator.jsonl"))
    a = ap.parse_args(argv)
    dev = jax.devices()[0]
    limit = device_memory_bytes(dev)
    print(f"{dev.device_kind} ({dev.platform}), jax {jax.__version__}, memory limit "
          f"{limit / 2**30 if limit else float('nan'):.1f} GiB", flush=True)
    speeds = np.linspace(20.0, 900.0, a.speeds)
    t0 = time.perf_counter()
    ms = models(a.damping)
    print(f"models built in {time.perf_counter() - t0:.1f} s", flush=True)
    chunks = [int(c) for c in a.chunks.split(",")]
    first_df = {}
    for form in a.formulations.split(","):
        model = ms[form]
        opts = periodic_start_options(model)
        for chunk in chunks:
            row = dict(formulation=form, speeds=a.speeds, chunk=chunk, device=dev.device_kind)
            t0 = time.perf_counter()
            lowered = lower_sweep(model, speeds, Transient(**opts), chunk_size=chunk)
            t1 = time.perf_counter()
            compiled = lowered.compile()
            row.update(lower_s=t1 - t0, compile_s=time.perf_counter() - t1,
                       memory_gib=(memory_bytes(compiled) or float("nan")) / 2**30)
            if limit and row["memory_gib"] * 2**30 > limit:
                row["skipped"] = "memory estimate over the device's limit"
            else:
                t0 = time.perf_counter()
                res = sweep(model, speeds, Transient(**opts), chunk_size=chunk)
                row["run_s"] = time.perf_counter() - t0
                df = np.asarray(res.dynamic_factor)
                row["unconverged"] = int(np.sum(~np.asarray(res.converged)))
                row["peak_df"] = float(np.max(df))
                if form in first_df:
                    row["max_df_diff"] = float(np.max(np.abs(df - first_df[form])))
                else:
                    first_df[form] = df
            print(json.dumps(row), flush=True)
            with open(a.out, "a") as fh:
                fh.write(json.dumps(row) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
