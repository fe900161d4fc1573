"""Strict numerics for every test: float64 and no silent rank promotion (as diffrax does)."""

import jax

jax.config.update("jax_enable_x64", True)
jax.config.update("jax_numpy_rank_promotion", "raise")


import pytest  # noqa: E402


@pytest.fixture(scope="session")
def torsional_cli_sweep(tmp_path_factory):
    """One ``gearjax sweep --model torsional`` run (te and reference at 40, 370 and 700 rad/s,
    signals at 300 rad/s, JSON summary) shared by tests/test_cli.py and
    tests/test_cli_dynamics.py, which check different parts of its output (the sdof sweep
    compiles and runs once per test worker instead of once per test).

    Returns ``(summary dict, output folder)``."""
    import contextlib
    import io
    import json

    from gearjax.cli.main import main

    out = tmp_path_factory.mktemp("torsional_cli") / "sw"
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        rc = main(["sweep", "--model", "torsional", "--speeds", "40:700:3",
                   "--formulations", "te,reference", "--signals", "300",
                   "--out", str(out), "--json"])
    assert rc == 0
    return json.loads(buf.getvalue()), out
