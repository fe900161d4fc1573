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

``--geared`` adds issue #7's benchmark 2 (about 3 min), the *geared* rotor in both codes: the pinion and
gear lines coupled by ROSS's own gear mesh (``ross.MultiRotor``, built by
:func:`gearjax.ross_bridge.ross_geared_rotor`) against the 3D model (perfect spur gears,
averaged mesh vector V, all 258 dof, zeta 0.1):

* natural frequencies of the coupled system at the mean mesh stiffness k_m (ROSS
  ``run_modal`` against the modes of gearjax's (M, K + k_m V V^T));
* one speed point: ROSS's Newmark time response (average acceleration, fixed step;
  ``update_mesh_stiffness=True`` interpolates our k(theta) table at every step) against
  ``gearjax.simulate`` (reference formulation, default tolerances). What ROSS integrates
  is the deviation from the static state under the period mean k_bar of k(t), driven by
  ``-(k(t) - k_bar) c c^T y_s`` (``c`` ROSS's coupling vector, ``y_s`` the static
  deflection under the motor torque; splitting at k_m instead moved DF by 6e-6):
  the same equations, started where gearjax's slow modes start (ROSS's Newmark always
  starts from rest, and from rest the 61.8 rad/s mode needs seconds to decay). ROSS has no
  modal damping: its ``C`` is replaced by ``M Phi diag(2 zeta omega) Phi^T M`` computed
  from ROSS's own M and K (zeta 0.1 on every mode, as ours); gyroscopic terms are off in
  both.

Measured 2026-11-22 (2 shared cores, load 2-4; ROSS 2.3): the 102 coupled modes below
10 kHz agree to 5.5e-9, the static mesh force to 6e-9. 900 rad/s (near the main critical
speed, zeta 0.1):

=======================================  =======  =========  ==========  ==========
run                                      steps    time [s]   DF          Fmin / F_S
=======================================  =======  =========  ==========  ==========
gearjax simulate (default, 400 periods)  53 946   13-15      1.684078    0.361922
gearjax, 1024 samples/period             53 946   12.4       1.684083    0.361206
gearjax, 1024 samples, rtol 1e-9         109 042  19.0       1.684082    0.361206
gearjax, 1024 samples, 2000 periods      268 196  34.3       1.684069    0.361203
ROSS Newmark 128 steps/mesh period       7 680    19.8       1.671926    0.367768
ROSS Newmark 256                         15 360   38.0       1.679526    0.363438
ROSS Newmark 512                         30 720   67-69      1.683167    0.361352
ROSS Newmark 1024                        61 440   139        1.683208    0.361345
ROSS Newmark 2048                        122 880  240        1.683213    0.361342
=======================================  =======  =========  ==========  ==========

(ROSS: 60 mesh periods from the static state, 1.9-4.8 ms per step -- it reassembles K
every step; its last two periods move by < 5e-6, but over 180 periods its per-period
maximum still beats by +-1e-4 (slow modes). gearjax's default 128 samples per mesh period
miss the force minimum, which sits at a stiffness jump, by 7e-4 F_S.) The mesh stiffness
jumps (sampled once per step) make ROSS's fixed-step scheme first order at coarse steps;
it converges in the step to DF 1.68321, 5.2e-4 (relative) below gearjax's 1.68408, which
is stable to 1.4e-5 under rtol, sampling and transient length. Same k(theta) in both (to
1e-12), same coupled modes, same static state: the remaining 5e-4 is not explained yet
(the damping matrices were built the same way but not compared entry by entry). Cost
for a result within 1e-3 of its own step limit: ROSS 512 steps/period ~68 s against 13 s
for gearjax's converged point (5x).

    python benchmarks/bench_ross.py [--geared [--speed 900] [--steps 128,256,512] [--periods 60]]
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


def _geared_rig(shear_coefficient):
    from gearjax.rigfile import parse_rig

    data = tomllib.loads(EXAMPLE.read_text())
    for shaft in data["shaft"]:
        shaft["shear_coefficient"] = shear_coefficient
    return data, parse_rig(data, source=str(EXAMPLE))


def run_geared(speed=900.0, steps_per_period=(128, 256, 512), periods=60, zeta=0.1):
    """Issue #7 benchmark 2 (module docstring): coupled natural frequencies and one speed
    point, ROSS Newmark against gearjax.simulate."""
    import jax
    import jax.numpy as jnp
    import scipy.linalg as sl

    import equinox as eqx
    from gearjax import ToothModifications, quasi_static
    from gearjax.models.geared3d import Geared3DModel
    from gearjax.ross_bridge import ross_geared_rotor, ross_shear_coefficient
    from gearjax.simulate import simulate

    kappa = ross_shear_coefficient(0.05, method="cowper")
    data, rig = _geared_rig(kappa)
    model = Geared3DModel.from_rig(rig, None, formulation="reference", damping_ratio=zeta,
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

    # ROSS: Newmark with the time-varying mesh stiffness
    n_tab = 8192
    th = np.linspace(0.0, period, n_tab + 1)
    qs = quasi_static(model.mesh, ToothModifications.none(), jnp.asarray(th), f_s)
    k_tab = np.asarray(qs.loaded_stiffness_N_per_m)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        mr, dof = ross_geared_rotor(EXAMPLE, k_m, update_mesh_stiffness=True)
    mr.mesh.theta_range, mr.mesh.stiffness_range, mr.mesh.stiffness = th, k_tab, k_m
    M, K = mr.M(), mr.K(speed)
    n = M.shape[0]
    w2, phi = sl.eigh(K, M)
    om = np.sqrt(np.clip(w2, 0.0, None))
    C = M @ phi @ np.diag(2 * zeta * om) @ phi.T @ M
    mr.C = lambda frequency=None, **kw: C  # ROSS has no modal damping (see docstring)
    f0 = np.zeros(n)
    f0[dof(int(data["motor_node"]), 5)] = float(model.pinion_torque_Nm)
    dofs = [*mr.mesh.driving_gear.dof_global_index.values(), *mr.mesh.driven_gear.dof_global_index.values()]
    lam, U = np.linalg.eigh(mr.coupling_matrix())
    c = np.zeros(n)
    c[dofs] = U[:, -1] * np.sqrt(lam[-1])
    zero = np.zeros((n, n))
    for spp in steps_per_period:
        t = np.arange(periods * spp + 1) * (period / speed / spp)
        k_t = np.interp(np.mod(speed * t, period), th, k_tab)
        # static state under the period mean k_bar of k(t) as ROSS samples it (zero-mean
        # forcing); the rigid rotation and the seismic nodes (< 1 rad/s) take no static load
        k_bar = float(np.mean(k_t[:spp]))
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
            _, z, _ = mr.time_response(np.full(t.shape, speed), F, t, method="newmark", G=zero, Ksdt=zero)
            t_r = time.perf_counter() - t0
        fm = k_t * (c @ (y_s[:, None] + z.T)) / f_s
        last, prev = fm[-2 * spp:], fm[-4 * spp:-2 * spp]
        print(f"{f'ROSS Newmark, {spp}/mesh period':34s} {t.size - 1:8d} {t_r:9.1f} {last.max():10.6f} "
              f"{last.min():10.6f} {last.max() - df_g:+11.2e} (last 2 periods moved {abs(last.max() - prev.max()):.0e})")


def main():
    import argparse

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--geared", action="store_true", help="add the geared-rotor section (minutes)")
    ap.add_argument("--speed", type=float, default=900.0)
    ap.add_argument("--steps", default="128,256,512", help="Newmark steps per mesh period")
    ap.add_argument("--periods", type=int, default=60, help="mesh periods integrated by ROSS")
    args = ap.parse_args()
    structure_only()
    if args.geared:
        print()
        run_geared(args.speed, tuple(int(x) for x in args.steps.split(",")), args.periods)


def structure_only():
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
