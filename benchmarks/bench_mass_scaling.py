"""Selective modal mass scaling at low speed: a lever against lockstep, measured and rejected.

Why: vmapped speeds run in lockstep, and on the 3D main-job model the lowest speed sets each
first chunk's cost (te, Dopri8: 2561 steps at 20 rad/s against 386 at 900 rad/s; on an H100
the 4,500-speed sweep took 44.6 s after compile against issue #14's 10 s target). Those steps
are held by the explicit solver's stability limit at the top retained mode (16.8 kHz), not
by accuracy. Selective mass scaling, as explicit finite-element codes use it, would lift the
limit per speed without a second compiled program: every modal coordinate ``j`` whose
frequency ``omega_j`` exceeds ``omega_c(Omega) = max(2 pi floor, kappa z1 Omega)`` (rad/s;
``kappa`` mesh harmonics) gets the modal mass ``mu_j = (omega_j / omega_c)^2`` (its frequency
becomes ``omega_c``, its static response is unchanged) and its damping ``x sqrt(mu_j)`` (the
same damping ratio).

This script measures what that does to the metrics, against the same model unscaled
(te formulation of the README main job, damping 0.1, modes below 16.8 kHz; fixed transient
of ``--periods`` excitation periods and no periodic estimate, so both runs integrate the same
periods). The scaling wraps ``Geared3DModel._accel`` here only: it is not in the library.

Result (``benchmarks/results/mass_scaling.md``): the error in the peak mesh force stays above
issue #14's 1e-4 F_S criterion at 20-50 rad/s even with 40 mesh harmonics kept (6 kHz floor),
and the pinion-centre acceleration moves by 3-10 %: at low speed the response is the free
ringing after the stiffness jumps, spread over every retained mode, and scaling those modes
changes it.

Usage: python benchmarks/bench_mass_scaling.py [--kappa 10 40] [--floor-hz 1000 6000]
"""

from __future__ import annotations

import argparse
import os
import sys
import time

os.environ.setdefault("EQX_ON_ERROR", "nan")

import equinox as eqx  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_accelerator import models  # noqa: E402  (the main job's three models)

from gearjax.dynamics.simulate import simulate  # noqa: E402
from gearjax.models import geared3d as g3  # noqa: E402

SPEEDS = (20.0, 35.0, 50.0, 100.0, 200.0, 300.0)


def scaled(accel, kappa: float, floor_hz: float):
    """``Geared3DModel._accel`` with the modes above ``omega_c(Omega)`` mass-scaled."""

    def _accel(self, s, y, omega, contact=True):
        q, qp, up = accel(self, s, y, omega, contact)
        wc = jnp.maximum(2 * jnp.pi * floor_hz, kappa * self.mesh.pair.z1 * omega)
        mu = jnp.maximum(1.0, (self.omega_r / wc) ** 2)
        d4 = mu ** 0.25
        force, _ = self._elastic(s, q, contact)
        plain = -(force + omega * self._damping_product(qp)) / omega**2
        heavy = -(force + omega * d4 * self._damping_product(qp * d4)) / (omega**2 * mu)
        return q, qp, up - plain + heavy

    return _accel


def measure(model, periods: int):
    run = eqx.filter_jit(lambda m, w: simulate(m, w, n_transient_periods=periods,
                                               accelerate=False))
    out = {}
    for w in SPEEDS:
        t0 = time.perf_counter()
        r = run(model, jnp.asarray(w))
        r.n_steps.block_until_ready()
        out[w] = dict(fmax=float(r.max_mesh_force_N), fmin=float(r.min_mesh_force_N),
                      dte=float(r.dte_ptp_m), acc=float(r.accel_ptp_m_s2),
                      steps=int(r.n_steps), conv=float(r.convergence),
                      s=time.perf_counter() - t0)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--kappa", type=float, nargs="+", default=[10.0, 40.0])
    ap.add_argument("--floor-hz", type=float, nargs="+", default=[1000.0, 6000.0])
    ap.add_argument("--periods", type=int, default=30)
    ap.add_argument("--formulation", default="te", choices=["reference", "te", "perturbation"])
    a = ap.parse_args(argv)
    model = models(0.1)[a.formulation]
    fs = float(model.static_force_N)
    plain_accel = g3.Geared3DModel._accel
    full = measure(model, a.periods)
    for kappa, floor_hz in zip(a.kappa, a.floor_hz):
        g3.Geared3DModel._accel = scaled(plain_accel, kappa, floor_hz)
        try:
            sc = measure(model, a.periods)
        finally:
            g3.Geared3DModel._accel = plain_accel
        print(f"\n{a.formulation}, kappa {kappa:g} mesh harmonics, floor {floor_hz:g} Hz: "
              f"scaled against unscaled ({a.periods} transient periods each)")
        print("| speed rad/s | f_c Hz | steps unscaled / scaled | max F error / F_S | "
              "min F error / F_S | DTE ptp rel. error | accel ptp rel. error |")
        print("|---|---|---|---|---|---|---|")
        for w in SPEEDS:
            f, s = full[w], sc[w]
            fc = max(floor_hz, kappa * model.mesh.pair.z1 * w / (2 * np.pi))
            print(f"| {w:g} | {fc:.0f} | {f['steps']} / {s['steps']} | "
                  f"{(s['fmax'] - f['fmax']) / fs:+.2e} | {(s['fmin'] - f['fmin']) / fs:+.2e} | "
                  f"{(s['dte'] - f['dte']) / f['dte']:+.2e} | {(s['acc'] - f['acc']) / f['acc']:+.2e} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
