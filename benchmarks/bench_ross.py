"""Modal analysis of the Baud-Velex rig structure: gearjax against ROSS (needs gearjax[ross]).

Same shafts, discs, bearings and couplings (``examples/rigs/baud_velex_spur.toml``), no
mesh, speed 0, undamped; see :mod:`gearjax.ross_bridge` for how the two models are
matched. Prints the timings (build and modal analysis separately, median of repeats) and
the frequency table below 10 kHz:

* ``ours(k_ROSS)``: our structure with ROSS's (Cowper) shear coefficient -> same model;
* ``ours(default)``: the built-in rig, Hutchinson's shear coefficient (0.925 vs 0.886);
* ROSS's own ``"hutchinson"`` option (0.712, see :mod:`gearjax.ross_bridge`) is summarised.

Modes are paired by sorted order, so near 9 kHz, where the default-coefficient modes
cross, the ``ours(default)`` column pairs some modes with neighbours.

    python benchmarks/bench_ross.py
"""

from __future__ import annotations

import platform
import time
import warnings
from pathlib import Path

import numpy as np

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "rigs" / "baud_velex_spur.toml"
F_MAX_HZ = 10_000.0


def _median(xs):
    return sorted(xs)[len(xs) // 2]


def run_ours(shear_coefficient=None, repeats=5):
    from gearjax.rigfile import parse_rig
    from gearjax.structure import modal_basis

    data = tomllib.loads(EXAMPLE.read_text())
    if shear_coefficient is not None:
        for shaft in data["shaft"]:
            shaft["shear_coefficient"] = shear_coefficient
    t_build, t_modal = [], []
    for _ in range(repeats):
        t0 = time.perf_counter()
        s = parse_rig(data, source=str(EXAMPLE)).structure()
        t1 = time.perf_counter()
        f = modal_basis(s.M, s.K, warn=False).frequencies_hz
        t2 = time.perf_counter()
        t_build.append(t1 - t0)
        t_modal.append(t2 - t1)
    return f[(f > 1.0) & (f < F_MAX_HZ)], _median(t_build), _median(t_modal)


def run_ross(method="cowper", repeats=3):
    from gearjax.ross_bridge import ross_natural_frequencies_hz, ross_rotors

    t_build, t_modal = [], []
    for _ in range(repeats):  # fresh rotors each time: ROSS caches run_modal per rotor
        t0 = time.perf_counter()
        rotors = ross_rotors(EXAMPLE, shear_method=method)
        t1 = time.perf_counter()
        f = np.sort(np.concatenate([ross_natural_frequencies_hz(r) for r in rotors.values()]))
        t2 = time.perf_counter()
        t_build.append(t1 - t0)
        t_modal.append(t2 - t1)
    return f[f < F_MAX_HZ], _median(t_build), _median(t_modal)


def main():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        import ross

        from gearjax.ross_bridge import ross_shear_coefficient

        kappa = ross_shear_coefficient(0.05, method="cowper")
        f_r, rb, rm = run_ross("cowper")
        f_rh, _, _ = run_ross("hutchinson", repeats=1)
    f_o, ob, om = run_ours(kappa)
    f_d, _, _ = run_ours(None, repeats=1)

    print(f"# Baud-Velex rig structure (258 dof, no mesh), modes below {F_MAX_HZ:.0f} Hz  "
          f"({platform.processor() or platform.machine()}, ROSS {ross.__version__})")
    print(f"{'code':28s} {'build [ms]':>11s} {'modal [ms]':>11s} {'modes':>6s}")
    print(f"{'gearjax (dense eigh, 258)':28s} {ob * 1e3:11.1f} {om * 1e3:11.1f} {f_o.size:6d}")
    print(f"{'ROSS 2 rotors (state eig)':28s} {rb * 1e3:11.1f} {rm * 1e3:11.1f} {f_r.size:6d}")
    print(f"modal-analysis ratio ROSS / gearjax: {rm / om:.0f}x")
    print()
    n = min(f_o.size, f_r.size, f_d.size)
    print(f"{'mode':>4s} {'ROSS [Hz]':>11s} {'ours(k_ROSS)':>13s} {'rel diff':>10s} "
          f"{'ours(default)':>14s} {'rel diff':>10s}")
    for i in range(n):
        print(f"{i + 1:4d} {f_r[i]:11.3f} {f_o[i]:13.3f} {f_o[i] / f_r[i] - 1:+10.1e} "
              f"{f_d[i]:14.3f} {f_d[i] / f_r[i] - 1:+10.1e}")
    print()
    if f_o.size == f_r.size:
        print(f"max |rel diff|, same shear coefficient ({kappa:.4f}, Cowper): "
              f"{np.max(np.abs(f_o / f_r - 1)):.1e} over {f_r.size} modes")
    if f_d.size == f_r.size:
        print(f"max |rel diff|, our default (Hutchinson 2001) vs ROSS Cowper: "
              f"{np.max(np.abs(f_d / f_r - 1)):.2e}")
    print(f"ROSS shear_method_calc='hutchinson' (kappa {ross_shear_coefficient(0.05, method='hutchinson'):.4f}, "
          f"one (1 + nu) short of Hutchinson 2001) gives {f_rh.size} modes below {F_MAX_HZ:.0f} Hz")


if __name__ == "__main__":
    main()
