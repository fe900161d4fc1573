"""``gearjax sweep`` and ``gearjax stability``: dynamic response curves (Figs. 8-13) and
Floquet stability maps, for the sdof torsional model and the 3D model.

Registered by :mod:`gearjax.cli.main` (``_EXTENSIONS``). The commands parse options, build the
models with :func:`gearjax.rigs.factory.build_model` and format results; the physics lives
in :mod:`gearjax.models`, :mod:`gearjax.dynamics.simulate`, :mod:`gearjax.dynamics.sweep`,
:mod:`gearjax.dynamics.stability` and :mod:`gearjax.rigs.figures` (predicted critical
speeds).

Section 6.3 cases (Velex & Ajmi), one command each (``--speeds`` to taste)::

    gearjax sweep                                           # 6.3.1, zeta 0.1 (the default case)
    gearjax sweep --damping 0.03                            # 6.3.1, zeta 0.03 (Fig. 8)
    gearjax sweep --relief long --signals 100,400,800       # 6.3.2 (Figs. 10, 11)
    gearjax sweep --relief long --no-nlte-terms --formulations te      # 6.3.2, NLTE'' = 0
    gearjax sweep --relief long --zero-nlte --formulations te          # NLTE = 0 everywhere
    gearjax sweep --pitch-errors                            # 6.3.3 (Fig. 12)
    gearjax sweep --rig baud-velex-helical --pitch-errors --damping 0.03   # 6.3.4 (Fig. 13)
    gearjax sweep --encoders 2                              # 6.3.5 (also 1 and 3)

Several hosts (or several processes on one host): start the same command on every process
with ``--distributed`` (cluster auto-detection: SLURM, Open MPI, ...) or with
``--coordinator HOST:PORT --num-processes N --process-id I``; the speeds are shared over
every device of every process and process 0 writes the outputs. ``--backlash`` (sweep):
:mod:`gearjax.cli.backlash`; stability analyses the linear equations, without back flanks.

3D modal cut-off: without ``--max-frequency`` the model keeps the modes below 3 mesh
harmonics of the highest requested speed times 1.5, at least 6 kHz
(:func:`default_max_frequency_hz`; 16.8 kHz for the default sweep to 900 rad/s, 27.9 kHz
for the default stability range to 1500 rad/s); ``--max-frequency 0`` keeps all modes.

NLTE'' reaction: at the drive by default, as in the 3D model and the design commands
(``--nlte-reaction``, :func:`gearjax.cli.scenario.add_nlte_reaction`); ``--nlte-reaction
pinion`` (torsional model only) gives Eqs. (15)-(16) as written. ``case.json`` and
``summary.json`` record it.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import sys
import time

import numpy as np

from ..runtime import watchdog
from ..runtime.cache import program_store
from ..runtime.progress import command_meter
from ..models.base import LINEAR_FORMULATIONS
from ..dynamics.harmonic_sweep import HARMONIC_FLOQUET_MAX_STATES
from ..dynamics.sweep import FREQUENCY_DOMAIN_MIN_SPEEDS
from ..gears.quasistatic import static_mesh_force
from ..rigs.campbell import campbell
from ..rigs.figures import predicted_critical_speeds
from .ahead import Ahead, build_and_compile_ahead
from .backlash import add_backlash
from .branches import DIRECTION_CHOICES, check_direction, plot_directions, run_branches
from .case import (DynamicsCase, SweepCase, dynamics_case, sweep_case,
                   transient_tolerances)
from .devices import device_count, init_distributed, sweep_devices
from .contact import add_te_contact
from .iso import iso_dynamic_factor
from .refine import add_refine, refine_runner, refine_sweeps
from .signals import last_mesh_period_signals, write_order_tracks, write_signals
from .solvers import METHODS, STABILITY_METHODS, solver_for
from .scenario import (add_nlte_reaction, add_nlte_switches, add_speeds, add_torque,
                       missed_critical_speed)

__all__ = ["register", "cmd_sweep", "cmd_stability", "check_processes", "work_estimate"]
# undamped stability: |spectral radius - 1| below this is round-off of the monodromy matrix
# (neutral), above it a parametric instability
NEUTRAL_TOLERANCE = 1e-6


def register(sub, add_rig, add_scenario):
    """Add ``sweep`` and ``stability`` to the ``gearjax`` sub-command parser."""
    sw = sub.add_parser(
        "sweep", help="steady-state dynamic response over pinion speeds (Figs. 8-13)",
        description="Steady-state response curves of Section 6 (default: the paper's spur case, "
                    "3D model, short relief, damping 0.1, all three formulations, 20-900 rad/s). "
                    "A second run loads its models, programs and executables from the cache "
                    "folder ($XDG_CACHE_HOME/gearjax/jax, default ~/.cache/gearjax/jax; "
                    "GEARJAX_COMPILATION_CACHE=0: none).",
    )
    add_rig(sw)
    add_scenario(sw)
    _add_dynamics(sw)
    sw.add_argument("--formulations", default=None,
                    help="comma-separated subset of reference,te,perturbation (default all; "
                         "te,perturbation with --te-file)")
    add_speeds(sw, "sweep")
    add_backlash(sw)
    sw.add_argument("--signals", default=None, metavar="SPEEDS",
                    help="comma-separated pinion speeds (rad/s) whose mesh force over the last "
                         "mesh period is also written and plotted (Fig. 11), e.g. 100,400,800")
    sw.add_argument("--out", default=None, metavar="DIR",
                    help="output folder (default ./gearjax-out/<case>/, whose earlier run a "
                         "plain re-run replaces, saying so); a given folder holding an "
                         "earlier run is refused unless --resume or --overwrite")
    sw.add_argument("--resume", action="store_true",
                    help="continue an interrupted sweep in its --out folder: same options "
                         "(checked against its case.json), speeds already in results.csv skipped")
    sw.add_argument("--overwrite", action="store_true",
                    help="replace the results of an earlier run in the --out folder")
    sw.add_argument("--method", default="auto", choices=METHODS,
                    help="periodic steady-state solver: harmonic (frequency domain, te and "
                         "perturbation; speeds where the linear orbit loses contact or is not "
                         "proven stable go to the transient), steady (shooting), transient; "
                         "auto (default): the cheapest measured from what the model declares "
                         "and the number of speeds (gearjax.Auto): harmonic for te of the 3D "
                         f"model from {FREQUENCY_DOMAIN_MIN_SPEEDS} speeds, the transient "
                         "otherwise (3D: accelerated by a periodic estimate after every "
                         "period; perturbation started on its frequency-domain orbit)")
    sw.add_argument("--rtol", type=float, default=None, metavar="R",
                    help="requested relative accuracy of the metrics (default: each solver's "
                         "own, rtol 1e-7 and periodicity 1e-3): integrator rtol (atol R/100), "
                         "harmonic truncation, transient decay and periodicity test "
                         "(gearjax.dynamics.sweep.tolerance_options); independent sweeps")
    sw.add_argument("--direction", default="independent", choices=DIRECTION_CHOICES,
                    help="independent (default): every speed from the quasi-static start; "
                         "up/down: each speed from its neighbour's periodic orbit (shooting; "
                         "--method not used; results.csv gains direction, orbit, spectral_radius,"
                         " restarted); both: up, down and the whole curve, stable and unstable, "
                         "by arclength continuation with its folds and jumps (branches.csv)")
    sw.add_argument("--chunk", type=int, default=None,
                    help="speeds per compiled call (progress and CSV rows per chunk; default "
                         "gearjax.dynamics.sweep.default_chunk_size: on a CPU 16-64 speeds per "
                         "core by the model's size (the speeds of a chunk run in lockstep and "
                         "their solver stages must stay in cache), on a GPU every speed that "
                         "memory holds)")
    from .iso import add_iso_options

    add_iso_options(sw)
    add_te_contact(sw)
    add_refine(sw)
    dist = sw.add_argument_group("several hosts (jax.distributed)")
    dist.add_argument("--distributed", action="store_true",
                      help="join a multi-process run (jax.distributed.initialize with cluster "
                           "auto-detection); run the same command on every process")
    dist.add_argument("--coordinator", default=None, metavar="HOST:PORT",
                      help="address of process 0's coordinator (implies --distributed)")
    dist.add_argument("--num-processes", type=int, default=None, metavar="N")
    dist.add_argument("--process-id", type=int, default=None, metavar="I")
    sw.set_defaults(func=cmd_sweep)

    st = sub.add_parser(
        "stability", help="Floquet spectral radius of the linear formulations over speeds",
        description="Parametric stability: spectral radius of the monodromy matrix of the "
                    "linear time-periodic te (or perturbation) equations; > 1 inside an "
                    "instability zone.",
    )
    add_rig(st)
    add_scenario(st)
    _add_dynamics(st)
    st.add_argument("--formulation", default="te", choices=["te", "perturbation"],
                    help="linear formulation to analyse (default te; the reference linearised "
                         "about the quasi-static contact is the te equation)")
    add_speeds(st, "stability")
    st.add_argument("--method", default="auto", choices=STABILITY_METHODS,
                    help="steady: the spectral radius of the monodromy matrix (one period "
                         "of n columns, as the shooting's: costly on the 3D rig); "
                         "harmonic: the frequency-domain solver's small-gain bound first, "
                         "which proves stability without integrating (3D, damping 0.1: "
                         "every speed), the monodromy only where it does not; auto "
                         "(default): steady up to "
                         f"{HARMONIC_FLOQUET_MAX_STATES} states (sdof), harmonic above")
    st.add_argument("--rtol", type=float, default=None, metavar="R",
                    help="integrator rtol of the monodromy (atol R/100; default 1e-10)")
    st.set_defaults(func=cmd_stability)


def _add_dynamics(p: argparse.ArgumentParser):
    p.add_argument("--model", default="3d", choices=["torsional", "3d"],
                   help="3d (default: shafts, bearings, pinion-gear element, Eqs. (14), (42), "
                        "(48a)) or torsional (sdof, Eqs. (16), (20), (47a); solid gear bodies, "
                        "not the rig's discs)")
    add_torque(p)
    add_nlte_reaction(p)
    p.add_argument("--damping", type=float, default=0.1, metavar="ZETA",
                   help="modal damping factor (default 0.1; the paper also uses 0.03)")
    p.add_argument("--encoders", type=int, default=1, choices=[1, 2, 3],
                   help="3d: encoder positions of Fig. 7 defining TE and DTE (default 1)")
    add_nlte_switches(p)
    p.add_argument("--te-file", default=None, metavar="FILE.csv",
                   help="te/perturbation: TE_S, NLTE and mesh stiffness from a CSV file "
                        "(columns mesh_cycle_fraction or pinion_angle_rad, te_s_m, optional "
                        "nlte_m, mesh_stiffness_N_per_m; paper Section 6.2) instead of the "
                        "quasi-static solve; 3d: TE_S as measured at --encoders")
    p.add_argument("--max-frequency", type=float, default=None, metavar="HZ",
                   help="3d: keep the modes below HZ plus static correction (0: all modes; "
                        "default: 3 mesh harmonics of the highest speed x 1.5, at least "
                        "6000 Hz)")


def _stderr(command: str, kind: str, text: str) -> None:
    print(f"gearjax {command}: {kind}: {text}", file=sys.stderr, flush=True)


def _prepare_outputs(case: SweepCase, lead: bool) -> dict:
    """Check the output folder and write ``case.json`` before anything is computed
    (process 0 only); the ``{formulation: speeds}`` already in ``results.csv`` when
    resuming, else empty."""
    from ..dynamics.results import CSV_COLUMNS, ORDER_COLUMNS, check_header
    from .outputs import prepare_output_dir
    from .results import RESULT_FILES, check_resume, done_speeds, read_rows, write_case

    if not lead:
        return {}
    prepare_output_dir("--out", case.out, results=RESULT_FILES, resume=case.args.resume,
                       overwrite=case.args.overwrite or case.replace)
    if case.replace:
        _stderr("sweep", "note", f"replacing the earlier run in {case.out} (this case's default "
                "folder; --resume continues it instead, --out DIR keeps both)")
    done: dict = {}
    if case.args.resume:
        check_resume(case.out, case.record())
        for path, columns in ((case.csv_path, CSV_COLUMNS), (case.orders_path, ORDER_COLUMNS)):
            check_header(path, columns, "--resume")
        done = done_speeds(read_rows(case.csv_path, repair=True))
        read_rows(case.orders_path, repair=True)
    write_case(case.out, case.record())
    return done


def _summary_head(case: SweepCase, devices, notes: list[str]) -> dict:
    """``summary.json`` before any result: the case record and what the run chose."""
    a = case.args
    return {
        **case.record(), "relief": a.relief or case.scenario.key,
        "nlte_inertia": case.nlte["nlte_inertia"], "te_file": a.te_file,
        "max_frequency_source": case.cutoff_source, "rtol": a.rtol,
        "devices": device_count(devices), "backlash_m": case.rig.backlash_m,
        "static_mesh_force_N": static_mesh_force(case.rig.pair, case.rig.pinion_torque_Nm),
        **case.spec.record(),
        **({"excitation": _excitation(a, case.te, case.scenario)} if case.te is not None else {}),
        "formulations": {},
        **({"warnings": [case.warning]} if case.warning else {}),
        **({"notes": notes} if notes else {}),
        **({"replaced_earlier_run": True} if case.replace else {}),
        **iso_dynamic_factor(a, case.rig, case.scenario.mods, case.speeds),
    }


def _model_summary(model, speeds, lead: bool, three_d: bool) -> dict:
    """What the first model built tells ``summary.json``: its predicted critical speeds
    (and a warning where the sweep misses the main one), its k_m as ``gearjax info`` names
    it (:mod:`gearjax.rigs.loaded`), its own critical speeds (``gearjax campbell``'s marked
    crossings, orders 1-5: ``gearjax paper`` judges "near a critical speed" by them) and,
    3D, its mode count and w_x0."""
    out = {"predicted": predicted_critical_speeds(model)}
    missed = missed_critical_speed(out["predicted"], speeds)
    if missed:
        out["warnings"] = [missed]
        if lead:
            _stderr("sweep", "warning", missed)
    out["loaded_mean_mesh_stiffness_N_per_m"] = float(model.k_m)
    out["critical_speeds"] = campbell(model, float(np.max(speeds))).critical_speeds()
    if three_d:
        out.update(n_modes=int(model.n_modes), w_x0_m=float(model.w_x0))
    return out


@dataclasses.dataclass
class _Runs:
    """What the formulations' sweeps gave: per formulation (build s, sweep s), the speeds
    per solver, the continuation summaries and the ``--signals`` records."""

    times: dict = dataclasses.field(default_factory=dict)
    methods: dict = dataclasses.field(default_factory=dict)
    branches: dict = dataclasses.field(default_factory=dict)
    signals: dict = dataclasses.field(default_factory=dict)
    interrupted: bool = False


def _sweep_formulations(case: SweepCase, first, done: dict, devices, lead: bool,
                        summary: dict) -> _Runs:
    """Sweep every formulation of ``case`` in turn (``first``: the model of the first one,
    already built), appending rows to ``results.csv``/``orders.csv``; a 3D te/perturbation
    pair shares one build, and the next program compiles ahead (:mod:`gearjax.cli.ahead`).
    Ctrl-C ends the loop with what is written."""
    from ..dynamics.sweep import sweep
    from .results import method_counts

    a, speeds, runs = case.args, case.speeds, _Runs()
    programs = program_store()  # exported by an earlier run: not traced again

    def todo_of(form):  # vectorised: ten million speeds in well under a second
        got = np.fromiter(done.get(form, ()), dtype=float)
        return speeds[~np.isin(speeds, got)] if got.size else speeds

    def sweep_options(model):
        size = None if a.chunk is None else min(a.chunk, todo_of(model.formulation.name).size)
        return dict(solver=solver_for(a.method, model, a.rtol, case.tolerances),
                    chunk_size=size, devices=devices, programs=programs)

    linear, models = None, {}  # a 3D te/perturbation model: the other one shares its build
    early, ahead = {case.forms[0]: first}, Ahead()  # models built ahead, compiling programs
    try:
        for form in case.forms:
            t0 = time.perf_counter()
            shared = linear is not None and form in LINEAR_FORMULATIONS
            if shared:
                model = linear.with_formulation(form)
            elif form in early:
                model, t_pre = early.pop(form)
                t0 -= t_pre  # its build's time, before this formulation's turn
            else:
                model = case.build(form)
            t_build = time.perf_counter() - t0
            traced = 0.0
            if ahead.own is None and ahead.nxt is None:
                ahead = build_and_compile_ahead(a, list(case.forms), form, model, case.build,
                                                todo_of, sweep_options, early)
                traced = ahead.own_trace_s  # this formulation's tracing, done ahead
            built = (f"the {linear.formulation} build" if shared else
                     f"{a.model} model built in {t_build:.1f} s")
            if a.model == "3d" and form in LINEAR_FORMULATIONS and not shared:
                linear = model
            if "predicted" not in summary:
                extra = _model_summary(model, speeds, lead, a.model == "3d")
                summary.setdefault("warnings", []).extend(extra.pop("warnings", []))
                summary.update(extra)
            todo = todo_of(form)
            if lead and not a.json:
                left = f", {todo.size} left to compute" if todo.size < speeds.size else ""
                print(f"  {form}: {speeds.size} speeds {speeds[0]:.0f}-{speeds[-1]:.0f} rad/s"
                      f"{left} ({built})", file=sys.stderr, flush=True)
            t0 = time.perf_counter()
            if todo.size and a.direction != "independent":
                runs.branches[form] = run_branches(model, todo, a.direction, case.csv_path,
                                                   progress=command_meter(not a.json))
            elif todo.size:
                ahead.join(mine=form == "reference", linear=form in LINEAR_FORMULATIONS)
                res = sweep(model, todo, progress=command_meter(not a.json),
                            out_csv=case.csv_path, orders_csv=case.orders_path,
                            **sweep_options(model))
                runs.methods[form] = method_counts(res)
            runs.times[form], models[form] = (t_build, time.perf_counter() - t0 + traced), model
            if case.signal_speeds and lead:
                runs.signals[form] = last_mesh_period_signals(model, list(case.signal_speeds))
        if case.refinement is not None:  # every formulation at every added speed
            meter = command_meter(not a.json)
            run = refine_runner(lambda m, w, **o: sweep(
                m, w, out_csv=case.csv_path, progress=meter, orders_csv=case.orders_path, **o),
                sweep_options, speeds.size)
            summary["refinement"] = refine_sweeps(models, case.csv_path,
                                                  (case.csv_path, case.orders_path), run,
                                                  case.refinement, meter)
    except KeyboardInterrupt:
        runs.interrupted = True
    if not summary.get("warnings"):
        summary.pop("warnings", None)
    return runs


def _agreement(rows: list[dict], forms) -> dict:
    """Per te/perturbation formulation, the largest and median relative difference of
    the max mesh force from the reference's at the speeds both computed."""
    from .results import max_force_by_speed

    ref = max_force_by_speed(rows, "reference")
    agree = {}
    for f in forms:
        if f == "reference":
            continue
        mine = max_force_by_speed(rows, f)
        rel = [abs(mine[w] - ref[w]) / ref[w] for w in mine if w in ref]
        if rel:
            agree[f] = {"max_rel_diff_max_mesh_force": float(np.nanmax(rel)),
                        "median_rel_diff_max_mesh_force": float(np.nanmedian(rel))}
    return agree


def _finish(case: SweepCase, summary: dict, runs: _Runs, t_all: float) -> int:
    """Summarise whatever rows ``results.csv`` holds, draw the figures, write
    ``summary.json`` and print the closing table (or the JSON, or the interruption)."""
    from ..plotting import plot_response_curves
    from .results import print_summary, read_rows, summarise_rows

    a, speeds = case.args, case.speeds
    rows = read_rows(case.csv_path)
    for form in case.forms:
        if not any(r["formulation"] == form for r in rows):
            continue
        s = summarise_rows(rows, form, speeds)
        t_build, elapsed = runs.times.get(form, (float("nan"), float("nan")))
        s.update(build_time_s=t_build, wall_time_s=elapsed)
        if form in runs.methods:
            s["method"] = runs.methods[form]
        if form in runs.branches:
            s["branches"] = runs.branches[form]
        summary["formulations"][form] = s
    if "reference" in summary["formulations"]:
        summary["agreement_with_reference"] = _agreement(rows, summary["formulations"])
    summary["results_csv"] = case.csv_path
    scen = case.scenario
    title = (f"{case.rig.name}, {a.model}, "
             f"{summary['excitation'] if case.te is not None else scen.label}"
             f"{', pitch errors' if scen.pitch_errors else ''}, damping {a.damping}"
             + (", NLTE = 0" if a.zero_nlte else ", NLTE'' = 0" if a.no_nlte_terms else "")
             + f"{' (interrupted)' if runs.interrupted else ''}")
    if rows:
        fig_path = os.path.join(case.out, "response_curves.png")
        if a.direction == "independent":
            dense = np.linspace(float(speeds[0]), float(speeds[-1]), 400)  # ISO's ranges' kinks
            kv = iso_dynamic_factor(a, case.rig, scen.mods, dense)["iso6336_kv"]
            plot_response_curves(case.csv_path, fig_path, title=title,
                                 iso_kv=(dense, kv, summary["iso6336_resonance_speed_rad_s"]))
        else:  # the continuations' figure (gearjax.cli.branches)
            plot_directions(a.direction, case.out, summary, fig_path, title)
        summary["response_curves_png"] = fig_path
        summary.update(write_order_tracks(case.orders_path, case.out, title))
    if runs.signals and not runs.interrupted:
        summary.update(write_signals(runs.signals, case.out, title))
    summary["total_time_s"] = time.perf_counter() - t_all
    if runs.interrupted:
        summary["interrupted"] = True
    with open(os.path.join(case.out, "summary.json"), "w") as fh:
        json.dump(summary, fh, indent=2)
    if runs.interrupted:
        n = len(rows)
        print(f"gearjax: interrupted (Ctrl-C); kept {n} result row{'s' * (n != 1)} in {case.out} "
              f"(summary.json{', response_curves.png' if rows else ''}); continue with the same "
              "command and --resume", file=sys.stderr)
        return 130
    if a.json:
        print(json.dumps(summary, indent=2))
    else:
        print_summary(case.rig, summary, case.out)
    return 0


def check_processes(args) -> None:
    """The option checks that must come before joining a distributed run: ``--resume``
    and ``--direction`` are for one process."""
    if args.resume and (args.distributed or args.coordinator is not None
                        or args.num_processes is not None):
        raise ValueError("--resume: not with several processes (resume on one process, or "
                         "start a new --out folder)")
    check_direction(args)


def cmd_sweep(args) -> int:
    """``gearjax sweep``: a validated case, the first model built (a bad cut-off is an
    input error, reported before any output), the output folder prepared, every
    formulation swept, the summary written."""
    check_processes(args)
    lead = init_distributed(args)
    case = sweep_case(args)
    if case.warning and lead:
        _stderr("sweep", "warning", case.warning)
    t0 = time.perf_counter()
    first = (case.build(case.forms[0]), time.perf_counter() - t0)
    done = _prepare_outputs(case, lead)
    devices = sweep_devices(args.method)
    notes = list(case.notes)
    estimate = work_estimate(args.model, case.speeds.size, len(case.forms))
    if estimate:
        notes.append(estimate)
    if lead:
        for note in notes:
            _stderr("sweep", "note", note)
    summary = _summary_head(case, devices, notes)
    if done:
        summary["resumed"] = {f: len(v) for f, v in done.items()}
    if lead:  # a stall (gearjax.runtime.watchdog) ends the process: say where the rows are
        watchdog.add_stall_hook(lambda: f"the speeds finished so far are in {case.csv_path}; "
                                        "continue with the same command and --resume")
    t_all = time.perf_counter()
    runs = _sweep_formulations(case, first, done, devices, lead, summary)
    if not lead:
        return 130 if runs.interrupted else 0  # process 0 writes the outputs
    return _finish(case, summary, runs, t_all)


# Cost of one speed of one formulation after compiling, on 2 CPU cores
# (benchmarks/results/scaling_3d.md and sdof_exact_2000.md): the estimate announced
# before a long sweep.
SECONDS_PER_SPEED = {"3d": 0.024, "torsional": 0.001}
ANNOUNCE_S = 600.0  # sweeps estimated to take longer are announced with their estimate


def work_estimate(model: str, n_speeds: int, n_forms: int) -> str | None:
    """A one-line estimate of a sweep's computing time where it exceeds
    :data:`ANNOUNCE_S` (speeds x formulations x :data:`SECONDS_PER_SPEED`), else None."""
    t = SECONDS_PER_SPEED[model] * n_speeds * n_forms
    if t < ANNOUNCE_S:
        return None
    when = f"{t / 3600:.1f} h" if t >= 3600 else f"{t / 60:.0f} min"
    return (f"{n_speeds:,} speeds x {n_forms} formulation(s): about {when} of computing at "
            f"the measured ~{SECONDS_PER_SPEED[model] * 1e3:g} ms per speed of the {model} "
            "model on 2 CPU cores; rows are written as they finish, Ctrl-C keeps them and "
            "--resume continues")


def _excitation(args, te, scen) -> str:
    """What excites a --te-file sweep: the file (and the relief only where the file has
    no stiffness column: the model's own mesh stiffness)."""
    name = os.path.basename(args.te_file)
    if te.has_stiffness:
        return f"TE file {name} (TE_S, NLTE, stiffness)"
    return f"TE file {name} (TE_S, NLTE; mesh stiffness from {scen.label})"


def cmd_stability(args) -> int:
    from ..dynamics.harmonic import small_gain_bounds
    from ..dynamics.small_gain import SMALL_GAIN_MARGIN
    from ..dynamics.stability import spectral_radius

    # the monodromy's integrator takes --rtol (atol R/100): the accuracy of rho
    tols = {k: v for k, v in transient_tolerances(args).items() if k in ("rtol", "atol")}
    case = DynamicsCase(**dynamics_case(args, "stability", [args.formulation]))
    rig, spec, speeds, scen = case.rig, case.spec, case.speeds, case.scenario
    reaction, cutoff_hz, cutoff_source = case.reaction, case.cutoff_hz, case.cutoff_source
    warning, notes = case.warning, list(case.notes)  # after every input check: one line
    if warning:
        _stderr("stability", "warning", warning)
    for note in notes:
        _stderr("stability", "note", note)
    model = case.build(args.formulation, back_flanks=False)  # linear: no back flanks
    method = args.method
    if method == "auto":  # the monodromy costs n columns: cheap for the sdof model only
        method = "steady" if model.state_size <= HARMONIC_FLOQUET_MAX_STATES else "harmonic"
    t0 = time.perf_counter()
    bound = np.full(speeds.size, np.nan)
    rho = np.full(speeds.size, np.nan)
    proven = np.zeros(speeds.size, dtype=bool)
    if method == "harmonic":
        bound = small_gain_bounds(model, speeds)
        proven = bound < SMALL_GAIN_MARGIN
    need = np.flatnonzero(~proven)
    if need.size:
        rho[need] = np.asarray(spectral_radius(model, speeds[need], **tols), dtype=float)
    # Undamped, a stable linear time-periodic system has all Floquet multipliers on the unit
    # circle: radius 1 up to the round-off of the monodromy matrix is neutral, not unstable.
    tol = NEUTRAL_TOLERANCE if args.damping == 0 else 0.0
    state = np.where(proven, "stable", np.where(rho > 1.0 + tol, "unstable",
                     np.where(rho >= 1.0 - tol, "neutral", "stable")))
    state = np.where(~proven & ~np.isfinite(rho), "failed", state)
    out = {
        "rig": rig.name, "model": args.model, "formulation": args.formulation,
        "relief": args.relief or scen.key, **scen.summary(), "damping": args.damping,
        "stiffness_law": args.stiffness, "nlte_reaction": reaction, "te_file": args.te_file,
        "pinion_torque_Nm": rig.pinion_torque_Nm, **spec.record(),
        **({"notes": notes} if notes else {}),
        "max_frequency_hz": cutoff_hz, "max_frequency_source": cutoff_source,
        "method": method, "rtol": args.rtol, "monodromies": int(need.size),
        "wall_time_s": time.perf_counter() - t0,
        "neutral_tolerance": tol,
        "results": [{"speed_rad_s": float(w),
                     "spectral_radius": None if p else float(r),
                     **({} if np.isnan(b) else {"small_gain_bound": float(b)}),
                     "state": str(st), **({"proof": "small-gain bound"} if p else {})}
                    for w, r, b, st, p in zip(speeds, rho, bound, state, proven)],
        "unstable_speeds_rad_s": [float(w) for w, st in zip(speeds, state) if st == "unstable"],
        **({"warnings": [warning]} if warning else {}),
    }
    if args.json:
        print(json.dumps(out, indent=2))
        return 0
    print(f"  {rig.description}; {args.model} {args.formulation}, {scen.label}, "
          f"damping {args.damping}, NLTE'' reaction at the {reaction}")
    if args.model == "3d":
        print(f"  modes {'below %.0f Hz' % cutoff_hz if cutoff_hz else 'all'} ({cutoff_source})")
    print(f"  method {method}: " + (
        f"small-gain bound, monodromy at {need.size} of {speeds.size} speed(s)"
        if method == "harmonic" else "monodromy at every speed")
        + f" ({out['wall_time_s']:.1f} s)")
    if tol:
        print(f"  undamped: a spectral radius within {tol:g} of 1 is neutral (Floquet "
              "multipliers on the unit circle), not unstable")
    head = f"  {'speed [rad/s]':>14s} {'spectral radius':>16s}"
    print(head + (f" {'small-gain bound':>17s}" if method == "harmonic" else ""))
    flag = {"unstable": "   UNSTABLE (parametric)", "neutral": "   neutral", "stable": "",
            "failed": "   monodromy integration failed"}
    for w, r, b, st, p in zip(speeds, rho, bound, state, proven):
        radius = f"{'< 1 (proven)':>16s}" if p else f"{r:16.6f}"
        extra = f" {b:17.4f}" if method == "harmonic" else ""
        print(f"  {w:14.1f} {radius}{extra}{flag[str(st)]}")
    return 0
