"""Modal analysis of the Baud-Velex rig structure: gearjax against ROSS (needs gearjax[ross]).

Same shafts, discs, bearings and couplings (``examples/rigs/baud_velex_spur.toml``), no
mesh, speed 0, undamped; see :mod:`gearjax.rigs.ross_bridge` for how the two models are
matched. Prints the timings (build and modal analysis separately, median of repeats) and
the frequency table below 10 kHz:

* ``ours(k_ROSS)``: our structure with ROSS's (Cowper) shear coefficient -> same model;
* ``ours(default)``: the built-in rig, Hutchinson's shear coefficient (0.925 vs 0.886);
* ROSS's own ``"hutchinson"`` option (0.712, see :mod:`gearjax.rigs.ross_bridge`) is summarised.

Modes are paired by sorted order, so near 9 kHz, where the default-coefficient modes
cross, the ``ours(default)`` column pairs some modes with neighbours.

``--geared`` adds issue #7's benchmark 2 (about 8 min), the *geared* rotor in both codes: the pinion and
gear lines coupled by ROSS's own gear mesh (``ross.MultiRotor``, built by
:func:`gearjax.rigs.ross_bridge.ross_geared_rotor`) against the 3D model (perfect spur gears,
averaged mesh vector V, all 258 dof, zeta 0.1):

* natural frequencies of the coupled system at the mean mesh stiffness k_m (ROSS
  ``run_modal`` against the modes of gearjax's (M, K + k_m V V^T));
* one speed point: ``gearjax.dynamics.simulate`` (reference formulation, default tolerances)
  against (i) the exact periodic orbit of ROSS's assembled matrices (its modes and mesh
  participations, :func:`gearjax.rigs.ross_bridge.periodic_mesh_force`: shooting, no
  time-marching error) and (ii) ROSS's Newmark time response (average acceleration,
  ``update_mesh_stiffness=True`` interpolates our k(theta) table at every step). What ROSS
  integrates is the deviation from the static state under the period mean k_bar of k(t),
  driven by ``-(k(t) - k_bar) c c^T y_s`` (``c`` ROSS's coupling vector, ``y_s`` the static
  deflection under the motor torque), started from rest there (ROSS's Newmark always
  starts from rest). ROSS has no modal damping: its ``C`` is replaced by ``M Phi diag(2
  zeta omega) Phi^T M`` computed from ROSS's own M and K (zeta 0.1 on every mode, as ours);
  gyroscopic terms are off in both.
* Newmark steps: k(t) jumps twice per mesh period; sampled once per step at uniform steps
  (``--uniform``, with a uniform 8192-point table) the jump acts at the middle of its step
  and the scheme is first order with an erratic constant (where the jump falls in the
  step). By default the steps are aligned on the jumps: ``spp`` uniform steps per mesh
  period plus a step of 2e-7 periods across each jump, and ROSS's table holds k at
  exactly those angles, so that Newmark keeps its second order.

Measured 2026-11-23 (2 shared cores, load 4-5; ROSS 2.3): the 102 coupled modes below
10 kHz agree to 5.5e-9, their mesh participations to 1e-8, the static mesh force to 6e-9.
900 rad/s (near the main critical speed, zeta 0.1):

==========================================  =======  =========  ==========  ==========
run                                         steps    time [s]   DF          Fmin / F_S
==========================================  =======  =========  ==========  ==========
gearjax simulate (default, 400 periods)     53 946   7-15       1.684078    0.361922
gearjax, 1024 samples, 2000 periods         268 196  34.3       1.684069    0.361203
ROSS matrices, exact periodic orbit                  5-12       1.684068    0.360911
  (the same, 4096 RK4 steps per period)                         1.684070    0.360911
ROSS Newmark, aligned, 128 /period, 120 P   15 720   50         1.683241    0.360995
ROSS Newmark, aligned, 256                  31 080   108        1.683915    0.360933
ROSS Newmark, aligned, 512                  61 800   213        1.684045    0.360917
==========================================  =======  =========  ==========  ==========

(gearjax's default 128 samples per mesh period miss the force minimum, which sits at a
stiffness jump, by 1e-3 F_S; the maximum is smooth.) ROSS's Newmark is second order on
the aligned steps: the same scheme replayed in ROSS's modal coordinates (it reproduces
ROSS's runs to 1e-8) gives 1.683215 / 1.683890 / 1.684020 / 1.684055 / 1.684065 at 128 /
256 / 512 / 1024 / 2048 steps per period after 600 periods. From rest, the 643.5 rad/s
mode (1.4 % of the mesh compliance, decay 64 /s) still beats by 1e-4 after 120 mesh
periods: +2.6e-5 at 512 here, -1.3e-4 after 60 periods. So gearjax and ROSS's model agree
to 5e-6 (gearjax's converged DF against the exact orbit of ROSS's matrices).

The 5.2e-4 "gap" of the first measurement (2026-11-22; uniform steps, 60 periods, ROSS
DF 1.671926 / 1.679526 / 1.683167 at 128 / 256 / 512) was ROSS's time discretisation:
first order at the jumps (uniform steps, 600 periods: 1.683288 / 1.683599 / 1.683741 /
1.683810 / 1.684026 at 512 / 1024 / 2048 / 4096 / 8192), the 60-period transient (-1.3e-4
at 512), and the uniform 8192-point table, whose linear ramps move each jump by up to half
an interval (-2.6e-5: the exact orbit with that table is 1.684026). Its 1024 and 2048 rows
(1.683208, 1.683213, which made the step look converged at 512) are not reproduced: ROSS
at 1024 steps, 60 periods gives 1.683472 (re-run 2026-11-23, 275 s). Cost: a ROSS result
within 1e-3 of the orbit 50 s (128 aligned steps, 120 periods), within 5e-5 213 s, against
7-15 s for gearjax's converged point (DF to 5e-6).

    python benchmarks/bench_ross.py [--geared [--speed 900] [--steps 128,256,512] [--periods 120] [--uniform]]
"""

from __future__ import annotations

import contextlib
import io
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
    from gearjax.rigs.rigfile import parse_rig
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
    from gearjax.rigs.ross_bridge import ross_natural_frequencies_hz, ross_rotors

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


def _geared_rig(shear_coefficient):
    from gearjax.rigs.rigfile import parse_rig

    data = tomllib.loads(EXAMPLE.read_text())
    for shaft in data["shaft"]:
        shaft["shear_coefficient"] = shear_coefficient
    return data, parse_rig(data, source=str(EXAMPLE))


def run_geared(speed=900.0, steps_per_period=(128, 256, 512), periods=120, zeta=0.1, uniform=False):
    """Issue #7 benchmark 2 (module docstring): coupled natural frequencies and one speed
    point, ROSS Newmark against gearjax.dynamics.simulate."""
    import jax
    import jax.numpy as jnp
    import scipy.linalg as sl

    import equinox as eqx
    from gearjax import ToothModifications, quasi_static
    from gearjax.rigs import build_model
    from gearjax.rigs.ross_bridge import (periodic_mesh_force, ross_geared_rotor, ross_mesh_modes,
                                     ross_shear_coefficient)
    from gearjax.dynamics.simulate import simulate

    kappa = ross_shear_coefficient(0.05, method="cowper")
    data, rig = _geared_rig(kappa)
    model = build_model(rig, None, formulation="reference", damping_ratio=zeta,
                                   mesh_vectors="mean")
    k_m, f_s = float(model.k_m), float(model.static_force_N)
    period = rig.pair.mesh_period_rad

    # natural frequencies of the coupled system at k_m
    f_ours = np.sort(np.asarray(model.omega_r)[: model.n_modes]) / (2 * np.pi)
    f_ours = f_ours[(f_ours > 1.0) & (f_ours < F_MAX_HZ)]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        mr0, _ = ross_geared_rotor(EXAMPLE, k_m)
        t0 = time.perf_counter()
        modal = mr0.run_modal(speed=0.0, num_modes=mr0.ndof, sparse=False)
        t_modal = time.perf_counter() - t0
    f_ross = np.sort(np.abs(np.asarray(modal.wn))) / (2 * np.pi)
    f_ross = f_ross[(f_ross > 1.0) & (f_ross < F_MAX_HZ)]
    print(f"# geared rotor (ROSS MultiRotor vs gearjax 3D, k_m = {k_m:.4e} N/m), modes below "
          f"{F_MAX_HZ:.0f} Hz: ROSS {f_ross.size}, gearjax {f_ours.size}; ROSS run_modal {t_modal:.1f} s")
    if f_ross.size == f_ours.size:
        print(f"max |rel diff| of the coupled natural frequencies: {np.max(np.abs(f_ours / f_ross - 1)):.1e}")
    print()

    # gearjax: one converged speed point
    run = eqx.filter_jit(lambda m, w: simulate(m, w))
    times = []
    for _ in range(2):
        t0 = time.perf_counter()
        res = run(model, jnp.asarray(speed))
        jax.block_until_ready(res.dynamic_factor)
        times.append(time.perf_counter() - t0)
    df_g, fmin_g = float(res.dynamic_factor), float(res.min_mesh_force_N) / f_s
    print(f"# one speed, {speed:g} rad/s (mesh frequency {speed * rig.pair.z1 / (2 * np.pi):.0f} Hz)")
    print(f"{'code':34s} {'steps':>8s} {'time [s]':>9s} {'DF':>10s} {'Fmin/F_S':>10s} {'DF - DF_gj':>11s}")
    print(f"{'gearjax simulate (1st call)':34s} {int(res.n_steps):8d} {times[0]:9.1f} {df_g:10.6f} {fmin_g:10.6f}")
    print(f"{'gearjax simulate':34s} {int(res.n_steps):8d} {times[1]:9.1f} {df_g:10.6f} {fmin_g:10.6f} "
          f"({int(res.transient_periods)} transient periods, converged {bool(res.converged)})")

    # ROSS's matrices, periodic orbit computed exactly (shooting, no time-marching error)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        mr, dof = ross_geared_rotor(EXAMPLE, k_m, update_mesh_stiffness=True)
    mr.mesh.stiffness = k_m

    def k_of(theta):
        qs = quasi_static(model.mesh, ToothModifications.none(), jnp.asarray(theta), f_s)
        return np.asarray(qs.loaded_stiffness_N_per_m)

    t0 = time.perf_counter()
    om, v, c, phi = ross_mesh_modes(mr, speed=speed)
    _, f_orb = periodic_mesh_force(om, v, zeta, k_m, f_s, k_of, model.jump_thetas, period, speed, 1024)
    print(f"{'ROSS matrices, exact periodic orbit':34s} {'':8s} {time.perf_counter() - t0:9.1f} {f_orb.max():10.6f} "
          f"{f_orb.min():10.6f} {f_orb.max() - df_g:+11.2e}")

    # ROSS: Newmark with the time-varying mesh stiffness
    M, K = mr.M(), mr.K(speed)
    n = M.shape[0]
    w2, phi = sl.eigh(K, M)
    om = np.sqrt(np.clip(w2, 0.0, None))
    C = M @ phi @ np.diag(2 * zeta * om) @ phi.T @ M
    mr.C = lambda frequency=None, **kw: C  # ROSS has no modal damping (see docstring)
    f0 = np.zeros(n)
    f0[dof(int(data["motor_node"]), 5)] = float(model.pinion_torque_Nm)
    zero = np.zeros((n, n))
    jumps = sorted({float(np.mod(j, period)) for j in model.jump_thetas})
    jumps = [0.0 if min(j, period - j) < 1e-9 * period else j for j in jumps]
    for spp in steps_per_period:
        if uniform:  # uniform steps, k interpolated in a uniform 8192-point table
            th = np.linspace(0.0, period, 8193)
            k_tab = k_of(th)
            grid = np.arange(1, spp + 1) * (period / spp)
        else:  # jump-aligned steps, the table holds k at the step angles (module docstring)
            grid, th, k_tab = _aligned_grid(jumps, period, spp, k_of)
        mr.mesh.theta_range, mr.mesh.stiffness_range = th, k_tab
        theta = np.concatenate([[0.0], (np.arange(periods)[:, None] * period + grid[None, :]).ravel()])
        t = theta / speed
        k_t = np.interp(np.mod(theta, period), th, k_tab)
        n_per = grid.size
        # static state under the period mean k_bar of k(t) as ROSS samples it (zero-mean
        # forcing); the rigid rotation and the seismic nodes (< 1 rad/s) take no static load
        k_bar = float(np.sum(0.5 * (k_t[:n_per] + k_t[1:n_per + 1]) * np.diff(t[:n_per + 1])) / (period / speed))
        mr.mesh.stiffness = k_bar
        w2s, phis = sl.eigh(mr.K(speed), M)
        mr.mesh.stiffness = k_m
        flex = w2s > 1.0
        y_s = phis[:, flex] @ ((phis[:, flex].T @ f0) / w2s[flex])
        c = c if c @ y_s > 0 else -c
        if spp == steps_per_period[0]:
            print(f"(static mesh force: ROSS {k_bar * (c @ y_s):.6f} N, gearjax F_S {f_s:.6f} N)")
        F = -np.outer(k_t - k_bar, c) * (c @ y_s)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            t0 = time.perf_counter()
            with contextlib.redirect_stdout(io.StringIO()):  # ROSS's progress prints
                _, z, _ = mr.time_response(np.full(t.shape, speed), F, t, method="newmark", G=zero, Ksdt=zero)
            t_r = time.perf_counter() - t0
        fm = k_t * (c @ (y_s[:, None] + z.T)) / f_s
        last = fm[-2 * n_per:]
        # the slowest damped modes (61.8 and 643.5 rad/s) beat over ~36 mesh periods: spread
        # of the per-period maxima over the last 36 periods
        tail = fm[1:][-min(36, periods // 2) * n_per:].reshape(-1, n_per).max(axis=1)
        print(f"{f'ROSS Newmark, {spp}/mesh period':34s} {t.size - 1:8d} {t_r:9.1f} {last.max():10.6f} "
              f"{last.min():10.6f} {last.max() - df_g:+11.2e} (per-period max over the last "
              f"{tail.size} periods spans {np.ptp(tail):.0e})")


def _aligned_grid(jumps, period, spp, k_of, eps=1e-7):
    """One mesh period of step angles (``spp`` uniform ones, each jump of k straddled by two
    angles ``+-eps * period`` apart, one step of ~0 length across it) and ROSS's stiffness
    table ``(theta_range, stiffness_range)`` holding k at exactly those angles (0 and the
    period carry the one-sided values)."""
    u = np.arange(spp + 1) * (period / spp)
    extra = []
    for j in jumps:
        for ref in ((j,) if j > 0 else (0.0, period)):
            u = u[np.abs(u - ref) > 2 * eps * period]
        extra += [j - eps * period, j + eps * period] if j > 0 else [eps * period, period - eps * period]
    grid = np.sort(np.concatenate([u, extra]))
    grid = grid[(grid > 0) & (grid < period)]
    th = np.concatenate([[0.0], grid, [period]])
    k = k_of(np.concatenate([[1e-12 * period], grid, [period * (1 - 1e-12)]]))
    return grid, th, k


def main():
    import argparse

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--geared", action="store_true", help="add the geared-rotor section (minutes)")
    ap.add_argument("--speed", type=float, default=900.0)
    ap.add_argument("--steps", default="128,256,512", help="Newmark steps per mesh period")
    ap.add_argument("--periods", type=int, default=120, help="mesh periods integrated by ROSS")
    ap.add_argument("--uniform", action="store_true",
                    help="uniform Newmark steps and a uniform k table (first order at the jumps)")
    args = ap.parse_args()
    structure_only()
    if args.geared:
        print()
        run_geared(args.speed, tuple(int(x) for x in args.steps.split(",")), args.periods,
                   uniform=args.uniform)


def structure_only():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        import ross

        from gearjax.rigs.ross_bridge import ross_shear_coefficient

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
