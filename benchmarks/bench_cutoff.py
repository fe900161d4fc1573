"""Modal cut-off of the 3D model against the full 258-dof model (issue #7, "Modes").

Scenario: ``build_model(baud_velex_rig(False), table1_relief("short"), formulation="te",
damping_ratio=0.1, max_frequency_hz=f_c)`` (the paper's spur rig of Section 6.1, cell
structure vectors), steady state by shooting (:func:`gearjax.dynamics.steady.steady_sweep`, default
tolerances: exact to ~1e-9, so every difference below is the cut-off's).

Reference: all modes (``max_frequency_hz=None``: the 258 modes of ``(M, K_bar)``, highest
71 kHz). Cut-offs ``f_c = c f_m`` with the mesh frequency ``f_m = z1 Omega / (2 pi)``
(Hz, ``z1 = 26``, ``Omega`` the pinion speed in rad/s) and ``c`` in ``--factors`` (mesh
harmonics, with or without a margin), plus the former fixed 6 kHz and the CLI's default rule
(:func:`gearjax.cli.dynamics.default_max_frequency_hz`) for speeds up to that speed and,
below 900 rad/s, for the default sweep range 20-900 rad/s (cut-offs giving the same modes
are computed once). The reduced model
keeps the modes below ``f_c`` plus static-correction pseudo-modes (the static response to
the mesh load patterns is exact at any cut-off), so the error comes from the *dynamic*
amplification of the dropped modes, ~ (h f_m / f_j)^2 for harmonic h and a dropped mode
at f_j.

Metrics: dynamic factor ``K_v = max F_D / F_S`` (the relative error of the maximum mesh
force is the same number: F_S does not depend on the cut-off) and the DTE peak-to-peak
(encoders at position 1), relative errors against the full model; the run time of one
``steady_sweep`` call per model (the first call of a shape includes compilation).

Usage (writes ``benchmarks/results/cutoff.md``)::

    python benchmarks/bench_cutoff.py                    # 300, 860, 1500 rad/s
    python benchmarks/bench_cutoff.py --speeds 860 --factors 1,3
"""

from __future__ import annotations

import argparse
import datetime
import math
import os
import sys
import time

import numpy as np

from gearjax import table1_relief
from gearjax.rigs import baud_velex_rig, build_model
from gearjax.models.geared3d import default_max_frequency_hz
from gearjax.dynamics.steady import steady_sweep

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from bench_work_precision import machine  # noqa: E402

Z1 = 26
DEFAULT_SWEEP_MAX = 900.0  # rad/s, top of `gearjax sweep`'s default --speeds 20:900:45


def mesh_frequency_hz(speed_rad_s: float, z1: int = Z1) -> float:
    """f_m = z1 Omega / (2 pi) (Hz) for the pinion speed Omega (rad/s)."""
    return z1 * speed_rad_s / (2 * math.pi)


def build(max_frequency_hz):
    return build_model(baud_velex_rig(False), table1_relief("short"), formulation="te",
                                    damping_ratio=0.1, max_frequency_hz=max_frequency_hz)


def solve(model, speed):
    t0 = time.perf_counter()
    st = steady_sweep(model, [speed])
    dt = time.perf_counter() - t0
    return (float(st.dynamic_factor[0]), float(st.dte_ptp_m[0]), bool(st.converged[0]),
            float(st.spectral_radius[0]), dt)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--speeds", default="300,860,1500", help="pinion speeds, rad/s")
    p.add_argument("--factors", default="1,2,3,4,4.5",
                   help="cut-offs in mesh frequencies of each speed")
    p.add_argument("--out", default=os.path.join(HERE, "results", "cutoff.md"))
    args = p.parse_args(argv)
    speeds = [float(v) for v in args.speeds.split(",")]
    factors = [float(v) for v in args.factors.split(",")]
    t_all = time.perf_counter()

    def say(*a):
        print(*a, flush=True)

    full = build(None)
    say(f"full model: {full.n_modes} modes, {full.n_reduced} coordinates")
    ref = {w: solve(full, w) for w in speeds}
    for w, r in ref.items():
        say(f"  full {w:.0f} rad/s: K_v {r[0]:.8f}, DTE ptp {r[1]:.6e} m, converged {r[2]}, "
            f"rho {r[3]:.5f}, {r[4]:.1f} s")

    rows = []
    cache = {}  # number of kept modes -> result (same modes: same model)
    for w in speeds:
        fm = mesh_frequency_hz(w)
        cuts = [(f"{c:g} f_m", c * fm) for c in factors]
        cuts.append(("6 kHz (old default)", 6000.0))
        cuts.append(("CLI default, speeds to this one", default_max_frequency_hz(w, Z1)))
        if w < DEFAULT_SWEEP_MAX:
            cuts.append((f"CLI default, speeds to {DEFAULT_SWEEP_MAX:g}",
                         default_max_frequency_hz(DEFAULT_SWEEP_MAX, Z1)))
        for label, fc in cuts:
            n_below = int(np.sum(np.asarray(full.omega_r) <= 2 * math.pi * fc))
            if n_below >= full.n_modes:
                res, n_modes, n_red = ref[w], full.n_modes, full.n_reduced
            elif (n_below, w) in cache:
                res, n_modes, n_red = cache[(n_below, w)]
            else:
                t0 = time.perf_counter()
                m = build(fc)
                t_build = time.perf_counter() - t0
                res, n_modes, n_red = solve(m, w), m.n_modes, m.n_reduced
                cache[(n_below, w)] = (res, n_modes, n_red)
                say(f"  {w:.0f} rad/s, {label} = {fc:.0f} Hz: {n_modes} modes + "
                    f"{n_red - n_modes} static, K_v {res[0]:.8f}, build {t_build:.1f} s, "
                    f"shoot {res[4]:.1f} s")
            r = ref[w]
            rows.append(dict(speed=w, fm=fm, label=label, fc=fc, n_modes=n_modes, n_red=n_red,
                             df=res[0], e_df=res[0] / r[0] - 1, e_dte=res[1] / r[1] - 1,
                             conv=res[2], t=res[4]))

    lines = [
        "# Modal cut-off against the full 258-dof model (`bench_cutoff.py`)",
        f"machine: {machine()}",
        f"date: {datetime.datetime.now():%Y-%m-%d %H:%M}, total {time.perf_counter() - t_all:.0f} s",
        "",
        "Spur rig (Section 6.1), te formulation (Eq. (42)), Table 1 short relief, zeta 0.1, "
        "steady state by shooting. f_m = 26 Omega / (2 pi). Errors relative to all 258 modes "
        "(K_v error = max mesh force error).",
        "",
        "| speed rad/s | full K_v | full DTE ptp um | full run s |",
        "|---|---|---|---|",
    ]
    for w, r in ref.items():
        lines.append(f"| {w:.0f} | {r[0]:.6f} | {1e6 * r[1]:.5f} | {r[4]:.1f} |")
    lines += ["", "| speed rad/s | f_m Hz | cut-off | f_c Hz | modes + static | K_v | "
              "rel err K_v | rel err DTE ptp | run s |", "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['speed']:.0f} | {r['fm']:.0f} | {r['label']} | {r['fc']:.0f} | "
                     f"{r['n_modes']} + {r['n_red'] - r['n_modes']} | {r['df']:.6f} | "
                     f"{r['e_df']:+.2e} | {r['e_dte']:+.2e} | {r['t']:.1f} |"
                     + ("" if r["conv"] else " not converged"))
    lines.append("")
    lines.append("run s: one steady_sweep call; the first call of each model shape includes "
                 "its compilation (same mode count at another speed reuses it).")
    text = "\n".join(lines) + "\n"
    os.makedirs(os.path.dirname(args.out), exist_ok=True)
    with open(args.out, "w") as fh:
        fh.write(text)
    say(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
