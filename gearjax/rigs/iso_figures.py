"""ISO 6336-1 figures of a rig (:mod:`gearjax.gears.iso6336`) with the rig's own data: its
torque, its ``[iso6336]`` accuracy data and the tip relief of the modifications in use.
Used by ``gearjax info`` (c', c_gamma_alpha, n_E1, K_v at the rated speed) and ``gearjax
sweep`` (the ISO K_v curve beside the computed dynamic factor)."""

from __future__ import annotations

import dataclasses

import numpy as np

from ..gears.iso6336 import AccuracyData, DynamicFactorB, dynamic_factor
from ..gears.modifications import ToothModifications
from .rig import Rig

__all__ = ["rig_accuracy", "tip_relief_of", "rig_dynamic_factor", "default_modifications",
           "info_figures"]


def rig_accuracy(rig: Rig, **overrides) -> AccuracyData:
    """The rig's :class:`AccuracyData` (its rig file's ``[iso6336]`` table, else the
    defaults), with the fields in ``overrides`` that are not None replaced (the command
    line's ``--iso-*`` options)."""
    base = rig.accuracy or AccuracyData()
    given = {k: v for k, v in overrides.items() if v is not None}
    return dataclasses.replace(base, **given) if given else base


def tip_relief_of(mods: ToothModifications | None) -> float:
    """The larger tip relief amplitude of ``mods`` (m; 0 without modifications): the C_a
    that method B takes when none is given."""
    if mods is None:
        return 0.0
    return float(np.max(np.asarray(mods.relief_amplitude_m, dtype=float)))


def rig_dynamic_factor(rig: Rig, speeds_rad_s, mods: ToothModifications | None = None,
                       accuracy: AccuracyData | None = None) -> DynamicFactorB:
    """ISO 6336-1 method-B K_v of ``rig`` at its torque over pinion speeds (rad/s), with
    ``accuracy`` (default :func:`rig_accuracy`) and C_a defaulting to the tip relief of
    ``mods``."""
    acc = accuracy if accuracy is not None else rig_accuracy(rig)
    return dynamic_factor(rig.pair, rig.pinion_torque_Nm, speeds_rad_s, acc,
                          scenario_tip_relief_m=tip_relief_of(mods))


def default_modifications(rig: Rig) -> ToothModifications | None:
    """The modifications a command uses when given none: the rig file's
    ``[modifications]``, else Table 1's short relief (as ``gearjax sweep``)."""
    if rig.modifications_default is not None:
        return rig.modifications_default
    if rig.relief_presets is None:
        return None
    return rig.modifications("short")


def info_figures(rig: Rig, accuracy: AccuracyData | None = None) -> dict:
    """ISO 6336-1 figures for ``gearjax info``: c' and c_gamma_alpha (SI and N/(mm um)),
    the resonance speed, the method-B inputs and sources, K_v in the main resonance range
    and, when a rated speed is known, K_v there (``iso6336_kv_at_rated_speed``)."""
    acc = accuracy if accuracy is not None else rig_accuracy(rig)
    mods = default_modifications(rig)
    probe = rig_dynamic_factor(rig, [0.0], mods, acc)
    w_e = probe.resonance_speed_rad_s
    speeds = [w_e] + ([acc.rated_speed_rad_s] if acc.rated_speed_rad_s else [])
    kv = rig_dynamic_factor(rig, speeds, mods, acc)
    out = kv.summary()
    out["iso6336_kv_main_resonance"] = float(kv.kv[0])
    if acc.rated_speed_rad_s:
        out["iso6336_rated_speed_rad_s"] = float(acc.rated_speed_rad_s)
        out["iso6336_resonance_ratio_at_rated_speed"] = float(kv.resonance_ratio[1])
        out["iso6336_kv_at_rated_speed"] = float(kv.kv[1])
    return out
