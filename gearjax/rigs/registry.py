"""The registry of built-in rigs: :func:`get_rig` finds a rig by name (the Baud & Velex
spur and helical rigs of Section 6.1, :mod:`gearjax.rigs.baud_velex`) or loads a rig file
(:mod:`gearjax.rigs.rigfile`)."""

from __future__ import annotations

import os

from ..errors import RigError
from .baud_velex import baud_velex_rig
from .rig import Rig
from .rigfile import load_rig

__all__ = ["Rig", "RIGS", "get_rig", "RigError"]


RIGS = {
    "baud-velex-spur": lambda: baud_velex_rig(False),
    "baud-velex-helical": lambda: baud_velex_rig(True),
}


def get_rig(name: str) -> Rig:
    """A built-in rig by name (``baud-velex-spur`` or ``baud-velex-helical``), or a rig
    file (a name ending in ``.toml`` or an existing path; see :mod:`gearjax.rigs.rigfile`)."""
    if name not in RIGS and (str(name).endswith(".toml") or os.path.isfile(name)):
        return load_rig(name)
    try:
        return RIGS[name]()
    except KeyError:
        raise RigError(f"rig={name!r}: unknown rig; built-in rigs are {sorted(RIGS)}") from None
