"""Periodic excitation tables and the simulation-angle map shared by the gear models.

:class:`PeriodicHermiteTable` stores speed-independent excitations (quasi-static
transmission error, loaded mesh stiffness, NLTE; paper Eqs. (9), (17)-(19)) over one
excitation period as cubic Hermite data with extra knots on both sides of every jump, so
jumps and kinks are reproduced exactly. :class:`AngleMap` is the periodic C^1 change of the
independent variable ``theta = phi(s)`` that pins the design-dependent switching angles at
fixed simulation angles ``s_j`` (see :mod:`gearjax.excitation.events`). Angles in rad.

Both gear models fill their tables the same way: :func:`one_sided_samples` (the values and
slopes at the knots, each knot of a jump read on its own side) and :func:`keeps_structure`
(whether a design keeps the build's discrete quasi-static state at every mapped knot).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

__all__ = ["PeriodicHermiteTable", "AngleMap", "hermite_segment", "one_sided_samples",
           "keeps_structure"]

_COMPARE_ALL_NODES = 64  # AngleMap nodes up to which its segment is found by comparisons


def hermite_segment(v0, v1, d0, d1, u, w):
    """(value, d/dtheta) of the cubic Hermite segment of width ``w`` (rad) with end values
    ``v0, v1`` and end slopes times the width ``d0, d1``, at the fraction ``u`` in [0, 1]
    of the segment (NumPy or JAX arrays, broadcast)."""
    u2, u3 = u * u, u * u * u
    val = (2 * u3 - 3 * u2 + 1) * v0 + (u3 - 2 * u2 + u) * d0 + (-2 * u3 + 3 * u2) * v1 + (u3 - u2) * d1
    der = ((6 * u2 - 6 * u) * v0 + (3 * u2 - 4 * u + 1) * d0 + (-6 * u2 + 6 * u) * v1 + (3 * u2 - 2 * u) * d1) / w
    return val, der


class PeriodicHermiteTable(eqx.Module):
    """Piecewise cubic Hermite interpolation of periodic signals with known jumps.

    Knots cover ``[origin, origin + period]``: a uniform grid of ``n_cells`` intervals plus
    extra knots (e.g. the two floating-point neighbours of a jump). Values and slopes are
    given at every knot, so jumps and kinks placed between two adjacent extra knots are
    reproduced exactly. Lookup is O(1): the uniform cell gives the first knot, at most
    ``max_extra`` comparisons give the segment. With the exact quasi-static values and
    slopes (forward-mode AD) at the knots, the interpolant is exact at the jumps of the
    loaded stiffness and at the kinks of ``TE_S`` and NLTE (no smearing), exact for the
    piecewise linear/quadratic NLTE of linear/parabolic reliefs, and O(h^4) elsewhere.

    Attributes
    ----------
    knots : (K,) sorted angles (rad), ``knots[0] = origin``, ``knots[-1] = origin + period``.
    values, slopes : (K, q) signal values and d/dtheta at the knots.
    cell_first : (n_cells,) index of the uniform knot opening each cell.
    origin : () the first knot (rad), data (it moves with the design's jumps).
    period, n_cells, max_extra : static layout (``max_extra`` a bound: knots beyond the
        last real one repeat it, zero-width segments that no lookup selects).
    """

    knots: jax.Array
    values: jax.Array
    slopes: jax.Array
    cell_first: jax.Array
    origin: jax.Array = eqx.field(converter=jnp.asarray)
    period: float = eqx.field(static=True)
    n_cells: int = eqx.field(static=True)
    max_extra: int = eqx.field(static=True)

    @staticmethod
    def layout(origin: float, period: float, n_cells: int, extra) -> tuple[np.ndarray, np.ndarray, int]:
        """Knots (uniform grid + ``extra`` folded into the period), first knot per cell,
        and the largest number of extra knots in a cell (NumPy, build time)."""
        grid = origin + np.arange(n_cells + 1) * (period / n_cells)
        grid[-1] = origin + period
        extra = np.asarray(extra, dtype=float).reshape(-1)
        extra = extra[(extra > origin) & (extra < origin + period)]
        knots = np.unique(np.concatenate([grid, extra]))
        cell_first = np.searchsorted(knots, grid[:-1], side="left")
        counts = np.diff(np.concatenate([cell_first, [len(knots) - 1]])) - 1
        return knots, cell_first, int(max(1, counts.max()))

    def wrap(self, theta):
        """theta folded into [origin, origin + period), derivative 1: ``mod`` of a
        difference a little below a multiple of the period rounds up to the period itself,
        which is folded back (the padding knots repeat ``origin + period``, and a lookup
        there would pick a zero-width segment, whose second derivative is 0 / 0)."""
        s = self.origin + jnp.mod(theta - self.origin, self.period)
        return jnp.where(s < self.origin + self.period, s, s - self.period)

    def __call__(self, theta):
        """(values (q,), slopes (q,)) at ``theta`` (rad)."""
        s = self.wrap(theta)
        h = self.period / self.n_cells
        i = jnp.clip(jnp.floor((s - self.origin) / h).astype(jnp.int32), 0, self.n_cells - 1)
        j0 = self.cell_first[i]
        last = self.knots.shape[0] - 2
        cand = jnp.minimum(j0 + 1 + jnp.arange(self.max_extra), last + 1)
        j = jnp.minimum(j0 + jnp.sum(self.knots[cand] <= s), last)
        t0, t1 = self.knots[j], self.knots[j + 1]
        w = jnp.maximum(t1 - t0, 1e-300)
        u = (s - t0) / w  # clipped to [0, 1] in value alone: d/ds stays 1/w at the knots
        u = u + jax.lax.stop_gradient(jnp.clip(u, 0.0, 1.0) - u)
        return hermite_segment(self.values[j], self.values[j + 1], self.slopes[j] * w,
                               self.slopes[j + 1] * w, u, w)

    def mean(self):
        """Exact mean over one period of the Hermite interpolant, (q,)."""
        w = jnp.diff(self.knots)[:, None]
        v, d = self.values, self.slopes
        seg = w * (v[:-1] + v[1:]) / 2 + w * w * (d[:-1] - d[1:]) / 12
        return jnp.sum(seg, axis=0) / self.period


class AngleMap(eqx.Module):
    """Periodic C^1 map ``theta = phi(s) = s + H(s)`` from the simulation angle s (rad) to
    the pinion angle theta (rad) that sends the build-time switching angles ``s_j`` to the
    current ones ``theta_j = s_j + Delta_j`` (``H`` is the cubic Hermite interpolant of the
    ``Delta_j`` with zero slopes at the nodes, so ``phi' = 1`` there and is continuous).

    Attributes
    ----------
    nodes : (n + 2,) the ``s_j`` in [0, period), extended by one node on each side.
    deltas : (n + 2,) the ``Delta_j`` (rad) at those nodes.
    period : the period (rad), ``phi(s + period) = phi(s) + period``.
    """

    nodes: jax.Array
    deltas: jax.Array
    period: float = eqx.field(static=True)

    @classmethod
    def through(cls, s_j, theta_j, period: float) -> "AngleMap":
        """The map sending the sorted build angles ``s_j`` (in [0, period)) to
        ``theta_j``."""
        s_j = jnp.asarray(s_j, dtype=float)  # traced where the build angles are data
        d = theta_j - s_j
        nodes = jnp.concatenate([s_j[-1:] - period, s_j, s_j[:1] + period])
        return cls(nodes=nodes, deltas=jnp.concatenate([d[-1:], d, d[:1]]), period=period)

    def __call__(self, s):
        """(theta, dtheta/ds) at the simulation angle ``s``."""
        k = jnp.floor(s / self.period)
        sm = s - k * self.period
        # the segment by one vectorised comparison (a binary search's loop costs more than
        # the few dozen nodes of a spur mesh; helical meshes have hundreds)
        method = "compare_all" if self.nodes.shape[0] <= _COMPARE_ALL_NODES else "scan"
        i = jnp.clip(jnp.searchsorted(self.nodes, sm, side="right", method=method) - 1, 0,
                     self.nodes.shape[0] - 2)
        s0, s1 = self.nodes[i], self.nodes[i + 1]
        w = s1 - s0
        u = (sm - s0) / w
        d0, d1 = self.deltas[i], self.deltas[i + 1]
        h = d0 + (d1 - d0) * (u * u * (3.0 - 2.0 * u))
        dh = (d1 - d0) * 6.0 * u * (1.0 - u) / w
        return s + h, 1.0 + dh


def one_sided_samples(q, knots, side, period: float, angle_map: AngleMap | None = None):
    """Values and slopes (d/ds) at the table ``knots`` of ``s -> q(phi(s) + side delta,
    phi'(s))``, each taken back to its knot along its own slope (``delta = 1e-9 period``):
    the two knots bracketing a jump (``side`` -1 and +1, 0 for a uniform knot) are read on
    their own side of it, so the Hermite table reproduces the jump exactly between them.
    Slopes by forward-mode AD (exact, the kinks included). ``q(theta, dtheta_ds)`` returns
    the excitation vector at the pinion angle ``theta`` (rad); ``angle_map`` None: phi the
    identity (``dtheta_ds`` 1). Traceable (differentiable in what ``q`` closes over).

    Returns ``(values (n, m), slopes (n, m))``."""
    delta = 1e-9 * period
    if angle_map is None:
        def one(t, sd):
            v, d = jax.jvp(lambda th: q(th, 1.0), (t + sd * delta,), (jnp.ones_like(t),))
            return v - sd * delta * d, d  # back to the knot
    else:
        def one(t, sd):
            def f(s):
                th, dth = angle_map(s)
                return q(th + sd * delta, dth)

            v, d = jax.jvp(f, (t,), (jnp.ones_like(t),))
            return v - sd * delta * d / angle_map(t)[1], d  # back to the knot
    return jax.vmap(one)(knots, side)


def keeps_structure(code, knots, side, period: float, table_codes,
                    angle_map: AngleMap | None = None):
    """Whether the design keeps the build's discrete quasi-static state on each side of
    every knot (traced bool): the codes ``code(theta)`` (an int vector at the pinion angle
    ``theta``, :func:`gearjax.excitation.events.code`) at the mapped knots, read on their
    side as :func:`one_sided_samples` reads them, equal the build's ``table_codes``. Where
    they do not, the angle map is not valid for this design (the model must be rebuilt)."""
    at = (jax.vmap(angle_map)(knots)[0] if angle_map is not None else knots) + side * (
        1e-9 * period)
    return jnp.all(jax.vmap(code)(at) == table_codes)
