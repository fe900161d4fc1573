"""Gradient cost of the tip-relief design objective: forward value vs forward-mode gradient
(``diffrax.ForwardMode`` + ``jax.jacfwd``) vs reverse mode
(``diffrax.RecursiveCheckpointAdjoint`` + ``jax.jacrev``), compile time apart from run time.

Objective: smoothed peak dynamic mesh force over N speeds (default formulation of
:class:`gearjax.design.DynamicObjective`),
spur Baud-Velex pair, gear-body inertias (the default since the measurements below were
taken with the former rig-line inertias), shared linear relief (2 design variables) or
separate reliefs (4). Each timing is the median of ``--repeat`` runs after the first
(compiling) call; ratios are to the forward value in the same process.

    python benchmarks/bench_gradients.py [--speeds 8] [--separate] [--repeat 3] [--model 3d]
        [--method auto|transient|steady] [--jvp] [--kernels K]

``--jvp`` adds two rows: one forward-mode direction (``jax.jvp`` along the relief
amplitude), the cost of one tangent beside the primal, and the Jacobian as one ``jax.jvp``
per design variable one after the other (``jax.lax.map``, the primal solved again per
direction), against ``jacfwd``'s tangents vmapped on one primal solve; and the same four
for the model's right-hand side alone (``vector_field`` of the model mapped to the design,
4000 calls in a ``fori_loop``), microseconds per call. ``--kernels K`` (implies
``--jvp``) adds, for the right-hand side's primal, one direction and ``jacfwd``, the K
dearest compiled kernels of one profiled call (``jax.profiler``), each with its output
shape and the table reads fused into it.

Measured (te, 4 speeds, 2 variables, this 2-core CPU shared with other jobs): compile
29 s / 58 s / 104 s and run 0.065 s / 0.34 s (5.2x) / 8.2 s (125x) for the forward value,
jacfwd + ForwardMode and jacrev + RecursiveCheckpointAdjoint; the two gradients agree to
5.5e-10. Forward mode wins, as expected for 2-4 design variables.

Measured ``--model 3d --speeds 2 --repeat 1`` (perturbation, 8.9 kHz cut-off = 130 modal
coordinates, periodic steady state by shooting, 2-core CPU shared with a notebook run):
compile 16 s / 25 s, run 4.7 s / 19.0 s (4.05x) for the forward value and jacfwd; the
shooting differentiates in forward mode only (its period integrations carry the monodromy
matrix with ``diffrax.ForwardMode``), so there is no reverse-mode row.

Re-run 2026-11-24 (quiet 2-core CPU, one device): te, 4 speeds, 2 variables: compile 5.9 /
10.2 / 25.0 s, run 0.038 / 0.050 (1.3x) / 1.59 s (41x), gradients equal to 3.1e-7;
``--model 3d --speeds 2 --repeat 1`` (te, shooting, now ``--method steady``): compile 18 /
26 s, run 48 / 164 s (3.4x).

``--model 3d --speeds 2 --repeat 3`` with the objective's default since 2026-11-24, the
accelerated transient (quiet 2-core CPU): model build 15 s; compile 23 / 41 / 79 s, run
0.48 / 1.33 (2.8x) / 4.05 s (8.5x) for the forward value, jacfwd + ForwardMode and jacrev
+ RecursiveCheckpointAdjoint; the two gradients equal to 2.4e-10. Against shooting: 100x
(value), 123x (jacfwd).
"""

from __future__ import annotations

import argparse
import collections
import re
import tempfile
import time
from pathlib import Path

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

import gearjax  # noqa: F401  (x64)
from gearjax.cli.solvers import design_solver
from gearjax.design import DynamicObjective, ReliefSpace
from gearjax.gears.mesh import Mesh
from gearjax.rigs.registry import get_rig


def _time(fn, repeat):
    t0 = time.perf_counter()
    out = fn()
    jax.block_until_ready(out)
    first = time.perf_counter() - t0
    runs = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        jax.block_until_ready(fn())
        runs.append(time.perf_counter() - t0)
    run = float(np.median(runs))
    return first - run, run, out


def _rhs_rows(obj, x, speeds, n_calls: int = 4000, repeat: int = 5, kernels: int = 0):
    """Microseconds per call of the model's right-hand side at the design ``x`` and the
    highest speed: primal, one ``jax.jvp`` direction, ``jax.jacfwd`` (one direction per
    design variable, vmapped), and one ``jax.jvp`` per variable under ``jax.lax.map``.
    ``kernels`` > 0: also the ``kernels`` dearest compiled kernels of the primal, the one
    direction and ``jacfwd`` (:func:`_kernel_rows`)."""
    w = jnp.asarray(float(speeds[-1]))
    y0 = obj.model.transient_start(w)
    n = obj.space.size
    arrays, static = eqx.partition(obj.model, eqx.is_array)

    def prim(p, xx):  # the design enters through the model's tables (with_modifications)
        mm = eqx.combine(p, static).with_modifications(obj.space.mods(xx))
        return jax.lax.fori_loop(0, n_calls, lambda i, y: y + 1e-7 * mm.vector_field(
            0.01 + i * 1e-4, y, w), y0)

    e0 = jnp.zeros(n).at[0].set(1.0)
    fns = {"primal": jax.jit(prim),
           "jvp (1 direction)": jax.jit(lambda p, xx: jax.jvp(
               lambda z: prim(p, z), (xx,), (e0,))),
           f"jacfwd ({n}, vmapped)": jax.jit(lambda p, xx: jax.jacfwd(
               lambda z: prim(p, z))(xx)),
           f"jvp per variable, lax.map ({n})": jax.jit(lambda p, xx: jax.lax.map(
               lambda v: jax.jvp(lambda z: prim(p, z), (xx,), (v,))[1], jnp.eye(n)))}
    xj = jnp.asarray(x)
    times = {k: [] for k in fns}
    for f in fns.values():
        jax.block_until_ready(f(arrays, xj))
    for _ in range(repeat):  # alternately, so that the machine's drift hits every row
        for k, f in fns.items():
            t0 = time.perf_counter()
            jax.block_until_ready(f(arrays, xj))
            times[k].append((time.perf_counter() - t0) / n_calls * 1e6)
    print(f"right-hand side at {float(w):g} rad/s, {n_calls} calls, median of {repeat}:")
    base = float(np.median(times["primal"]))
    for k, v in times.items():
        print(f"  {k:40s} {np.median(v):8.2f} us per call  {np.median(v) / base:6.2f}")
    if kernels:
        for k in list(fns)[:3]:
            _kernel_rows(k, fns[k], (arrays, xj), n_calls, kernels)


def _kernel_rows(name, fn, args, n_calls: int, top: int):
    """The ``top`` dearest kernels of the compiled ``fn`` that run once per right-hand-side
    call (``n_calls`` times or more), from one profiled call (``jax.profiler.trace``; the
    tracer adds about the same to every kernel, so the times are for comparing kernels and
    rows, not absolute): microseconds per call, the kernel's output shape and how many
    dynamic slices and gathers its fused computation holds (a table lookup fused into an
    elementwise kernel may be redone for every element of its output)."""
    text = fn.lower(*args).compile().as_text()
    shapes, reads, bodies = {}, {}, {}
    for line in text.splitlines():
        m = re.match(r"\s*(?:ROOT )?%([\w.\-]+) = (\S+) fusion\(.*calls=%([\w.\-]+)", line)
        if m:
            shapes[m.group(1)], bodies[m.group(1)] = m.group(2), m.group(3)
        m = re.match(r"\s*(?:ROOT )?%([\w.\-]+) = (\S+) (dot|copy|concatenate)\(", line)
        if m:
            shapes[m.group(1)] = m.group(2)
    for comp in set(bodies.values()):
        block = re.search(rf"^%{re.escape(comp)} .*?^}}", text, re.S | re.M)
        reads[comp] = len(re.findall(r"= \S+ (?:dynamic-slice|gather)\(",
                                     block.group(0))) if block else 0
    with tempfile.TemporaryDirectory() as d:
        with jax.profiler.trace(d):
            jax.block_until_ready(fn(*args))
        data = jax.profiler.ProfileData.from_file(str(next(Path(d).rglob("*.xplane.pb"))))
    total, count = collections.Counter(), collections.Counter()
    for plane in data.planes:
        for line in plane.lines:
            for ev in line.events:
                total[ev.name] += ev.duration_ns
                count[ev.name] += 1
    rows = [(t / 1e3 / n_calls, k) for k, t in total.items()
            if k in shapes and count[k] >= n_calls]
    rows.sort(reverse=True)
    print(f"  {name}: {len(rows)} kernels per call, profiled sum "
          f"{sum(r[0] for r in rows):.2f} us per call; the dearest:")
    for us, k in rows[:top]:
        print(f"    {k:34s} {shapes[k]:22s} {us:7.2f} us  "
              f"{reads.get(bodies.get(k), 0):3d} table reads")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--speeds", type=int, default=8)
    ap.add_argument("--separate", action="store_true")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--no-reverse", action="store_true")
    ap.add_argument("--jvp", action="store_true",
                    help="also time one forward-mode direction, one jvp per variable "
                         "(lax.map), and the model's right-hand side alone")
    ap.add_argument("--kernels", type=int, default=0, metavar="K",
                    help="also the K dearest compiled kernels of the right-hand side's "
                         "primal, one direction and jacfwd, from a profiled call (implies "
                         "--jvp)")
    ap.add_argument("--model", default="torsional", choices=["torsional", "3d"],
                    help="3d: the rig's 3D model (the objective's automatic cut-off, 8.9 kHz "
                         "at 480 rad/s; zeta 0.1)")
    ap.add_argument("--method", default="auto", choices=["auto", "transient", "steady"],
                    help="the objective's solver (auto: the transient); steady (shooting) is "
                         "forward mode only")
    args = ap.parse_args()
    args.jvp = args.jvp or args.kernels > 0
    rig = get_rig("baud-velex-spur")
    mesh = Mesh.build(rig.pair, "iso6336")
    space = ReliefSpace(shared=not args.separate)
    speeds = np.linspace(330.0, 480.0, args.speeds)
    x = np.array([13.3e-6, 0.35]) if space.shared else np.array([13.3e-6, 12e-6, 0.35, 0.4])
    kw = dict(model="3d", rig=rig, damping_ratio=0.1) if args.model == "3d" else {}
    if args.method == "steady":
        args.no_reverse = True  # the shooting is forward mode only
    solver = design_solver(args.method, None)
    fwd = DynamicObjective(mesh, space, speeds, "peak-force", solver=solver, **kw)
    fwd.model = fwd.build(x)
    rows = []
    c, r, ev = _time(lambda: fwd(x, grad=False).smooth, args.repeat)
    rows.append(("forward value", c, r, None))
    if args.jvp:  # the objective's own function, as DynamicObjective differentiates it
        from gearjax.design.objectives import DYNAMIC_OBJECTIVES, _dyn_values_impl

        k = DYNAMIC_OBJECTIVES.index(fwd.kind)
        sp, e0 = jnp.asarray(speeds), jnp.zeros(space.size).at[0].set(1e-6)

        def along(m, xx, v):  # the smoothed objective and its derivative along v
            return jax.jvp(lambda y: _dyn_values_impl(m, y, sp, fwd._static,
                                                      diffrax.ForwardMode())[0][k], (xx,), (v,))

        one = eqx.filter_jit(lambda m, xx: along(m, xx, e0))
        c, r, _ = _time(lambda: one(fwd.model, jnp.asarray(x)), args.repeat)
        rows.append(("jvp + ForwardMode (1 direction)", c, r, None))
        each = eqx.filter_jit(lambda m, xx: jax.lax.map(lambda v: along(m, xx, v)[1],
                                                        jnp.eye(space.size)))
        c, r, _ = _time(lambda: each(fwd.model, jnp.asarray(x)), args.repeat)
        rows.append((f"jvp per variable, lax.map ({space.size})", c, r, None))
    c, r, ev_f = _time(lambda: fwd(x, grad=True).grad, args.repeat)
    rows.append((f"jacfwd + ForwardMode ({space.size} vars)", c, r, ev_f))
    if not args.no_reverse:
        rev = DynamicObjective(mesh, space, speeds, "peak-force", solver=solver,
                               adjoint=diffrax.RecursiveCheckpointAdjoint(), **kw)
        rev.model = fwd.model
        c, r, ev_r = _time(lambda: rev(x, grad=True).grad, args.repeat)
        rows.append(("jacrev + RecursiveCheckpointAdjoint", c, r, ev_r))
    base = rows[0][2]
    print(f"# {rig.name}, {args.model} {args.method}, {fwd.formulation}, {args.speeds} speeds 330-480 rad/s, {space.size} design variables, "
          f"build {fwd.build_time_s:.2f} s, {jax.device_count()} {jax.devices()[0].platform} device(s)")
    print(f"{'what':40s} {'compile [s]':>12s} {'run [s]':>10s} {'run / forward':>14s}")
    for name, c, r, _ in rows:
        print(f"{name:40s} {c:12.2f} {r:10.3f} {r / base:14.2f}")
    if args.jvp:
        _rhs_rows(fwd, x, speeds, kernels=args.kernels)
    if not args.no_reverse:
        g_f, g_r = np.asarray(rows[-2][3]), np.asarray(rows[-1][3])
        print("forward vs reverse gradient, max relative difference:",
              float(np.max(np.abs(g_f - g_r) / np.abs(g_f))))


if __name__ == "__main__":
    main()
