"""Assembly of the shaft-line structure: the constant matrices M and K.

The :class:`Structure` holds the constant matrices ``M`` and ``K`` of Eq. (14) of
Velex & Ajmi: ``K`` "accounts for everything except the pinion and the gear" (Eq. (12));
the pinion-gear element (``sum_i k_i V(M_i) V(M_i)^T``) is added later by the mesh core
at the dofs of :attr:`Structure.pinion_node` and :attr:`Structure.gear_node`.

Node numbering is 0-based; the dof of node ``n``, local dof ``d`` is ``6 n + d`` with
``d`` in ``(u, v, w, phi, psi, theta)`` (see :mod:`gearjax.structure.beams`).

Everything is NumPy float64, built once outside ``jit``; :meth:`Structure.as_jax`
converts the arrays to ``jax.numpy``.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import Any

import equinox as eqx
import numpy as np
from numpy.typing import ArrayLike, NDArray

from .beams import (
    DOF_NAMES,
    DOFS_PER_NODE,
    STEEL,
    Material,
    bearing_stiffness,
    coupling_stiffness,
    rigid_disc,
    timoshenko_element,
    torsional_spring_to_ground,
)
from ..errors import StructureInputError

__all__ = [
    "ElementRecord",
    "Structure",
    "StructureBuilder",
    "StructureInputError",
]


@dataclasses.dataclass(frozen=True)
class ElementRecord:
    """What was assembled where (metadata only; the numbers live in ``M`` and ``K``).

    Attributes
    ----------
    name : str
        Unique element name.
    kind : str
        One of ``"shaft"``, ``"disc"``, ``"bearing"``, ``"torsional_ground"``,
        ``"coupling"``, ``"stiffness"``.
    nodes : tuple of int
        Nodes (0-based) the element connects.
    params : tuple of (str, float)
        Defining parameters in SI units (e.g. ``("k_s", 1e9)``).
    """

    name: str
    kind: str
    nodes: tuple[int, ...]
    params: tuple[tuple[str, float], ...] = ()

    def param(self, key: str) -> float:
        """Value of parameter ``key``."""
        for k, v in self.params:
            if k == key:
                return v
        raise KeyError(f"element {self.name!r} has no parameter {key!r}")


class Structure(eqx.Module):
    """Shafts, discs, bearings and couplings: constant ``M`` and ``K`` plus metadata.

    Attributes
    ----------
    M, K : ndarray, shape (6 n_nodes, 6 n_nodes)
        Total mass matrix and the stiffness matrix without the pinion-gear element
        (Eqs. (12), (14)); symmetric, float64.
    node_positions_m : ndarray, shape (n_nodes, 3)
        Node positions, columns ``(S, T, z)`` (m). Used by the mesh core for the
        vectors ``O_1 M_i`` and ``O_2 M_i`` of Eq. (8a).
    node_labels : tuple of str
        Human-readable label of each node.
    node_lines : tuple of str
        Shaft line (e.g. ``"pinion"``, ``"gear"``) of each node. Eq. (14) item (ii) needs
        the torsional dofs of the gear shaft line.
    elements : tuple of ElementRecord
        Everything assembled, in order.
    pinion_node, gear_node : int or None
        Nodes at the pinion centre ``O_1`` and gear centre ``O_2``.
    """

    M: NDArray[np.float64]
    K: NDArray[np.float64]
    node_positions_m: NDArray[np.float64]
    node_labels: tuple[str, ...] = eqx.field(static=True)
    node_lines: tuple[str, ...] = eqx.field(static=True)
    elements: tuple[ElementRecord, ...] = eqx.field(static=True)
    pinion_node: int | None = eqx.field(static=True, default=None)
    gear_node: int | None = eqx.field(static=True, default=None)

    @property
    def n_nodes(self) -> int:
        """Number of nodes."""
        return len(self.node_labels)

    @property
    def n_dof(self) -> int:
        """Number of dof, ``6 n_nodes``."""
        return DOFS_PER_NODE * self.n_nodes

    def dof(self, node: int, name: str | int) -> int:
        """Global index of dof ``name`` (``"u"``, ..., ``"theta"`` or 0-5) of ``node``."""
        node = _check_node("node", node, self.n_nodes)
        d = DOF_NAMES.index(name) if isinstance(name, str) else int(name)
        if not 0 <= d < DOFS_PER_NODE:
            raise StructureInputError(f"name must be one of {DOF_NAMES} or 0-5, got {name!r}")
        return DOFS_PER_NODE * node + d

    def node_dofs(self, node: int) -> NDArray[np.int64]:
        """The six global dof of ``node`` in the order ``(u, v, w, phi, psi, theta)``."""
        node = _check_node("node", node, self.n_nodes)
        return DOFS_PER_NODE * node + np.arange(DOFS_PER_NODE)

    def translation_dofs_stz(self, node: int) -> NDArray[np.int64]:
        """Global dof of the translation vector of ``node`` in component order (S, T, z).

        ``X[translation_dofs_stz(n)]`` is ``u^R(O)`` of Eq. (6a) written in (S, T, z).
        """
        return self.node_dofs(node)[[1, 2, 0]]

    def rotation_dofs_stz(self, node: int) -> NDArray[np.int64]:
        """Global dof of the rotation vector of ``node`` in component order (S, T, z).

        ``X[rotation_dofs_stz(n)]`` is ``omega^R`` of Eq. (6a) written in (S, T, z).
        """
        return self.node_dofs(node)[[3, 4, 5]]

    @property
    def torsional_dofs(self) -> NDArray[np.int64]:
        """Global indices of all ``theta`` dofs."""
        return DOFS_PER_NODE * np.arange(self.n_nodes) + 5

    def line_nodes(self, line: str) -> tuple[int, ...]:
        """Nodes of shaft line ``line``."""
        nodes = tuple(i for i, ln in enumerate(self.node_lines) if ln == line)
        if not nodes:
            raise StructureInputError(
                f"line must be one of {sorted(set(self.node_lines))}, got {line!r}"
            )
        return nodes

    def elements_of_kind(self, kind: str) -> tuple[ElementRecord, ...]:
        """All element records of a given kind."""
        return tuple(e for e in self.elements if e.kind == kind)

    def node_position(self, node: int) -> NDArray[np.float64]:
        """Position ``(S, T, z)`` of ``node`` (m)."""
        node = _check_node("node", node, self.n_nodes)
        return np.asarray(self.node_positions_m[node])

    def with_stiffness(
        self, K_extra: ArrayLike, name: str, nodes: Sequence[int] = ()
    ) -> Structure:
        """A copy with ``K + K_extra`` (e.g. an averaged pinion-gear element ``k_m V V^T``).

        ``K_extra`` must be a symmetric ``(n_dof, n_dof)`` matrix.
        """
        Kx = np.asarray(K_extra, dtype=np.float64)
        if Kx.shape != self.K.shape:
            raise StructureInputError(f"K_extra must have shape {self.K.shape}, got {Kx.shape}")
        if not np.allclose(Kx, Kx.T, rtol=1e-12, atol=1e-12 * max(1.0, np.abs(Kx).max())):
            raise StructureInputError("K_extra must be symmetric")
        rec = ElementRecord(name, "stiffness", tuple(int(n) for n in nodes))
        return dataclasses.replace(
            self, K=np.asarray(self.K) + Kx, elements=self.elements + (rec,)
        )

    def as_jax(self) -> Structure:
        """The same structure with ``jax.numpy`` float64 arrays."""
        import jax.numpy as jnp

        return dataclasses.replace(
            self,
            M=jnp.asarray(self.M, dtype=jnp.float64),
            K=jnp.asarray(self.K, dtype=jnp.float64),
            node_positions_m=jnp.asarray(self.node_positions_m, dtype=jnp.float64),
        )


def _check_node(field: str, node: Any, n_nodes: int | None) -> int:
    if isinstance(node, bool) or not isinstance(node, (int, np.integer)):
        raise StructureInputError(f"{field} must be an integer node index, got {node!r}")
    n = int(node)
    if n < 0 or (n_nodes is not None and n >= n_nodes):
        bound = f"[0, {n_nodes - 1}]" if n_nodes is not None else ">= 0"
        raise StructureInputError(f"{field} must be a node index in {bound}, got {node!r}")
    return n


def _check_nonneg(field: str, value: Any) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError) as exc:
        raise StructureInputError(f"{field} must be a real number, got {value!r}") from exc
    if not math.isfinite(x) or x < 0.0:
        raise StructureInputError(f"{field} must be finite and >= 0, got {value!r}")
    return x


class StructureBuilder:
    """Incremental assembly of a :class:`Structure` (pure NumPy, outside ``jit``).

    Every ``add_*`` method returns the builder so calls chain::

        s = (StructureBuilder(n_nodes=3)
             .add_shaft([0, 1, 2], positions_m=[0.0, 0.2, 0.4], outer_diameters_m=0.05)
             .add_bearing(0, k_s=1e9, k_t=1e9, k_axial=1e8)
             .add_bearing(2, k_s=1e9, k_t=1e9)
             .add_disc(1, mass_kg=2.5, transverse_inertia_kg_m2=2e-3, polar_inertia_kg_m2=3e-3)
             .build())

    Parameters
    ----------
    n_nodes : int, optional
        Number of nodes. If given, node indices are range-checked at once; otherwise the
        structure has ``max(index) + 1`` nodes, and every node must be used by some element.
    """

    def __init__(self, n_nodes: int | None = None) -> None:
        if n_nodes is not None:
            if isinstance(n_nodes, bool) or not isinstance(n_nodes, (int, np.integer)):
                raise StructureInputError(f"n_nodes must be a positive integer, got {n_nodes!r}")
            if n_nodes <= 0:
                raise StructureInputError(f"n_nodes must be a positive integer, got {n_nodes!r}")
        self._n_nodes = None if n_nodes is None else int(n_nodes)
        self._blocks: list[tuple[NDArray[np.int64], NDArray[np.float64], str]] = []
        self._elements: list[ElementRecord] = []
        self._labels: dict[int, str] = {}
        self._lines: dict[int, str] = {}
        self._positions: dict[int, NDArray[np.float64]] = {}
        self._pinion: int | None = None
        self._gear: int | None = None

    # ------------------------------------------------------------------ helpers
    def _node(self, field: str, node: Any) -> int:
        return _check_node(field, node, self._n_nodes)

    def _name(self, name: str | None, kind: str) -> str:
        if name is None:
            name = f"{kind}_{sum(e.kind == kind for e in self._elements)}"
        if any(e.name == name for e in self._elements):
            raise StructureInputError(f"name must be unique, got duplicate {name!r}")
        return name

    def _add(self, dofs: NDArray[np.int64], block: NDArray[np.float64], which: str) -> None:
        self._blocks.append((dofs, block, which))

    @staticmethod
    def _dofs(*nodes: int) -> NDArray[np.int64]:
        return np.concatenate([DOFS_PER_NODE * n + np.arange(DOFS_PER_NODE) for n in nodes])

    # --------------------------------------------------------------- elements
    def set_node(
        self,
        node: int,
        *,
        label: str | None = None,
        position_m: Sequence[float] | None = None,
        line: str | None = None,
    ) -> StructureBuilder:
        """Attach a label, a position ``(S, T, z)`` (m) and/or a shaft line to ``node``."""
        n = self._node("node", node)
        if label is not None:
            self._labels[n] = str(label)
        if line is not None:
            self._lines[n] = str(line)
        if position_m is not None:
            p = np.asarray(position_m, dtype=np.float64)
            if p.shape != (3,) or not np.all(np.isfinite(p)):
                raise StructureInputError(
                    f"position_m must be 3 finite numbers (S, T, z), got {position_m!r}"
                )
            self._positions[n] = p
        return self

    def add_shaft(
        self,
        nodes: Sequence[int],
        *,
        positions_m: Sequence[float] | None = None,
        lengths_m: Sequence[float] | None = None,
        start_m: float = 0.0,
        outer_diameters_m: float | Sequence[float],
        inner_diameters_m: float | Sequence[float] = 0.0,
        material: Material = STEEL,
        axis_st_m: tuple[float, float] = (0.0, 0.0),
        line: str | None = None,
        shear_coeff: float | None = None,
        name: str | None = None,
    ) -> StructureBuilder:
        """A chain of Timoshenko elements ``nodes[i] -> nodes[i+1]`` along ``z``.

        Parameters
        ----------
        nodes : sequence of int
            At least two distinct node indices, in order along the shaft.
        positions_m : sequence of float, optional
            Axial coordinate ``z`` of each node (m), strictly increasing.
        lengths_m : sequence of float, optional
            Element lengths (m), all > 0; nodes then sit at ``start_m + cumsum``.
            Exactly one of ``positions_m`` and ``lengths_m`` must be given.
        start_m : float
            ``z`` of the first node when ``lengths_m`` is used (m).
        outer_diameters_m, inner_diameters_m : float or sequence of float
            Per-element diameters (m), scalar for a uniform shaft.
        material : Material
            Shaft material.
        axis_st_m : (float, float)
            ``(S, T)`` coordinates of the shaft axis (m); sets the node positions.
        line : str, optional
            Shaft-line name stored for each node (default: ``name``).
        shear_coeff : float, optional
            Override of the Hutchinson shear coefficient.
        name : str, optional
            Element-name prefix; elements are named ``f"{name}[{i}]"``.
        """
        nodes_t = tuple(self._node(f"nodes[{i}]", n) for i, n in enumerate(nodes))
        if len(nodes_t) < 2:
            raise StructureInputError(f"nodes must list at least 2 nodes, got {list(nodes)!r}")
        if len(set(nodes_t)) != len(nodes_t):
            raise StructureInputError(f"nodes must be distinct, got {list(nodes)!r}")
        n_el = len(nodes_t) - 1
        if (positions_m is None) == (lengths_m is None):
            raise StructureInputError("give exactly one of positions_m and lengths_m")
        if positions_m is not None:
            z = np.asarray(positions_m, dtype=np.float64)
            if z.shape != (len(nodes_t),) or not np.all(np.isfinite(z)):
                raise StructureInputError(
                    f"positions_m must be {len(nodes_t)} finite numbers, got {positions_m!r}"
                )
            lengths = np.diff(z)
            bad = np.flatnonzero(lengths <= 0.0)
            if bad.size:
                i = int(bad[0])
                raise StructureInputError(
                    f"positions_m must be strictly increasing: element {i} has length "
                    f"{lengths[i]!r} m (positions {z[i]!r} -> {z[i + 1]!r})"
                )
        else:
            lengths = np.asarray(lengths_m, dtype=np.float64)
            if lengths.shape != (n_el,):
                raise StructureInputError(
                    f"lengths_m must have {n_el} entries, got {lengths_m!r}"
                )
            bad = np.flatnonzero(~(lengths > 0.0) | ~np.isfinite(lengths))
            if bad.size:
                i = int(bad[0])
                raise StructureInputError(
                    f"lengths_m[{i}] must be finite and > 0, got {lengths[i]!r}"
                )
            z = float(start_m) + np.concatenate([[0.0], np.cumsum(lengths)])

        def per_element(field: str, val: float | Sequence[float]) -> NDArray[np.float64]:
            arr = np.broadcast_to(np.asarray(val, dtype=np.float64), (n_el,)) if np.ndim(
                val
            ) == 0 else np.asarray(val, dtype=np.float64)
            if arr.shape != (n_el,):
                raise StructureInputError(
                    f"{field} must be a scalar or {n_el} values, got {val!r}"
                )
            return arr

        do = per_element("outer_diameters_m", outer_diameters_m)
        di = per_element("inner_diameters_m", inner_diameters_m)
        for i in range(n_el):
            if not (np.isfinite(do[i]) and do[i] > 0.0):
                raise StructureInputError(
                    f"outer_diameters_m[{i}] must be finite and > 0, got {do[i]!r}"
                )
            if not (np.isfinite(di[i]) and 0.0 <= di[i] < do[i]):
                raise StructureInputError(
                    f"inner_diameters_m[{i}] must satisfy 0 <= d < {do[i]!r}, got {di[i]!r}"
                )
        if not isinstance(material, Material):
            raise StructureInputError(f"material must be a Material, got {material!r}")
        prefix = self._name(name, "shaft")
        line_name = prefix if line is None else str(line)
        s0, t0 = (float(a) for a in axis_st_m)
        for i in range(n_el):
            Ke, Me = timoshenko_element(
                float(lengths[i]),
                float(do[i]),
                float(di[i]),
                E=material.E,
                nu=material.nu,
                rho=material.rho,
                shear_coeff=shear_coeff,
            )
            dofs = self._dofs(nodes_t[i], nodes_t[i + 1])
            self._add(dofs, Ke, "K")
            self._add(dofs, Me, "M")
            self._elements.append(
                ElementRecord(
                    f"{prefix}[{i}]",
                    "shaft",
                    (nodes_t[i], nodes_t[i + 1]),
                    (
                        ("length_m", float(lengths[i])),
                        ("outer_diameter_m", float(do[i])),
                        ("inner_diameter_m", float(di[i])),
                    ),
                )
            )
        for n, zi in zip(nodes_t, z):
            self._positions.setdefault(n, np.array([s0, t0, float(zi)]))
            self._lines.setdefault(n, line_name)
        return self

    def add_disc(
        self,
        node: int,
        *,
        mass_kg: float,
        transverse_inertia_kg_m2: float,
        polar_inertia_kg_m2: float,
        name: str | None = None,
    ) -> StructureBuilder:
        """Rigid disc (gear body, coupling hub, rotor) lumped at ``node``; see
        :func:`~gearjax.structure.beams.rigid_disc` and
        :func:`~gearjax.structure.beams.disc_properties`."""
        n = self._node("node", node)
        Md = rigid_disc(mass_kg, transverse_inertia_kg_m2, polar_inertia_kg_m2)
        self._add(self._dofs(n), Md, "M")
        self._elements.append(
            ElementRecord(
                self._name(name, "disc"),
                "disc",
                (n,),
                (
                    ("mass_kg", float(mass_kg)),
                    ("transverse_inertia_kg_m2", float(transverse_inertia_kg_m2)),
                    ("polar_inertia_kg_m2", float(polar_inertia_kg_m2)),
                ),
            )
        )
        return self

    def add_bearing(
        self,
        node: int,
        k_s: float,
        k_t: float,
        k_axial: float = 0.0,
        *,
        k_phi: float = 0.0,
        k_psi: float = 0.0,
        name: str | None = None,
    ) -> StructureBuilder:
        """Bearing between ``node`` and the rigid housing (Table 2): radial ``k_s`` and
        ``k_t`` (N/m), axial ``k_axial`` (N/m), optional tilting ``k_phi``, ``k_psi``
        (N m/rad)."""
        n = self._node("node", node)
        vals = {
            "k_s": _check_nonneg("k_s", k_s),
            "k_t": _check_nonneg("k_t", k_t),
            "k_axial": _check_nonneg("k_axial", k_axial),
            "k_phi": _check_nonneg("k_phi", k_phi),
            "k_psi": _check_nonneg("k_psi", k_psi),
        }
        self._add(self._dofs(n), bearing_stiffness(**vals), "K")
        self._elements.append(
            ElementRecord(self._name(name, "bearing"), "bearing", (n,), tuple(vals.items()))
        )
        return self

    def add_torsional_spring_to_ground(
        self, node: int, k: float, *, name: str | None = None
    ) -> StructureBuilder:
        """Torsional spring ``k`` (N m/rad) from ``theta`` of ``node`` to ground."""
        n = self._node("node", node)
        kv = _check_nonneg("k", k)
        self._add(self._dofs(n), torsional_spring_to_ground(kv), "K")
        self._elements.append(
            ElementRecord(
                self._name(name, "torsional_ground"), "torsional_ground", (n,), (("k", kv),)
            )
        )
        return self

    def add_coupling(
        self,
        n1: int,
        n2: int,
        *,
        k_torsion: float,
        k_radial: float = 0.0,
        k_axial: float = 0.0,
        k_tilt: float = 0.0,
        name: str | None = None,
    ) -> StructureBuilder:
        """Zero-length flexible coupling between ``n1`` and ``n2``; see
        :func:`~gearjax.structure.beams.coupling_stiffness`."""
        a = self._node("n1", n1)
        b = self._node("n2", n2)
        if a == b:
            raise StructureInputError(f"n2 must differ from n1, got n1 = n2 = {a}")
        vals = {
            "k_torsion": _check_nonneg("k_torsion", k_torsion),
            "k_radial": _check_nonneg("k_radial", k_radial),
            "k_axial": _check_nonneg("k_axial", k_axial),
            "k_tilt": _check_nonneg("k_tilt", k_tilt),
        }
        self._add(self._dofs(a, b), coupling_stiffness(**vals), "K")
        self._elements.append(
            ElementRecord(self._name(name, "coupling"), "coupling", (a, b), tuple(vals.items()))
        )
        return self

    def add_torsional_coupling(
        self, n1: int, n2: int, k: float, *, name: str | None = None
    ) -> StructureBuilder:
        """Torsion spring ``k`` (N m/rad) between the ``theta`` dofs of ``n1`` and ``n2``."""
        return self.add_coupling(n1, n2, k_torsion=k, name=name)

    def set_pinion_node(self, node: int) -> StructureBuilder:
        """Declare the pinion centre ``O_1``."""
        self._pinion = self._node("pinion_node", node)
        return self

    def set_gear_node(self, node: int) -> StructureBuilder:
        """Declare the gear centre ``O_2``."""
        self._gear = self._node("gear_node", node)
        return self

    # ------------------------------------------------------------------- build
    def build(self) -> Structure:
        """Assemble ``M`` and ``K`` and check that every node carries some element."""
        used: set[int] = set()
        for e in self._elements:
            used.update(e.nodes)
        used.update(self._labels)
        used.update(self._positions)
        n_nodes = self._n_nodes
        if n_nodes is None:
            if not used:
                raise StructureInputError("the structure is empty: add at least one element")
            n_nodes = max(used) + 1
        on_elements = {n for e in self._elements for n in e.nodes}
        missing = sorted(set(range(n_nodes)) - on_elements)
        if missing:
            raise StructureInputError(
                f"every node must belong to an element; node(s) {missing} have none"
            )
        n_dof = DOFS_PER_NODE * n_nodes
        M = np.zeros((n_dof, n_dof))
        K = np.zeros((n_dof, n_dof))
        for dofs, block, which in self._blocks:
            target = K if which == "K" else M
            target[np.ix_(dofs, dofs)] += block
        # Exact symmetry (assembly only adds symmetric blocks; this removes round-off).
        M = 0.5 * (M + M.T)
        K = 0.5 * (K + K.T)
        pos = np.full((n_nodes, 3), np.nan)
        for n, p in self._positions.items():
            pos[n] = p
        labels = tuple(self._labels.get(n, f"node {n}") for n in range(n_nodes))
        lines = tuple(self._lines.get(n, "") for n in range(n_nodes))
        return Structure(
            M=M,
            K=K,
            node_positions_m=pos,
            node_labels=labels,
            node_lines=lines,
            elements=tuple(self._elements),
            pinion_node=self._pinion,
            gear_node=self._gear,
        )
