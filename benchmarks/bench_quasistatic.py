"""Time to compute TE_S over one mesh period at 256 positions (helical Table 1 pair).

Prints compile time and run time separately (median of repeats after compile), for both
stiffness laws and a few discretisations, and the cost per position.

    python benchmarks/bench_quasistatic.py
"""

from __future__ import annotations

import platform
import time

import jax

import gearjax as gj


def bench(helical: bool, law: str, cells_per_line: int, positions: int = 256, repeats: int = 20):
    rig = gj.get_rig("baud-velex-helical" if helical else "baud-velex-spur")
    mesh = gj.Mesh.build(rig.pair, law, cells_per_line=cells_per_line)
    mods = rig.modifications("short")
    theta = mesh.theta_grid(positions)
    f_s = gj.static_mesh_force(rig.pair, rig.pinion_torque_Nm)
    t0 = time.perf_counter()
    jax.block_until_ready(gj.quasi_static(mesh, mods, theta, f_s).te_s_m)
    compile_s = time.perf_counter() - t0
    runs = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(gj.quasi_static(mesh, mods, theta, f_s).te_s_m)
        runs.append(time.perf_counter() - t0)
    runs.sort()
    return mesh.n_cells, compile_s, runs[len(runs) // 2]


def main():
    print(f"# gearjax quasi-static TE_S benchmark  ({platform.processor() or platform.machine()}, "
          f"jax {jax.__version__}, {jax.devices()[0].platform}, 256 positions / mesh period)")
    print(f"{'pair':8s} {'law':8s} {'cells':>6s} {'compile [s]':>12s} {'run [ms]':>10s} {'us/position':>12s}")
    for helical in (True, False):
        for law in ("iso6336", "uniform"):
            for cpl in ((10, 40, 100) if helical else (1, 10)):
                n, c, r = bench(helical, law, cpl)
                print(f"{'helical' if helical else 'spur':8s} {law:8s} {n:6d} {c:12.3f} {r * 1e3:10.3f} "
                      f"{r / 256 * 1e6:12.2f}")


if __name__ == "__main__":
    main()
