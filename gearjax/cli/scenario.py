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
import math

import numpy as np

__all__ = ["linspace_option", "Scenario", "scenario_modifications", "add_nlte_reaction",
           "nlte_reaction_of", "add_nlte_switches", "nlte_options_of", "add_eccentricity",
           "eccentricity_of", "add_torque", "rig_of", "file_digest", "input_digests",
           "rig_notes", "Speeds", "add_speeds", "speeds_of", "missed_critical_speed",
           "PAPER_RIGS"]


def linspace_option(text: str, option: str, *, example: str, lo: float = 0.0,
                    hi: float = math.inf, positive: bool = True, unit: str = "") -> np.ndarray:
    """The values ``A:B:N`` of a range option (``--speeds``, ``--amplitudes``, ...):
    ``numpy.linspace(A, B, N)``, with ``lo <= A <= B <= hi`` (``0 < A`` if ``positive``),
    ``B`` finite and ``N >= 1``; else ``ValueError`` naming ``option``, the ``unit`` of A
    and B and an ``example``."""
    try:
        a, b, n = text.split(":")
        a, b, n = float(a), float(b), int(n)
    except ValueError:
        raise ValueError(f"{option}={text!r}: expected A:B:N, e.g. {example}") from None
    low = f"{lo:g} < A" if positive and lo <= 0.0 else f"{lo:g} <= A"
    high = ("" if math.isinf(hi) else f" <= {hi:g}") + (f" ({unit})" if unit else "")
    if not (lo <= a <= b <= hi and (a > 0.0 or not positive) and n >= 1
            and math.isfinite(b)):
        raise ValueError(f"{option}={text!r}: need {low} <= B{high} and N >= 1")
    return np.linspace(a, b, n)


MAX_ECCENTRICITY_M = 1e-3  # above 1 mm: a unit mistake (the option is in metres)


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
        ecc = {} if m.eccentricity_m is None else {  # only when present: older case.json stay
            "eccentricity_m": [float(v) for v in np.asarray(m.eccentricity_m)],  # resumable
            "eccentricity_phase_rad": [float(v) for v in np.asarray(m.eccentricity_phase_rad)]}
        return {**ecc,
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
    ecc = eccentricity_of(args)
    if ecc is not None:
        mods = mods.with_eccentricity(*ecc)
    # an --eccentricity is a command-line value, not the rig file's: the source says so
    given = changed + (["--eccentricity"] if ecc is not None else [])
    source = base + (" with " + ", ".join(given) if given else "")
    if not changed and file_mods is None:
        label = f"relief {relief}" + (f" ({shape})" if shape != "linear" else "")
        key = relief if shape == "linear" else f"{relief}-{shape}"
    else:
        um = amp * 1e6
        a = f"{um[0]:.3g}" if um[0] == um[1] else f"{um[0]:.3g}/{um[1]:.3g}"
        e = f"{ext[0]:.3g}" if ext[0] == ext[1] else f"{ext[0]:.3g}/{ext[1]:.3g}"
        label = f"relief {a} um x {e} {shape}" + (" (rig file)" if file_mods is not None
                                                   and not changed else "")  # the relief's
        key = ("file" if file_mods is not None and not changed
               else f"relief{amp[0]:g}x{ext[0]:g}" + ("" if shape == "linear" else f"-{shape}"))
    if ecc is not None:
        um = ecc[0] * 1e6
        label += f", eccentricity {um[0]:g}/{um[1]:g} um"
        key += f"-ecc{um[0]:g}x{um[1]:g}" + (f"-ph{ecc[1][0]:g}x{ecc[1][1]:g}"
                                             if np.any(ecc[1] != 0) else "")
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


def add_eccentricity(p) -> None:
    """Add ``--eccentricity E1[,E2]`` (m, as every length option) and
    ``--eccentricity-phase P1[,P2]`` (rad)."""
    p.add_argument("--eccentricity", default=None, metavar="E1[,E2]",
                   help="eccentricities of the pinion and the gear in metres, as every length "
                        "option (e.g. 20e-6; one value: pinion only); the excitation period "
                        "becomes a revolution of each eccentric body (gear: z2 mesh periods); "
                        "replaces a rig file's")
    p.add_argument("--eccentricity-phase", default=None, metavar="P1[,P2]",
                   help="phases lambda_1, lambda_2 of the eccentricities (rad, default 0)")


def _pair_of(flag: str, text: str, what: str) -> np.ndarray:
    from ..errors import GearjaxError

    try:
        vals = [float(v) for v in text.split(",")]
    except ValueError:
        raise GearjaxError(flag, text, f"expected one or two comma-separated {what}") from None
    if not 1 <= len(vals) <= 2:
        raise GearjaxError(flag, text, f"expected one or two comma-separated {what}")
    if not all(np.isfinite(vals)):
        raise GearjaxError(flag, text, f"{what} must be finite")
    return np.array(vals + [0.0] * (2 - len(vals)))


def eccentricity_of(args):
    """``(e (2,) m, lambda (2,) rad)`` of ``--eccentricity`` (metres, as every length
    option; one value: the pinion's, the gear's 0) and ``--eccentricity-phase`` (rad,
    default 0), or None without ``--eccentricity``. Raises
    :class:`gearjax.errors.GearjaxError` for a negative, non finite or absurd (> 1 mm: a
    value in micrometres) eccentricity, or a phase without an eccentricity."""
    from ..errors import GearjaxError

    text, ph = getattr(args, "eccentricity", None), getattr(args, "eccentricity_phase", None)
    if text is None:
        if ph is not None:
            raise GearjaxError("--eccentricity-phase", ph, "needs --eccentricity")
        return None
    e = _pair_of("--eccentricity", text, "eccentricities (m)")
    if np.any(e < 0):
        raise GearjaxError("--eccentricity", text, "eccentricities must be >= 0 (m; the "
                           "direction is the phase)")
    if np.any(e > MAX_ECCENTRICITY_M):
        raise GearjaxError("--eccentricity", text, f"above {MAX_ECCENTRICITY_M:g} m = 1 mm; "
                           "the values are in metres like every length option (20 um is 20e-6)")
    phase = np.zeros(2) if ph is None else _pair_of("--eccentricity-phase", ph, "phases (rad)")
    return e, phase


# ------------------------------------------------------------------ the rig of a command
PAPER_RIGS = ("baud-velex-spur", "baud-velex-helical")  # the built-in rigs of Section 6.1


def add_torque(p) -> None:
    """Add ``--torque NM`` (the pinion torque C_m0, N m; default the rig's)."""
    p.add_argument("--torque", type=float, default=None, metavar="NM",
                   help="pinion torque C_m0 in N m (default: the rig's, e.g. 254.8 for the "
                        "Baud-Velex rigs or a rig file's [operating] pinion_torque_Nm)")


def rig_of(args):
    """The rig of parsed ``args`` (``rig``, optional ``torque`` and ``backlash``): a
    built-in rig or a rig file, with ``--torque`` replacing its nominal torque and
    ``--backlash`` its backlash (:mod:`gearjax.cli.backlash`). Raises
    :class:`gearjax.errors.GearjaxError` for a torque that is not finite and > 0 or a bad
    backlash."""
    from ..errors import GearjaxError
    from ..rigs.registry import get_rig

    torque = getattr(args, "torque", None)
    if torque is not None and not (math.isfinite(torque) and 0.0 < torque <= 1e8):
        raise GearjaxError("--torque", torque, "the pinion torque must be finite, > 0 and at "
                                               "most 1e8 (N m)")
    rig = get_rig(args.rig)
    if torque is not None:
        rig = dataclasses.replace(rig, pinion_torque_Nm=float(torque))
    from .backlash import with_backlash

    return with_backlash(rig, args)  # --backlash replaces the rig's


def file_digest(path: str) -> str:
    """SHA-256 (hex) of a file's bytes: ``--resume`` compares the rig and TE files' contents,
    not only their names."""
    import hashlib

    with open(path, "rb") as fh:
        return hashlib.sha256(fh.read()).hexdigest()


def input_digests(args) -> dict:
    """``{"rig_file_sha256": ..., "te_file_sha256": ...}`` of the files a command reads
    (a built-in rig has none)."""
    import os

    out = {}
    if str(args.rig).endswith(".toml") or os.path.isfile(str(args.rig)):
        out["rig_file_sha256"] = file_digest(args.rig)
    if getattr(args, "te_file", None):
        out["te_file_sha256"] = file_digest(args.te_file)
    return out


def rig_notes(rig, model: str) -> list[str]:
    """What a run takes from the rig that a user might not expect, one sentence each (the
    commands print them and store them in their JSON as ``notes``): unequal face widths
    (the common width carries the load) and, for the torsional model, the body inertias
    it uses instead of the rig's discs and shafts."""
    from ..gears.geometry import solid_cylinder_inertias

    p = rig.pair
    notes = []
    if p.face_width1_m != p.face_width2_m:
        notes.append(f"face widths {p.face_width1_m * 1e3:g} / {p.face_width2_m * 1e3:g} mm "
                     f"differ: the common width b = {p.face_width_m * 1e3:g} mm carries the "
                     "load (mesh stiffness, contact lines)")
    if model == "torsional":
        j1, j2 = solid_cylinder_inertias(p)
        notes.append(f"the torsional model takes solid steel cylinders at the pitch radii "
                     f"(J1 {j1:.3g}, J2 {j2:.3g} kg m^2), not the rig's discs, shafts or "
                     "bearings; --model 3d uses them")
    return notes


@dataclasses.dataclass(frozen=True)
class Speeds:
    """The pinion speeds of a command: ``rad_s`` (rad/s), the ``spec`` as given or chosen
    (``"A:B:N"`` rad/s, or ``"A:B:N rpm"``) and its ``source``."""

    rad_s: np.ndarray
    spec: str
    source: str

    def record(self) -> dict:
        """The speed specification for a JSON record (not the speeds themselves)."""
        w = self.rad_s
        return {"speeds_rad_s": [float(w[0]), float(w[-1]), int(w.size)],
                "speeds_spec": self.spec, "speeds_source": self.source}


# the default ranges of each command: the paper's on its rigs; on any other rig, relative
# to the rig's own predicted main critical speed Omega_c: (low, high, count), with low
# None for high / count
PAPER_SPEEDS = {"sweep": "20:900:45", "stability": "100:1500:15", "design": "660:900:8"}
OWN_SPEEDS = {"sweep": (None, 1.2, 45), "stability": (None, 2.0, 15),
              "design": (0.85, 1.16, 8)}


def add_speeds(p, command: str, what: str = "pinion speeds") -> None:
    """Add ``--speeds A:B:N`` (rad/s), ``--speeds-rpm A:B:N`` (rev/min) and
    ``--speeds-mesh-hz A:B:N`` (mesh frequency, Hz) to ``p``, the defaults of ``command``
    (:data:`PAPER_SPEEDS`, :data:`OWN_SPEEDS`)."""
    lo, hi, n = OWN_SPEEDS[command]
    own = (f"{lo:g}-{hi:g} x" if lo else f"up to {hi:g} x") + f" its predicted main critical speed, {n} speeds"
    p.add_argument("--speeds", default=None, metavar="A:B:N",
                   help=f"N {what} from A to B rad/s (default: {PAPER_SPEEDS[command]} on the "
                        f"Baud-Velex rigs, the paper's; on any other rig {own})")
    p.add_argument("--speeds-rpm", default=None, metavar="A:B:N",
                   help="the same in rev/min of the pinion (instead of --speeds)")
    p.add_argument("--speeds-mesh-hz", default=None, metavar="A:B:N",
                   help="the same as mesh frequencies f_m = z1 Omega1 / (2 pi) in Hz "
                        "(instead of --speeds)")


def _nice(x: float) -> float:
    return float(f"{x:.3g}")


def speeds_of(args, rig, command: str, *, law: str, model: str, damping: float) -> Speeds:
    """The :class:`Speeds` of parsed ``args`` (``speeds``, ``speeds_rpm``): as given, or the
    default of ``command`` for ``rig`` (the paper's range on the Baud-Velex rigs, else
    relative to :func:`gearjax.rigs.figures.rig_critical_speeds` of ``model``, ``law`` and
    ``damping``). ``ValueError`` naming the option for a bad range or both options."""
    from ..errors import GearjaxError

    text, rpm = getattr(args, "speeds", None), getattr(args, "speeds_rpm", None)
    hz = getattr(args, "speeds_mesh_hz", None)
    given = [o for o, v in (("--speeds", text), ("--speeds-rpm", rpm), ("--speeds-mesh-hz", hz))
             if v is not None]
    if len(given) > 1:
        raise GearjaxError(given[1], rpm if given[1] == "--speeds-rpm" else hz,
                           f"give one of --speeds (rad/s), --speeds-rpm, --speeds-mesh-hz, "
                           f"not both {given[0]} and {given[1]}")
    if hz is not None:
        f = linspace_option(hz, "--speeds-mesh-hz", example="500:5000:40", unit="Hz")
        return Speeds(f * (2.0 * math.pi / rig.pair.z1), f"{hz} mesh-Hz", "--speeds-mesh-hz")
    if rpm is not None:
        w = linspace_option(rpm, "--speeds-rpm", example="1000:9000:40", unit="rev/min")
        return Speeds(w * (2.0 * math.pi / 60.0), f"{rpm} rpm", "--speeds-rpm")
    if text is not None:
        return Speeds(linspace_option(text, "--speeds", example="20:900:60", unit="rad/s"),
                      text, "--speeds")
    if rig.name in PAPER_RIGS:
        spec = PAPER_SPEEDS[command]
        return Speeds(linspace_option(spec, "--speeds", example=spec), spec,
                      "default: the paper's range (Baud-Velex rig)")
    from ..rigs.figures import rig_critical_speeds

    wc = rig_critical_speeds(rig, law, model, damping)["critical_speed_rad_s"]
    lo, hi, n = OWN_SPEEDS[command]
    b = _nice(hi * wc)
    a = _nice(lo * wc) if lo else _nice(b / n)
    spec = f"{a:g}:{b:g}:{n}"
    how = f"{lo:g}-{hi:g} x" if lo else f"up to {hi:g} x"
    return Speeds(np.linspace(a, b, n), spec,
                  f"default: {how} the rig's predicted critical speed {wc:.0f} rad/s ({model})")


def missed_critical_speed(predicted: dict, speeds_rad_s) -> str | None:
    """A warning when the predicted main critical speed lies outside the swept range."""
    wc = predicted.get("critical_speed_rad_s")
    w = np.asarray(speeds_rad_s)
    if wc is None or not np.isfinite(wc) or w[0] <= wc <= w[-1]:
        return None
    return (f"the predicted main tooth critical speed {wc:.0f} rad/s lies outside the swept "
            f"speeds {w[0]:.0f}-{w[-1]:.0f} rad/s: the peak found is not the resonance; "
            "sweep through it (e.g. leave --speeds out on a rig file)")
