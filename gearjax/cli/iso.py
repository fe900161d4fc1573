"""Command-line options of the ISO 6336-1 method-B accuracy data (``gearjax info`` and
``gearjax sweep``): each replaces one field of the rig's ``[iso6336]`` table or of the
defaults of :mod:`gearjax.gears.iso6336`."""

from __future__ import annotations

import argparse

__all__ = ["add_iso_options", "accuracy_of", "iso_dynamic_factor"]


def add_iso_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group(
        "ISO 6336-1 method B (K_v beside the simulation; defaults: the rig file's [iso6336], "
        "else grade 5, C_a = the tip relief in use, K_A = 1)")
    g.add_argument("--iso-grade", type=int, default=None, metavar="Q",
                   help="ISO 1328-1 accuracy grade giving f_pb and f_falpha (1-12, default 5)")
    g.add_argument("--iso-fpb", type=float, default=None, metavar="METRES",
                   help="base pitch deviation f_pb (m), e.g. 9e-6")
    g.add_argument("--iso-ffa", type=float, default=None, metavar="METRES",
                   help="profile form deviation f_falpha (m)")
    g.add_argument("--iso-tip-relief", type=float, default=None, metavar="METRES",
                   help="tip relief C_a (m; default the scenario's relief amplitude, else C_ay)")
    g.add_argument("--iso-ka", type=float, default=None, metavar="K_A",
                   help="application factor K_A (default 1)")
    g.add_argument("--iso-speed", type=float, default=None, metavar="RAD_S",
                   help="info: the rated pinion speed (rad/s) at which K_v is reported")


def accuracy_of(args, rig):
    """The :class:`gearjax.gears.iso6336.AccuracyData` of ``rig`` with the options given."""
    from ..rigs.iso_figures import rig_accuracy

    return rig_accuracy(
        rig, accuracy_grade=args.iso_grade, base_pitch_deviation_m=args.iso_fpb,
        profile_form_deviation_m=args.iso_ffa, tip_relief_m=args.iso_tip_relief,
        application_factor=args.iso_ka, rated_speed_rad_s=getattr(args, "iso_speed", None))


def iso_dynamic_factor(args, rig, mods, speeds) -> dict:
    """ISO 6336-1 method-B K_v at a sweep's speeds for its ``summary.json``
    (:func:`gearjax.rigs.iso_figures.rig_dynamic_factor`; C_a defaults to the scenario's tip
    relief): ``iso6336_kv`` (one per speed), ``iso6336_resonance_speed_rad_s`` and the method's
    inputs under ``iso6336``. ISO's K_v multiplies F_t at the reference circle, the sweep's
    ``dynamic_factor`` divides by F_S on the base plane; both are ratios of a dynamic to a
    static load."""
    from ..rigs.iso_figures import rig_dynamic_factor

    kv = rig_dynamic_factor(rig, speeds, mods, accuracy_of(args, rig))
    return {"iso6336_kv": [float(v) for v in kv.kv],
            "iso6336_resonance_speed_rad_s": kv.resonance_speed_rad_s,
            "iso6336": kv.summary()}
