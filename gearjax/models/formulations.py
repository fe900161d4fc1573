"""The three dynamic formulations of Velex & Ajmi as small final classes.

* :class:`Reference` -- Eq. (14) (sdof Eq. (16)): the structure's stiffness plus the
  contact cells' stiffness on their instantaneous contact, each cell's gap from its own
  tooth geometry and errors; nonlinear (unilateral contact per cell).
* :class:`TransmissionError` -- Eq. (42) (sdof Eq. (20)): linearised about the quasi-static
  contact, the loaded quasi-static stiffness ``(sum k_i)^S`` times ``TE_S - NLTE`` on the
  right-hand side (assumption (18a)); the mesh force cut by a contact law where it would
  turn tensile.
* :class:`Perturbation` -- Eq. (48a) (sdof Eq. (47a)): the same with the mean stiffness
  ``k_m`` on the left-hand side (main-order perturbation).

A model holds one of them as a static field; what differs between them is asked of the
object (``linear``: affine in the state about the quasi-static contact, so the frequency
domain applies; ``te_weight``: the weight of the time-varying stiffness in the linear
family, 1 for Eq. (42), 0 for Eq. (48a)), never of a name. The builders also take the
names (``"reference"``, ``"te"``, ``"perturbation"``: the command line's and the result
files' words), read here by :func:`formulation_of`. Comparing a formulation with a string
raises ``TypeError`` (it would always be False).
"""

from __future__ import annotations

from typing import ClassVar

import equinox as eqx

from ..errors import ModelError

__all__ = ["AbstractFormulation", "Reference", "TransmissionError", "Perturbation",
           "FORMULATION_NAMES", "formulation_of"]


class AbstractFormulation(eqx.Module):
    """A dynamic formulation (module docstring). ``name``: its word in results and on the
    command line; ``equations``: the paper's equation numbers (3D, sdof); ``linear``:
    affine in the state about the quasi-static contact (Eqs. (42), (48a)); ``te_weight``:
    the weight of the loaded quasi-static stiffness against ``k_m`` in that family (None
    for the reference)."""

    name: ClassVar[str]
    equations: ClassVar[str]
    linear: ClassVar[bool]
    te_weight: ClassVar[float | None]

    def __str__(self) -> str:
        return self.name

    def __eq__(self, other) -> bool:
        if isinstance(other, str):
            raise TypeError(f"compare the formulation {self.name!r} with a formulation object "
                            f"or its .name, not with the string {other!r}")
        return type(self) is type(other)

    def __hash__(self) -> int:
        return hash(type(self).__name__)


class Reference(AbstractFormulation):
    """Eq. (14) / sdof Eq. (16): unilateral contact on every cell (nonlinear)."""

    name: ClassVar[str] = "reference"
    equations: ClassVar[str] = "(14) / (16)"
    linear: ClassVar[bool] = False
    te_weight: ClassVar[float | None] = None


class TransmissionError(AbstractFormulation):
    """Eq. (42) / sdof Eq. (20): linear with the loaded quasi-static stiffness, excited by
    ``TE_S - NLTE``."""

    name: ClassVar[str] = "te"
    equations: ClassVar[str] = "(42) / (20)"
    linear: ClassVar[bool] = True
    te_weight: ClassVar[float | None] = 1.0


class Perturbation(AbstractFormulation):
    """Eq. (48a) / sdof Eq. (47a): linear with the mean stiffness ``k_m``."""

    name: ClassVar[str] = "perturbation"
    equations: ClassVar[str] = "(48a) / (47a)"
    linear: ClassVar[bool] = True
    te_weight: ClassVar[float | None] = 0.0


_BY_NAME = {c.name: c for c in (Reference, TransmissionError, Perturbation)}
FORMULATION_NAMES = tuple(_BY_NAME)  # ("reference", "te", "perturbation")


def formulation_of(value) -> AbstractFormulation:
    """The formulation ``value`` stands for: a formulation object as it is, or one of
    :data:`FORMULATION_NAMES`. Raises :class:`~gearjax.errors.ModelError` for anything else."""
    if isinstance(value, AbstractFormulation):
        return value
    if isinstance(value, str) and value in _BY_NAME:
        return _BY_NAME[value]()
    raise ModelError("formulation", value, f"must be a formulation object or one of "
                     f"{FORMULATION_NAMES}")
