"""Frequency-domain periodic solver against the transient sweep (and shooting), sdof.

Scenario: Baud & Velex spur pair, Table 1 short relief, 254.8 N m, solid-cylinder
inertias, the README main job's speeds (45 from 20 to 900 rad/s), damping ratio 0.1 (the
main job) and 0.03 (paper Section 6.1), te (Eq. (20)) and perturbation (Eq. (47a)).

Methods, each one jitted call over all speeds, timed in the same process:

* transient: :func:`gearjax.dynamics.sweep.sweep` (automatic transient, 3 measured
  periods, exact metrics);
* harmonic: :func:`gearjax.dynamics.harmonic_sweep.harmonic_sweep` at ``--rtol`` (harmonics
  chosen per speed), without and with the Floquet radius (one monodromy period);
* shooting: :func:`gearjax.dynamics.steady.steady_sweep` (monodromy, metrics by a
  2-period simulate), as the accuracy reference: Dopri8 at rtol 1e-10 for both.

Compile time = first call minus the second (warm) call; run time = the warm call (best of
``--repeat``). Accuracy: the largest difference of the peak mesh force over the speeds, in
units of F_S. ``periods`` counts the excitation periods each method integrates (transient:
its automatic transient plus 3 measured; harmonic: none, one with the Floquet radius).

``--convergence``: error against the number of harmonics H instead, on the sdof te square
wave (perfect spur teeth, uniform stiffness, zeta 0.1) whose exact periodic orbit is a
product of matrix exponentials (``exact_force_extrema`` of ``tests/test_metrics.py``):
peak and minimum mesh force error over F_S, and the solver's ``error_estimate``.

Usage::

    python benchmarks/bench_harmonic.py              # ~10 min on the loaded 2-core CPU
    python benchmarks/bench_harmonic.py --zetas 0.1 --formulations te
    python benchmarks/bench_harmonic.py --convergence
"""

from __future__ import annotations

import argparse
import platform
import sys
import time
from pathlib import Path

import jax
import numpy as np

import gearjax  # noqa: F401  (x64, CPU flags)
from gearjax import (Mesh, ToothModifications, baud_velex_pair, static_mesh_force,
                     table1_relief)
from gearjax.dynamics.harmonic_sweep import harmonic_sweep
from gearjax.dynamics.steady import Shooting, steady_sweep
from gearjax.dynamics.sweep import sweep
from gearjax.models.torsional import TorsionalModel


def _timed(fn, repeat):
    t0 = time.perf_counter()
    out = fn()
    first = time.perf_counter() - t0
    runs = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        runs.append(time.perf_counter() - t0)
    run = min(runs)
    return out, max(first - run, 0.0), run


def convergence(speeds=(100.0, 226.0, 600.0), harmonics=(16, 32, 64, 128, 256, 512, 1024, 2048)):
    """Error of the peak / minimum mesh force against the exact orbit, per H."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    from test_metrics import TORQUE, ZETA, exact_force_extrema

    pair = baud_velex_pair(False)
    mesh = Mesh.build(pair, "uniform")
    model = TorsionalModel.build(mesh, ToothModifications.none(), formulation="te",
                                 damping_ratio=ZETA, pinion_torque_Nm=TORQUE)
    p, eps = pair.mesh_period_rad, pair.transverse_contact_ratio
    k2 = float(mesh.stiffness(0.5 * (eps - 1) * p))
    k1 = float(mesh.stiffness(0.5 * (eps - 1) * p + 0.5 * p))
    f_s = static_mesh_force(pair, TORQUE)
    inert = tuple(np.asarray(model.inertias_kg_m2))
    exact = [exact_force_extrema(pair, k1, k2, inert, w, f_s) for w in speeds]
    print("# sdof te square wave (zeta 0.1): |error| / F_S of max F_D, min F_D; estimate")
    print("| H | " + " | ".join(f"{w:.0f} rad/s" for w in speeds) + " |")
    print("|---|" + "---|" * len(speeds))
    for h in harmonics:
        r = harmonic_sweep(model, np.asarray(speeds), harmonics=h, max_harmonics=h,
                           floquet=False)
        cells = [f"{abs(r.max_mesh_force_N[i] - e[0]) / f_s:.1e}, "
                 f"{abs(r.min_mesh_force_N[i] - e[1]) / f_s:.1e}; {r.stats['error_estimate'][i]:.1e}"
                 for i, e in enumerate(exact)]
        print(f"| {h} | " + " | ".join(cells) + " |", flush=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--convergence", action="store_true", help="error against H instead")
    ap.add_argument("--speeds", default="20:900:45", metavar="A:B:N")
    ap.add_argument("--zetas", default="0.1,0.03")
    ap.add_argument("--formulations", default="te,perturbation")
    ap.add_argument("--rtol", type=float, default=1e-6)
    ap.add_argument("--3d", dest="three_d", action="store_true",
                    help="the README main job's 3D rig instead (te and perturbation)")
    ap.add_argument("--repeat", type=int, default=2)
    args = ap.parse_args()
    if args.convergence:
        return convergence()
    a, b, n = args.speeds.split(":")
    speeds = np.linspace(float(a), float(b), int(n))
    if args.three_d:
        return three_d(speeds, args)
    mesh = Mesh.build(baud_velex_pair(False))
    print(f"# bench_harmonic: {platform.processor() or platform.machine()}, "
          f"{jax.devices()[0].platform}, {len(speeds)} speeds {a}-{b} rad/s, rtol {args.rtol}")
    head = ("| formulation | zeta | method | compile (s) | run (s) | run ratio | periods "
            "(sum / max) | max abs dF_max / F_S vs shooting | notes |")
    print(head)
    print("|" + "---|" * 9)
    for zeta in (float(z) for z in args.zetas.split(",")):
        for form in args.formulations.split(","):
            model = TorsionalModel.build(mesh, table1_relief("short"), formulation=form,
                                         damping_ratio=zeta)
            f_s = float(model.static_force_N)
            tr, tr_c, tr_r = _timed(lambda: sweep(model, speeds), args.repeat)
            hb, hb_c, hb_r = _timed(lambda: harmonic_sweep(model, speeds, rtol=args.rtol,
                                                           floquet=False), args.repeat)
            hf, hf_c, hf_r = _timed(lambda: harmonic_sweep(model, speeds, rtol=args.rtol,
                                                           floquet=True), args.repeat)
            sh, sh_c, sh_r = _timed(lambda: steady_sweep(
                model, speeds, Shooting(rtol=1e-10, atol=1e-12, measure_rtol=1e-10,
                                        measure_atol=1e-12)), 1)
            ref = sh.max_mesh_force_N
            err = lambda r: np.max(np.abs(r.max_mesh_force_N - ref)) / f_s  # noqa: E731
            n_tr = tr.transient_periods + 3
            hs = np.unique(hb.stats['n_harmonics'])
            rows = [
                ("transient", tr_c, tr_r, f"{n_tr.sum():.0f} / {n_tr.max():.0f}", err(tr),
                 f"converged {int(tr.converged.sum())}/{len(speeds)}"),
                ("harmonic", hb_c, hb_r, "0 / 0", err(hb),
                 f"H in {hs.tolist()}, est max {np.max(hb.stats['error_estimate']):.1e}, "
                 f"contact holds {int(hb.stats['contact_holds'].sum())}/{len(speeds)}"),
                ("harmonic + Floquet", hf_c, hf_r, f"{len(speeds)} / 1", err(hf),
                 f"rho max {np.nanmax(hf.spectral_radius):.4f}, "
                 f"unstable {int((~hf.stats['stable']).sum())}"),
                ("shooting", sh_c, sh_r, f"{3 * len(speeds)} / 3", 0.0,
                 "reference: rtol 1e-10 (n+1 columns over 1 period, 2 measured)"),
            ]
            for name, c, r, per, e, note in rows:
                print(f"| {form} | {zeta} | {name} | {c:.1f} | {r:.3f} | {tr_r / r:.1f} | "
                      f"{per} | {e:.1e} | {note} |", flush=True)


def three_d(speeds, args, subset=(2, 22, 42)):
    """README main job's rig (3D, 292 states, short relief, zeta 0.1, 16.8 kHz cut-off):
    harmonic on all speeds; transient (automatic) and shooting (rtol 1e-10, reference)
    on ``subset`` only (per-speed times compared)."""
    from gearjax.models.geared3d import default_max_frequency_hz
    from gearjax.rigs import baud_velex_rig, build_model

    rig = baud_velex_rig(False)
    hz = default_max_frequency_hz(float(speeds.max()), rig.pair.z1)
    sub = speeds[np.asarray(subset)]
    print(f"# bench_harmonic --3d: {platform.machine()}, {jax.devices()[0].platform}, "
          f"{len(speeds)} speeds {speeds.min():g}-{speeds.max():g} rad/s, rtol {args.rtol}; "
          f"transient and shooting on {sub.tolist()} rad/s")
    print("| formulation | method | speeds | compile (s) | run (s) | run per speed (s) | "
          "periods (sum / max) | max abs dF_max / F_S vs shooting | notes |")
    print("|" + "---|" * 9)
    for form in args.formulations.split(","):
        model = build_model(rig, table1_relief("short"), formulation=form, damping_ratio=0.1,
                            max_frequency_hz=hz)
        f_s = float(model.static_force_N)
        hb, hb_c, hb_r = _timed(lambda: harmonic_sweep(model, speeds, rtol=args.rtol,
                                                       floquet=False), 1)
        hs, _, hs_r = _timed(lambda: harmonic_sweep(model, sub, rtol=args.rtol,
                                                    floquet=False), 1)
        tr, tr_c, tr_r = _timed(lambda: sweep(model, sub), 1)
        sh = steady_sweep(model, sub, Shooting(rtol=1e-10, atol=1e-12,
                                                measure_rtol=1e-10, measure_atol=1e-12))
        idx = np.asarray(subset)
        e_hb = np.max(np.abs(hb.max_mesh_force_N[idx] - sh.max_mesh_force_N)) / f_s
        e_tr = np.max(np.abs(tr.max_mesh_force_N - sh.max_mesh_force_N)) / f_s
        n_tr = tr.transient_periods + 3
        print(f"| {form} | harmonic | {len(speeds)} | {hb_c:.1f} | {hb_r:.2f} | "
              f"{hb_r / len(speeds):.3f} | 0 / 0 | {e_hb:.1e} | H in "
              f"{np.unique(hb.stats['n_harmonics']).tolist()}, est max {np.max(hb.stats['error_estimate']):.1e}, "
              f"contact holds {int(hb.stats['contact_holds'].sum())}/{len(speeds)}, DF max "
              f"{np.max(hb.dynamic_factor):.4f} |")
        print(f"| {form} | harmonic (subset) | {len(sub)} | - | {hs_r:.2f} | "
              f"{hs_r / len(sub):.3f} | 0 / 0 | - | same compiled function |")
        print(f"| {form} | transient | {len(sub)} | {tr_c:.1f} | {tr_r:.2f} | "
              f"{tr_r / len(sub):.3f} | {n_tr.sum():.0f} / {n_tr.max():.0f} | {e_tr:.1e} | "
              f"per speed {tr_r / hs_r:.1f}x the harmonic subset |", flush=True)


if __name__ == "__main__":
    main()
