"""The jump angles of a model as data: :class:`JumpSet`, padded to a static bound.

The right-hand side of a gear model jumps or kinks at speed-independent angles (cells
entering or leaving the path of contact, changes of the quasi-static loaded set, of the
cell realising NLTE, relief-zone starts: paper Eqs. (9), (17)-(19); the vocabulary of
:mod:`gearjax.excitation.events`). How many there are and where they lie depends on the
design (tip relief, pitch errors). A :class:`JumpSet` holds them as arrays of a fixed length
``bound`` (static): the ``count`` valid angles sorted in ``[0, period)``, then padding
entries that repeat the last valid one (angle, kind and cells), so that every consumer
sees a sorted array in which the padding is inert:

* the jump-aware step-size controller (:class:`gearjax.dynamics.integrate.PeriodicJumpController`)
  finds the same next jump in a sorted array with repeated entries;
* the angle map (:class:`gearjax.excitation.tables.AngleMap`) through repeated nodes with
  equal displacements is the same map;
* the output grid, its jump windows and the mesh-order corrections
  (:mod:`gearjax.dynamics.grid`) mask the padding with :attr:`JumpSet.valid`.

So one compiled program serves every design whose jumps fit the bound: a new relief, a new
pitch-error set is new data, not a new program.
"""

from __future__ import annotations

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .events import EV_FIXED

__all__ = ["JumpSet", "round_up", "separated_density"]


def round_up(n: int, step: int = 8) -> int:
    """``n`` rounded up to a multiple of ``step`` (at least ``step``)."""
    return max(step, int(math.ceil(int(n) / step)) * step)


def separated_density(angles, mesh_period: float, period: float) -> float:
    """Separated angles per mesh period: angles closer than 1e-3 of a mesh period count
    once (NumPy, build time)."""
    j = np.sort(np.asarray(angles, dtype=float).reshape(-1))
    if j.size == 0:
        return 0.0
    n = 1 + int(np.sum(np.diff(j) > 1e-3 * mesh_period))
    return n * mesh_period / period


class JumpSet(eqx.Module):
    """Jump angles of a model, padded to a static bound (module docstring).

    Attributes
    ----------
    thetas : (bound,) the ``count`` valid angles (rad) sorted in ``[0, period)``, then the
        last valid one repeated (0.0 when there is none).
    kinds : (bound,) int32 kind of each event (``EV_*`` of :mod:`gearjax.excitation.events`;
        ``EV_FIXED`` for angles that do not move with the design), padding as ``thetas``.
    cells : (bound, 2) int32 cells of each event (see
        :func:`gearjax.excitation.events.switch_value`), padding as ``thetas``.
    count : () int32, the number of valid entries.
    period : the excitation period (rad), static.
    density : separated jumps per mesh period of the angles that do not depend on the
        design (static: it chooses the integrator, :func:`gearjax.dynamics.simulate.
        default_solver`, and must not change with the design).
    """

    thetas: jax.Array
    kinds: jax.Array
    cells: jax.Array
    count: jax.Array
    period: float = eqx.field(static=True)
    density: float = eqx.field(static=True, default=0.0)

    @property
    def bound(self) -> int:
        """The static length of the arrays."""
        return int(self.thetas.shape[-1])

    @property
    def valid(self):
        """(bound,) bool, True at the valid entries."""
        return jnp.arange(self.bound) < self.count

    def distinct(self, rtol: float = 1e-9):
        """(bound,) bool: the entries that count as distinct angles, as
        :func:`gearjax.excitation.events.distinct_angles` merges them (traced): the valid
        ones, less any within ``rtol * period`` of the one before it or, for the last, of
        the first one period on (so the padding, a repeat, never counts)."""
        thj, valid = self.thetas, self.valid
        if self.bound == 0:
            return valid
        tol = rtol * self.period
        close = jnp.concatenate([jnp.zeros(1, bool), jnp.diff(thj) <= tol])
        last = jnp.arange(self.bound) == self.count - 1
        wrap = last & (self.count > 1) & (thj[0] + self.period - thj <= tol)
        return valid & ~close & ~wrap

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_angles(cls, thetas, period: float, kinds=None, cells=None, *,
                    bound: int | None = None, density: float | None = None,
                    mesh_period: float | None = None) -> "JumpSet":
        """A jump set from concrete angles (NumPy, build time): sorted in ``[0, period)``,
        padded to ``bound`` (default: the count). ``kinds``/``cells`` default to fixed
        events; ``density`` defaults to :func:`separated_density` of the angles per
        ``mesh_period`` (default: the period)."""
        th = np.mod(np.asarray(thetas, dtype=float).reshape(-1), float(period))
        order = np.argsort(th, kind="stable")
        th = th[order]
        n = th.size
        k = (np.full(n, EV_FIXED, np.int32) if kinds is None
             else np.asarray(kinds, dtype=np.int32).reshape(-1)[order])
        c = (np.zeros((n, 2), np.int32) if cells is None
             else np.asarray(cells, dtype=np.int32).reshape(-1, 2)[order])
        b = n if bound is None else int(bound)
        if b < n:
            raise ValueError(f"bound={b}: {n} jump angles do not fit")
        if density is None:
            density = separated_density(th, mesh_period or float(period), float(period))
        return cls.padded(jnp.asarray(th), jnp.asarray(k), jnp.asarray(c), jnp.asarray(n),
                          float(period), b, float(density))

    @classmethod
    def padded(cls, thetas, kinds, cells, count, period: float, bound: int,
               density: float = 0.0) -> "JumpSet":
        """The jump set of the first ``count`` entries of ``thetas``/``kinds``/``cells``
        (sorted; traceable, ``count`` may be traced), cut or extended to ``bound`` and
        padded by repeating the last valid entry."""
        thetas = jnp.asarray(thetas, dtype=float)
        kinds = jnp.asarray(kinds, dtype=jnp.int32)
        cells = jnp.asarray(cells, dtype=jnp.int32).reshape(-1, 2)
        n_in = thetas.shape[0]
        count = jnp.asarray(count, dtype=jnp.int32)
        if n_in < bound:
            extra = bound - n_in
            thetas = jnp.concatenate([thetas, jnp.zeros(extra)])
            kinds = jnp.concatenate([kinds, jnp.full(extra, EV_FIXED, jnp.int32)])
            cells = jnp.concatenate([cells, jnp.zeros((extra, 2), jnp.int32)])
        thetas, kinds, cells = thetas[:bound], kinds[:bound], cells[:bound]
        count = jnp.minimum(count, bound)
        idx = jnp.minimum(jnp.arange(bound), jnp.maximum(count - 1, 0))
        has = count > 0
        return cls(thetas=jnp.where(has, thetas[idx], 0.0),
                   kinds=jnp.where(has, kinds[idx], EV_FIXED),
                   cells=jnp.where(has, cells[idx], 0), count=count,
                   period=float(period), density=float(density))

    # ------------------------------------------------------------------ host views
    def _n(self) -> int:
        if isinstance(self.count, jax.core.Tracer):
            raise TypeError("JumpSet: the valid entries of a traced jump set are not known "
                            "on the host; use .thetas with .valid inside traced code")
        return int(self.count)

    def angles(self) -> tuple:
        """The valid angles (rad) as a tuple of floats (concrete jump sets only)."""
        return tuple(float(t) for t in np.asarray(self.thetas)[: self._n()])

    def kind_tuple(self) -> tuple:
        """The valid kinds as a tuple of ints (concrete jump sets only)."""
        return tuple(int(k) for k in np.asarray(self.kinds)[: self._n()])

    def cell_tuple(self) -> tuple:
        """The valid cell pairs as a tuple of ``(int, int)`` (concrete jump sets only)."""
        return tuple((int(a), int(b)) for a, b in np.asarray(self.cells)[: self._n()])
