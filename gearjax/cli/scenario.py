"""The tooth modifications of a command-line scenario and a label made from the values used.

Precedence: a rig file's ``[modifications]`` table is the rig's default relief; the CLI
relief options override it (``--relief`` replaces it by a Table 1 relief, then
``--relief-amplitude`` / ``--relief-extent`` / ``--relief-shape`` replace single fields).
Without a ``[modifications]`` table the default is Table 1's short relief.

The NLTE'' reaction convention (``--nlte-reaction``) is part of the scenario too: one
option, one default (``drive``, the 3D model's: :mod:`gearjax.models.torsional`, "Where
the NLTE'' reaction torque acts") for ``sweep``, ``stability``, ``optimise`` and
``harris-map``, so that every command runs the same model unless told otherwise.
"""

from __future__ import annotations

import dataclasses

import numpy as np

__all__ = ["Scenario", "scenario_modifications", "add_nlte_reaction", "nlte_reaction_of",
           "add_nlte_switches", "nlte_options_of"]


@dataclasses.dataclass(frozen=True)
class Scenario:
    """Modifications of a scenario and where they come from.

    source : ``"rig file [modifications]"``, ``"--relief short"`` (Table 1), ...
    label : short text for titles, e.g. ``relief short`` or ``relief 10 um x 0.30 linear``.
    key : folder-name part, e.g. ``short`` or ``relief1e-05x0.3``.
    """

    mods: object
    source: str
    label: str
    key: str

    def summary(self) -> dict:
        m = self.mods
        return {
            "relief_source": self.source,
            "relief_label": self.label,
            "relief_amplitude_m": [float(v) for v in np.asarray(m.relief_amplitude_m)],
            "relief_extent": [float(v) for v in np.asarray(m.relief_extent)],
            "relief_shape": m.relief_shape,
            "pitch_errors": self.pitch_errors,
        }

    @property
    def pitch_errors(self) -> bool:
        """Pitch errors in the modifications (``--pitch-errors`` or the rig file's)."""
        return self.mods.pitch_errors_m is not None


def _overridden(args) -> bool:
    return (getattr(args, "relief", None) is not None or args.relief_amplitude is not None
            or args.relief_extent is not None or getattr(args, "relief_shape", None) is not None)


def scenario_modifications(rig, args) -> Scenario:
    """The :class:`Scenario` of parsed CLI ``args`` (``relief``, ``relief_amplitude``,
    ``relief_extent``, ``relief_shape``, ``pitch_errors``) on ``rig``."""
    from ..gears.modifications import ToothModifications

    relief = getattr(args, "relief", None)
    shape = getattr(args, "relief_shape", None)
    file_mods = getattr(rig, "modifications_default", None)
    if file_mods is not None and relief is None:
        amp = np.asarray(file_mods.relief_amplitude_m, dtype=float)
        ext = np.asarray(file_mods.relief_extent, dtype=float)
        base_shape = file_mods.relief_shape
        base = "rig file [modifications]"
    else:
        relief = relief or "short"
        base_mods = rig.modifications(relief, None, None, shape or "linear", False)
        amp = np.asarray(base_mods.relief_amplitude_m, dtype=float)
        ext = np.asarray(base_mods.relief_extent, dtype=float)
        base_shape = base_mods.relief_shape
        base = f"--relief {relief}" + (" (default)" if getattr(args, "relief", None) is None else "")
        file_mods = None
    changed = []
    if args.relief_amplitude is not None:
        amp = np.full(2, float(args.relief_amplitude))
        changed.append("--relief-amplitude")
    if args.relief_extent is not None:
        ext = np.full(2, float(args.relief_extent))
        changed.append("--relief-extent")
    if shape is not None and shape != base_shape:
        changed.append("--relief-shape")
    shape = shape or base_shape
    mods = ToothModifications.tip_relief(amp, ext, shape)
    if file_mods is not None:  # keep the file's pitch errors, eccentricity and crowning
        mods = dataclasses.replace(
            mods, pitch_errors_m=file_mods.pitch_errors_m, eccentricity_m=file_mods.eccentricity_m,
            eccentricity_phase_rad=file_mods.eccentricity_phase_rad,
            crowning_m=file_mods.crowning_m)
    if getattr(args, "pitch_errors", False):
        mods = mods.with_pitch_errors(rig.pinion_pitch_errors_m, np.zeros(rig.pair.z2))
    source = base + (" with " + ", ".join(changed) if changed else "")
    if not changed and file_mods is None:
        label = f"relief {relief}" + (f" ({shape})" if shape != "linear" else "")
        key = relief if shape == "linear" else f"{relief}-{shape}"
    else:
        um = amp * 1e6
        a = f"{um[0]:.3g}" if um[0] == um[1] else f"{um[0]:.3g}/{um[1]:.3g}"
        e = f"{ext[0]:.3g}" if ext[0] == ext[1] else f"{ext[0]:.3g}/{ext[1]:.3g}"
        label = f"relief {a} um x {e} {shape}" + (" (rig file)" if file_mods is not None
                                                   and not changed else "")
        key = ("file" if file_mods is not None and not changed
               else f"relief{amp[0]:g}x{ext[0]:g}" + ("" if shape == "linear" else f"-{shape}"))
    return Scenario(mods=mods, source=source, label=label, key=key)


def add_nlte_reaction(p) -> None:
    """Add ``--nlte-reaction {drive,pinion}`` (default drive) to the parser ``p``."""
    from ..models.torsional import NLTE_REACTIONS

    p.add_argument("--nlte-reaction", default=NLTE_REACTIONS[0], choices=list(NLTE_REACTIONS),
                   help="torsional model: where the NLTE'' reaction torque acts: drive (default, "
                        "as in the 3D model: kappa = 1) or pinion (Eqs. (15)-(16): kappa = 1 + "
                        "J2 Rb1^2 / (J1 Rb2^2)); the 3D model takes drive only")


def nlte_reaction_of(args) -> str:
    """The NLTE'' reaction convention of parsed ``args`` (``model``, ``nlte_reaction``);
    refuses ``pinion`` with the 3D model (which puts it at its torque node) before any
    computing."""
    from ..errors import GearjaxError
    from ..rigs.factory import NLTE_REACTION_3D

    if args.model == "3d" and args.nlte_reaction != "drive":
        raise GearjaxError("--nlte-reaction", args.nlte_reaction, NLTE_REACTION_3D)
    return args.nlte_reaction


def add_nlte_switches(p) -> None:
    """Add ``--no-nlte-terms`` (Section 6.3.2: the NLTE'' inertial terms alone set to zero)
    and ``--zero-nlte`` (NLTE = 0 everywhere) to the parser ``p``."""
    p.add_argument("--no-nlte-terms", action="store_true",
                   help="Section 6.3.2 ('NLTE'' set at zero in the equations of motion'): drop "
                        "the inertial terms NLTE'' E + NLTE' F of Eqs. (14), (42), (48a) (sdof: "
                        "NLTE'' of (16), (20), (47a)); TE_S - NLTE stays in the forcing and "
                        "DTE = W^T X + NLTE")
    p.add_argument("--zero-nlte", action="store_true",
                   help="NLTE = 0 everywhere: no NLTE'' terms and TE_S instead of TE_S - NLTE "
                        "in the forcing (the model treats TE_S as the static approach)")


def nlte_options_of(args) -> dict:
    """``nlte_terms`` (False with ``--zero-nlte``, else None: kept unless NLTE is 0) and
    ``nlte_inertia`` (False with either switch) for :func:`gearjax.rigs.factory.build_model`."""
    zero = bool(getattr(args, "zero_nlte", False))
    return {"nlte_terms": False if zero else None,
            "nlte_inertia": not (zero or getattr(args, "no_nlte_terms", False))}
