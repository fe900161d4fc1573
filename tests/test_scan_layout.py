"""The traced layout shared by the sdof and 3D models (:func:`gearjax.excitation.layout.
scan_layout`) against a state whose changes are known in closed form: a counter of the
thresholds passed (modulo their number: periodic), so every change angle is a given float."""

from __future__ import annotations

import warnings

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from gearjax.excitation.layout import LayoutBounds, scan_layout, warn_unlocated

PERIOD = 1.0
# two changes share one scan interval of 1/16 (found in two bisection rounds)
CHANGES = np.array([0.1234567, 0.41, 0.4100003, 0.77])
FIXED = (0.3,)


def _code_fn(t):
    u = jnp.mod(t, PERIOD)
    passed = jnp.sum(u[:, None] >= jnp.asarray(CHANGES)[None, :], axis=1, keepdims=True)
    return passed % CHANGES.size  # periodic: the state after the last change is the first


def _layout(bounds):
    n = 16
    codes = _code_fn(jnp.arange(n) * (PERIOD / n))
    return jax.jit(lambda c: scan_layout(_code_fn, c, PERIOD, bounds, FIXED))(codes)


def test_changes_are_bracketed_by_adjacent_floats_and_join_the_fixed_angles():
    lay = _layout(LayoutBounds(jumps=8, brackets=8, max_extra=8, intervals=8))
    ch = lay.changes
    found = np.isfinite(np.asarray(ch.hi))
    lo, hi = np.asarray(ch.lo)[found], np.asarray(ch.hi)[found]
    assert found.sum() == CHANGES.size == int(ch.count)
    assert int(ch.n_intervals) == 3  # 0.41 and 0.4100003 in one interval
    np.testing.assert_array_equal(np.nextafter(lo, np.inf), hi)
    # each change lies in its bracket (table coordinates start at the origin)
    got = np.sort(np.mod(hi, PERIOD))
    np.testing.assert_allclose(got, CHANGES, rtol=0, atol=4e-16)
    n = int(lay.n_jumps)
    assert n == CHANGES.size + len(FIXED)
    np.testing.assert_allclose(np.asarray(lay.thetas)[:n], np.sort(np.r_[CHANGES, FIXED]),
                               rtol=0, atol=4e-16)
    # the origin: the middle of the widest gap between the scan angles before a change
    # (0.0625, 0.375, 0.75: the widest gap from 0.375 to 0.75)
    assert float(lay.origin) == pytest.approx(0.375 + 0.5 * 0.375, abs=1e-15)
    # the knots: the uniform grid from the origin and both floats of every bracket, the
    # jump knots read on the side their bracket names
    knots, side = np.asarray(lay.knots), np.asarray(lay.side)
    for a, b in zip(lo, hi):
        assert side[np.flatnonzero(knots == a)[0]] == -1.0
        assert side[np.flatnonzero(knots == b)[0]] == 1.0
    assert np.all(np.diff(knots) >= 0.0)
    assert knots[0] == pytest.approx(float(lay.origin))
    assert knots[-1] == pytest.approx(float(lay.origin) + PERIOD)
    codes = np.asarray(lay.knot_codes(_code_fn, PERIOD))[:, 0]
    for a, b in zip(lo, hi):  # the state before and after each change
        i, j = np.flatnonzero(knots == a)[0], np.flatnonzero(knots == b)[0]
        assert (codes[j] - codes[i]) % CHANGES.size == 1
    need = [int(v) for v in lay.need]
    assert need[:2] == [CHANGES.size + len(FIXED), CHANGES.size] and need[3] == 3


def test_a_design_beyond_its_bounds_says_what_it_needs():
    lay = _layout(LayoutBounds(jumps=2, brackets=2, max_extra=1, intervals=2))
    need = LayoutBounds(*(int(v) for v in lay.need))
    assert need.jumps > 2 and need.brackets > 2 and need.intervals > 2
    grown = LayoutBounds(2, 2, 1, 2).grown(need)
    assert all(g >= k for g, k in zip(grown, need))


def test_unlocated_events_warn_once_and_none_is_silent():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        warn_unlocated(0)
    with pytest.warns(RuntimeWarning, match="2 design-dependent switching angles"):
        warn_unlocated(2)
