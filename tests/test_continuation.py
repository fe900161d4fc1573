"""Up and down sweeps by continuation (gearjax.dynamics.continuation) on the sdof spur rig
(Table 1 short relief, damping 0.03, reference formulation Eq. (16): contact loss near
the tooth critical speed, Fig. 8), checked independently:

* every branch point is a periodic orbit: one period integrated from the returned start
  by a plain diffrax solve (Dopri5, its own step control, no Newton, no monodromy) comes
  back to it;
* the Floquet radius through contact loss against Liouville's formula: the sdof trace of
  df/dy is -2 zeta omega_n / Omega whatever the contact, so with complex multipliers
  rho = exp(-zeta omega_n T) (checks that the monodromy needs no saltation correction);
* in the hysteresis band the up sweep stays on the low orbit and the down sweep on the
  high one (different peak forces, a jump up between the two in the up sweep);
* far from resonance (one orbit) up, down and the independent transient sweep agree.
"""

from __future__ import annotations

import math

import diffrax
import equinox as eqx
import jax.numpy as jnp
import numpy as np
import pytest

from gearjax import table1_relief
from gearjax.dynamics.continuation import (
    branch_jumps,
    continuation_sweep,
    hysteresis_band,
)
from gearjax.dynamics.simulate import SimulationError
from gearjax.dynamics.sweep import sweep
from gearjax.rigs import build_model
from gearjax.rigs.registry import get_rig

# one worker runs both continuation files: they share the corrector's compiled programs
pytestmark = pytest.mark.xdist_group("sdof_continuation")


@pytest.fixture(scope="module")
def model():
    return build_model(get_rig("baud-velex-spur"), table1_relief("short"), model="torsional",
                       formulation="reference", damping_ratio=0.03)


def _period_map(model, omega, y0):
    """y(P) from y(0) = y0 by a plain diffrax solve (jumps of k(theta) as jump_ts); the
    model's jump angles read on the host (its jump set is data in the program)."""
    p = float(model.period_rad)
    jumps = np.asarray(model.jump_thetas, dtype=float)
    return _period_map_jit(model, omega, y0, jnp.asarray(jumps[(jumps > 0) & (jumps < p)]))


@eqx.filter_jit
def _period_map_jit(model, omega, y0, jumps):
    p = float(model.period_rad)
    sol = diffrax.diffeqsolve(
        diffrax.ODETerm(lambda t, y, a: model.vector_field(t, y, a)), diffrax.Dopri5(),
        t0=0.0, t1=p, dt0=None, y0=jnp.asarray(y0), args=jnp.asarray(omega),
        stepsize_controller=diffrax.PIDController(rtol=1e-11, atol=1e-13,
                                                  jump_ts=jnp.asarray(jumps)),
        max_steps=200_000)
    return sol.ys[-1]


def _check_periodic_and_liouville(model, branch):
    omega_n = float(model.natural_frequency_rad_s())
    for w, y0, rho in zip(branch.speed_rad_s, branch.stats["y0"], branch.spectral_radius):
        y_p = np.asarray(_period_map(model, jnp.asarray(w), jnp.asarray(y0)))
        assert np.linalg.norm(y_p - y0) < 1e-7 * np.linalg.norm(y0), (branch.direction, w)
        # complex multipliers at these speeds: |mu| = sqrt(det Phi) = exp(-zeta omega_n T)
        t_period = float(model.period_rad) / w
        assert abs(rho / math.exp(-0.03 * omega_n * t_period) - 1) < 1e-6, (branch.direction, w)


def test_up_and_down_sweeps_differ_in_the_hysteresis_band(model):
    """Near the tooth critical speed (omega_n / z1 = 776 rad/s, softening: the high orbit
    with contact loss leans to lower speeds) the sweeps see different orbits at 615 and
    640 rad/s; the up sweep jumps up between 640 and 665 rad/s. Far below (340 rad/s, one
    orbit) they agree."""
    speeds = np.array([690.0, 615.0, 340.0, 665.0, 640.0])  # any order: the caller's comes back
    up = continuation_sweep(model, speeds, "up")
    down = continuation_sweep(model, speeds, "down")
    np.testing.assert_array_equal(up.speed_rad_s, speeds)
    assert up.stats["stable"].all() and down.stats["stable"].all() and up.converged.all()
    f_s = float(model.static_force_N)
    low, high = (speeds < 650) & (speeds > 600), speeds > 650
    far = speeds == 340.0
    # one orbit far from resonance: the same to the metric solve's rtol 1e-7
    np.testing.assert_allclose(up.max_mesh_force_N[far], down.max_mesh_force_N[far], rtol=1e-6)
    assert not (up.contact_loss[far].any() or down.contact_loss[far].any())
    # up: contact kept below the jump, lost above; down: lost everywhere
    assert not up.contact_loss[low].any() and up.contact_loss[high].all()
    assert down.contact_loss[~far].all()
    assert np.all(down.max_mesh_force_N[low] > 1.8 * up.max_mesh_force_N[low])
    np.testing.assert_allclose(up.max_mesh_force_N[high], down.max_mesh_force_N[high],
                               rtol=1e-6)
    assert np.all(up.max_mesh_force_N > f_s) and np.all(down.max_mesh_force_N > f_s)
    (jump,) = branch_jumps(up, "up")
    assert (jump["from_rad_s"], jump["to_rad_s"]) == (640.0, 665.0) and jump["restarted"]
    # the down sweep's only jump is the step 615 -> 340 rad/s, off the high branch's end
    assert [(j["from_rad_s"], j["to_rad_s"]) for j in branch_jumps(down, "down")] == [(615.0, 340.0)]
    assert hysteresis_band(up, down) == [615.0, 640.0]
    for br in (up, down):
        _check_periodic_and_liouville(model, br)


@pytest.mark.slow  # compiles the transient sweep as well (~15 s on 2 shared cores)
def test_one_orbit_far_from_resonance_agrees_with_the_sweep(model):
    """Well below the critical speed one orbit exists: up, down and the transient sweep
    (diffrax from the quasi-static start, automatic transient) give the same response."""
    speeds = np.array([300.0, 340.0])
    up = continuation_sweep(model, speeds, "up")
    down = continuation_sweep(model, speeds, "down")
    ref = sweep(model, speeds)
    # same orbit (to the Newton tolerance 1e-10), metrics measured by simulate at rtol 1e-7
    np.testing.assert_allclose(up.max_mesh_force_N, down.max_mesh_force_N, rtol=1e-6)
    # the transient's own accuracy (rtol 1e-7, decay 1e-6 of the transient)
    np.testing.assert_allclose(up.max_mesh_force_N, ref.max_mesh_force_N, rtol=1e-5)
    np.testing.assert_allclose(up.dte_ptp_m, ref.dte_ptp_m, rtol=1e-5)
    assert not up.stats["restarted"].any() and not down.stats["restarted"].any()
    assert hysteresis_band(up, down) is None and branch_jumps(up, "up") == []


def test_bad_input(model):
    with pytest.raises(SimulationError, match="direction"):
        continuation_sweep(model, [300.0], "sideways")
    with pytest.raises(SimulationError, match="distinct"):
        continuation_sweep(model, [300.0, 300.0], "up")
    with pytest.raises(SimulationError, match="speeds_rad_s"):
        continuation_sweep(model, [300.0, -1.0], "up")


def test_cli_direction_refuses_what_a_continuation_cannot_do(capsys, tmp_path):
    """One line, before any model is built."""
    from gearjax.cli.main import main

    code = main(["sweep", "--model", "torsional", "--direction", "up", "--resume",
                 "--out", str(tmp_path / "x")])
    err = capsys.readouterr().err
    assert code == 2 and "--direction=up" in err and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1


@pytest.mark.slow  # a CLI continuation (compiles the shooting, ~20 s on 2 shared cores)
def test_cli_direction_both(tmp_path):
    """``gearjax sweep --direction both``: results.csv keeps the default columns first and
    adds the branch columns; summary.json gives the jump up of the up sweep and the
    hysteresis band (the speeds of test_up_and_down_sweeps_differ_in_the_hysteresis_band)."""
    import csv
    import json

    from gearjax.cli.main import main
    from gearjax.dynamics.results import CSV_COLUMNS

    out = tmp_path / "both"
    assert main(["sweep", "--model", "torsional", "--formulations", "reference",
                 "--damping", "0.03", "--speeds", "615:665:3", "--direction", "both",
                 "--out", str(out), "--json"]) == 0
    rows = list(csv.DictReader(open(out / "results.csv")))
    assert tuple(rows[0])[:len(CSV_COLUMNS)] == CSV_COLUMNS
    assert sorted((r["direction"], float(r["speed_rad_s"])) for r in rows
                  if r["orbit"] == "followed") == sorted(
        (d, w) for d in ("up", "down") for w in (615.0, 640.0, 665.0))
    br = json.loads((out / "summary.json").read_text())["formulations"]["reference"]["branches"]
    assert br["jump_up_rad_s"] == [[640.0, 665.0]] and br["jump_down_rad_s"] == []
    assert br["hysteresis_band_rad_s"] == [615.0, 640.0]
    assert (out / "response_curves.png").stat().st_size > 0
    # and the traced curve (gearjax.dynamics.arclength): the low branch's fold between the
    # up sweep's 640 and 665 rad/s, the jump up there, two stable branches and the
    # unstable one between them in branches.csv
    from gearjax.cli.branches import BRANCH_COLUMNS

    traced = br["traced"]
    (fold,) = traced["folds"]
    assert 640.0 < fold["speed_rad_s"] < 665.0 and abs(fold["multiplier"][0] - 1) < 1e-4
    assert traced["jump_up_rad_s"] == [fold["speed_rad_s"]] and traced["jump_down_rad_s"] == []
    rows = list(csv.DictReader(open(out / "branches.csv")))
    assert tuple(rows[0]) == BRANCH_COLUMNS
    stable = {r["branch"]: r["stable"] for r in rows if r["point"] == "regular"}
    assert sorted(stable.values()) == ["False", "True", "True"]
