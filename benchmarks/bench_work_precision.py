"""Work-precision, scaling and stress summary (issue #7): one command, markdown + PNG.

Scenario (sdof): Baud & Velex spur pair (Table 1), short tip relief, 254.8 N m, damping
ratio 0.03, default inertias; the three formulations (reference Eq. (16), te Eq. (20),
perturbation Eq. (47a)). 3D: ``build_model(baud_velex_rig(False), short relief,
formulation="te", damping_ratio=0.1, max_frequency_hz=6000, mesh_vectors="mean")``.

Error = max over the speeds of ``|max F_D - max F_D,ref| / F_S`` (dynamic mesh force) and
of ``|DTE_ptp - DTE_ptp,ref| / DTE_ptp,ref``, against a tight reference: the shooting
solver at rtol 1e-12 for te/perturbation (exact periodic orbit), simulate with Dopri8 at
rtol 1e-11 and a transient of 1500 periods for the reference formulation. Transient
methods carry their transient error too (that is what a user gets). Run time: the
median of repeated calls after compilation (compile time reported apart, via a first
call minus the run time).

Methods: the frequency-domain solver :func:`gearjax.dynamics.harmonic_sweep.harmonic_sweep`
(te/perturbation, speeds where its linear orbit keeps contact); diffrax through :func:`gearjax.dynamics.simulate.simulate` (Tsit5, Dopri5, Dopri8,
Kvaerno5 implicit) with its automatic transient; a fixed-step Tsit5 (diffrax
``ConstantStepSize``, steps not aligned with the jumps); the shooting solver
:func:`gearjax.dynamics.steady.steady_sweep`; ``scipy.integrate.solve_ivp`` (RK45, DOP853, LSODA)
looping over the speeds (NumPy right-hand side on the model's excitation table for
te/perturbation, the jitted JAX right-hand side for the reference) with the same
transient and jump splitting; a Newmark-beta average-acceleration integrator in NumPy
(the paper's method), vectorised over the speeds, fixed steps per mesh period.

Usage::

    python benchmarks/bench_work_precision.py --quick    # a few minutes
    python benchmarks/bench_work_precision.py            # full study
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import resource
import subprocess
import sys
import time

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

import gearjax  # noqa: F401
from gearjax import Mesh, baud_velex_pair, table1_relief
from gearjax.rigs import baud_velex_rig, build_model
from gearjax.models.torsional import TorsionalModel
from gearjax.dynamics.simulate import simulate
from gearjax.dynamics.steady import Shooting, steady_sweep
from gearjax.dynamics.harmonic_sweep import harmonic_sweep
from gearjax.dynamics.sweep import sweep

HERE = os.path.dirname(os.path.abspath(__file__))
OUT = os.path.join(HERE, "results")
sys.path.insert(0, HERE)
from baselines import solve_ivp_piecewise  # noqa: E402
from bench_sweep_sdof import _numpy_rhs  # noqa: E402

ZETA = 0.03
LINES: list[str] = []


def say(s=""):
    print(s, flush=True)
    LINES.append(s)


def rss_mb():
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def machine():
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    return (f"{cpu}, {os.cpu_count()} logical CPUs visible, Python {platform.python_version()}, "
            f"jax {jax.__version__}, diffrax {diffrax.__version__}, backend "
            f"{jax.default_backend()}, devices {jax.devices()}")


def sdof(formulation):
    return TorsionalModel.build(Mesh.build(baud_velex_pair(False)), table1_relief("short"),
                                formulation=formulation, damping_ratio=ZETA)


def timed(fn, repeats=2):
    t0 = time.perf_counter()
    out = fn()
    first = time.perf_counter() - t0
    ts = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        ts.append(time.perf_counter() - t0)
    run = float(np.median(ts))
    return out, run, max(first - run, 0.0)


# ---------------------------------------------------------------------- metrics
def metrics_from_samples(model, mp, w, ts, ys):
    out = jax.vmap(lambda t, y: mp.outputs(t, y, w))(jnp.asarray(ts), jnp.asarray(ys))
    fd, dte = np.asarray(out.mesh_force_N), np.asarray(out.dte_m)
    return float(fd.max()), float(dte.max() - dte.min())


def errors(fmax, dte, ref_fmax, ref_dte, f_s):
    e_f = float(np.nanmax(np.abs(np.asarray(fmax) - ref_fmax)) / f_s)
    e_d = float(np.nanmax(np.abs(np.asarray(dte) / ref_dte - 1)))
    if not (np.all(np.isfinite(fmax)) and np.all(np.isfinite(dte))):
        e_f = e_d = float("inf")
    return e_f, e_d


def n_transient(model, w, decay=1e-6, n_min=8, n_max=400):
    """simulate's automatic transient (excitation periods) at speed w."""
    mp = model
    n_mesh = int(round(model.period_rad / model.mesh_period_rad))
    rate = float(mp.decay_rate_per_rad(w))
    n = math.ceil(math.log(1 / decay) / (rate * model.period_rad))
    return int(min(max(n, math.ceil(n_min / n_mesh)), math.ceil(n_max / n_mesh))), mp


# ---------------------------------------------------------------------- methods
def run_simulate(model, speeds, solver, rtol, atol, **kw):
    fn = eqx.filter_jit(eqx.filter_vmap(
        lambda m, w: simulate(m, w, solver=solver, rtol=rtol, atol=atol, **kw), in_axes=(None, 0)))
    res, run, comp = timed(lambda: jax.block_until_ready(fn(model, jnp.asarray(speeds))))
    return np.asarray(res.max_mesh_force_N), np.asarray(res.dte_ptp_m), run, comp


def run_steady(model, speeds, rtol):
    def f():
        return steady_sweep(model, speeds, Shooting(rtol=rtol, atol=rtol / 100,
                                                    measure_rtol=rtol, measure_atol=rtol / 100))
    res, run, comp = timed(f)
    return res.max_mesh_force_N, res.dte_ptp_m, run, comp


def run_harmonic(model, speeds, rtol):
    """The frequency-domain solver (:func:`gearjax.dynamics.harmonic_sweep.harmonic_sweep`,
    te/perturbation): NaN at the speeds where its linear orbit loses contact (there the
    contact law's orbit is not the linear one; ``sweep`` hands those to the transient)."""
    def f():
        return harmonic_sweep(model, speeds, rtol=rtol, floquet=False)
    res, run, comp = timed(f)
    keep = np.asarray(res.stats["contact_holds"])
    return (np.where(keep, res.max_mesh_force_N, np.nan), np.where(keep, res.dte_ptp_m, np.nan),
            run, comp)


def run_fixed(model, speeds, steps_per_mesh, n_measured=3, samples=128):
    """Tsit5 with a constant step (diffrax ConstantStepSize), steps not aligned with the
    jump angles, same transient and sampling as simulate."""
    period = model.period_rad
    n_mesh = int(round(period / model.mesh_period_rad))
    n_tr = max(n_transient(model, w)[0] for w in speeds)
    dt = model.mesh_period_rad / steps_per_mesh

    @eqx.filter_jit
    def go(model, speeds):
        def one(w):
            m = model
            t_tr = n_tr * period
            ts = t_tr + (jnp.arange(n_measured * samples * n_mesh) + 0.5) * (period / (samples * n_mesh))
            sol = diffrax.diffeqsolve(
                diffrax.ODETerm(lambda t, y, a: m.vector_field(t, y, a)), diffrax.Tsit5(),
                t0=0.0, t1=t_tr + n_measured * period, dt0=dt, y0=m.initial_state(w), args=w,
                saveat=diffrax.SaveAt(ts=ts), stepsize_controller=diffrax.ConstantStepSize(),
                max_steps=int((n_tr + n_measured) * period / dt) + 10, throw=False)
            out = jax.vmap(lambda t, y: m.outputs(t, y, w))(ts, sol.ys)
            return jnp.max(out.mesh_force_N), jnp.max(out.dte_m) - jnp.min(out.dte_m)
        return jax.vmap(one)(speeds)

    (f, d), run, comp = timed(lambda: jax.block_until_ready(go(model, jnp.asarray(speeds))))
    return np.asarray(f), np.asarray(d), run, comp


def run_scipy(model, speeds, method, rtol, n_measured=3, samples=128):
    """solve_ivp looping over speeds, integration split at the jump angles, the same
    automatic transient as simulate; sdof te/perturbation: NumPy RHS on the model's table,
    else the jitted JAX right-hand side."""
    fm, dp = [], []
    total = 0.0
    for w in speeds:
        n_tr, mp = n_transient(model, w)
        period = model.period_rad
        n_mesh = int(round(period / model.mesh_period_rad))
        if model.formulation == "reference" or not isinstance(model, TorsionalModel):
            vf = jax.jit(lambda t, y: mp.vector_field(t, y, w))
            f = lambda t, y: np.asarray(vf(t, y))  # noqa: E731
        else:
            f = _numpy_rhs(mp, float(w))
        t_tr = n_tr * period
        t_end = t_tr + n_measured * period
        n_s = samples * n_mesh
        grid = t_tr + (np.arange(n_measured * n_s) + 0.5) * (period / n_s)
        # the start simulate uses (3D: slow modes on their period mean; sdof: the
        # quasi-static state), so that both integrate the same transient
        ys, dt = solve_ivp_piecewise(f, np.asarray(mp.transient_start(w)), period, mp.jump_thetas,
                                     t_tr, t_end, grid, method, rtol, rtol / 100)
        total += dt
        a, b = metrics_from_samples(model, mp, w, grid, ys)
        fm.append(a)
        dp.append(b)
    return np.array(fm), np.array(dp), total, 0.0


def _tables(mp, theta):
    """(x_S, k_S) (m, N/m) at angles theta from the model's table, and for the reference
    the cell gaps and stiffnesses (NumPy arrays, computed once: all speeds share theta)."""
    from gearjax import contact_gaps

    val, _ = jax.vmap(mp.excitations)(jnp.asarray(theta))
    out = {"x_s": np.asarray(val[:, 0]), "k_s": np.asarray(val[:, 1])}
    if mp.formulation == "reference":
        cells, de, _ = jax.vmap(lambda t: contact_gaps(mp.mesh, mp.mods, t))(jnp.asarray(theta))
        out["k"] = np.asarray(cells.stiffness_N_per_m)
        out["de"] = np.asarray(de)
    return out


def run_newmark(model, speeds, steps_per_mesh, n_measured=3, samples=128):
    """Newmark-beta, average acceleration (beta = 1/4, gamma = 1/2), in theta, NumPy,
    vectorised over the speeds, on the scaled equation
    ``u'' + 2 zeta r u' + r^2 (F(theta, u) / F_S - 1) = 0`` (``u = x / x_ref``,
    ``r = omega_n / Omega``); every formulation by Newton per step (the reference's cell
    law and the te/perturbation mesh contact law are piecewise linear: exact after the
    active set settles)."""
    t_start = time.perf_counter()
    speeds = np.asarray(speeds, dtype=float)
    mp = model
    d = mp
    period = model.period_rad
    n_mesh = int(round(period / model.mesh_period_rad))
    n_trs = np.array([n_transient(model, w)[0] for w in speeds])
    n_tot = int(n_trs.max()) + n_measured
    n_per = steps_per_mesh * n_mesh
    h = period / n_per
    theta = np.arange(n_per + 1) * h
    tab = _tables(mp, theta[:-1])
    r = float(d.omega_n) / speeds
    x_ref, k_m, cb = float(d.x_ref), float(d.k_m), model.cos_bb
    f_s = float(model.static_force_N)
    zeta = float(model.damping_ratio)
    ref = model.formulation == "reference"
    stiff_tab = tab["k_s"] if model.formulation == "te" else np.full(n_per, k_m)

    def force(j, u):
        """(F/F_S - 1, d/du) at table index j for scaled approaches u (per speed)."""
        if ref:
            pen = u[:, None] * x_ref * cb - tab["de"][j][None, :]
            act = pen > 0
            f = np.sum(tab["k"][j][None, :] * np.where(act, pen, 0.0), axis=1)
            df = np.sum(np.where(act, tab["k"][j][None, :], 0.0), axis=1) * x_ref * cb
            return f / f_s - 1.0, df / f_s
        k = stiff_tab[j]
        # contact law (gearjax.gears.contact.te_contact): no mesh force once it would be tensile
        g = k * cb * (u * x_ref - tab["x_s"][j]) / f_s
        return np.maximum(g, -1.0), np.where(g > -1.0, k * cb * x_ref / f_s, 0.0)

    y0 = np.stack([np.asarray(mp.initial_state(w)) for w in speeds])
    u, v = y0[:, 0], y0[:, 1] * r  # v = u'
    g, _ = force(0, u)
    a = -2 * zeta * r * v - r**2 * g
    # outputs on simulate's grid: every (steps_per_mesh / samples)-th step, at mid-cells
    stride = steps_per_mesh // samples
    off = stride // 2
    fmax = np.full(speeds.size, -np.inf)
    dmax = np.full(speeds.size, -np.inf)
    dmin = np.full(speeds.size, np.inf)
    for step in range(n_tot * n_per):
        j = (step + 1) % n_per
        up = u + h * v + h * h / 4 * a
        vp = v + h / 2 * a
        un = up.copy()
        for _ in range(20):  # Newton: piecewise linear (every formulation has a contact law)
            g, dg = force(j, un)
            an = 4 / (h * h) * (un - up)
            vn = vp + h / 2 * an
            res = an + 2 * zeta * r * vn + r**2 * g
            jac = 4 / (h * h) + 2 * zeta * r * 2 / h + r**2 * dg
            du = -res / jac
            un = un + du
            if np.max(np.abs(du)) < 1e-13:
                break
        a = 4 / (h * h) * (un - up)
        v = vp + h / 2 * a
        u = un
        k_step = step + 1
        per = k_step // n_per
        if (k_step % n_per - off) % stride == 0 and stride > 0:
            meas = per >= n_trs  # per-speed window (the last n_measured periods of each)
            meas &= per < n_trs + n_measured
            if np.any(meas):
                x = u * x_ref
                if ref:
                    pen = x[:, None] * cb - tab["de"][j][None, :]
                    fd = np.sum(tab["k"][j][None, :] * np.maximum(pen, 0.0), axis=1)
                else:
                    in_contact = f_s + stiff_tab[j] * cb * (x - tab["x_s"][j]) > 0.0
                    fd = np.where(in_contact, np.maximum(f_s + tab["k_s"][j] * cb
                                                         * (x - tab["x_s"][j]), 0.0), 0.0)
                fmax = np.where(meas, np.maximum(fmax, fd), fmax)
                dmax = np.where(meas, np.maximum(dmax, x), dmax)
                dmin = np.where(meas, np.minimum(dmin, x), dmin)
    return fmax, dmax - dmin, time.perf_counter() - t_start, 0.0


# ---------------------------------------------------------------------- studies
def work_precision(args):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    speeds = np.linspace(150.0, 1400.0, 4 if args.quick else 12)
    say("## Work-precision, sdof (spur, short relief, zeta 0.03)")
    say(f"speeds: {len(speeds)} in {speeds[0]:.0f}-{speeds[-1]:.0f} rad/s")
    rows_all = {}
    tols = [1e-5, 1e-7, 1e-9] if not args.quick else [1e-5, 1e-8]
    forms = ["te", "perturbation", "reference"]
    for form in forms:
        model = sdof(form)
        f_s = float(model.static_force_N)
        t0 = time.perf_counter()
        if form == "reference":
            rf, rd, _, _ = run_simulate(model, speeds, diffrax.Dopri8(), 1e-11, 1e-13,
                                        n_transient_periods=1500)
        else:
            rf, rd, _, _ = run_steady(model, speeds, 1e-12)
        say(f"\n### {form} (reference solution in {time.perf_counter() - t0:.1f} s)\n")
        say("| method | setting | err max F_D / F_S | err DTE ptp (rel) | run s | compile s |")
        say("|---|---|---|---|---|---|")
        rows = []

        def add(name, setting, res):
            fm, dp, run, comp = res
            ef, ed = errors(fm, dp, rf, rd, f_s)
            rows.append((name, setting, ef, ed, run, comp))
            say(f"| {name} | {setting} | {ef:.2e} | {ed:.2e} | {run:.3f} | {comp:.1f} |")

        for tol in tols:
            add("steady (shooting)", f"rtol {tol:g}", run_steady(model, speeds, tol))
        for tol in (tols if form != "reference" else []):
            fm, dp, run, comp = run_harmonic(model, speeds, tol)
            ok = np.isfinite(fm)
            if ok.any():
                ef, ed = errors(fm[ok], dp[ok], rf[ok], rd[ok], f_s)
                rows.append(("harmonic balance", f"rtol {tol:g}", ef, ed, run, comp))
                say(f"| harmonic balance | rtol {tol:g} ({int(ok.sum())}/{len(speeds)} speeds "
                    f"in contact) | {ef:.2e} | {ed:.2e} | {run:.3f} | {comp:.1f} |")
        for name, solver in [("Tsit5", diffrax.Tsit5()), ("Dopri5", diffrax.Dopri5()),
                             ("Dopri8", diffrax.Dopri8())]:
            for tol in tols:
                add(f"diffrax {name}", f"rtol {tol:g}",
                    run_simulate(model, speeds, solver, tol, tol / 100))
        add("diffrax Kvaerno5 (implicit)", "rtol 1e-7",
            run_simulate(model, speeds, diffrax.Kvaerno5(), 1e-7, 1e-9))
        for spm in ([128, 512] if args.quick else [128, 256, 512, 1024]):
            add("diffrax Tsit5 fixed step", f"{spm}/mesh period", run_fixed(model, speeds, spm))
        sub = speeds[:: max(1, len(speeds) // (2 if args.quick else 4))]
        for method in ["RK45", "DOP853", "LSODA"]:
            if form == "reference" and method != "DOP853" and args.quick:
                continue
            fm, dp, run, comp = run_scipy(model, sub, method, 1e-7)
            scale = len(speeds) / len(sub)
            ef, ed = errors(fm, dp, rf[np.isin(speeds, sub)], rd[np.isin(speeds, sub)], f_s)
            rows.append((f"scipy {method}", "rtol 1e-7", ef, ed, run * scale, 0.0))
            say(f"| scipy {method} | rtol 1e-7 ({len(sub)} speeds, time x{scale:.1f}) | "
                f"{ef:.2e} | {ed:.2e} | {run * scale:.3f} | 0 |")
        for spm in ([256] if args.quick else [256, 1024]):
            if form == "reference" and args.quick:
                continue
            add("Newmark avg. accel. (NumPy)", f"{spm}/mesh period",
                run_newmark(model, speeds, spm))
        rows_all[form] = rows
        fig, ax = plt.subplots(1, 2, figsize=(11, 4.2))
        names = sorted({r[0] for r in rows})
        for name in names:
            rr = [r for r in rows if r[0] == name]
            for i, col in enumerate((2, 3)):
                ax[i].loglog([max(r[4], 1e-4) for r in rr], [max(r[col], 1e-16) for r in rr],
                             "o-", label=name)
        for i, lab in enumerate(("error max F_D / F_S", "relative error DTE ptp")):
            ax[i].set_xlabel("run time (s)")
            ax[i].set_ylabel(lab)
            ax[i].grid(True, which="both", alpha=0.3)
        ax[1].legend(fontsize=7)
        fig.suptitle(f"sdof {form}: {len(speeds)} speeds")
        fig.tight_layout()
        fig.savefig(os.path.join(OUT, f"work_precision_sdof_{form}.png"), dpi=110)
        plt.close(fig)
        say("\nPareto front (run time, error max F_D): " + ", ".join(
            f"{r[0]} [{r[1]}] {r[4]:.3f} s / {r[2]:.1e}" for r in pareto(rows)))
        say(ratio_at_equal_error(rows))
        say(f"peak RSS so far: {rss_mb():.0f} MB")
    return rows_all


def pareto(rows):
    good = [r for r in rows if np.isfinite(r[2])]
    good.sort(key=lambda r: r[4])
    front, best = [], np.inf
    for r in good:
        if r[2] < best:
            front.append(r)
            best = r[2]
    return front


def ratio_at_equal_error(rows, target=1e-5):
    """Fastest run of each method family reaching the target error (max F_D and DTE)."""
    fam = {}
    for r in rows:
        if max(r[2], r[3]) <= target:
            key = r[0]
            if key not in fam or r[4] < fam[key][4]:
                fam[key] = r
    if not fam:
        return f"no method reached {target:g}"
    best = min(fam.values(), key=lambda r: r[4])
    parts = [f"{k} {v[4] / best[4]:.1f}x" for k, v in sorted(fam.items(), key=lambda kv: kv[1][4])]
    return (f"time to reach error <= {target:g} (both metrics), relative to the fastest "
            f"({best[0]} [{best[1]}], {best[4]:.3f} s): " + ", ".join(parts))


def study_3d(args):

    say("\n## 3D te model (spur rig, reduced to 6 kHz, mesh_vectors='mean', zeta 0.1)")
    t0 = time.perf_counter()
    model = build_model(baud_velex_rig(False), table1_relief("short"), formulation="te",
                                     damping_ratio=0.1, max_frequency_hz=6000.0,
                                     mesh_vectors="mean")
    say(f"build {time.perf_counter() - t0:.1f} s, {model.n_reduced} modal coordinates")
    speeds = np.array([300.0, 1200.0]) if args.quick else np.array([300.0, 700.0, 1100.0, 1500.0])
    f_s = float(model.static_force_N)
    rf, rd, _, _ = run_steady(model, speeds, 1e-11)
    say("| method | setting | err max F_D / F_S | err DTE ptp (rel) | run s | compile s |")
    say("|---|---|---|---|---|---|")
    rows = []
    for tol in ([1e-6, 1e-9] if args.quick else [1e-6, 1e-8, 1e-9]):
        fm, dp, run, comp = run_steady(model, speeds, tol)
        ef, ed = errors(fm, dp, rf, rd, f_s)
        rows.append(("steady (shooting)", f"rtol {tol:g}", ef, ed, run, comp))
    for tol in [1e-6, 1e-9]:
        fm, dp, run, comp = run_harmonic(model, speeds, tol)
        ef, ed = errors(fm, dp, rf, rd, f_s)
        rows.append(("harmonic balance", f"rtol {tol:g}", ef, ed, run, comp))
    for name, solver, tol in [("Tsit5", diffrax.Tsit5(), 1e-7), ("Dopri8", diffrax.Dopri8(), 1e-7)]:
        fm, dp, run, comp = run_simulate(model, speeds, solver, tol, tol / 100)
        ef, ed = errors(fm, dp, rf, rd, f_s)
        rows.append((f"diffrax {name} (auto transient)", f"rtol {tol:g}", ef, ed, run, comp))
    if not args.no_scipy_3d:  # the jitted JAX right-hand side, one speed at a time
        fm, dp, run, comp = run_scipy(model, speeds, "DOP853", 1e-9)
        ef, ed = errors(fm, dp, rf, rd, f_s)
        rows.append(("scipy DOP853 (auto transient, 128 samples)", "rtol 1e-09", ef, ed, run, comp))
    for r in rows:
        say(f"| {r[0]} | {r[1]} | {r[2]:.2e} | {r[3]:.2e} | {r[4]:.3f} | {r[5]:.1f} |")
    say("The transients start from gearjax.dynamics.simulate.transient_start (the slow, weakly coupled "
        "61.8 rad/s mode, Floquet radius 0.995-0.999 per mesh period, starts on its period "
        "mean): before that start their error was ~1e-3 (the mode outlived the automatic "
        "transient); the shooting needs no transient.")
    say(f"peak RSS so far: {rss_mb():.0f} MB")
    return rows


def scaling(args):
    say("\n## Scaling")
    model = sdof("te")
    counts = [n for n in (1, 10, 100, 1000, 10000) if n <= args.max_speeds]
    say("\n### time against number of speeds (sdof te, 100-1400 rad/s)\n")
    say(f"devices: {len(jax.devices())} (the transient sweep shards its speeds over them)\n")
    say("Above 100 speeds one call each, its time including compilation (marked +c; the "
        "compile column of the rows above gives its size). The shooting's speeds with contact "
        "loss are continued by simulate in one more batch.\n")
    say("| speeds | harmonic run s | compile s | steady run s | compile s | sweep (transient) run s "
        "| compile s | transient s / speed |")
    say("|---|---|---|---|---|---|---|---|")

    def once(fn):
        t0 = time.perf_counter()
        fn()
        return time.perf_counter() - t0

    for n in counts:
        sp = np.linspace(100.0, 1400.0, n)
        if n <= 100:
            _, rh, ch = timed(lambda: harmonic_sweep(model, sp, floquet=False), repeats=1)
            _, rs, cs = timed(lambda: steady_sweep(model, sp), repeats=1)
            _, rt, ct = timed(lambda: sweep(model, sp), repeats=1)
            say(f"| {n} | {rh:.3f} | {ch:.1f} | {rs:.3f} | {cs:.1f} | {rt:.3f} | {ct:.1f} | {rt / n:.2e} |")
        else:
            rh = once(lambda: harmonic_sweep(model, sp, floquet=False))
            rs = once(lambda: steady_sweep(model, sp))
            rt = once(lambda: sweep(model, sp))
            say(f"| {n} | {rh:.1f} +c | - | {rs:.1f} +c | - | {rt:.1f} +c | - | {rt / n:.2e} |")
    say(f"peak RSS so far: {rss_mb():.0f} MB")
    harmonics_scaling(model)

    say("\n### time against number of contact cells (sdof reference, helical pair, 4 speeds)\n")
    say("| cells per line | cells | sweep run s | compile s |")
    say("|---|---|---|---|")
    sp = np.linspace(200.0, 1200.0, 4)
    for cpl in ([5, 20] if args.quick else [5, 10, 20, 40]):
        m = TorsionalModel.build(Mesh.build(baud_velex_pair(True), cells_per_line=cpl),
                                 table1_relief("short"), formulation="reference",
                                 damping_ratio=ZETA)
        _, rt, ct = timed(lambda: sweep(m, sp), repeats=1)
        say(f"| {cpl} | {m.mesh.n_cells if hasattr(m.mesh, 'n_cells') else '-'} | {rt:.3f} | {ct:.1f} |")
    say(f"peak RSS so far: {rss_mb():.0f} MB")

    say("\n### time against number of dofs (te, one speed 900 rad/s)\n")

    say("| model | states | steady run s | compile s | transient (simulate) run s | compile s |")
    say("|---|---|---|---|---|---|")
    cases = [("sdof", model)]
    cases.append(("3D reduced 6 kHz", build_model(
        baud_velex_rig(False), table1_relief("short"), formulation="te", damping_ratio=0.1,
        max_frequency_hz=6000.0, mesh_vectors="mean")))
    if not args.quick:
        cases.append(("3D full (all modes)", build_model(
            baud_velex_rig(False), table1_relief("short"), formulation="te", damping_ratio=0.1,
            max_frequency_hz=None, mesh_vectors="mean")))
    for name, m in cases:
        n_state = int(2 * m.n_reduced) if hasattr(m, "n_reduced") else 2
        _, rs, cs = timed(lambda: steady_sweep(m, [900.0]), repeats=1)
        _, rt, ct = timed(lambda: sweep(m, [900.0]), repeats=1)
        say(f"| {name} | {n_state} | {rs:.3f} | {cs:.1f} | {rt:.3f} | {ct:.1f} |")
    say(f"peak RSS: {rss_mb():.0f} MB")


def harmonics_scaling(model):
    """Run time and error of the frequency-domain solver against its number of harmonics
    (fixed: min = max), sdof te, 4 speeds; error against shooting at rtol 1e-12."""
    say("\n### time and error against number of harmonics (sdof te, frequency domain, 4 speeds)\n")
    speeds = np.linspace(150.0, 1400.0, 4)
    f_s = float(model.static_force_N)
    rf, rd, _, _ = run_steady(model, speeds, 1e-12)
    say("| harmonics per excitation period | err max F_D / F_S | err DTE ptp (rel) | run s | compile s |")
    say("|---|---|---|---|---|")
    for h in (32, 64, 128, 256, 512, 1024, 2048):
        def f():
            return harmonic_sweep(model, speeds, rtol=0.5, harmonics=h, max_harmonics=h,
                                  floquet=False)
        res, run, comp = timed(f)
        keep = np.asarray(res.stats["contact_holds"])
        ef, ed = errors(np.where(keep, res.max_mesh_force_N, np.nan),
                        np.where(keep, res.dte_ptp_m, np.nan), rf, rd, f_s)
        say(f"| {h} | {ef:.2e} | {ed:.2e} | {run:.4f} | {comp:.1f} |")


def stress_summary():
    say("\n## Stress tests (tests/test_stress.py, slow ones included)\n")
    xml = os.path.join(OUT, "stress_junit.xml")
    cmd = [sys.executable, "-m", "pytest", "-q", "-m", "slow or not slow",
           os.path.join(HERE, "..", "tests", "test_stress.py"), f"--junitxml={xml}"]
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True)
    say(f"pytest exit {proc.returncode} in {time.perf_counter() - t0:.0f} s")
    import xml.etree.ElementTree as ET

    if os.path.exists(xml):
        say("| test | outcome | s |")
        say("|---|---|---|")
        for tc in ET.parse(xml).getroot().iter("testcase"):
            outcome = "failed" if tc.find("failure") is not None else (
                "skipped" if tc.find("skipped") is not None else "passed")
            say(f"| {tc.get('name')} | {outcome} | {float(tc.get('time')):.1f} |")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="reduced sizes (a few minutes)")
    ap.add_argument("--skip", default="", help="comma list of: wp,3d,scaling,stress")
    ap.add_argument("--name", default=None,
                    help="results file name (default work_precision[_quick])")
    ap.add_argument("--max-speeds", type=int, default=None,
                    help="largest speed count of the scaling table (1, 10, ... 10000; default "
                         "100 with --quick, else 10000)")
    ap.add_argument("--no-scipy-3d", action="store_true",
                    help="leave out the SciPy row of the 3D work-precision table")
    args = ap.parse_args()
    if args.max_speeds is None:
        args.max_speeds = 100 if args.quick else 10000
    skip = set(filter(None, args.skip.split(",")))
    os.makedirs(OUT, exist_ok=True)
    say("# gearjax work-precision benchmark" + (" (--quick)" if args.quick else ""))
    say(f"machine: {machine()}")
    say(f"date: {time.strftime('%Y-%m-%d %H:%M')}")
    res = {}
    if "wp" not in skip:
        res["sdof"] = work_precision(args)
    if "3d" not in skip:
        res["3d"] = study_3d(args)
    if "scaling" not in skip:
        scaling(args)
    if "stress" not in skip:
        stress_summary()
    name = args.name or ("work_precision_quick" if args.quick else "work_precision")
    with open(os.path.join(OUT, name + ".md"), "w") as fh:
        fh.write("\n".join(LINES) + "\n")
    with open(os.path.join(OUT, name + ".json"), "w") as fh:
        json.dump(res, fh, indent=1, default=float)


if __name__ == "__main__":
    main()
