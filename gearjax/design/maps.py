"""Harris maps: an objective over a grid of shared reliefs (:func:`harris_map`) and the
classic Harris curves, TE_S peak-to-peak against torque (:func:`harris_curves`)."""

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

__all__ = ["HarrisMap", "harris_map", "harris_curves"]


@dataclasses.dataclass
class HarrisMap:
    """Objective over a grid of (amplitude, extent) of a shared relief.

    Attributes: ``amplitudes_m`` (na,), ``extents`` (ne,), ``smooth`` and ``exact``
    (na, ne), ``objective`` (name), ``wall_time_s``.
    """

    amplitudes_m: np.ndarray
    extents: np.ndarray
    smooth: np.ndarray
    exact: np.ndarray
    objective: str
    wall_time_s: float


def harris_map(objective, amplitudes_m, extents) -> HarrisMap:
    """The objective over the grid ``amplitudes_m x extents`` (shared relief), computed by
    the objective's vmapped ``grid`` in one call."""
    if objective.space.size != 2:
        raise DesignError("space", objective.space.names, "a Harris map needs a shared relief")
    a = np.asarray(amplitudes_m, dtype=float)
    e = np.asarray(extents, dtype=float)
    xs = np.stack(np.meshgrid(a, e, indexing="ij"), -1).reshape(-1, 2)
    for x in xs:
        objective.space.check(x, "grid point")
    t0 = time.perf_counter()
    sm, ex = objective.grid(xs)
    return HarrisMap(a, e, sm.reshape(a.size, e.size), ex.reshape(a.size, e.size),
                     objective.kind, time.perf_counter() - t0)


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
