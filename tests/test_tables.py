"""The periodic Hermite table (gearjax.excitation.tables) against a closed form: a
trigonometric signal tabulated at its exact values and slopes, padded as the models pad
their tables, read where the fold of the angle into the period rounds."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from gearjax.excitation.tables import PeriodicHermiteTable

PERIOD, ORIGIN, N_CELLS, PAD, PHASE = 0.25, 0.13, 16, 3, 0.7
NU = 2 * np.pi / PERIOD


def _signal(theta, order: int = 0):
    """The ``order``-th derivative of cos(nu (theta - origin) + phase) (closed form)."""
    return NU**order * np.cos(NU * (theta - ORIGIN) + PHASE + order * np.pi / 2)


def _table():
    knots, cell_first, max_extra = PeriodicHermiteTable.layout(ORIGIN, PERIOD, N_CELLS, [])
    # padded as the models pad: knots beyond the last repeat it (zero-width segments)
    knots = np.concatenate([knots, np.full(PAD, knots[-1])])
    v, d = _signal(knots), _signal(knots, 1)
    return PeriodicHermiteTable(knots=jnp.asarray(knots), values=jnp.asarray(v)[:, None],
                                slopes=jnp.asarray(d)[:, None], cell_first=jnp.asarray(cell_first),
                                origin=ORIGIN, period=PERIOD, n_cells=N_CELLS,
                                max_extra=max_extra + PAD)


def test_padded_table_reads_the_signal_and_its_derivatives_at_the_period_fold():
    """At angles just below a whole number of periods from the origin (where ``mod``
    rounds the fold up to the period itself, onto the padding knots) and at knots, the
    table's value, first and second derivatives (forward mode) are finite and those of the
    signal (to the interpolation error of 16 cells: the second derivative of a cubic
    Hermite segment is O(h^2)); the fold has derivative 1."""
    table = _table()

    def derivs(theta):
        f = lambda t: table(t)[0][0]  # noqa: E731
        d1 = lambda t: jax.jvp(f, (t,), (jnp.ones_like(t),))  # noqa: E731
        (v, s), (_, s2) = jax.jvp(d1, (theta,), (jnp.ones_like(theta),))
        return jnp.stack([v, s, s2])

    below = np.nextafter(ORIGIN, -np.inf)  # the float below the origin
    thetas = [below, np.nextafter(below, -np.inf), ORIGIN + PERIOD, ORIGIN - 2 * PERIOD, ORIGIN]
    folded = float(table.origin + jnp.mod(jnp.asarray(below) - table.origin, PERIOD))
    assert folded == ORIGIN + PERIOD  # the rounding this test is about does happen
    knot = float(table.knots[5])
    for t in thetas + [knot]:
        out = np.asarray(jax.jit(derivs)(jnp.asarray(t)))
        assert np.all(np.isfinite(out)), (t, out)
        expect = [_signal(t, k) for k in range(3)]
        np.testing.assert_allclose(out[:2], expect[:2], rtol=1e-12, atol=1e-9 * NU)
        # a cubic Hermite segment's second derivative is off by ~ h^2 f'''' / 12: 1.3e-2 nu^2
        np.testing.assert_allclose(out[2], expect[2], atol=2e-2 * NU**2)
        assert float(jax.grad(table.wrap)(jnp.asarray(t))) == 1.0
    # elsewhere the table is the signal to O(h^4)
    th = ORIGIN + np.linspace(0, PERIOD, 97)[:-1]
    vals = np.asarray(jax.vmap(lambda t: table(t)[0][0])(jnp.asarray(th)))
    np.testing.assert_allclose(vals, _signal(th), atol=1e-4)
