"""``--backlash METRES``: the clearance between the back flanks on the command line.

The value replaces the rig's (a rig file's ``[gear_pair] backlash_m``, none for the built-in
rigs) in the :class:`gearjax.rigs.rig.Rig` of the command (:func:`with_backlash`, applied by
:func:`gearjax.cli.scenario.rig_of`), so that every model the command builds through
:func:`gearjax.rigs.factory.build_model` takes it. The physics: :mod:`gearjax.gears.backlash`.
"""

from __future__ import annotations

import dataclasses

__all__ = ["add_backlash", "backlash_of", "with_backlash", "backlash_key", "backlash_record"]


def add_backlash(p) -> None:
    """Add ``--backlash METRES`` (default: the rig's, none for the built-in rigs)."""
    p.add_argument(
        "--backlash", type=float, default=None, metavar="METRES",
        help="clearance between the back flanks (normal backlash along the line of action, "
             "m, at most a module; e.g. 1e-4): teeth that separate strike the back flanks "
             "(double-sided impacts); default the rig file's [gear_pair] backlash_m, else none")


def backlash_of(args, rig):
    """The backlash (m) of a command: ``--backlash`` checked against the rig's pair (a
    one-line :class:`gearjax.errors.GearjaxError` on ``--backlash`` for a negative, NaN or
    more-than-a-module value), else the rig's (None: none)."""
    from ..gears.backlash import check_backlash
    from ..errors import GearjaxError

    value = getattr(args, "backlash", None)
    if value is None:
        return rig.backlash_m
    return check_backlash("--backlash", value, rig.pair, error=GearjaxError)


def with_backlash(rig, args):
    """``rig`` with the command's backlash (:func:`backlash_of`)."""
    b = backlash_of(args, rig)
    return rig if b == rig.backlash_m else dataclasses.replace(rig, backlash_m=b)


def backlash_key(args) -> str | None:
    """Folder-name part of ``--backlash`` (``backlash1e-04``), None without it."""
    value = getattr(args, "backlash", None)
    return None if value is None else f"backlash{value:g}"


def backlash_record(rig) -> dict:
    """``{"backlash_m": b}`` for a ``case.json`` record where the rig has a backlash, else
    ``{}`` (a run without one keeps its record, so ``--resume`` still accepts it)."""
    return {} if rig.backlash_m is None else {"backlash_m": float(rig.backlash_m)}
