"""Issue 49's continuation cases on the sdof model: the whole curve of periodic orbits
through the contact-loss band, by pseudo-arclength continuation (``gearjax sweep
--direction both``), timed as the command a user types (a subprocess with an empty
compilation cache: Python start, import, build, compile, trace, the up and down sweeps,
CSV, figure), and the curve's folds, jumps and bands read from its ``summary.json``.

Cases (the issue's "done when", target under 2 minutes each on the 2-core CPU):

* ``exact``: perfect spur teeth, uniform stiffness per unit contact length,
  ``gearjax sweep --model torsional --stiffness uniform --relief none --damping 0.03
  --speeds 250:900:66 --direction both --formulations reference``;
* ``spur``: the default spur case (Table 1 short relief) over 300-900 rad/s,
  ``gearjax sweep --model torsional --damping 0.03 --speeds 300:900:61 --direction both
  --formulations reference``.

``--library`` also times :func:`gearjax.dynamics.arclength.trace_speed` alone in one
process, twice (the first call compiles, the second runs from the compiled programs).

Usage::

    python benchmarks/bench_arclength.py                    # both cases
    python benchmarks/bench_arclength.py --cases exact --library
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

CASES = {
    "exact": ["--stiffness", "uniform", "--relief", "none", "--speeds", "250:900:66"],
    "spur": ["--speeds", "300:900:61"],
}
COMMON = ["sweep", "--model", "torsional", "--damping", "0.03", "--direction", "both",
          "--formulations", "reference", "--json"]


def _args():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", default=",".join(CASES), help="comma-separated of " + ",".join(CASES))
    ap.add_argument("--library", action="store_true",
                    help="also time trace_speed alone (compile, then run)")
    return ap.parse_args()


def run_command(case: str) -> dict:
    """The whole command in a fresh process with an empty compilation cache."""
    with tempfile.TemporaryDirectory() as tmp:
        env = {**os.environ, "JAX_COMPILATION_CACHE_DIR": os.path.join(tmp, "cache")}
        argv = [sys.executable, "-m", "gearjax.cli.main"] + COMMON + CASES[case] + [
            "--out", os.path.join(tmp, "out")]
        t0 = time.perf_counter()
        done = subprocess.run(argv, env=env, capture_output=True, text=True)
        wall = time.perf_counter() - t0
        if done.returncode != 0:
            raise SystemExit(f"{case}: exit {done.returncode}\n{done.stderr[-2000:]}")
        summary = json.loads(done.stdout)
    return {"wall_s": wall, "summary": summary}


def library_times(case: str) -> tuple[float, float, object]:
    """trace_speed twice in this process: (first call, second call, result)."""
    import numpy as np

    from gearjax import table1_relief
    from gearjax.dynamics.arclength import trace_speed
    from gearjax.rigs import build_model
    from gearjax.rigs.registry import get_rig

    relief = "none" if case == "exact" else "short"
    law = "uniform" if case == "exact" else "iso6336"
    lo, hi, n = (250.0, 900.0, 66) if case == "exact" else (300.0, 900.0, 61)
    model = build_model(get_rig("baud-velex-spur"), table1_relief(relief), model="torsional",
                        formulation="reference", law=law, damping_ratio=0.03)
    speeds = np.linspace(lo, hi, n)
    t0 = time.perf_counter()
    trace_speed(model, speeds)
    t1 = time.perf_counter()
    res = trace_speed(model, speeds)
    t2 = time.perf_counter()
    return t1 - t0, t2 - t1, res


def report(case: str, out: dict) -> None:
    f = out["summary"]["formulations"]["reference"]
    tr = f["branches"]["traced"]
    print(f"\n## {case}: gearjax {' '.join(COMMON[:-1] + CASES[case])}\n")
    print(f"whole command {out['wall_s']:.1f} s (summary: trace and sweeps "
          f"{f['wall_time_s']:.1f} s, build {f['build_time_s']:.1f} s); "
          f"{tr['n_points']} traced points")
    print("\n| bifurcation | speed [rad/s] | multiplier | DF | ends a stable branch |")
    print("|---|---|---|---|---|")
    for b in tr["bifurcations"]:
        mu = complex(*b["multiplier"])
        print(f"| {b['kind']} | {b['speed_rad_s']:.3f} | {mu.real:+.8f}{mu.imag:+.2g}j | "
              f"{b['metrics']['dynamic_factor']:.3f} | {b['ends_stable_branch']} |")
    print("\n| jump | sweep | from [rad/s] | max force before -> after [N] | lands on |")
    print("|---|---|---|---|---|")
    for j in tr["jumps"]:
        where = (f"branch {j['landed_branch']}" if j["landed_branch"] >= 0 else
                 "a periodic orbit off the curve" if j["landed_periodic"] else
                 "no orbit of the excitation period")
        after = j["max_mesh_force_after_N"]
        print(f"| {'yes' if j['discontinuous'] else 'no'} | {j['sweep']} | "
              f"{j['from_rad_s']:.3f} | {j['max_mesh_force_before_N']:.0f} -> "
              f"{'-' if after is None else f'{after:.0f}'} | {where} |")
    print(f"\njump up at {[round(w, 3) for w in tr['jump_up_rad_s']]} rad/s, jump down at "
          f"{[round(w, 3) for w in tr['jump_down_rad_s']]} rad/s; two stable orbits coexist "
          f"over {[[round(a, 2), round(b, 2)] for a, b in tr['coexistence_rad_s']]} rad/s; "
          f"the natural-parameter sweeps' band {f['branches'].get('hysteresis_band_rad_s')}")


def main() -> int:
    args = _args()
    print(f"# arclength continuation, sdof ({platform.node()}, {os.cpu_count()} CPUs, "
          f"load average {os.getloadavg()[0]:.1f})")
    for case in args.cases.split(","):
        report(case, run_command(case))
        if args.library:
            first, second, res = library_times(case)
            print(f"\ntrace_speed alone: first call {first:.1f} s (compiles), second "
                  f"{second:.1f} s, {res.points.speed_rad_s.size} points")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
