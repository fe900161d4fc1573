"""3D sweep against the number of speeds (issue #14 "scaling with speeds 1...10,000"), as a
user runs it: the README main job's command (``gearjax sweep``: Baud & Velex spur rig,
short relief, damping 0.1, speeds 20-900 rad/s, default modal cut-off 16.8 kHz: 133
modes) with ``--speeds 20:900:N`` for each N, one formulation at a time, each in a
fresh process.

Per N and formulation it reports the whole command's wall time, the model build, the
sweep's own time and its first chunk (which includes the compilation: the chunks after
it have the same shape and reuse the program), the time per speed after compilation
(the later chunks' time over their speeds; for a single chunk not separable and left
blank), and the speeds flagged unconverged. The persistent compilation cache
(``XDG_CACHE_HOME``) is warmed by a first run, so the builds' compiled programs are
reused, as on a user's second run; the sweep programs are never cached (diffrax's
``SaveAt`` checks are host callbacks).

Usage::

    python benchmarks/bench_scaling_3d.py --counts 1,10,100,1000 --formulations te,reference
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
CHUNK = re.compile(r"chunk (\d+)/(\d+): (\d+) speeds .* in ([0-9.]+) s")


def run(n: int, formulation: str, out: str, env: dict) -> dict:
    cmd = ["gearjax", "sweep", "--formulations", formulation, "--speeds", f"20:900:{n}",
           "--out", out, "--overwrite"]
    t0 = time.perf_counter()
    p = subprocess.run(cmd, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if p.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed ({p.returncode}):\n{p.stderr[-3000:]}")
    chunks = [(int(m[1]), int(m[3]), float(m[4])) for m in CHUNK.finditer(p.stderr)]
    with open(os.path.join(out, "summary.json")) as fh:
        summary = json.load(fh)
    s = summary["formulations"][formulation]
    later = chunks[1:]
    per_speed = (sum(t for _, _, t in later) / sum(k for _, k, _ in later)) if later else None
    return dict(n=n, formulation=formulation, wall_s=wall, build_s=s["build_time_s"],
                sweep_s=s["wall_time_s"], chunks=len(chunks), first_chunk_s=chunks[0][2],
                first_chunk_speeds=chunks[0][1], per_speed_s=per_speed,
                unconverged=len(s["unconverged_speeds"]),
                peak_dynamic_factor=s["peak_dynamic_factor"], devices=summary["devices"])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--counts", default="1,10,100,1000")
    ap.add_argument("--formulations", default="te,reference")
    ap.add_argument("--out", default=os.path.join(HERE, "results", "scaling_3d.md"))
    args = ap.parse_args(argv)
    counts = [int(c) for c in args.counts.split(",")]
    forms = args.formulations.split(",")
    work = tempfile.mkdtemp(prefix="gearjax-scaling-")
    env = dict(os.environ)
    env.setdefault("XDG_CACHE_HOME", os.path.join(work, "cache"))
    sys.path.insert(0, HERE)
    from bench_work_precision import machine

    lines = ["# 3D sweep against the number of speeds (whole command)", "",
             f"machine: {machine()}", f"date: {time.strftime('%Y-%m-%d %H:%M')}", "",
             "`gearjax sweep --formulations F --speeds 20:900:N` (the README main job's "
             "scenario), one process per row, compilation cache warmed by a first run.", "",
             "| formulation | speeds | command s | build s | sweep s | chunks | first chunk s "
             "(speeds, incl. compile) | s / speed after compile | unconverged | peak K_v |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    print("\n".join(lines), flush=True)
    for f in forms:
        run(2, f, os.path.join(work, "warm"), env)  # the build's programs to the cache
        for n in counts:
            r = run(n, f, os.path.join(work, f"{f}-{n}"), env)
            ps = "-" if r["per_speed_s"] is None else f"{r['per_speed_s']:.3f}"
            row = (f"| {f} | {n} | {r['wall_s']:.1f} | {r['build_s']:.1f} | {r['sweep_s']:.1f} | "
                   f"{r['chunks']} | {r['first_chunk_s']:.1f} ({r['first_chunk_speeds']}) | {ps} | "
                   f"{r['unconverged']} | {r['peak_dynamic_factor']:.3f} |")
            if f == forms[0] and n == counts[0]:
                lines.insert(-2, f"The command's CPU devices (speeds sharded over them): "
                                 f"{r['devices']}.\n")
            lines.append(row)
            print(row, flush=True)
            with open(args.out, "w") as fh:  # nothing lost if a long count is stopped
                fh.write("\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
