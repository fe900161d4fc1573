"""Programs and models kept between runs (gearjax.dynamics.exported, gearjax.dynamics.stored):
an exported sweep program gives the jitted program's results exactly and a later store
object calls it without tracing the simulation; a store entry whose code, static structure
or bytes changed is never used (a new one is written, the results stay right); a stored
model equals the built one leaf for leaf and is rebuilt when any input changes; the
command line keeps both beside JAX's compilation cache and turns all three off together."""

from __future__ import annotations

import os
import subprocess
import sys

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import gearjax.dynamics.exported as exported_mod
import gearjax.dynamics.stored as stored_mod
import gearjax.dynamics.sweep as sweep_mod
from gearjax import Mesh, baud_velex_pair, table1_relief
from gearjax.dynamics.exported import NoProgramStore, ProgramStore
from gearjax.dynamics.results import METRIC_FIELDS
from gearjax.dynamics.stored import BuildStore, NoBuildStore, Undigestable, digest
from gearjax.dynamics.sweep import Transient, sweep
from gearjax.models.torsional import TorsionalModel
from gearjax.rigs import baud_velex_rig, build_model

TR = Transient(n_transient_periods=12, n_measured_periods=2)
SPEEDS = [900.0, 100.0, 300.0, 500.0, 700.0]  # two chunks of 4, the second padded


@pytest.fixture(scope="module")
def model():
    return TorsionalModel.build(Mesh.build(baud_velex_pair(False)), table1_relief("short"),
                                formulation="perturbation")


@pytest.fixture(scope="module")
def jitted_result(model):
    return sweep(model, SPEEDS, TR, chunk_size=4)


def _count_calls(monkeypatch, module, name: str) -> list:
    """``module.name`` replaced by a wrapper counting its calls; returns ``[count]``."""
    count = [0]
    inner = getattr(module, name)

    def counted(*args, **kwargs):
        count[0] += 1
        return inner(*args, **kwargs)

    monkeypatch.setattr(module, name, counted)
    return count


@pytest.fixture
def traces(monkeypatch):
    """How often the sweep traces :func:`gearjax.dynamics.simulate.simulate`."""
    return _count_calls(monkeypatch, sweep_mod, "simulate")


def _same(a, b):
    for f in METRIC_FIELDS:
        np.testing.assert_array_equal(np.asarray(getattr(a, f)), np.asarray(getattr(b, f)),
                                      err_msg=f)


def _entries(folder):
    return sorted(p for p in os.listdir(folder) if p.endswith(".bin"))


def test_exported_sweep_is_the_jitted_one_and_a_warm_run_does_not_trace(
        model, jitted_result, traces, tmp_path):
    cold = sweep(model, SPEEDS, TR, chunk_size=4, programs=ProgramStore(tmp_path))
    assert traces[0] == 1 and len(_entries(tmp_path)) == 1
    _same(cold, jitted_result)
    store = ProgramStore(tmp_path)
    # the program the command line compiles ahead on a thread is the one the sweep calls
    lowered = sweep_mod.lower_sweep(model, SPEEDS, TR, chunk_size=4, programs=store)
    assert isinstance(lowered, jax.stages.Lowered) and traces[0] == 1
    warm = sweep(model, SPEEDS, TR, chunk_size=4, programs=store)
    assert traces[0] == 1  # loaded, not traced
    _same(warm, jitted_result)
    # new array data of the model (more damping): the same program, still not traced
    damped = TorsionalModel.build(model.mesh, model.mods, formulation="perturbation",
                                  damping_ratio=0.08)
    more = sweep(damped, SPEEDS[:3], TR, chunk_size=4, programs=ProgramStore(tmp_path))
    assert traces[0] == 1 and len(_entries(tmp_path)) == 1
    assert np.all(more.dynamic_factor < warm.dynamic_factor[:3])


def test_stale_or_corrupt_entries_are_never_used(model, jitted_result, traces, tmp_path,
                                                 monkeypatch):
    sweep(model, SPEEDS, TR, chunk_size=4, programs=ProgramStore(tmp_path))
    (first,) = _entries(tmp_path)
    # gearjax's code changed: another key, exported again, the old entry left alone
    with monkeypatch.context() as m:
        m.setattr(exported_mod, "code_digest", lambda: "other code")
        res = sweep(model, SPEEDS, TR, chunk_size=4, programs=ProgramStore(tmp_path))
    _same(res, jitted_result)
    assert traces[0] == 2 and len(_entries(tmp_path)) == 2
    # a corrupt entry: ignored, exported again and overwritten
    path = tmp_path / first
    data = bytearray(path.read_bytes())
    data[-100] ^= 0xFF
    path.write_bytes(bytes(data))
    before = traces[0]
    res = sweep(model, SPEEDS, TR, chunk_size=4, programs=ProgramStore(tmp_path))
    _same(res, jitted_result)
    assert traces[0] == before + 1 and path.read_bytes() != bytes(data)
    # a truncated one, and one whose header names other inputs under this name
    path.write_bytes(path.read_bytes()[:1000])
    res = sweep(model, SPEEDS, TR, chunk_size=4, programs=ProgramStore(tmp_path))
    _same(res, jitted_result)
    assert traces[0] == before + 2


def test_entries_check_their_header(tmp_path):
    inputs = {"function": "f", "code": "c"}
    assert stored_mod.write_entry(tmp_path, inputs, b"payload")
    assert stored_mod.read_entry(tmp_path, inputs) == b"payload"
    other = {"function": "f", "code": "d"}
    # another entry's file under this entry's name: its header gives it away
    os.replace(stored_mod.entry_path(tmp_path, inputs), stored_mod.entry_path(tmp_path, other))
    assert stored_mod.read_entry(tmp_path, other) is None
    assert stored_mod.read_entry(tmp_path / "missing", inputs) is None
    # an unwritable folder: not kept, no error
    blocker = tmp_path / "file"
    blocker.write_text("")
    assert not stored_mod.write_entry(blocker / "sub", inputs, b"x")


class _Out(eqx.Module):
    value: jax.Array
    label: str = eqx.field(static=True)


@eqx.filter_jit
def _scaled(x, factor: float, label: str):
    return _Out(x * factor, label), jnp.sum(x)


def test_static_arguments_and_array_shapes_key_the_program(tmp_path):
    store = ProgramStore(tmp_path)
    x = jnp.arange(3.0)
    out, total = store.call(_scaled, x, 2.0, "a")
    assert out.label == "a" and float(total) == 3.0
    np.testing.assert_array_equal(out.value, [0.0, 2.0, 4.0])
    store.call(_scaled, x, 3.0, "a")  # another static value
    store.call(_scaled, jnp.arange(4.0), 2.0, "a")  # another shape
    store.call(_scaled, x.astype(jnp.int64), 2.0, "a")  # another dtype
    assert len(_entries(tmp_path)) == 4
    again, _ = ProgramStore(tmp_path).call(_scaled, x + 1, 2.0, "a")
    np.testing.assert_array_equal(again.value, [2.0, 4.0, 6.0])
    assert len(_entries(tmp_path)) == 4
    lowered = ProgramStore(tmp_path).lower(_scaled, x, 2.0, "a")
    assert isinstance(lowered, jax.stages.Lowered)


class _Gain(eqx.Module):
    gain: jax.Array
    power: int = eqx.field(static=True)


@eqx.filter_jit
def _apply(g, x):
    return g.gain * x**g.power


def test_a_call_like_an_earlier_one_reuses_its_key(tmp_path, monkeypatch):
    """The arguments are digested once per call signature: the same module object and
    arrays of the same type (a sweep's next chunk) reuse the key; another object, static
    value, scalar or shape is digested and keyed apart (its own entry, its own result)."""
    count = _count_calls(monkeypatch, exported_mod, "digest")
    store = ProgramStore(tmp_path)
    g2, g3 = _Gain(jnp.asarray(2.0), 2), _Gain(jnp.asarray(2.0), 3)
    x = jnp.arange(3.0)
    np.testing.assert_array_equal(store.call(_apply, g2, x), [0.0, 2.0, 8.0])
    np.testing.assert_array_equal(store.call(_apply, g2, x + 1), [2.0, 8.0, 18.0])
    assert count[0] == 1 and len(_entries(tmp_path)) == 1
    np.testing.assert_array_equal(store.call(_apply, g3, x), [0.0, 2.0, 16.0])
    store.call(_apply, g2, jnp.arange(4.0))
    assert count[0] == 3 and len(_entries(tmp_path)) == 3
    store.call(_scaled, x, 2.0, "a")
    store.call(_scaled, x, 3.0, "a")
    store.call(_scaled, x, 3.0, "a")
    assert count[0] == 5 and len(_entries(tmp_path)) == 5


@eqx.filter_jit
def _total(x, scale: float):
    return jnp.sum(x) * scale


def test_values_are_keyed_by_the_content_of_their_arguments(tmp_path, monkeypatch):
    x = jnp.arange(3.0)
    assert float(ProgramStore(tmp_path).value(_total, x, 2.0)) == 6.0
    assert len(_entries(tmp_path)) == 2  # the program and its value

    def no_call(self, jitted, *args):
        raise AssertionError("computed again")

    with monkeypatch.context() as m:
        m.setattr(ProgramStore, "call", no_call)
        assert float(ProgramStore(tmp_path).value(_total, jnp.arange(3.0), 2.0)) == 6.0
    # other content, other static value, other context (XLA flags): computed
    assert float(ProgramStore(tmp_path).value(_total, x + 1, 2.0)) == 12.0
    assert float(ProgramStore(tmp_path).value(_total, x, 3.0)) == 9.0
    assert float(ProgramStore(tmp_path, context="--flag").value(_total, x, 2.0)) == 6.0
    assert len(_entries(tmp_path)) == 2 + 1 + 2 + 1


@pytest.mark.parametrize("against_plain", [False, pytest.param(True, marks=pytest.mark.slow)])
def test_frequency_domain_sweep_through_the_store(tmp_path, monkeypatch, against_plain):
    """The frequency domain's split, plan and batch through a store: a later store
    neither traces the batch nor recomputes the split and plan, and gives the first one's
    results exactly; (slow: another compilation) those of the plain sweep too."""
    import gearjax.dynamics.harmonic_sweep as hs
    from gearjax.dynamics.harmonic_sweep import harmonic_sweep

    model = TorsionalModel.build(Mesh.build(baud_velex_pair(False)), table1_relief("short"),
                                 formulation="te", damping_ratio=0.1)
    opts = dict(harmonics=256, max_harmonics=256, floquet=False)
    cold = harmonic_sweep(model, [310.0, 520.0], programs=ProgramStore(tmp_path), **opts)
    plain = harmonic_sweep(model, [310.0, 520.0], **opts) if against_plain else cold
    traces = [0]
    real = hs.harmonic_steady_states

    def counted(*args, **kwargs):  # runs only while the batch is traced
        traces[0] += 1
        return real(*args, **kwargs)

    monkeypatch.setattr(hs, "harmonic_steady_states", counted)
    warm = harmonic_sweep(model, [310.0, 520.0], programs=ProgramStore(tmp_path), **opts)
    assert traces[0] == 0
    for res in (cold, warm):
        _same(res, plain)
        for k, v in plain.stats.items():
            np.testing.assert_array_equal(res.stats[k], v, err_msg=k)


def test_a_program_with_a_host_callback_runs_as_traced_and_is_not_stored(tmp_path,
                                                                        monkeypatch):
    from equinox import _errors

    monkeypatch.setattr(_errors, "EQX_ON_ERROR", "raise")  # equinox's default: a callback

    @eqx.filter_jit
    def checked(x):
        return eqx.error_if(x, x < 0, "negative") * 2.0

    np.testing.assert_array_equal(ProgramStore(tmp_path).call(checked, jnp.ones(2)), [2.0, 2.0])
    assert _entries(tmp_path) == []
    with pytest.raises(Exception, match="negative"):
        ProgramStore(tmp_path).call(checked, -jnp.ones(2))


def test_digest_is_by_content_and_the_same_in_another_process(model):
    assert digest(model) == digest(TorsionalModel.build(
        Mesh.build(baud_velex_pair(False)), table1_relief("short"), formulation="perturbation"))
    damped = TorsionalModel.build(model.mesh, model.mods, formulation="perturbation",
                                  damping_ratio=0.08)
    assert digest(damped) != digest(model)
    assert digest(damped, arrays="aval") == digest(model, arrays="aval")  # same program
    with pytest.raises(Undigestable):
        digest(object())
    code = ("from gearjax import Mesh, baud_velex_pair, table1_relief\n"
            "from gearjax.models.torsional import TorsionalModel\n"
            "from gearjax.rigs import baud_velex_rig\n"
            "from gearjax.dynamics.stored import digest\n"
            "m = TorsionalModel.build(Mesh.build(baud_velex_pair(False)), table1_relief('short'),"
            " formulation='perturbation')\n"
            "print(digest(m)); print(digest(m, arrays='aval')); print(digest(baud_velex_rig(False)))")
    env = dict(os.environ, PYTHONHASHSEED="123")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         env=env, timeout=300)
    assert run.returncode == 0, run.stderr[-800:]
    # the rig holds functions (its structure and reliefs): digested by their bytecode
    assert run.stdout.split() == [digest(model), digest(model, arrays="aval"),
                                  digest(baud_velex_rig(False))]


_BUILDS = [0]


def _counted_build(*args, **kwargs):
    _BUILDS[0] += 1
    return build_model(*args, **kwargs)


def test_build_store_returns_the_built_model_and_misses_when_an_input_changes(
        tmp_path, monkeypatch):
    rig = baud_velex_rig(False)
    store = BuildStore(tmp_path)
    opts = dict(model="torsional", formulation="te", damping_ratio=0.1)
    built = build_model(rig, table1_relief("short"), **opts)
    n = _BUILDS[0]
    first = store.build(_counted_build, rig, table1_relief("short"), **opts)
    again = BuildStore(tmp_path).build(_counted_build, rig, table1_relief("short"), **opts)
    assert _BUILDS[0] == n + 1 and len(_entries(tmp_path)) == 1
    for got in (first, again):
        a, ta = jax.tree_util.tree_flatten(built)
        b, tb = jax.tree_util.tree_flatten(got)
        assert ta == tb and type(got) is type(built)
        for x, y in zip(a, b):
            assert type(x) is type(y) and np.asarray(x).dtype == np.asarray(y).dtype
            assert getattr(x, "weak_type", None) == getattr(y, "weak_type", None)
            np.testing.assert_array_equal(np.asarray(x), np.asarray(y))
    # each input is in the key: another damping, relief, or code
    store.build(_counted_build, rig, table1_relief("short"), **dict(opts, damping_ratio=0.05))
    store.build(_counted_build, rig, table1_relief("long"), **opts)
    with monkeypatch.context() as m:
        m.setattr(stored_mod, "code_digest", lambda: "other code")
        store.build(_counted_build, rig, table1_relief("short"), **opts)
    assert _BUILDS[0] == n + 4 and len(_entries(tmp_path)) == 4
    # a corrupt entry is rebuilt and overwritten
    for name in _entries(tmp_path):
        (tmp_path / name).write_bytes(b"gearjax-store 1\n{}\n")
    store.build(_counted_build, rig, table1_relief("short"), **opts)
    assert _BUILDS[0] == n + 5
    assert store.build(_counted_build, rig, table1_relief("short"), **opts) is not None
    assert _BUILDS[0] == n + 5


def test_the_stores_sit_beside_the_compilation_cache_and_go_off_with_it(monkeypatch,
                                                                       tmp_path):
    from gearjax import runtime

    monkeypatch.setenv("JAX_COMPILATION_CACHE_DIR", str(tmp_path / "jax"))
    monkeypatch.delenv("GEARJAX_COMPILATION_CACHE", raising=False)
    assert runtime.program_store().folder == str(tmp_path / "jax" / "programs")
    assert runtime.build_store().folder == str(tmp_path / "jax" / "models")
    monkeypatch.setenv("GEARJAX_COMPILATION_CACHE", "0")
    assert runtime.compilation_cache_dir() is None
    assert isinstance(runtime.program_store(), NoProgramStore)
    assert isinstance(runtime.build_store(), NoBuildStore)


def test_command_line_sweep_loads_its_programs_and_models(monkeypatch, tmp_path, capsys):
    """A second ``gearjax sweep`` neither traces its sweep program nor builds its model:
    both come from the stores the first run filled (beside the compilation cache)."""
    from gearjax.cli.main import main

    monkeypatch.setenv("JAX_COMPILATION_CACHE_DIR", str(tmp_path / "jax"))
    monkeypatch.delenv("GEARJAX_COMPILATION_CACHE", raising=False)
    builds = [0]
    inner = TorsionalModel.build

    def counted_build(*args, **kwargs):
        builds[0] += 1
        return inner(*args, **kwargs)

    monkeypatch.setattr(TorsionalModel, "build", counted_build)
    count = [0]
    simulate = sweep_mod.simulate

    def counted_simulate(*args, **kwargs):
        count[0] += 1
        return simulate(*args, **kwargs)

    monkeypatch.setattr(sweep_mod, "simulate", counted_simulate)
    argv = ["sweep", "--model", "torsional", "--formulations", "te", "--speeds", "100:300:3",
            "--json"]
    assert main(argv + ["--out", str(tmp_path / "a")]) == 0
    assert count[0] == 1 and builds[0] == 1
    assert _entries(tmp_path / "jax" / "programs") and _entries(tmp_path / "jax" / "models")
    assert main(argv + ["--out", str(tmp_path / "b")]) == 0
    assert count[0] == 1 and builds[0] == 1  # neither traced nor built again
    a = (tmp_path / "a" / "results.csv").read_text()
    assert a == (tmp_path / "b" / "results.csv").read_text()
    capsys.readouterr()
