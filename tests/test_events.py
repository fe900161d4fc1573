"""Switching events (gearjax.excitation.events): which of coinciding state changes names an
event, and the Newton iteration that moves it with the design, must not depend on the
rounding of the compiled code (the order in which bisection finds changes a few floats
apart, an iterate landing on the flat side of a kink)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from gearjax.excitation.events import (EV_FIXED, EV_LOADED, EV_NLTE, EV_ZONE2, check_event_roots,
                                       classify_events, moved_event_angles)
from gearjax.gears.mesh import Mesh
from gearjax.gears.modifications import ToothModifications
from gearjax.models import torsional_layout
from gearjax.models.torsional import TorsionalModel
from gearjax.rigs.registry import get_rig


def _codes(nlte_arg, loaded, zone):
    """One code row (layout of events.code) for 2 cells, both inside the path."""
    return np.array([nlte_arg, *loaded, 1, 1, *zone])


def test_coinciding_changes_are_named_by_priority_not_by_order():
    """A cell entering its gear relief zone (zone 0 -> 2) and the NLTE cell that the
    argmin of equal removed materials picks (0 -> 1) change 1e-17 rad apart: the zone event
    names the angle whichever bracket comes first; a loaded-set change outranks NLTE."""
    period, t = 0.25, 0.083
    zone = (_codes(0, (1, 1), (0, 0)), _codes(0, (1, 1), (2, 0)))
    nlte = (_codes(0, (1, 1), (2, 0)), _codes(1, (1, 1), (2, 0)))
    load = (_codes(1, (1, 1), (2, 0)), _codes(1, (0, 1), (2, 0)))

    def named(brackets):  # the event named at t by these brackets, in this order
        hi = np.array([t, t + 1e-17])
        return classify_events([t], hi - 1e-17, hi, np.stack([b[0] for b in brackets]),
                               np.stack([b[1] for b in brackets]), 2, period)

    assert named([nlte, zone]) == named([zone, nlte]) == ((EV_ZONE2,), ((0, 0),))
    assert named([nlte, load]) == named([load, nlte]) == ((EV_LOADED,), ((0, 0),))


def test_newton_on_the_flat_side_of_a_kink_holds():
    """g(theta) = max(theta - 1, 0) (a removed material that starts at a relief zone): from
    the sloped side one Newton step reaches the root 1; from the flat side (g = dg = 0) the
    iterate stays where it is instead of 0/0 = NaN."""
    def switch(kind, a, b, th):
        return jnp.maximum(th - 1.0, 0.0)

    out = np.asarray(moved_event_angles(switch, [1.5, 0.5], [EV_NLTE, EV_NLTE], [(0, 1), (0, 1)]))
    np.testing.assert_array_equal(out, [1.0, 0.5])


def test_build_check_follows_every_newton_step_the_models_take():
    """A concave switching function undefined left of its root (NaN there): from 1e-9 to
    the right of the root the first Newton step overshoots by 1e-12 to the left, still
    within the check's 1e-8 mesh periods, and the second is NaN. The build check runs the
    models' four steps, so it keeps that event fixed with a warning (it ran one step and
    let the NaN reach the model); a plain root passes unchanged."""
    def switch(kind, a, b, th):
        u = th - 1.0
        return u - 1e6 * u**2 + 0.0 * jnp.sqrt(u)  # NaN, and NaN slope, for u < 0

    s = [1.0 + 1e-9]
    with pytest.warns(RuntimeWarning, match="kept at their build angles"):
        kinds, cells = check_event_roots(switch, s, [EV_NLTE], [(0, 1)], 1.0)
    assert kinds == [EV_FIXED] and cells == [(0, 0)]
    plain = lambda kind, a, b, th: th - 1.0  # noqa: E731
    assert check_event_roots(plain, [1.0], [EV_NLTE], [(0, 1)], 1.0) == ([EV_NLTE], [(0, 1)])


@pytest.fixture
def xla_optimised():
    """XLA's optimisations on (the users' compile; the suite's conftest turns them off),
    restored afterwards: the two round the quasi-static codes differently."""
    before = jax.config.read("jax_disable_most_optimizations")
    jax.config.update("jax_disable_most_optimizations", False)
    yield
    jax.config.update("jax_disable_most_optimizations", before)


def test_sdof_build_names_the_same_events_whatever_the_bracket_order(monkeypatch, xla_optimised):
    """Tip relief 13.3 um over 0.2 of the path (iso6336 stiffness, Baud-Velex spur): at
    0.0832 rad a cell enters its gear relief zone and the NLTE cell (the argmin of equal
    removed materials) changes with it. Built with the brackets handed to the
    classification in the order found and reversed, the model names the same events, the
    zone start, and its structure flag holds at its own design. Before, the first bracket
    named the event: with XLA's optimisations the NLTE change (2 on the old code); under
    XLA:CPU's legacy emitters without optimisations its Newton iteration gave NaN, the
    flag was False at the build design and every sweep refused the freshly built model."""
    mesh = Mesh.build(get_rig("baud-velex-spur").pair, "iso6336")
    mods = ToothModifications.tip_relief(13.3e-6, 0.2)

    def build():
        return TorsionalModel.build(mesh, mods, formulation="te", damping_ratio=0.03)

    found = build()

    def reversed_order(angles, lo, hi, c_lo, c_hi, n_cells, period):
        return classify_events(angles, lo[::-1], hi[::-1], c_lo[::-1], c_hi[::-1], n_cells, period)

    monkeypatch.setattr(torsional_layout, "classify_events", reversed_order)
    flipped = build()
    for m in (found, flipped):
        j = int(np.argmin(np.abs(np.asarray(m.jump_thetas) - 0.08316)))
        assert abs(m.jump_thetas[j] - 0.08316) < 1e-4
        assert m.jump_kinds[j] == EV_ZONE2, m.jump_kinds
        assert bool(m.structure_ok) and bool(m.with_modifications(mods).structure_ok)
        assert np.all(np.isfinite(np.asarray(m.jump_angles_rad())))
    assert (flipped.jump_kinds, flipped.jump_cells) == (found.jump_kinds, found.jump_cells)
