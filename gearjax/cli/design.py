"""``gearjax optimise`` and ``gearjax harris-map``: tip-relief design from the command line.

Registered through the ``_EXTENSIONS`` hook of :mod:`gearjax.cli.main`. All physics lives in
:mod:`gearjax.design`; this module parses options and formats results.
"""

from __future__ import annotations

import json
import math
import os
import sys
import time

import numpy as np

from ..runtime import HostProgressMeter, watchdog
from ..design.objectives import DynamicObjective
from ..errors import DesignError
from .design_options import add_map_refine, add_orbits, map_refine_of, orbits_of
from .solvers import DESIGN_METHODS, design_solver
from .scenario import (add_nlte_reaction, add_speeds, add_torque, linspace_option,
                       nlte_reaction_of, rig_notes, rig_of, speeds_of)

__all__ = ["register"]

_OBJECTIVES = ("peak-force", "dynamic-factor", "dte-ptp", "te-ptp", "te-rms")
_DYNAMIC = _OBJECTIVES[:3]


def _range(text: str, option: str, lo: float, hi: float, unit: str):
    try:
        return linspace_option(text, option, example="300:500:8", lo=lo, hi=hi,
                               positive=False, unit=unit)
    except ValueError as exc:
        raise DesignError(str(exc)) from None


def _common(p, add_rig):
    add_rig(p)
    p.add_argument("--model", default="torsional", choices=["torsional", "3d"],
                   help="dynamic model: torsional (sdof, default) or 3d (the rig's 3D model "
                        "at its periodic steady state: each value and gradient integrates "
                        "the 3D model from every --orbits start at every speed; with "
                        "--formulation reference a relief where NLTE appears or vanishes "
                        "compiles once more; see the "
                        "Performance page of the documentation for what a step costs)")
    p.add_argument("--max-frequency", type=float, default=None, metavar="HZ",
                   help="3D model: keep the modes below HZ (0 = all modes; default: 3 mesh "
                        "harmonics x 1.5 of the highest speed, at least 6 kHz, as for sweep)")
    p.add_argument("--method", default="auto", choices=list(DESIGN_METHODS),
                   help="periodic steady-state solver of the dynamic objectives: transient "
                        "(diffrax, forward-mode gradients; on the 3D model cut short by a "
                        "periodic estimate after every period), steady (shooting: Newton on "
                        "the periodicity residual, far dearer than the transient on the 3D "
                        "model: one period with a tangent per state each Newton step); auto "
                        "(default): the transient")
    p.add_argument("--rtol", type=float, default=None, metavar="R",
                   help="requested relative accuracy of the dynamic metrics (default: the "
                        "solvers' own, rtol 1e-7 and periodicity 1e-3): integrator rtol "
                        "(atol R/100) and periodicity test, as sweep --rtol")
    p.add_argument("--objective", default="peak-force", choices=list(_OBJECTIVES),
                   help="peak-force (N), dynamic-factor, dte-ptp (m) over --speeds, or te-ptp / "
                        "te-rms (quasi-static TE_S fluctuation at the rig torque)")
    add_speeds(p, "design", "pinion speeds of the dynamic objectives")
    add_torque(p)
    p.add_argument("--inertias", default="bodies", metavar="J1,J2",
                   help="sdof inertias (kg m^2): 'bodies' (default: the gear bodies, solid "
                        "cylinders at the pitch radii) or two values, e.g. 4.48e-3,4.76")
    add_nlte_reaction(p)
    p.add_argument("--formulation", default="te", choices=["te", "reference", "perturbation"],
                   help="formulation (default te, Eq. (20)/(42), with the contact law; "
                        "reference, Eq. (16)/(14): cell-by-cell contact; perturbation, "
                        "Eq. (47a)/(48a))")
    p.add_argument("--shape", default="linear", choices=["linear", "parabolic"])
    p.add_argument("--damping", type=float, default=0.03, help="damping ratio zeta (default 0.03)")
    p.add_argument("--amplitudes", default="2e-6:30e-6:7", metavar="A:B:N",
                   help="map grid of amplitudes (m), default 2e-6:30e-6:7")
    p.add_argument("--extents", default=None, metavar="A:B:N",
                   help="map grid of extents, default 0.1:E:7 with E the upper extent bound "
                        "(0.786 for a linear relief on the spur rig, 0.8 otherwise)")
    p.add_argument("--out", default="design_out", help="output directory (figures, JSON)")
    add_orbits(p)
    add_map_refine(p)


def register(subparsers, add_rig, add_scenario):
    """Add the ``optimise`` and ``harris-map`` sub-commands."""
    opt = subparsers.add_parser("optimise", help="optimise the tip relief (optax, exact gradients)")
    _common(opt, add_rig)
    opt.add_argument("--separate", action="store_true",
                     help="separate pinion and gear reliefs (4 variables; no map)")
    opt.add_argument("--starts", type=int, default=2,
                     help="multi-start grid points per variable (default 2)")
    opt.add_argument("--max-iter", type=int, default=30, help="optimiser steps per start")
    opt.add_argument("--learning-rate", type=float, default=0.1)
    opt.add_argument("--no-map", action="store_true", help="skip the Harris map")
    opt.set_defaults(func=_cmd_optimise)
    hm = subparsers.add_parser("harris-map", help="objective over an (amplitude, extent) grid")
    _common(hm, add_rig)
    hm.set_defaults(func=_cmd_harris_map)


def _setup(args, separate=False):
    from ..design import ReliefSpace, make_objective
    from ..gears.mesh import Mesh
    from .outputs import prepare_output_dir

    if not (0.0 <= args.damping < 1.0):
        raise DesignError(f"--damping={args.damping!r}: must lie in [0, 1)")
    if args.objective not in _DYNAMIC and (args.method != "auto" or args.rtol is not None):
        raise DesignError(f"--method/--rtol: the quasi-static objective {args.objective} "
                          "solves no dynamics (they set peak-force, dynamic-factor, dte-ptp)")
    if args.objective in _DYNAMIC:
        solver = design_solver(args.method, args.rtol)
    reaction = nlte_reaction_of(args)
    prepare_output_dir("--out", args.out)  # before any computing: created and writable
    try:
        rig = rig_of(args)
        spec = speeds_of(args, rig, "design", law=args.stiffness, model=args.model,
                         damping=args.damping)
    except DesignError:
        raise
    except ValueError as exc:  # GearjaxError / range errors: the commands' DesignError
        raise DesignError(str(exc)) from None
    speeds = spec.rad_s
    amps = _range(args.amplitudes, "--amplitudes", 0.0, 40e-6, "m")
    if args.max_frequency is not None and not (math.isfinite(args.max_frequency)
                                               and args.max_frequency >= 0):
        raise DesignError(f"--max-frequency={args.max_frequency!r}: need a cut-off >= 0 Hz (0: all modes)")
    mesh = Mesh.build(rig.pair, args.stiffness, pinion_torque_Nm=rig.pinion_torque_Nm)
    space = ReliefSpace(shape=args.shape, shared=not separate)
    inertias = args.inertias
    if inertias != "bodies":
        try:
            inertias = tuple(float(v) for v in inertias.split(","))
        except ValueError:
            raise DesignError(f"--inertias={args.inertias!r}: expected 'bodies' or J1,J2") from None
        if len(inertias) != 2 or not all(math.isfinite(v) and v > 0 for v in inertias):
            raise DesignError(f"--inertias={args.inertias!r}: need two finite values > 0 (kg m^2)")
    kw = {}
    if args.objective in _DYNAMIC:
        kw = dict(formulation=args.formulation, damping_ratio=args.damping,
                  model=args.model, solver=solver, orbits=orbits_of(args))
        if args.model == "3d":
            kw.update(rig=rig, max_frequency_hz=("auto" if args.max_frequency is None
                                                 else args.max_frequency or None))
        else:
            kw.update(inertias_kg_m2=inertias, nlte_reaction=reaction)
    elif args.model == "3d":
        kw = dict(model="3d", rig=rig)
    obj = make_objective(args.objective, mesh, space, speeds_rad_s=speeds,
                         torques_Nm=rig.pinion_torque_Nm, **kw)
    top = float(obj.space.upper[-1])
    exts = (np.linspace(0.1, min(0.8, top), 7) if args.extents is None
            else _range(args.extents, "--extents", float(obj.space.lower[-1]), top, ""))
    if args.objective in _DYNAMIC:
        args.speeds_record = spec.record()
    for note in rig_notes(rig, args.model):  # after every input check
        print(f"gearjax {args.command}: note: {note}", file=sys.stderr, flush=True)
    return rig, obj, amps, exts


def _case(args, rig) -> dict:
    """What a design run used, for its JSON: rig (and file), model, formulation, torque,
    stiffness law, damping, NLTE'' reaction, speeds."""
    case = {"rig": rig.name, "rig_arg": args.rig, "model": args.model,
            "formulation": args.formulation, "pinion_torque_Nm": rig.pinion_torque_Nm,
            "stiffness_law": args.stiffness, "damping": args.damping,
            "nlte_reaction": args.nlte_reaction, "objective": args.objective,
            "inertias": args.inertias}
    case.update(getattr(args, "speeds_record", {}))
    notes = rig_notes(rig, args.model)
    if notes:
        case["notes"] = notes
    return case


def check_command(args, rig, x: dict) -> tuple[str, str | None]:
    """The ``gearjax sweep`` command that checks an optimum ``x`` (``amplitude_m``,
    ``extent``) by forward sweeps of the same model, damping, torque, law and speeds, and
    a note on what it cannot reproduce (separate reliefs, explicit inertias), or None."""
    import shlex

    amp = x.get("amplitude_m", x.get("amplitude1_m"))
    ext = x.get("extent", x.get("extent1"))
    spec = getattr(args, "speeds_record", {}).get("speeds_spec", "")
    speeds = (["--speeds-rpm", spec.split()[0]] if spec.endswith(" rpm") else
              ["--speeds-mesh-hz", spec.split()[0]] if spec.endswith(" mesh-Hz") else
              ["--speeds", spec])
    forms = "reference,te" if args.formulation == "te" else f"reference,{args.formulation}"
    argv = ["gearjax", "sweep", "--rig", args.rig, "--model", args.model,
            "--formulations", forms, "--relief-amplitude", f"{amp:.6g}",
            "--relief-extent", f"{ext:.6g}", "--relief-shape", args.shape,
            "--damping", f"{args.damping:g}", "--torque", f"{rig.pinion_torque_Nm:g}",
            "--stiffness", args.stiffness, *speeds]
    if args.model == "torsional":
        argv += ["--nlte-reaction", args.nlte_reaction]
    if args.model == "3d" and args.max_frequency is not None:
        argv += ["--max-frequency", f"{args.max_frequency:g}"]
    argv += ["--out", os.path.join(args.out, "check")]
    note = []
    if "amplitude1_m" in x:
        note.append("separate pinion/gear reliefs: the sweep applies the pinion's to both")
    if args.inertias != "bodies":
        note.append(f"--inertias {args.inertias}: the sweep's torsional model takes the bodies")
    return " ".join(shlex.quote(a) for a in argv), "; ".join(note) or None


def _cmd_harris_map(args) -> int:
    from ..design import harris_map
    from ..plotting import plot_design_map

    try:
        rig, obj, amps, exts = _setup(args)
    except DesignError as exc:
        return _fail(str(exc))
    try:
        refine = map_refine_of(args)
    except DesignError as exc:
        return _fail(str(exc))
    hmap = harris_map(obj, amps, exts, refine=refine)
    os.makedirs(args.out, exist_ok=True)
    fig = plot_design_map(hmap, os.path.join(args.out, "harris_map.png"),
                          marks={"short": (13.3e-6, 0.2), "long": (13.3e-6, 0.5)},
                          title=f"{rig.name}: {args.objective}")
    (best_a, best_e), best_v = hmap.best()
    out = {**_case(args, rig), "amplitudes_m": amps.tolist(),
           "extents": exts.tolist(), "exact": hmap.exact.tolist(), "smooth": hmap.smooth.tolist(),
           "best_amplitude_m": float(best_a), "best_extent": float(best_e),
           "best_objective": best_v, "refine_levels": refine,
           "patches": [{"amplitudes_m": q.amplitudes_m.tolist(), "extents": q.extents.tolist(),
                        "exact": q.exact.tolist(), "level": q.level} for q in hmap.patches],
           "wall_time_s": hmap.wall_time_s, "map_png": fig, **_solver(obj, args)}
    with open(os.path.join(args.out, "harris_map.json"), "w") as fh:
        json.dump(out, fh, indent=2)
    if args.json:
        print(json.dumps(out, indent=2))
    else:
        print(f"  {rig.name}: {args.objective} over {amps.size} x {exts.size} reliefs "
              f"({hmap.wall_time_s:.1f} s)")
        print(f"  best point ({'grid' if not refine else f'{refine} refinement level(s)'}): "
              f"amplitude_m {best_a:.3e}  extent {best_e:.3f}  objective {best_v:.6g}")
        print(f"  wrote {fig}")
    return 0


def _cmd_optimise(args) -> int:
    from ..design import coarse_starts, harris_map, multi_start
    from ..plotting import plot_design_map, plot_history

    if args.starts < 1:
        return _fail(f"--starts={args.starts}: need at least 1 start per variable")
    if args.max_iter < 1:
        return _fail(f"--max-iter={args.max_iter}: need at least 1 step")
    try:
        refine = map_refine_of(args)
    except DesignError as exc:
        return _fail(str(exc))
    if not (0 < args.learning_rate <= 10):
        return _fail(f"--learning-rate={args.learning_rate}: must lie in (0, 10]")
    try:
        rig, obj, amps, exts = _setup(args, separate=args.separate)
    except DesignError as exc:
        return _fail(str(exc))
    starts = coarse_starts(obj.space, args.starts)
    steps = [time.monotonic()]

    def n_builds():  # models the dynamic objective has built (a quasi-static one builds none)
        return obj.n_builds if isinstance(obj, DynamicObjective) else 0

    at = {"start": 0, "builds": n_builds()}

    def _step(record):  # one optimiser step done: tell the user
        steps.append(time.monotonic())
        at["start"] = (record["start"] + 1 if "start" in record  # lockstep starts
                       else at["start"] + (record["iteration"] == 0))
        if args.json:  # stdout is the JSON; progress as sweep gives it: not with --json
            return
        builds = n_builds()
        rebuilt = ", model built at this design" if builds > at["builds"] else ""
        at["builds"] = builds
        x = " ".join(f"{n}={v:.5g}" for n, v in zip(obj.space.names, record["x"]))
        print(f"  start {at['start']}/{len(starts)} step {record['iteration']}: {x}  "
              f"objective {record['exact']:.6g} (smoothed {record['smooth']:.6g}), "
              f"{steps[-1] - steps[-2]:.1f} s{rebuilt}", file=sys.stderr, flush=True)

    best, runs = multi_start(obj, starts, max_iter=args.max_iter,
                             learning_rate=args.learning_rate, callback=_step,
                             progress=HostProgressMeter())  # watchdog, map cap
    # the value a forward sweep of the optimum gives: the objective's model was built at
    # a start and mapped to each design (gearjax.design.DynamicObjective.rebuilt)
    rebuilt = obj.rebuilt(best.x) if isinstance(obj, DynamicObjective) else None
    # the map is one vmapped call over the grid: allow it 3x the forward cost estimated
    # from the slowest optimiser step (value and gradient)
    slowest = max(np.diff(steps[1:]), default=steps[-1] - steps[0])
    watchdog.progress("optimiser done, Harris map next", expect_s=3.0 * amps.size * exts.size * slowest)
    os.makedirs(args.out, exist_ok=True)
    out = {**_case(args, rig), "shape": args.shape, "shared": not args.separate,
           **_solver(obj, args)}
    out.update(best.as_dict(obj.space))
    if args.objective in _DYNAMIC:  # everything a forward sweep of the optimum needs
        out["check_command"], why = check_command(args, rig, out)
        if why:
            out["check_command_note"] = why
    if rebuilt is not None:
        out["objective_after_rebuilt"] = rebuilt.exact
        out["orbits"] = obj.orbits.label
        if rebuilt.per_orbit is not None:
            out["objective_per_orbit"] = [float(v) for v in rebuilt.per_orbit]
    out["runs"] = [r.as_dict(obj.space) for r in runs]
    out["history_png"] = plot_history(runs, os.path.join(args.out, "history.png"), args.objective)
    if not args.no_map and not args.separate:
        hmap = harris_map(obj, amps, exts, refine=refine, around=[best.x])
        out["map_value_at_optimum"] = hmap.value_at(best.x)
        (out["map_best_amplitude_m"], out["map_best_extent"]), out["map_best_objective"] = (
            tuple(float(v) for v in hmap.best()[0]), hmap.best()[1])
        out["map_png"] = plot_design_map(
            hmap, os.path.join(args.out, "map.png"), results=runs,
            marks={"short": (13.3e-6, 0.2), "long": (13.3e-6, 0.5)},
            title=f"{rig.name}: {args.objective}")
    with open(os.path.join(args.out, "optimum.json"), "w") as fh:
        json.dump(out, fh, indent=2)
    if args.json:
        print(json.dumps(out, indent=2))
        return 0
    names = obj.space.names
    how = f", {args.method}" if isinstance(obj, DynamicObjective) else ""
    print(f"  {rig.name}: {args.objective} ({args.model}{how}, {args.shape} relief, NLTE'' "
          f"reaction at the {args.nlte_reaction}), {len(runs)} starts")
    for n in names:
        print(f"  {n:14s} {out[n]:.6g}")
    print(f"  objective before {best.exact0:.6g}  after {best.exact:.6g} "
          f"(smoothed {best.smooth0:.6g} -> {best.smooth:.6g}), stop: {best.stop_reason}")
    if "objective_after_rebuilt" in out:
        print(f"  on a model built at the optimum, as sweep builds it: "
              f"{out['objective_after_rebuilt']:.6g}")
    if "orbits" in out:
        per = out.get("objective_per_orbit")
        print(f"  orbits: the largest over the starts {out['orbits']}"
              + (f" ({', '.join(f'{v:.6g}' for v in per)} at the optimum)" if per else ""))
    if "map_value_at_optimum" in out:
        print(f"  Harris map at the optimum {out['map_value_at_optimum']:.6g}, its best point "
              f"{out['map_best_objective']:.6g} at amplitude_m "
              f"{out['map_best_amplitude_m']:.3e} extent {out['map_best_extent']:.3f}")
    print(f"  wrote {out['history_png']}" + (f", {out['map_png']}" if "map_png" in out else "")
          + f", {os.path.join(args.out, 'optimum.json')}")
    if "check_command" in out:
        print(f"  check the optimum by forward sweeps: {out['check_command']}"
              + (f"  ({out['check_command_note']})" if "check_command_note" in out else ""))
    return 0


def _solver(obj, args) -> dict:
    """The solver of a dynamic objective for the JSON outputs (``--method``, ``--rtol``,
    the orbit set)."""
    if not isinstance(obj, DynamicObjective):
        return {}
    return {"method": args.method, "rtol": args.rtol, "orbits": obj.orbits.label}




def _fail(msg: str) -> int:
    print(f"gearjax: error: {msg}", file=sys.stderr)
    return 2
