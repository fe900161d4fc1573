"""Speed sweeps: one compilation for repeated sweeps, CSV/progress output, caller's order,
agreement with single-speed simulations, and sharding across (fake) devices."""

from __future__ import annotations

import csv
import json
import math
import os
import subprocess
import sys
import textwrap

import equinox as eqx
import jax
import numpy as np
import jax.numpy as jnp
import pytest

import gearjax.dynamics.sweep as sweep_mod
from gearjax import Mesh, baud_velex_pair, table1_relief
from gearjax.rigs import baud_velex_rig, build_model
from gearjax.models.torsional import TorsionalModel
from gearjax.dynamics.simulate import SimulationError, simulate
from gearjax.dynamics.sweep import CSV_COLUMNS, Transient, sweep
from gearjax.dynamics.results import METRIC_FIELDS, append_rows
from gearjax.errors import GearjaxError
from gearjax.runtime import TextProgressMeter

OPTS = dict(n_transient_periods=12, n_measured_periods=2)
TR = Transient(**OPTS)


@pytest.fixture(scope="module")
def model():
    return TorsionalModel.build(Mesh.build(baud_velex_pair(False)), table1_relief("short"),
                                formulation="perturbation")


def test_repeated_sweeps_trace_once(model, monkeypatch):
    """New speeds (and new array data of the model) never retrace the chunk function."""
    counted = eqx.debug.assert_max_traces(simulate, max_traces=1)
    monkeypatch.setattr(sweep_mod, "simulate", counted)
    a = sweep(model, [900.0, 100.0, 300.0, 500.0, 700.0, 200.0, 400.0], chunk_size=4,
              solver=TR)
    b = sweep(model, [150.0, 250.0, 350.0], chunk_size=4, solver=TR)
    damped = TorsionalModel.build(model.mesh, model.mods, formulation="perturbation",
                                  damping_ratio=0.08)
    c = sweep(damped, [150.0, 250.0, 350.0], chunk_size=4, solver=TR)
    assert eqx.debug.get_num_traces(counted) <= 1
    assert a.speed_rad_s.tolist() == [900.0, 100.0, 300.0, 500.0, 700.0, 200.0, 400.0]
    assert np.all(c.dynamic_factor < b.dynamic_factor)  # more damping, same speeds
    # caller's order is kept and each entry is the single-speed simulation
    one = eqx.filter_jit(simulate)(model, np.float64(300.0), **OPTS)
    i = 2
    for f in ("max_mesh_force_N", "min_mesh_force_N", "dte_ptp_m"):
        np.testing.assert_allclose(getattr(a, f)[i], float(getattr(one, f)), rtol=1e-10, err_msg=f)
    # convergence is a difference of nearly equal extrema over F_S: compare absolutely
    assert abs(a.convergence[i] - float(one.convergence)) < 1e-11
    assert np.all(np.isnan(a.accel_ptp_m_s2))  # torsional model: no acceleration observable


def test_lowered_sweep_program_is_the_one_the_sweep_runs(model, monkeypatch):
    """lower_sweep gives the program sweep then calls (the command line compiles the te one
    on a thread while the reference sweep runs, gearjax.cli.ahead): compiled beforehand,
    the sweep neither traces simulate again nor compiles anything of its size (every XLA
    compilation during it under a tenth of the program's own; the persistent cache off, so
    that only the in-memory one can serve it)."""
    from jax import monitoring

    from gearjax.dynamics.sweep import lower_sweep

    counted = eqx.debug.assert_max_traces(simulate, max_traces=1)
    monkeypatch.setattr(sweep_mod, "simulate", counted)
    compiles, on = [], [False]
    monitoring.register_event_duration_secs_listener(
        lambda event, secs, **kw: compiles.append(secs)
        if on[0] and event == "/jax/core/compile/backend_compile_duration" else None)
    speeds = [130.0, 230.0, 330.0, 430.0, 530.0]  # 5 speeds in one chunk: a shape of its own
    was = jax.config.jax_enable_compilation_cache
    jax.config.update("jax_enable_compilation_cache", False)
    try:
        on[0] = True
        lower_sweep(model, speeds, TR, chunk_size=5).compile()
        own, compiles[:] = max(compiles), []
        res = sweep(model, speeds, chunk_size=5, solver=TR)
        on[0] = False
    finally:
        on[0] = False
        jax.config.update("jax_enable_compilation_cache", was)
    assert eqx.debug.get_num_traces(counted) == 1
    assert own > 0.3 and max(compiles, default=0.0) < 0.1 * own, (own, sorted(compiles)[-3:])
    assert np.all(res.solver_ok)


def test_default_chunk_fits_memory(model, monkeypatch, capsys):
    """Without chunk_size a sweep takes as many speeds per call as memory_chunk allows:
    the saved states of one speed are the output grid (samples plus both sides of every
    jump, per measured period; counted here from the model's jumps) times the state size,
    through the legs of the solve."""
    n_jumps = len(np.unique(np.mod(np.asarray(model.jump_thetas), model.period_rad)))
    n_grid = 2 * (128 + 2 * n_jumps)  # n_measured_periods=2, one mesh period
    per_speed = sweep_mod._BYTES_PER_ENTRY * n_grid * model.state_size
    assert sweep_mod.memory_chunk(model, OPTS, budget_bytes=10.5 * per_speed) == 10
    assert sweep_mod.memory_chunk(model, OPTS, budget_bytes=0.5 * per_speed) == 1
    monkeypatch.setattr(sweep_mod, "memory_chunk", lambda *a, **k: 2)
    sweep(model, [120.0, 640.0, 330.0, 880.0, 450.0], progress=TextProgressMeter(), solver=TR)
    assert "chunk 3/3" in capsys.readouterr().err


def test_default_chunk_rule(model, monkeypatch):
    """chunk_size=None (:func:`gearjax.dynamics.sweep.default_chunk_size`): on a CPU 16-64
    speeds per device by the model's size (3D rig, 266 states: 16; sdof: 64), on an
    accelerator all that memory holds; never more than the memory holds; the speeds split
    into equal chunks (less than one padding copy per chunk)."""
    from types import SimpleNamespace

    rule = sweep_mod.default_chunk_size
    rig3d, sdof = SimpleNamespace(state_size=266), SimpleNamespace(state_size=2)
    monkeypatch.setattr(sweep_mod, "memory_chunk", lambda *a, **k: 10_000)
    assert rule(rig3d, 45, 2) == 23 and rule(rig3d, 32, 2) == 32 and rule(rig3d, 33, 2) == 17
    assert rule(sdof, 2000, 2) == 2000 // 16 and rule(sdof, 3, 1) == 3
    assert rule(rig3d, 4500, 1, platform="gpu") == 4500
    for m, n_dev in ((rig3d, 1), (rig3d, 2), (sdof, 2), (SimpleNamespace(state_size=10**6), 4)):
        for n in range(1, 700, 7):
            c = rule(m, n, n_dev)
            k = -(-n // c)
            assert c <= max(16, min(64, 4096 // m.state_size)) * n_dev and k * c - n < k
    # memory: CPU devices share the host's (3 speeds fit: 1 per device of 2), an
    # accelerator has its own
    monkeypatch.setattr(sweep_mod, "memory_chunk", lambda *a, **k: 3)
    assert rule(sdof, 2000, 2) == 2 and rule(sdof, 2000, 1) == 3
    assert rule(rig3d, 4500, 2, platform="gpu") == 6
    monkeypatch.undo()
    # an accelerator's own memory sets its batch (a model whose 4,500 speeds fit in 40 %
    # of 80 GB but not of 10 MB); a CPU's devices ignore it (the host's memory); a device
    # without memory statistics reports None
    per_mb = sweep_mod.memory_chunk(model, budget_bytes=0.4e7)  # speeds in 10 MB
    assert 1 <= per_mb < 4500
    assert rule(model, 4500, 1, platform="gpu", device_bytes=80e9) == 4500
    assert rule(model, 4500, 1, platform="gpu", device_bytes=1e7) == \
        math.ceil(4500 / math.ceil(4500 / per_mb))
    assert rule(model, 2000, 2, device_bytes=1e7) == 2000 // 16
    assert sweep_mod.device_memory_bytes(jax.devices("cpu")[0]) is None


def test_csv_rows_and_progress(model, tmp_path, capsys):
    out = tmp_path / "sweep.csv"
    speeds = [120.0, 640.0, 330.0, 880.0, 450.0]
    # chunk_size 4 and OPTS as in test_repeated_sweeps_trace_once: the same compiled chunk
    res = sweep(model, speeds, chunk_size=4, out_csv=out, progress=TextProgressMeter(), solver=TR)
    err = capsys.readouterr().err
    assert "chunk 1/2" in err and "chunk 2/2" in err and "5/5 done" in err
    # the progress line counts the unconverged speeds so far, as it counts those done
    last = [ln for ln in err.splitlines() if "5/5 done" in ln][-1]
    assert f"{int(np.sum(~res.converged))} not converged" in last
    with open(out, newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert tuple(rows[0].keys()) == CSV_COLUMNS
    assert sorted(float(r["speed_rad_s"]) for r in rows) == sorted(speeds)
    for r in rows:
        i = speeds.index(float(r["speed_rad_s"]))
        assert r["formulation"] == "perturbation"
        assert r["accel_ptp_m_s2"] == ""
        assert float(r["max_mesh_force_N"]) == res.max_mesh_force_N[i]
        assert float(r["dynamic_factor"]) == res.dynamic_factor[i]
        assert r["contact_loss"] == str(bool(res.contact_loss[i]))
        assert r["converged"] == str(bool(res.converged[i]))
    # a second sweep appends rows (header written once)
    sweep(model, [500.0], chunk_size=4, out_csv=out, solver=TR)
    with open(out) as fh:
        lines = fh.read().splitlines()
    assert len(lines) == 1 + 5 + 1 and lines.count(",".join(CSV_COLUMNS)) == 1
    assert all(r["period_multiple"] == ("1" if r["converged"] == "True" else r["period_multiple"])
               for r in rows)
    # a file of another column set (an earlier gearjax's run) is refused, not appended to
    # with its rows read into the wrong columns
    old = tmp_path / "old.csv"
    old.write_text(",".join(CSV_COLUMNS[:-1]) + "\n")
    with pytest.raises(GearjaxError, match="period_multiple.*--overwrite"):
        append_rows(old, CSV_COLUMNS, [{c: "" for c in CSV_COLUMNS}])
    assert old.read_text() == ",".join(CSV_COLUMNS[:-1]) + "\n"


def test_bad_input(model):
    with pytest.raises(SimulationError, match="speeds_rad_s"):
        sweep(model, [100.0, 0.0])
    with pytest.raises(SimulationError, match="speeds_rad_s"):
        sweep(model, [])
    with pytest.raises(SimulationError, match="speeds_rad_s"):
        sweep(model, [100.0, float("nan")])
    with pytest.raises(SimulationError, match="chunk_size=0"):
        sweep(model, [100.0], chunk_size=0)


def test_mapped_batch_equals_the_vmapped_one(model, monkeypatch):
    """A chunk's speeds run one after the other (``jax.lax.map``) on a CPU for 3D models,
    vmapped for the sdof model and on accelerators (:mod:`gearjax.dynamics.batching`).
    Both programs, forced on the sdof model, give the same results in the caller's order
    to the integration tolerance (vmapped arithmetic rounds differently and the adaptive
    steps follow, as in ``test_sharded_equals_unsharded``): rtol 1e-7 of the forces and
    5e-7 of the DTE peak-to-peak where contact holds, 1e-5 where the contact law separates
    the teeth."""
    speeds = [700.0, 90.0, 1200.0, 310.0, 520.0, 860.0, 150.0]
    sw = np.asarray(speeds)
    assert sweep_mod._plan(model, sw, 4, None, TR).fn is sweep_mod._batched  # 2 states
    res = {}
    for mapped, fn in ((True, sweep_mod._sequential), (False, sweep_mod._batched)):
        monkeypatch.setattr(sweep_mod, "sequential_on", lambda platform, n, m=mapped: m)
        assert sweep_mod._plan(model, sw, 4, None, TR).fn is fn
        res[mapped] = sweep(model, speeds, chunk_size=4, solver=TR)
    a, b = res[True], res[False]
    assert a.speed_rad_s.tolist() == b.speed_rad_s.tolist() == speeds
    for f in ("converged", "contact_loss", "solver_ok"):
        assert np.array_equal(getattr(a, f), getattr(b, f)), f
    lost = np.asarray(a.contact_loss, bool)
    assert lost.any() and not lost.all()
    for f in ("max_mesh_force_N", "min_mesh_force_N", "dte_ptp_m"):
        x, y = getattr(a, f), getattr(b, f)
        np.testing.assert_allclose(x[~lost], y[~lost], rtol=5e-7 if f == "dte_ptp_m" else 1e-7,
                                   err_msg=f)
        np.testing.assert_allclose(x[lost], y[lost], rtol=1e-5, err_msg=f)


def test_mapped_chunk_skips_its_padding(model, monkeypatch):
    """Mapped, a chunk's padding slots hold NaN speeds and are not integrated (their step
    count is NaN, not a count), while the real slot next to them is the single-speed
    simulation; a sweep whose last chunk is padded reports only its own speeds."""
    monkeypatch.setattr(sweep_mod, "sequential_on", lambda platform, n: True)
    sw = np.asarray([300.0, 700.0, 500.0])
    plan = sweep_mod._plan(model, sw, 4, None, TR)
    idx, pad, slots = plan.padded_idx, plan.pad, plan.slot_speeds
    assert pad.tolist() == [False, False, False, True] and np.isnan(slots[3])
    assert sorted(idx[~pad].tolist()) == [0, 1, 2]
    out = sweep_mod._sequential(model, jnp.asarray([300.0, np.nan]), TR)
    steps = out[METRIC_FIELDS.index("n_steps")]
    one = eqx.filter_jit(simulate)(model, np.float64(300.0), **OPTS)
    assert steps[0] == int(one.n_steps) and np.isnan(steps[1])
    force = out[METRIC_FIELDS.index("max_mesh_force_N")]
    assert np.isnan(force[1])
    np.testing.assert_allclose(force[0], float(one.max_mesh_force_N), rtol=1e-10)
    res = sweep(model, sw, chunk_size=4, solver=TR)
    assert res.speed_rad_s.tolist() == sw.tolist()
    assert np.all(np.isfinite(res.max_mesh_force_N)) and np.all(res.n_steps > 0)


_SHARDED = textwrap.dedent(
    """
    import json
    import numpy as np
    import jax
    from gearjax import Mesh, baud_velex_pair, table1_relief
    from gearjax.models.torsional import TorsionalModel
    from gearjax.dynamics.sweep import Transient, sweep
    assert len(jax.devices()) == 4, jax.devices()
    m = TorsionalModel.build(Mesh.build(baud_velex_pair(False)), table1_relief("short"),
                             formulation="perturbation")
    speeds = [700.0, 90.0, 1200.0, 310.0, 520.0, 860.0, 150.0]
    kw = dict(n_transient_periods=12, n_measured_periods=2)
    # the same batch per call on one device as on each of the 4 (chunk 5 -> 8 over 4
    # devices: 2 speeds each); even so the shard_map program rounds differently (see the
    # test's docstring for how far the two agree)
    a = sweep(m, speeds, Transient(**kw), chunk_size=2)
    b = sweep(m, speeds, Transient(**kw), devices="all", chunk_size=5)
    fields = ["speed_rad_s", "max_mesh_force_N", "min_mesh_force_N", "dte_ptp_m",
              "convergence", "n_steps"]
    print(json.dumps({f: [np.asarray(getattr(r, f)).tolist() for r in (a, b)] for f in fields}
                     | {"flags": [[np.asarray(getattr(r, f)).tolist() for r in (a, b)]
                                  for f in ("converged", "contact_loss", "solver_ok")]}))
    """
)


def test_sharding_over_cpu_devices_warns_on_a_jaxlib_that_crashed_there(monkeypatch):
    """jaxlib 0.11.2's XLA:CPU segfaulted compiling the 3D sweep sharded over CPU devices
    (docs/limitations.md): such a sweep says so before it compiles; jaxlib 0.10, the
    version measured sound, and a single device stay silent."""
    import warnings

    from gearjax.runtime import xla

    cpu = jax.devices("cpu")[0]
    monkeypatch.setattr(xla, "jaxlib_minor", lambda: (0, 11))
    with pytest.warns(RuntimeWarning, match="segfaulted"):
        xla.warn_sharded_cpu([cpu, cpu])
    monkeypatch.setattr(xla, "jaxlib_minor", lambda: (0, 10))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        xla.warn_sharded_cpu([cpu, cpu])
    assert xla.jaxlib_minor() >= (0, 4)  # the installed one is read


def test_sharded_equals_unsharded():
    """Four fake CPU devices (shard_map over the speed axis, interleaved, padded to a
    multiple of the device count) give the single-device results, in order, to rounding.

    Not bit for bit: the shard_map program is compiled differently from the single-device
    one (the same batch of 2 per call in both), and the last-bit differences can change
    which steps the adaptive control accepts, so the two agree to the integration
    tolerance (rtol 1e-7 of the forces, measured <= 2e-8, and 2e-7 of the DTE peak-to-peak,
    where contact holds) and, where the contact law
    separates the teeth (700 and 860 rad/s), to what the impacts make of that (1e-7 to
    4e-7 of the forces, n_steps within 2 %)."""
    env = dict(os.environ, XLA_FLAGS="--xla_force_host_platform_device_count=4",
               JAX_PLATFORMS="cpu")  # fake CPU devices, also where a GPU is the default
    out = subprocess.run([sys.executable, "-c", _SHARDED], env=env, capture_output=True,
                         text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-3000:]
    data = json.loads(out.stdout.strip().splitlines()[-1])
    a, b = data["speed_rad_s"]
    assert a == b == [700.0, 90.0, 1200.0, 310.0, 520.0, 860.0, 150.0]
    for pair in data["flags"]:
        assert pair[0] == pair[1]
    lost = np.asarray(data["flags"][1][0], bool)
    assert lost.any() and not lost.all()
    for f in ("max_mesh_force_N", "min_mesh_force_N", "dte_ptp_m"):
        a, b = (np.asarray(v) for v in data[f])
        # the DTE peak-to-peak is a difference of two states (~1x the static approach):
        # the step-control tolerance 1e-7 of the state accumulates to a few 1e-7 of it
        # (measured 2e-7 at 520 rad/s, 1.5e-12 m)
        rtol = 5e-7 if f == "dte_ptp_m" else 1e-7
        np.testing.assert_allclose(a[~lost], b[~lost], rtol=rtol, err_msg=f)
        np.testing.assert_allclose(a[lost], b[lost], rtol=1e-5, err_msg=f)
    a, b = (np.asarray(v) for v in data["convergence"])
    # relative changes of extrema between periods: below ~1e-6 they are integration noise
    # (measured 6.2e-7 against 5.9e-7 at 150 rad/s); converged means <= 1e-3
    np.testing.assert_allclose(a, b, rtol=1e-4, atol=1e-7)
    a, b = (np.asarray(v) for v in data["n_steps"])
    np.testing.assert_allclose(a, b, rtol=0.05)


_MULTI_PROCESS = textwrap.dedent(
    """
    import csv, json, os, sys
    pid, port, out = int(sys.argv[1]), sys.argv[2], sys.argv[3]
    import jax
    from gearjax.cli.main import main
    args = ["sweep", "--model", "torsional", "--formulations", "te", "--speeds", "100:1300:7",
            "--chunk", "3", "--json", "--out", out, "--coordinator", f"127.0.0.1:{port}",
            "--num-processes", "2", "--process-id", str(pid)]
    with open(os.devnull, "w") as null:
        sys.stdout, real = null, sys.stdout
        rc = main(args)
        sys.stdout = real
    assert rc == 0, rc
    assert jax.process_count() == 2 and len(jax.devices()) == 4, jax.devices()
    if pid == 0:
        from gearjax.rigs.factory import build_model
        from gearjax.rigs.registry import get_rig
        from gearjax.dynamics.sweep import sweep
        rig = get_rig("baud-velex-spur")
        m = build_model(rig, rig.modifications("short", None, None, "linear", False),
                        model="torsional", formulation="te", damping_ratio=0.1)
        # one speed per call, as each of the 4 devices ran (chunk 3 -> 4 over 4 devices);
        # other batch sizes agree only to the solver tolerance (vectorised arithmetic
        # rounds differently and the adaptive steps follow: 4e-9 in the force here)
        ref = sweep(m, [100.0 + 200.0 * i for i in range(7)], devices=jax.local_devices()[:1],
                    chunk_size=1)
        with open(os.path.join(out, "results.csv")) as fh:
            rows = list(csv.DictReader(fh))
        print(json.dumps({"rows": rows, "ref_speed": ref.speed_rad_s.tolist(),
                          "ref_force": ref.max_mesh_force_N.tolist(),
                          "ref_dte": ref.dte_ptp_m.tolist()}))
    jax.distributed.shutdown()
    """
)


def _free_port():
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.slow  # 31 s (two processes compiling the same program); a non-default path
def test_multi_process_sweep_equals_single_device(tmp_path):
    """``gearjax sweep --coordinator ...`` on two processes with two fake CPU devices each
    (jax.distributed, gloo collectives): the speeds are shared over the 4 devices of both
    processes, process 0 alone writes results.csv, and its rows are exactly the
    single-device sweep of the same model with the same per-device batch (one speed)."""
    port = str(_free_port())
    env = dict(os.environ, XLA_FLAGS="--xla_force_host_platform_device_count=2",
               JAX_PLATFORMS="cpu")  # fake CPU devices, also where a GPU is the default
    procs = [subprocess.Popen([sys.executable, "-c", _MULTI_PROCESS, str(i), port,
                               str(tmp_path / "out")], env=env, stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for i in range(2)]
    outs = [p.communicate(timeout=600) for p in procs]
    for p, (o, e) in zip(procs, outs):
        assert p.returncode == 0, e[-3000:]
    # process 1 prints nothing (gloo's own connection lines aside: its C++ threads write
    # them unsynchronised, so one can arrive split, e.g. "2 is connected to 3 peer ranks.
    # Expected number of connected peer ranks is : 3" without its "[Gloo] Rank" prefix)
    # and no progress
    gloo = lambda ln: "[Gloo]" in ln or "peer ranks" in ln or not ln.strip()  # noqa: E731
    assert [ln for ln in outs[1][0].splitlines() if not gloo(ln)] == []
    assert "[gearjax]" not in outs[1][1]
    data = json.loads(outs[0][0].strip().splitlines()[-1])
    rows = sorted(data["rows"], key=lambda r: float(r["speed_rad_s"]))
    assert [float(r["speed_rad_s"]) for r in rows] == data["ref_speed"]
    assert [float(r["max_mesh_force_N"]) for r in rows] == data["ref_force"]
    assert [float(r["dte_ptp_m"]) for r in rows] == data["ref_dte"]
    assert all(r["formulation"] == "te" for r in rows)


@pytest.mark.slow
def test_3d_slow_mode_transient_is_right_or_flagged():
    """3D spur rig (te, zeta 0.1): a 61.8 rad/s mode, weakly coupled to the mesh, decays by
    only ~0.998 per mesh period at 700 rad/s, far slower than the automatic transient
    waits for. Against the shooting solver (periodic orbit, no transient -- independent of
    the transient): the default start (slow modes on their period mean) gives the dynamic
    factor to 1e-4; the plain quasi-static start (measured error ~1e-3) must then say
    converged=False (the convergence measure extrapolates the slow mode's decay), or be
    right to 1e-4."""
    from gearjax.rigs.registry import get_rig
    from gearjax.dynamics.steady import Shooting, steady_sweep

    model = build_model(baud_velex_rig(False), get_rig("baud-velex-spur").modifications("short"),
                                     formulation="te", damping_ratio=0.1,
                                     max_frequency_hz=6000.0)
    speeds = np.array([700.0, 840.0])
    ref = steady_sweep(model, speeds, Shooting(rtol=1e-10, atol=1e-12))
    assert np.all(ref.converged)
    auto = sweep(model, speeds)
    assert np.all(auto.converged)
    np.testing.assert_allclose(auto.dynamic_factor, ref.dynamic_factor, rtol=0, atol=1e-4)
    np.testing.assert_allclose(auto.dte_ptp_m, ref.dte_ptp_m, rtol=1e-4)
    plain = sweep(model, speeds, Transient(start="initial"))
    err = np.abs(plain.dynamic_factor - ref.dynamic_factor)
    assert np.all((err <= 1e-4) | ~plain.converged), (err, plain.convergence)


def test_method_steady_matches_steady_sweep(tmp_path):
    """sweep with Fallback(Shooting(), Transient()) is steady_sweep (shooting, the speeds it
    does not solve by the transient) with sweep's interface (CSV written)."""
    from gearjax.dynamics.solvers import Fallback
    from gearjax.dynamics.steady import Shooting, steady_sweep

    model = TorsionalModel.build(Mesh.build(baud_velex_pair(False)), table1_relief("short"),
                                 formulation="te", damping_ratio=0.03)
    speeds = np.array([500.0, 300.0])
    out = tmp_path / "r.csv"
    a = sweep(model, speeds, Fallback(Shooting(), Transient()), out_csv=out)
    b = steady_sweep(model, speeds)
    np.testing.assert_array_equal(a.dynamic_factor, b.dynamic_factor)
    np.testing.assert_array_equal(a.mesh_force_orders_N, b.mesh_force_orders_N)
    rows = out.read_text().strip().splitlines()
    assert len(rows) == 3 and rows[0].startswith("speed_rad_s")
    with pytest.raises(SimulationError):
        sweep(model, speeds, "fast")


@pytest.mark.slow  # 35 s; --method harmonic is not the default (the solver itself: test_harmonic)
def test_method_harmonic_keeps_the_linear_orbit_only_where_it_is_the_models(tmp_path):
    """sweep with Fallback(HarmonicBalance(), Transient()) on the sdof te model (damping 0.1, short relief): at the
    speeds where the linear orbit stays compressive it is the model's orbit, so the peak
    force equals the transient sweep's (independent solver: diffrax from the quasi-static
    start, automatic transient) to the transient's accuracy; at the speeds near the tooth
    critical speed where the linear mesh force turns tensile the harmonic result is not
    used: those speeds are solved by the transient (contact law) and equal it.
    The CLI's --method harmonic counts both in summary.json."""
    from gearjax.cli.main import main
    from gearjax.dynamics.harmonic_sweep import HarmonicBalance
    from gearjax.dynamics.solvers import Fallback
    from gearjax.dynamics.sweep import Auto

    model = TorsionalModel.build(Mesh.build(baud_velex_pair(False)), table1_relief("short"),
                                 formulation="te", damping_ratio=0.1)
    speeds = np.array([600.0, 850.0])  # the CLI's below: one compilation serves both
    out = tmp_path / "r.csv"
    h = sweep(model, speeds, Fallback(HarmonicBalance(), Transient()), out_csv=out)
    t = sweep(model, speeds, Transient())
    lost = t.contact_loss
    assert lost.any() and not lost.all()  # both branches of the method are exercised
    np.testing.assert_array_equal(h.solver, np.where(lost, "transient", "harmonic"))
    f_s = float(model.static_force_N)
    assert np.max(np.abs(h.max_mesh_force_N - t.max_mesh_force_N)[~lost]) < 1e-4 * f_s
    # same solver, but a batch of its own: vmapped adaptive steps run in lockstep, so the
    # steps (and the last digits) depend on the batch
    np.testing.assert_allclose(h.max_mesh_force_N[lost], t.max_mesh_force_N[lost], rtol=1e-6)
    # mesh orders (gearjax.dynamics.orders) of the two solvers' orbits agree too (the
    # transient's accuracy, as the peak force), and the fallback speeds are carried over
    # (the batch-dependent last digits, as above, relative to the largest order)
    for f, scale in (("mesh_force_orders_N", f_s), ("dte_orders_m", np.max(t.dte_orders_m))):
        assert np.max(np.abs(getattr(h, f) - getattr(t, f))[~lost]) < 1e-4 * scale, f
        big = np.max(getattr(t, f)[lost])
        np.testing.assert_allclose(getattr(h, f)[lost], getattr(t, f)[lost], atol=1e-6 * big)
    assert np.all(np.isnan(h.accel_orders_m_s2))  # torsional model: no acceleration
    assert np.all(h.converged) and not np.any(h.contact_loss[~lost])
    assert len(out.read_text().strip().splitlines()) == speeds.size + 1
    assert isinstance(Auto().choose(model, 10_000), Transient)  # the sdof transient is cheaper
    ref = TorsionalModel.build(Mesh.build(baud_velex_pair(False)), table1_relief("short"),
                               formulation="reference")
    with pytest.raises(SimulationError, match="formulation"):
        sweep(ref, speeds, Fallback(HarmonicBalance(), Transient()))
    assert main(["sweep", "--model", "torsional", "--formulations", "te", "--speeds",
                 "600:850:2", "--method", "harmonic", "--out", str(tmp_path / "cli"),
                 "--json"]) == 0
    summary = json.loads((tmp_path / "cli" / "summary.json").read_text())
    assert summary["formulations"]["te"]["method"] == {"harmonic": 1, "transient": 1}
