"""Value checks of a TOML rig file (:mod:`gearjax.rigs.rigfile`): typed access to one table
(:class:`Reader`, unknown keys rejected with a "did you mean" hint), the physical range of
every number (:data:`RANGES`), node numbers (:class:`Nodes`), arrays of tables, shaft axes and
per-element values. Every failure raises :class:`gearjax.errors.RigError` naming the field
path, the value found and why it is wrong."""

from __future__ import annotations

import difflib
import math
from typing import Any

from ..errors import RigError

__all__ = ["Reader", "Nodes", "REQUIRED", "MIN_ELEMENT_LENGTH_M", "RANGES", "AXIS_KEYS",
           "check_value", "check_range", "table_list", "read_axis", "per_element",
           "show_value", "is_real", "read_backlash"]

REQUIRED = object()
MIN_ELEMENT_LENGTH_M = 1e-4  # shortest shaft element accepted (0.1 mm)


class Reader:
    """Typed access to one TOML table; every error names the full field path."""

    def __init__(self, source: str, path: str, data: Any, allowed: tuple[str, ...]):
        self.source = source
        self.path = path
        if not isinstance(data, dict):
            self.fail(path, data, f"must be a table, got {type(data).__name__}")
        self.data = data
        for key in data:
            if key not in allowed:
                close = difflib.get_close_matches(key, allowed, n=1, cutoff=0.6)
                lower = [a for a in allowed if a.lower() == key.lower()]
                hint = lower or close
                why = f"unknown key; did you mean {hint[0]!r}?" if hint else (
                    f"unknown key; allowed keys are {sorted(allowed)}")
                self.fail(self.sub(key), data[key], why)

    def sub(self, key: str) -> str:
        return f"{self.path}.{key}" if self.path else key

    def fail(self, path: str, value: Any, why: str):
        raise RigError(f"{path}={show_value(value)}: {why} (rig file {self.source})")

    def missing(self, key: str, what: str):
        raise RigError(f"{self.sub(key)}: missing ({what}) (rig file {self.source})")

    def has(self, key: str) -> bool:
        return key in self.data

    def get(self, key: str, kind: str, what: str, default: Any = REQUIRED) -> Any:
        """Value of ``key`` checked as ``kind``: real, nonneg, positive, int, str, table,
        reals (list), ints (list)."""
        if key not in self.data:
            if default is REQUIRED:
                self.missing(key, what)
            return default
        return check_value(self, self.sub(key), self.data[key], kind, what)


def show_value(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


def is_real(x: Any) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)


# Physical ranges of the numbers of a rig file (by key), checked at load: values beyond
# them are typos or unit slips (mm for m), and values far beyond them make the structure's
# modal analysis meaningless (a 1e18 N/m bearing next to a 1e5 N m/rad torsional spring
# puts the soft modes below the round-off of the stiff ones).
# Translational stiffnesses up to 1e16 N/m: "rigid" supports (1e14 N/m) are accepted; above
# 1e16 N/m the structure's highest natural frequencies rise so far above the soft
# torsional modes that float64 eigenvalues lose them (round-off ~1e-16 max(w^2)).
N_PER_M = (0.0, 1e16, "N/m")
NM_PER_RAD = (0.0, 1e9, "N m/rad")
RANGES: dict[str, tuple[float, float, str]] = {
    "k_S_N_per_m": N_PER_M, "k_T_N_per_m": N_PER_M, "k_axial_N_per_m": N_PER_M,
    "k_radial_N_per_m": N_PER_M,
    "k_phi_Nm_per_rad": NM_PER_RAD, "k_psi_Nm_per_rad": NM_PER_RAD,
    "k_torsion_Nm_per_rad": NM_PER_RAD, "k_tilt_Nm_per_rad": NM_PER_RAD,
    "k_Nm_per_rad": NM_PER_RAD,
    "outer_diameter_m": (1e-3, 10.0, "m"), "inner_diameter_m": (0.0, 10.0, "m"),
    "width_m": (1e-4, 10.0, "m"), "lengths_m": (MIN_ELEMENT_LENGTH_M, 100.0, "m"),
    "z_m": (-100.0, 100.0, "m"), "start_z_m": (-100.0, 100.0, "m"),
    "axis_st_m": (-100.0, 100.0, "m"),
    "E_Pa": (1e6, 1e13, "Pa"), "rho_kg_per_m3": (1.0, 1e5, "kg/m^3"),
    "mass_kg": (0.0, 1e6, "kg"), "transverse_inertia_kg_m2": (0.0, 1e6, "kg m^2"),
    "polar_inertia_kg_m2": (0.0, 1e6, "kg m^2"), "pinion_torque_Nm": (0.0, 1e8, "N m"),
    "crowning_m": (0.0, 1e-3, "m"), "eccentricity_m": (0.0, 1e-3, "m"),
    "pitch_errors_m": (-1e-3, 1e-3, "m"),
}


def check_range(r: Reader, path: str, v: Any, x: float, what: str) -> None:
    key = path.rsplit(".", 1)[-1].split("[", 1)[0]
    if key in RANGES:
        lo, hi, unit = RANGES[key]
        if not lo <= x <= hi:
            r.fail(path, v, f"outside the physical range [{lo:g}, {hi:g}] {unit} ({what}); "
                            "check the value and its unit")


def check_value(r: Reader, path: str, v: Any, kind: str, what: str) -> Any:
    if kind in ("real", "nonneg", "positive"):
        if not is_real(v):
            r.fail(path, v, f"must be a number ({what}), got {type(v).__name__}")
        x = float(v)
        if not math.isfinite(x):
            r.fail(path, v, f"must be finite ({what})")
        if kind == "nonneg" and x < 0.0:
            r.fail(path, v, f"must be >= 0 ({what})")
        if kind == "positive" and x <= 0.0:
            r.fail(path, v, f"must be > 0 ({what})")
        check_range(r, path, v, x, what)
        return x
    if kind == "int":
        if isinstance(v, bool) or not isinstance(v, int):
            r.fail(path, v, f"must be an integer ({what}), got {type(v).__name__}")
        return int(v)
    if kind == "str":
        if not isinstance(v, str):
            r.fail(path, v, f"must be a string ({what}), got {type(v).__name__}")
        return v
    if kind in ("reals", "ints"):
        if not isinstance(v, list):
            r.fail(path, v, f"must be a list ({what}), got {type(v).__name__}")
        sub = "real" if kind == "reals" else "int"
        return [check_value(r, f"{path}[{i}]", x, sub, what) for i, x in enumerate(v)]
    raise AssertionError(kind)


class Nodes:
    """The declared nodes: file numbers <-> internal 0-based indices."""

    def __init__(self, first: int, declared: set[int]):
        self.first = first
        self.declared = declared

    def index(self, r: Reader, path: str, v: Any) -> int:
        n = check_value(r, path, v, "int", "a node number")
        if n not in self.declared:
            lo, hi = self.first, self.first + len(self.declared) - 1
            r.fail(path, v, f"unknown node; the declared nodes are {lo}..{hi} (shaft node "
                            "lists and [[node]] tables)")
        return n - self.first

    def number(self, index: int) -> int:
        return index + self.first


def table_list(root: Reader, key: str) -> list[tuple[str, Any]]:
    items = root.data.get(key, [])
    if not isinstance(items, list):
        root.fail(key, items, f"must be an array of tables ([[{key}]])")
    return [(f"{key}[{i}]", item) for i, item in enumerate(items)]


AXIS_KEYS = ("axis", "axis_st_m")


def read_axis(r: Reader) -> str | tuple[float, float]:
    if r.has("axis") and r.has("axis_st_m"):
        r.fail(r.sub("axis_st_m"), r.data["axis_st_m"], "give either axis or axis_st_m, not both")
    if r.has("axis_st_m"):
        st = r.get("axis_st_m", "reals", "(S, T) of the shaft axis, m")
        if len(st) != 2:
            r.fail(r.sub("axis_st_m"), r.data["axis_st_m"], "must be 2 numbers [S, T] (m)")
        return (st[0], st[1])
    axis = r.get("axis", "str", '"pinion" or "gear"', "pinion")
    if axis not in ("pinion", "gear"):
        r.fail(r.sub("axis"), axis, 'must be "pinion" or "gear" (or give axis_st_m)')
    return axis


def per_element(r: Reader, key: str, n_el: int, kind: str, what: str, default: Any) -> list[float]:
    if r.has(key) and isinstance(r.data[key], list):
        vals = r.get(key, "reals", what)
        if len(vals) != n_el:
            r.fail(r.sub(key), r.data[key], f"must be one number or {n_el} numbers (one per element)")
        for i, x in enumerate(vals):
            check_value(r, f"{r.sub(key)}[{i}]", x, kind, what)
        return vals
    return [r.get(key, kind, what, default)] * n_el


def read_backlash(root: Reader, pair) -> float | None:
    """``[gear_pair] backlash_m`` (m, the clearance between the back flanks, optional) of
    the rig file, checked against the pair (:func:`gearjax.gears.backlash.backlash_problem`:
    a finite number in ``[0, m_n]``); None when absent (no back flanks)."""
    from ..gears.backlash import backlash_problem

    table = root.data.get("gear_pair")
    if not isinstance(table, dict) or "backlash_m" not in table:
        return None
    path, v = "gear_pair.backlash_m", table["backlash_m"]
    if not is_real(v):
        root.fail(path, v, f"must be a number (the backlash, m), got {type(v).__name__}")
    why = backlash_problem(v, pair)
    if why is not None:
        root.fail(path, v, why)
    return float(v)
