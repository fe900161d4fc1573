"""Soak test of repeated 3D periodic-steady-state and design evaluations (issue 16: hang).

Repeats, in a loop, three kinds of evaluation of the Baud-Velex spur rig's 3D model at
the periodic steady state (shooting, vmapped over the speeds):

* ``steady``: :func:`gearjax.steady_state` of the model at each speed (one jitted call);
* ``value``:  the 3D :class:`gearjax.design.DynamicObjective` forward value;
* ``jacfwd``: the same objective's value and jacobian (``jax.jacfwd``),

each one watched: an evaluation that does not complete within ``--timeout`` seconds is a
*hang*. The evaluations run in a child process; on a hang the parent captures the
child's Python stacks (``py-spy dump``) and native stacks (``gdb -batch -ex "thread
apply all bt"``) into ``--stack-dir``, kills it and starts a fresh child for the
remaining evaluations. The last line printed is ``N evaluations, K hangs``.

One evaluation is kept cheap by default (modal cut-off 1 kHz, 2 speeds, 4 cells per
contact line, default tolerances) so that hundreds fit in a few minutes; ``--test-setting``
uses the slow test's setting instead (``tests/test_design.py::test_3d_dynamic_objective_
gradients``: 3 kHz, 10 cells, tolerances 1e-11).

The child sets XLA's CPU workarounds as the command line does
(:func:`gearjax.runtime.configure`, issue 16); run with ``GEARJAX_XLA_DEFAULTS=0`` in the
environment to soak XLA's defaults instead.

Examples::

    nice -n 10 timeout 1800 python benchmarks/soak_3d.py --evaluations 150 --timeout 120
    GEARJAX_XLA_DEFAULTS=0 python benchmarks/soak_3d.py --evaluations 150 --test-setting
    python benchmarks/soak_3d.py --evaluations 30 --xla-flags=--xla_cpu_use_thunk_runtime=false
"""

from __future__ import annotations

import argparse
import json
import os
import queue
import shutil
import signal
import subprocess
import sys
import threading
import time

KINDS = ("steady", "value", "jacfwd")


# --------------------------------------------------------------------------- child
def child(args) -> int:
    import equinox as eqx
    import gearjax as gj

    gj.runtime.configure()  # XLA's CPU workarounds, as the command line sets them

    import jax
    import jax.numpy as jnp
    import numpy as np

    if args.async_dispatch is not None:
        jax.config.update("jax_cpu_enable_async_dispatch", args.async_dispatch == "on")

    from gearjax.design import DynamicObjective, ReliefSpace
    from gearjax.gears.mesh import Mesh

    rig = gj.get_rig("baud-velex-spur")
    speeds = [float(s) for s in args.speeds.split(",")]
    mesh = Mesh.build(rig.pair, cells_per_line=args.cells)
    sim_kwargs = dict(rtol=args.rtol, atol=args.rtol * 1e-2,
                      measure_rtol=args.rtol, measure_atol=args.rtol * 1e-2)
    obj = DynamicObjective(mesh, ReliefSpace(), speeds, "peak-force", model="3d", rig=rig,
                           formulation=args.formulation, damping_ratio=0.1,
                           solver=gj.Shooting(**sim_kwargs),  # the shooting soaked for the hang
                           max_frequency_hz=args.max_frequency)
    x0 = np.array([13.3e-6, 0.2])
    model = obj.build(x0)
    speeds_j = jnp.asarray(speeds)

    @eqx.filter_jit
    def steady(m, w):
        r = jax.vmap(lambda s: gj.steady_state(m, s, gj.Shooting(**sim_kwargs)).result)(w)
        return r.max_mesh_force_N, r.solver_ok

    def evaluate(kind, i):
        # small design changes so no two evaluations are identical
        x = x0 * (1.0 + 1e-3 * ((i % 7) - 3) / 3)
        if kind == "steady":
            f, ok = steady(model, speeds_j)
            return float(np.max(np.asarray(f)))
        if kind == "value":
            sm, ex, _ = obj.all_metrics(x, grad=False)
            return float(sm[0])
        sm, ex, jac = obj.all_metrics(x)
        return float(jac[0, 0])

    print(json.dumps({"event": "start", "pid": os.getpid(), "jax": jax.__version__,
                      "xla_flags": os.environ.get("XLA_FLAGS", "")}), flush=True)
    for i in range(args.start, args.evaluations):
        kind = KINDS[i % len(KINDS)]
        print(json.dumps({"event": "begin", "i": i, "kind": kind}), flush=True)
        t0 = time.perf_counter()
        v = evaluate(kind, i)
        print(json.dumps({"event": "done", "i": i, "kind": kind,
                          "time_s": time.perf_counter() - t0, "value": v}), flush=True)
    return 0


# --------------------------------------------------------------------------- parent
def _capture(pid: int, path: str) -> None:
    """py-spy and gdb stacks of ``pid`` into ``path`` (whatever is installed)."""
    with open(path, "w") as f:
        spy = shutil.which("py-spy") or os.path.join(os.path.dirname(sys.executable), "py-spy")
        if os.path.exists(spy):
            f.write("==== py-spy dump --native\n")
            f.flush()
            subprocess.run([spy, "dump", "--pid", str(pid)], stdout=f, stderr=subprocess.STDOUT,
                           timeout=120)
        if shutil.which("gdb"):
            f.write("\n==== gdb thread apply all bt\n")
            f.flush()
            subprocess.run(["gdb", "-p", str(pid), "-batch", "-ex", "thread apply all bt"],
                           stdout=f, stderr=subprocess.STDOUT, timeout=300)
        try:
            with open(f"/proc/{pid}/stat") as st:
                f.write("\n==== /proc/PID/stat\n" + st.read())
        except OSError:
            pass


def _reader(stream, q):
    for line in stream:
        q.put(line)
    q.put(None)


def parent(args) -> int:
    env = dict(os.environ)
    if args.xla_flags:
        env["XLA_FLAGS"] = (env.get("XLA_FLAGS", "") + " " + args.xla_flags).strip()
    os.makedirs(args.stack_dir, exist_ok=True)
    times = {k: [] for k in KINDS}
    hangs: list = []
    t_all = time.perf_counter()

    def _stop(*_):
        raise KeyboardInterrupt

    signal.signal(signal.SIGTERM, _stop)
    proc_box: list = [None]
    try:
        _soak(args, env, times, hangs, proc_box)
    except KeyboardInterrupt:
        if proc_box[0] is not None:
            proc_box[0].kill()
        print("stopped early (SIGTERM / Ctrl-C); counts below are for the evaluations done")
    done = sum(len(v) for v in times.values())
    return _report(args, times, hangs, done, t_all, n_children=len(set(hangs)) + 1)


def _soak(args, env, times, hangs, proc_box) -> None:
    start = 0
    while start < args.evaluations:
        cmd = [sys.executable, os.path.abspath(__file__), "--child", "--start", str(start)]
        cmd += [a for a in sys.argv[1:] if a != "--child"]
        proc = proc_box[0] = subprocess.Popen(cmd, stdout=subprocess.PIPE, text=True, env=env)
        q: queue.Queue = queue.Queue()
        threading.Thread(target=_reader, args=(proc.stdout, q), daemon=True).start()
        seen, current, last = set(), None, time.perf_counter()
        while True:
            # the first evaluation of each kind in a child compiles: allow for it
            first = current is None or current["kind"] not in seen
            limit = args.timeout + (args.compile_timeout if first else 0)
            try:
                line = q.get(timeout=max(0.1, limit - (time.perf_counter() - last)))
            except queue.Empty:
                i = current["i"] if current else start
                path = os.path.join(args.stack_dir, f"hang_{i}_{int(time.time())}.txt")
                print(f"HANG at evaluation {i} ({current and current['kind']}): no completion "
                      f"in {limit:.0f} s; stacks -> {path}", flush=True)
                _capture(proc.pid, path)
                proc.kill()
                proc.wait()
                hangs.append(i)
                start = i + 1
                break
            if line is None:  # child ended
                rc = proc.wait()
                if rc != 0:
                    raise SystemExit(f"child exited with {rc} at evaluation {current}")
                start = args.evaluations
                break
            try:
                msg = json.loads(line)
            except ValueError:
                print(line, end="")
                continue
            if msg["event"] == "begin":
                current = msg
            elif msg["event"] == "done":
                times[msg["kind"]].append(msg["time_s"])
                seen.add(msg["kind"])
                last = time.perf_counter()
                if args.verbose:
                    print(f"{msg['i']:5d} {msg['kind']:7s} {msg['time_s']:8.3f} s", flush=True)
            elif msg["event"] == "start":
                print(f"child pid {msg['pid']}, jax {msg['jax']}, XLA_FLAGS (after "
                      f"gearjax.runtime.configure) {msg.get('xla_flags', env.get('XLA_FLAGS', ''))!r}", flush=True)


def _report(args, times, hangs, done, t_all, n_children) -> int:
    wall = time.perf_counter() - t_all
    import statistics

    for k in KINDS:
        ts = times[k]
        if ts:
            steady_ts = ts[1:] or ts
            print(f"{k:7s}: {len(ts)} done, first {ts[0]:.2f} s (compile), then median "
                  f"{statistics.median(steady_ts):.3f} s, max {max(steady_ts):.3f} s")
    if hangs:
        print(f"hangs at evaluations {hangs}; stacks in {args.stack_dir}")
    print(f"wall {wall:.0f} s, {n_children} child process(es)")
    print(f"{done + len(hangs)} evaluations, {len(hangs)} hangs")
    return 1 if hangs else 0


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--evaluations", type=int, default=100, help="number of evaluations N")
    p.add_argument("--timeout", type=float, default=120.0,
                   help="seconds without a completed evaluation that count as a hang")
    p.add_argument("--compile-timeout", type=float, default=600.0,
                   help="extra seconds allowed for the first evaluation of a child (compiling)")
    p.add_argument("--xla-flags", default="", help="appended to XLA_FLAGS of the child")
    p.add_argument("--async-dispatch", choices=("on", "off"), default=None,
                   help="set jax_cpu_enable_async_dispatch in the child")
    p.add_argument("--speeds", default="300,500", help="pinion speeds (rad/s), comma separated")
    p.add_argument("--max-frequency", type=float, default=1000.0, help="modal cut-off (Hz)")
    p.add_argument("--cells", type=int, default=4, help="cells per contact line")
    p.add_argument("--rtol", type=float, default=1e-7, help="solver rtol (atol = rtol/100)")
    p.add_argument("--formulation", default="te", choices=("te", "perturbation"))
    p.add_argument("--test-setting", action="store_true",
                   help="the slow test's setting: 3 kHz, 10 cells, rtol 1e-11")
    p.add_argument("--stack-dir", default="/tmp/soak_3d_stacks")
    p.add_argument("--verbose", "-v", action="store_true", help="one line per evaluation")
    p.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    p.add_argument("--start", type=int, default=0, help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.test_setting:
        args.max_frequency, args.cells, args.rtol = 3000.0, 10, 1e-11
    return child(args) if args.child else parent(args)


if __name__ == "__main__":
    sys.exit(main())
