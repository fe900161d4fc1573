"""Options of ``gearjax optimise`` and ``gearjax harris-map`` for the orbit set of the
dynamic objectives and the refinement of the Harris map: argument adders and ``x_of(args)``
readers (as :mod:`gearjax.cli.scenario`), hooked into :mod:`gearjax.cli.design`."""

from __future__ import annotations

from ..design.orbits import ORBIT_STARTS
from ..errors import DesignError

__all__ = ["add_orbits", "orbits_of", "add_map_refine", "map_refine_of", "DEFAULT_ORBITS"]

DEFAULT_ORBITS = "quasi-static,separated,far"


def add_orbits(p, default: str = DEFAULT_ORBITS) -> None:
    """``--orbits START[,START]``: the starts of the steady state at every speed of a
    dynamic objective (:class:`gearjax.design.OrbitSet`)."""
    p.add_argument("--orbits", default=default, metavar="STARTS",
                   help="starts of the steady state at every speed, comma-separated, among "
                        f"{', '.join(ORBIT_STARTS)} (default {default}: the objective is the "
                        "largest value over the orbits they reach, so an optimiser does not "
                        "follow a switch of orbit in the contact-loss band; quasi-static "
                        "alone: what a forward sweep shows)")


def orbits_of(args) -> tuple:
    """The start names of ``--orbits``; :class:`DesignError` for an unknown one."""
    names = tuple(n.strip() for n in str(args.orbits).split(",") if n.strip())
    bad = [n for n in names if n not in ORBIT_STARTS]
    if not names or bad or len(set(names)) != len(names):
        raise DesignError(f"--orbits={args.orbits!r}: give distinct starts among "
                          f"{', '.join(ORBIT_STARTS)}")
    return names


def add_map_refine(p, default: int = 1) -> None:
    """``--map-refine N``: refinement levels of the Harris map around its best points
    (and, for ``optimise``, around the optima)."""
    p.add_argument("--map-refine", type=int, default=default, metavar="N",
                   help=f"refinement levels of the Harris map: a 5 x 5 patch around its "
                        f"best points (and the optimiser's optima) per level, each level "
                        f"half the spacing of the one before (default {default}; 0: the grid "
                        "alone)")


def map_refine_of(args) -> int:
    """``--map-refine``; :class:`DesignError` below 0 or above 6."""
    n = int(args.map_refine)
    if not 0 <= n <= 6:
        raise DesignError(f"--map-refine={args.map_refine!r}: need 0 to 6 levels")
    return n
