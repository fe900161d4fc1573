"""A validated dynamics case: ``gearjax sweep`` / ``gearjax stability`` arguments checked
once, the rig, speeds, tooth modifications and TE file read once, and the one call of the
model builder (:func:`gearjax.rigs.factory.build_model`) every formulation goes through.

Every input problem is a ``ValueError`` naming the option, raised before any output is
written or any model is built; the record that defines a sweep (``case.json``, compared by
``--resume``) is the head of its ``summary.json``, so the two cannot disagree.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os

import numpy as np

from ..errors import ModelError, SimulationError
from ..excitation.te_file import read_te_csv
from ..models.geared3d import CUTOFF_FLOOR_HZ, CUTOFF_MARGIN, CUTOFF_MESH_HARMONICS, \
    default_max_frequency_hz
from ..rigs.factory import build_model
from ..dynamics.stored import AbstractBuildStore, NoBuildStore
from ..runtime.cache import build_store
from .backlash import backlash_key, backlash_record
from .contact import contact_record, contact_suffix, model_options_of
from .refine import refinement_of
from .signals import parse_signal_speeds
from .scenario import (Scenario, Speeds, input_digests, linspace_option, nlte_options_of,
                       nlte_reaction_of, rig_notes, rig_of, scenario_modifications, speeds_of)

__all__ = ["FORMULATIONS", "DynamicsCase", "SweepCase", "dynamics_case", "sweep_case",
           "parse_speeds", "modal_cutoff", "cutoff_warning", "case_name"]

FORMULATIONS = ("reference", "te", "perturbation")


def parse_speeds(text: str | None) -> np.ndarray:
    """The pinion speeds of ``--speeds A:B:N`` (rad/s): ``0 < A <= B``, ``N >= 1``; None
    (no ``--speeds``: the rig's default, :func:`gearjax.cli.scenario.speeds_of`) gives the
    paper's 20:900:45, which has the default's count of speeds."""
    if text is None:
        text = "20:900:45"
    return linspace_option(text, "--speeds", example="20:900:60", unit="rad/s")


def modal_cutoff(args, rig, speeds_rad_s) -> tuple[float | None, str]:
    """The 3D cut-off (Hz; None: all modes) of a command and where it comes from:
    ``--max-frequency`` (0: all modes) or, without it, :func:`default_max_frequency_hz` at
    the highest requested speed."""
    hz = args.max_frequency
    if hz is None:
        w = float(np.max(speeds_rad_s))
        hz = default_max_frequency_hz(w, rig.pair.z1)
        return hz, (f"default: max({CUTOFF_FLOOR_HZ:g} Hz, {CUTOFF_MESH_HARMONICS} mesh "
                    f"harmonics x {CUTOFF_MARGIN:g} at {w:g} rad/s)")
    if not (math.isfinite(hz) and hz >= 0):
        raise ValueError(f"--max-frequency={hz!r}: need a cut-off >= 0 Hz (0: all modes)")
    return (float(hz), "--max-frequency") if hz > 0 else (None, "--max-frequency 0: all modes")


def cutoff_warning(args, rig, cutoff_hz, speeds_rad_s) -> str | None:
    """A warning where ``--max-frequency`` lies below the mesh frequency of the highest
    speed, ``f_m = z1 Omega_max / (2 pi)`` (Hz): the modes that the mesh fundamental
    excites there then answer quasi-statically (static corrections), so the response
    curves are not those of the structure (``benchmarks/results/cutoff.md``). None for the
    default cut-off, all modes or the torsional model."""
    if args.model != "3d" or not cutoff_hz or args.max_frequency is None:
        return None
    w = float(np.max(speeds_rad_s))
    f_m = rig.pair.z1 * w / (2 * math.pi)
    if cutoff_hz >= f_m:
        return None
    return (f"--max-frequency={args.max_frequency:g} Hz lies below the mesh frequency at "
            f"{w:g} rad/s ({f_m:.0f} Hz): the modes it excites answer quasi-statically in this "
            f"reduced model, so the dynamic response is not the structure's; the default for "
            f"these speeds is {default_max_frequency_hz(w, rig.pair.z1):.0f} Hz (leave "
            f"--max-frequency out)")


def case_name(args, scenario: Scenario | None = None) -> str:
    """Folder name of a sweep case, e.g. ``baud-velex-spur-3d-short-zeta0.1-enc1``
    (``scenario``: the :class:`gearjax.cli.scenario.Scenario` used, naming its relief)."""
    rig = os.path.splitext(os.path.basename(args.rig))[0]
    relief = scenario.key if scenario is not None else (args.relief or "short")
    if scenario is None and (args.relief_amplitude is not None or args.relief_extent is not None):
        relief = f"relief{args.relief_amplitude or 'T1'}x{args.relief_extent or 'T1'}"
    parts = [rig, args.model, relief]
    if scenario.pitch_errors if scenario is not None else args.pitch_errors:
        parts.append("pitch")
    parts.append(f"zeta{args.damping:g}")
    if args.zero_nlte:
        parts.append("zero-nlte")
    elif args.no_nlte_terms:
        parts.append("no-nlte-dd")
    if args.nlte_reaction != "drive":
        parts.append(f"nlte-{args.nlte_reaction}")
    if args.model == "3d":
        parts.append(f"enc{args.encoders}")
    return "-".join(parts + [k for k in (backlash_key(args),) if k])


def formulations_of(text: str) -> list[str]:
    """The formulations of ``--formulations`` (comma-separated, in order, once each)."""
    forms = [f.strip() for f in text.split(",") if f.strip()]
    bad = [f for f in forms if f not in FORMULATIONS]
    if bad or not forms:
        raise ValueError(f"--formulations={text!r}: choose from reference,te,perturbation")
    return list(dict.fromkeys(forms))


def _check_damping(z: float) -> None:
    if not (math.isfinite(z) and 0.0 <= z < 1.0):
        raise ValueError(f"--damping={z!r}: the modal damping factor must lie in [0, 1)")


def _check_te_file(args, forms) -> None:
    """--te-file drives the te/perturbation formulations only (Section 6.2)."""
    if args.te_file and "reference" in forms:
        raise ValueError(f"--te-file={args.te_file}: the reference formulation (Eqs. (14), (16): a "
                         "gap per contact cell) cannot use a TE file; choose --formulations "
                         "te,perturbation (the default with --te-file)")


def transient_tolerances(args) -> dict:
    """``--rtol`` as :func:`gearjax.dynamics.sweep.tolerance_options` reads it, its range
    error as a command-line error."""
    from ..dynamics.sweep import tolerance_options

    try:
        return tolerance_options(args.rtol)
    except SimulationError as exc:
        raise ValueError(f"--rtol={args.rtol!r}: must lie in [1e-13, 1e-2]") from exc


@dataclasses.dataclass(frozen=True)
class DynamicsCase:
    """The inputs of a dynamics command, each read and checked once: the rig, its pinion
    speeds (rad/s), tooth modifications, TE file, NLTE options and 3D modal cut-off (Hz);
    ``builds``: the store of built models (:func:`gearjax.runtime.build_store`; default
    :class:`~gearjax.dynamics.stored.NoBuildStore`: every model built)."""

    args: argparse.Namespace
    rig: object
    spec: Speeds
    scenario: Scenario
    te: object
    reaction: str
    nlte: dict
    cutoff_hz: float | None
    cutoff_source: str | None
    warning: str | None
    notes: tuple
    builds: AbstractBuildStore = NoBuildStore()

    @property
    def speeds(self) -> np.ndarray:
        return self.spec.rad_s

    def build(self, formulation: str, back_flanks: bool = True):
        """The model of ``formulation`` (:func:`gearjax.rigs.factory.build_model`, forward
        only; ``back_flanks=False``: without the rig's backlash, the linear equations); a
        cut-off that keeps no vibration mode is reported as ``--max-frequency``'s error.
        Through the :attr:`builds` store (a stored build of the same inputs and code is
        loaded, not computed)."""
        a = self.args
        extra = {} if back_flanks else {"backlash_m": None}
        options = dict(model=a.model, formulation=formulation, law=a.stiffness,
                       damping_ratio=a.damping, encoder_position=a.encoders, **self.nlte,
                       max_frequency_hz=self.cutoff_hz, nlte_reaction=self.reaction,
                       te_table=self.te, moving_events=False, **extra)
        try:
            return self.builds.build(build_model, self.rig, self.scenario.mods, **options)
        except ModelError as exc:
            if exc.field != "max_frequency_hz":
                raise
            reason = str(exc).split(": ", 1)[1]
            raise ValueError(f"--max-frequency={a.max_frequency!r}: {reason}") from None


def dynamics_case(args, command: str, forms, extra_speeds=()) -> dict:
    """The fields of a :class:`DynamicsCase` for ``command`` (``sweep``/``stability``) and
    its formulations ``forms``: every option checked before the rig is read where it can
    be (a bad range, damping, TE file use), then the inputs read. ``extra_speeds``: other
    speeds the 3D cut-off must cover (``--signals``)."""
    if args.speeds is not None:
        parse_speeds(args.speeds)  # a bad range is reported before the rig is read
    _check_damping(args.damping)
    _check_te_file(args, forms)
    reaction = nlte_reaction_of(args)
    rig = rig_of(args)
    spec = speeds_of(args, rig, command, law=args.stiffness, model=args.model,
                     damping=args.damping)
    scen = scenario_modifications(rig, args)
    te = read_te_csv(args.te_file, rig.pair.mesh_period_rad) if args.te_file else None
    cutoff_hz, source = (modal_cutoff(args, rig, np.concatenate([spec.rad_s, extra_speeds]))
                         if args.model == "3d" else (None, None))
    return dict(args=args, rig=rig, spec=spec, scenario=scen, te=te, reaction=reaction,
                nlte=nlte_options_of(args), cutoff_hz=cutoff_hz, cutoff_source=source,
                warning=cutoff_warning(args, rig, cutoff_hz, spec.rad_s),
                notes=tuple(rig_notes(rig, args.model)), builds=build_store())


@dataclasses.dataclass(frozen=True)
class SweepCase(DynamicsCase):
    """A validated ``gearjax sweep``: the :class:`DynamicsCase` plus its formulations,
    ``--signals`` speeds (rad/s), transient tolerances, name, output folder and ``--refine``
    (:func:`gearjax.cli.refine.refinement_of`; None without it)."""

    forms: tuple = ()
    signal_speeds: tuple = ()
    tolerances: dict = dataclasses.field(default_factory=dict)
    name: str = ""
    out: str = ""
    replace: bool = False
    refinement: object = None

    @property
    def csv_path(self) -> str:
        return os.path.join(self.out, "results.csv")

    @property
    def orders_path(self) -> str:  # mesh orders 1-5 (gearjax.dynamics.orders)
        return os.path.join(self.out, "orders.csv")

    def record(self) -> dict:
        """What defines the case: ``case.json`` (``--resume`` compares it) and the head of
        ``summary.json``. The speed *specification*, not the speeds (ten million of them
        are hundreds of MB of JSON); the rig and TE files' contents by digest."""
        a = self.args
        return {
            "case": self.name, "rig": self.rig.name, "model": a.model,
            "stiffness_law": a.stiffness, **self.scenario.summary(), "damping": a.damping,
            "nlte_terms": not a.zero_nlte, "nlte_reaction": self.reaction,
            **({"nlte_inertia": False} if a.no_nlte_terms else {}),
            "encoders": a.encoders, "max_frequency_hz": self.cutoff_hz,
            "formulations": list(self.forms),
            **({"te_file": os.path.abspath(a.te_file)} if a.te_file else {}),
            **input_digests(a), "pinion_torque_Nm": self.rig.pinion_torque_Nm,
            **backlash_record(self.rig),
            **{k: v for k, v in self.spec.record().items() if k != "speeds_source"},
            **({"rtol": float(a.rtol)} if a.rtol is not None else {}),
            **({"direction": a.direction} if a.direction != "independent" else {}),
            **contact_record(a),
            **({"refine_max_speeds": self.refinement.max_speeds} if self.refinement else {}),
        }


def sweep_case(args) -> SweepCase:
    """The :class:`SweepCase` of ``gearjax sweep``'s parsed ``args``; ``ValueError`` naming
    the option for every bad input, before any output is written."""
    from .results import RESULT_FILES

    forms = formulations_of(args.formulations or ("te,perturbation" if args.te_file
                                                  else "reference,te,perturbation"))
    signals = parse_signal_speeds(args.signals)
    if args.model == "torsional" and args.encoders != 1:
        raise ValueError("--encoders: the torsional model has no encoder positions (3d only)")
    if args.resume and args.overwrite:
        raise ValueError("--resume --overwrite: choose one (continue the run, or replace it)")
    if args.chunk is not None and args.chunk < 1:
        raise ValueError(f"--chunk={args.chunk}: must be >= 1")
    tolerances = transient_tolerances(args)
    if tolerances and args.direction != "independent":
        raise ValueError(f"--rtol={args.rtol!r}: for independent sweeps (the continuation of "
                         "--direction keeps its shooting tolerances)")
    common = dynamics_case(args, "sweep", forms, extra_speeds=signals)
    common["nlte"] = model_options_of(args)  # and the te/perturbation contact law
    refinement = refinement_of(args, common["spec"].rad_s.size)
    name = case_name(args, common["scenario"]) + contact_suffix(args)
    out = args.out or os.path.join("gearjax-out", name)
    # a plain re-run (no --out) replaces the earlier run of its own default folder
    replace = (args.out is None and not args.resume and not args.overwrite
               and any(os.path.exists(os.path.join(out, n)) for n in RESULT_FILES))
    return SweepCase(**common, forms=tuple(forms), signal_speeds=tuple(signals),
                     tolerances=tolerances, name=name, out=out, replace=replace,
                     refinement=refinement)
