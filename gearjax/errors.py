"""The one family of input errors: every bad input raises a :class:`GearjaxError` whose
message names the field, the value and why it is wrong (``field=value: reason``).

Subclasses say where the input belongs (gear data, tooth modifications, structure, model,
simulation, design, rig); the command line catches the family and prints one line.
"""

from __future__ import annotations

__all__ = [
    "GearjaxError",
    "GeometryError",
    "ModificationError",
    "ElementInputError",
    "StructureInputError",
    "ModelError",
    "SimulationError",
    "DesignError",
    "RigError",
    "check_float64",
]

_NO_VALUE = object()


class GearjaxError(ValueError):
    """Invalid input: ``GearjaxError(field, value, reason)`` reads ``field=value: reason``.

    ``GearjaxError(message)`` (one argument) is accepted where the message already names the
    field and the value (e.g. ``"bearing[2].k_S_N_per_m=-3e8: must be >= 0"``); ``field``
    and ``value`` are then None.
    """

    def __init__(self, field: str, value=_NO_VALUE, reason: str | None = None):
        if value is _NO_VALUE and reason is None:
            self.field, self.value = None, None
            super().__init__(field)
            return
        self.field = field
        self.value = None if value is _NO_VALUE else value
        super().__init__(f"{field}={self.value!r}: {reason}")


class GeometryError(GearjaxError):
    """Invalid gear data (:class:`gearjax.GearPair`)."""


class ModificationError(GearjaxError):
    """Invalid tooth modification (:class:`gearjax.ToothModifications`)."""


class ElementInputError(GearjaxError):
    """A structural element parameter out of its physical range."""


class StructureInputError(ElementInputError):
    """Invalid structure assembly input (nodes, dofs, matrices)."""


class ModelError(GearjaxError):
    """Invalid dynamic-model input."""


class SimulationError(GearjaxError):
    """Invalid solver input (speeds, tolerances, sample counts)."""


class DesignError(GearjaxError):
    """Invalid design input (relief space, objective, optimiser)."""


class RigError(GearjaxError):
    """Unknown rig or bad rig data."""


def check_float64() -> None:
    """Raise a :class:`SimulationError` naming ``jax_enable_x64`` if JAX computes in float32.

    gearjax enables float64 on import; a caller that turns it off again (``jax.config.update(
    "jax_enable_x64", False)``) would get no answer but a long wait: the solvers' tolerances
    (shooting rtol 1e-9, measurement 1e-7) lie below float32's 1.2e-7 resolution, so every
    integration runs to its step limit and returns NaN metrics. The dynamic solvers call
    this on entry."""
    import jax

    if not jax.config.jax_enable_x64:
        raise SimulationError(
            "jax_enable_x64", False,
            "gearjax computes in float64 (its tolerances lie below float32's resolution); "
            'restore it with jax.config.update("jax_enable_x64", True)')
