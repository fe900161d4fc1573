"""Harris maps: an objective over a grid of shared reliefs, refined around its minima
(:func:`harris_map`), and the classic Harris curves, TE_S peak-to-peak against torque
(:func:`harris_curves`)."""

from __future__ import annotations

import dataclasses
import time

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..errors import DesignError
from ..gears.mesh import Mesh
from ..gears.quasistatic import quasi_static, static_mesh_force

__all__ = ["HarrisMap", "MapPatch", "harris_map", "harris_curves"]


@dataclasses.dataclass
class MapPatch:
    """A refined sub-grid of a :class:`HarrisMap`: ``amplitudes_m`` (na,), ``extents``
    (ne,), ``smooth`` and ``exact`` (na, ne), refinement ``level`` (1, 2, ...)."""

    amplitudes_m: np.ndarray
    extents: np.ndarray
    smooth: np.ndarray
    exact: np.ndarray
    level: int


@dataclasses.dataclass
class HarrisMap:
    """Objective over a grid of (amplitude, extent) of a shared relief, with refined
    patches around its best points (:func:`harris_map`).

    Attributes: ``amplitudes_m`` (na,), ``extents`` (ne,), ``smooth`` and ``exact``
    (na, ne) on the grid, ``objective`` (name), ``wall_time_s``, ``patches`` (a list of
    :class:`MapPatch`, coarsest first).
    """

    amplitudes_m: np.ndarray
    extents: np.ndarray
    smooth: np.ndarray
    exact: np.ndarray
    objective: str
    wall_time_s: float
    patches: list = dataclasses.field(default_factory=list)

    def _levels(self):
        """(amplitudes, extents, exact) of the grid and of every patch, finest first."""
        lv = [(p.amplitudes_m, p.extents, p.exact) for p in self.patches]
        return lv[::-1] + [(self.amplitudes_m, self.extents, self.exact)]

    def value_at(self, x) -> float:
        """The exact objective at the design ``x = (amplitude_m, extent)`` read from the
        map: its evaluated value where ``x`` is a point of the grid or of a patch (finite
        there), else bilinear interpolation on the finest patch (else the grid) that holds
        ``x`` with finite values at its cell's corners; NaN outside the map."""
        a, e = float(x[0]), float(x[1])
        levels = self._levels()
        for amps, exts, val in levels:
            i, j = np.nonzero(amps == a)[0], np.nonzero(exts == e)[0]
            if i.size and j.size and np.isfinite(val[i[0], j[0]]):
                return float(val[i[0], j[0]])
        for amps, exts, val in levels:
            if not (amps[0] <= a <= amps[-1] and exts[0] <= e <= exts[-1]):
                continue
            i = int(np.clip(np.searchsorted(amps, a) - 1, 0, amps.size - 2))
            j = int(np.clip(np.searchsorted(exts, e) - 1, 0, exts.size - 2))
            corners = val[i:i + 2, j:j + 2]
            if corners.shape != (2, 2) or not np.all(np.isfinite(corners)):
                continue
            u = (a - amps[i]) / (amps[i + 1] - amps[i])
            v = (e - exts[j]) / (exts[j + 1] - exts[j])
            return float((1 - u) * (1 - v) * corners[0, 0] + u * (1 - v) * corners[1, 0]
                         + (1 - u) * v * corners[0, 1] + u * v * corners[1, 1])
        return float("nan")

    def best(self) -> tuple[np.ndarray, float]:
        """The evaluated design of the lowest exact value (grid and patches) and that
        value."""
        best_x, best_v = None, np.inf
        for amps, exts, val in self._levels():
            if np.all(~np.isfinite(val)):
                continue
            i, j = np.unravel_index(np.nanargmin(val), val.shape)
            if val[i, j] < best_v:
                best_x, best_v = np.array([amps[i], exts[j]]), float(val[i, j])
        return best_x, best_v


def harris_map(objective, amplitudes_m, extents, *, refine: int = 0, around=(),
               n_best: int = 2, patch: int = 5) -> HarrisMap:
    """The objective over the grid ``amplitudes_m x extents`` (shared relief), computed by
    the objective's ``grid`` (one compiled program for the whole map), then refined
    ``refine`` times: around
    the designs ``around`` (e.g. an optimiser's optima, best first) and the ``n_best`` best
    points evaluated so far, a ``patch x patch`` sub-grid spanning the neighbouring cells
    of the last level (in calls of the grid's size; each level's spacing ``2 / (patch -
    1)`` of the one before), so that the map resolves
    the valleys where the objective's minimum lies (:meth:`HarrisMap.value_at` reads the
    finest level, an evaluated design its own value). A centre within half the new
    spacing of one taken before it (``around`` first, in order) takes no patch of its own:
    it lies well inside that one's, whose values would be nearly the same designs'.

    Raises
    ------
    DesignError
        for a space other than a shared relief, grid points outside its bounds, or bad
        refinement settings."""
    if objective.space.size != 2:
        raise DesignError("space", objective.space.names, "a Harris map needs a shared relief")
    if int(refine) < 0 or int(patch) < 3 or int(n_best) < 1:
        raise DesignError("refine", (refine, patch, n_best), "need refine >= 0, patch >= 3 "
                          "and n_best >= 1")
    a = np.asarray(amplitudes_m, dtype=float)
    e = np.asarray(extents, dtype=float)
    xs = np.stack(np.meshgrid(a, e, indexing="ij"), -1).reshape(-1, 2)
    for x in xs:
        objective.space.check(x, "grid point")
    around = [objective.space.check(x, "around") for x in around]
    t0 = time.perf_counter()
    sm, ex = objective.grid(xs)
    hmap = HarrisMap(a, e, sm.reshape(a.size, e.size), ex.reshape(a.size, e.size),
                     objective.kind, 0.0)
    lo, hi = objective.space.lower, objective.space.upper
    da = (a[-1] - a[0]) / max(a.size - 1, 1)
    de = (e[-1] - e[0]) / max(e.size - 1, 1)
    u = np.linspace(-1.0, 1.0, int(patch))
    for level in range(1, int(refine) + 1):
        centres = _distinct(list(around) + _best_points(hmap, int(n_best)),
                            da / (patch - 1), de / (patch - 1))
        grids = []
        for c in centres:
            pa = np.unique(np.clip(c[0] + da * u, lo[0], hi[0]))
            pe = np.unique(np.clip(c[1] + de * u, lo[1], hi[1]))
            grids.append((np.resize(pa, patch) if pa.size < patch else pa,
                          np.resize(pe, patch) if pe.size < patch else pe))
        grids = [(np.sort(pa), np.sort(pe)) for pa, pe in grids]
        pts = np.concatenate([np.stack(np.meshgrid(pa, pe, indexing="ij"), -1).reshape(-1, 2)
                              for pa, pe in grids])
        sm, ex = _in_chunks(objective, pts, xs.shape[0])
        n = patch * patch
        for k, (pa, pe) in enumerate(grids):
            s_k = sm[k * n:(k + 1) * n].reshape(patch, patch)
            e_k = ex[k * n:(k + 1) * n].reshape(patch, patch)
            pa_u, ia = np.unique(pa, return_index=True)
            pe_u, ie = np.unique(pe, return_index=True)
            hmap.patches.append(MapPatch(pa_u, pe_u, s_k[np.ix_(ia, ie)], e_k[np.ix_(ia, ie)],
                                         level))
        da, de = da * 2.0 / (patch - 1), de * 2.0 / (patch - 1)
    hmap.wall_time_s = time.perf_counter() - t0
    return hmap


def _in_chunks(objective, pts, size: int):
    """``objective.grid`` over ``pts`` in calls of ``size`` rows (the last padded with its
    last row): every call the one compiled program of the map's grid."""
    n = pts.shape[0]
    m = -(-n // size) * size
    padded = np.concatenate([pts, np.repeat(pts[-1:], m - n, axis=0)])
    out = [objective.grid(padded[i:i + size]) for i in range(0, m, size)]
    return (np.concatenate([o[0] for o in out])[:n], np.concatenate([o[1] for o in out])[:n])


def _distinct(centres: list, half_a: float, half_e: float) -> list:
    """``centres`` without those within ``half_a`` and ``half_e`` (amplitude, extent) of
    one before them."""
    kept = []
    for c in centres:
        if not any(abs(c[0] - k[0]) <= half_a and abs(c[1] - k[1]) <= half_e for k in kept):
            kept.append(c)
    return kept


def _best_points(hmap: HarrisMap, n: int) -> list:
    """The ``n`` evaluated designs of the lowest exact values (distinct)."""
    pts = []
    for amps, exts, val in hmap._levels():
        for i in range(amps.size):
            for j in range(exts.size):
                if np.isfinite(val[i, j]):
                    pts.append((float(val[i, j]), float(amps[i]), float(exts[j])))
    pts = sorted(set(pts))[:n]
    return [np.array([pa, pe]) for _, pa, pe in pts]


def harris_curves(mesh: Mesh, reliefs: dict, torques_Nm, n_positions: int = 256) -> dict:
    """Classic Harris plot data: TE_S peak-to-peak (m) against pinion torque for several
    reliefs (``{name: ToothModifications}``), vmapped over the torques for each relief.
    Returns ``{"torques_Nm": (n,), name: (n,) ...}``."""
    torques = np.asarray(torques_Nm, dtype=float)
    forces = jnp.asarray([static_mesh_force(mesh.pair, t) for t in torques])
    theta = mesh.theta_grid(int(n_positions))
    out = {"torques_Nm": torques}

    @eqx.filter_jit
    def ptp(mods):
        def one(f):
            te = quasi_static(mesh, mods, theta, f).te_s_m
            return jnp.max(te) - jnp.min(te)

        return jax.vmap(one)(forces)

    for name, mods in reliefs.items():
        out[name] = np.asarray(ptp(mods))
    return out
