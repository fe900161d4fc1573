"""The README main job (``gearjax sweep``, whole command; or another command, ``--cmd``)
on two checkouts, alternately: cold (an empty persistent compilation cache) then warm (its
second run), and the two results.csv compared in the units of the solver-interface issue's
criterion (max and min mesh force in F_S, DTE and acceleration peak-to-peak relative to
their largest value).

Usage::

    python benchmarks/ab_main_job.py OLD_CHECKOUT NEW_CHECKOUT [--repeat 2] [--out FILE]
    python benchmarks/ab_main_job.py OLD NEW --cmd "sweep --model torsional --speeds 50:1500:2000"

Each checkout runs from its own source (``PYTHONPATH``) in this Python environment (same
dependencies); each run gets a fresh cache folder for its cold run.
"""

from __future__ import annotations

import argparse
import csv
import os
import subprocess
import sys
import tempfile
import time

import numpy as np


def run(checkout: str, out: str, cache: str, cmd: list[str]) -> float:
    env = dict(os.environ, PYTHONPATH=checkout, XDG_CACHE_HOME=cache)
    env.pop("JAX_COMPILATION_CACHE_DIR", None)
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-c", "import sys; from gearjax.cli import main; "
                    "sys.exit(main())", *cmd, "--out", out, "--json"]
                   + (["--overwrite"] if cmd[0] == "sweep" else []),
                   env=env, check=True, capture_output=True, text=True, cwd=checkout)
    return time.perf_counter() - t0


def rows(path: str) -> dict:
    with open(path, newline="") as fh:
        return {(r["formulation"], float(r["speed_rad_s"])): r for r in csv.DictReader(fh)}


def compare(a: str, b: str, f_s: float) -> dict:
    ra, rb = rows(a), rows(b)
    assert ra.keys() == rb.keys(), "different speeds or formulations"
    keys = sorted(ra)
    out = {}
    for col in ("max_mesh_force_N", "min_mesh_force_N"):
        d = [abs(float(ra[k][col]) - float(rb[k][col])) for k in keys]
        out[col + " / F_S"] = max(d) / f_s
    for col in ("dte_ptp_m", "accel_ptp_m_s2"):  # empty where a model has none
        va = np.array([float(ra[k][col] or "nan") for k in keys])
        vb = np.array([float(rb[k][col] or "nan") for k in keys])
        if np.all(np.isnan(va)) and np.all(np.isnan(vb)):
            continue
        out[col + " / max"] = float(np.nanmax(np.abs(va - vb)) / np.nanmax(np.abs(va)))
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("old")
    ap.add_argument("new")
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--out", default=None, help="append a Markdown table here")
    ap.add_argument("--cmd", default="sweep", help="the gearjax command and its options")
    args = ap.parse_args()
    work = tempfile.mkdtemp(prefix="ab-main-job-")
    times = {"old": {"cold": [], "warm": []}, "new": {"cold": [], "warm": []}}
    for i in range(args.repeat):
        for name in ("old", "new"):
            checkout = os.path.abspath(getattr(args, name))
            cache = os.path.join(work, f"cache-{name}-{i}")
            out = os.path.join(work, f"out-{name}")
            cmd = args.cmd.split()
            times[name]["cold"].append(run(checkout, out, cache, cmd))
            times[name]["warm"].append(run(checkout, out, cache, cmd))
            print(name, i, times[name]["cold"][-1], times[name]["warm"][-1], flush=True)
    old_csv = os.path.join(work, "out-old", "results.csv")
    diff = {}
    if os.path.exists(old_csv):
        r0 = next(iter(rows(old_csv).values()))
        f_s = float(r0["max_mesh_force_N"]) / float(r0["dynamic_factor"])  # Eq. (24)
        diff = compare(old_csv, os.path.join(work, "out-new", "results.csv"), f_s)
    lines = [f"`gearjax {args.cmd}`", "", "| checkout | cold (s) | warm (s) |", "|---|---|---|"]
    for name in ("old", "new"):
        lines.append(f"| {name} `{getattr(args, name)}` | "
                     f"{', '.join(f'{t:.1f}' for t in times[name]['cold'])} | "
                     f"{', '.join(f'{t:.1f}' for t in times[name]['warm'])} |")
    if diff:
        lines += ["", "results.csv, new against old: " + ", ".join(
            f"{k} {v:.1e}" for k, v in diff.items())]
    text = "\n".join(lines)
    print(text)
    if args.out:
        with open(args.out, "a") as fh:
            fh.write(text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
