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
every device of every process and process 0 writes the outputs.

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
import json
import math
import os
import sys
import time

import numpy as np

from ..models.geared3d import (  # the default modal cut-off rule lives with the 3D model
    CUTOFF_FLOOR_HZ,
    CUTOFF_MARGIN,
    CUTOFF_MESH_HARMONICS,
    default_max_frequency_hz,
)
from ..runtime import watchdog
from ..runtime.progress import command_meter
from ..models.base import LINEAR_FORMULATIONS
from ..dynamics.harmonic_sweep import HARMONIC_FLOQUET_MAX_STATES
from ..dynamics.sweep import tolerance_options
from ..errors import SimulationError
from ..excitation.te_file import read_te_csv
from ..gears.quasistatic import static_mesh_force
from ..rigs.factory import build_model
from ..rigs.campbell import campbell
from ..rigs.figures import predicted_critical_speeds
from .ahead import Ahead, build_and_compile_ahead
from .branches import DIRECTION_CHOICES, check_direction, run_branches
from .devices import device_count, init_distributed, sweep_devices
from .iso import iso_dynamic_factor
from .signals import last_mesh_period_signals, write_order_tracks, write_signals
from .solvers import METHODS, STABILITY_METHODS, solver_for
from .scenario import (add_nlte_reaction, add_nlte_switches, add_speeds, add_torque,
                       input_digests, linspace_option, missed_critical_speed, nlte_options_of,
                       nlte_reaction_of, rig_notes, rig_of, speeds_of)

__all__ = ["register", "parse_speeds", "case_name", "default_max_frequency_hz", "modal_cutoff"]

FORMULATIONS = ("reference", "te", "perturbation")
# undamped stability: |spectral radius - 1| below this is round-off of the monodromy matrix
# (neutral), above it a parametric instability
NEUTRAL_TOLERANCE = 1e-6


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


def register(sub, add_rig, add_scenario):
    """Add ``sweep`` and ``stability`` to the ``gearjax`` sub-command parser."""
    sw = sub.add_parser(
        "sweep", help="steady-state dynamic response over pinion speeds (Figs. 8-13)",
        description="Steady-state response curves of Section 6 (default: the paper's spur case, "
                    "3D model, short relief, damping 0.1, all three formulations, 20-900 rad/s).",
    )
    add_rig(sw)
    add_scenario(sw)
    _add_dynamics(sw)
    sw.add_argument("--formulations", default=None,
                    help="comma-separated subset of reference,te,perturbation (default all; "
                         "te,perturbation with --te-file)")
    add_speeds(sw, "sweep")
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
                         "(gearjax.Auto): harmonic for te/perturbation of the 3D model, the "
                         "transient otherwise (3D: accelerated by a periodic estimate after "
                         "every period)")
    sw.add_argument("--rtol", type=float, default=None, metavar="R",
                    help="requested relative accuracy of the metrics (default: each solver's "
                         "own, rtol 1e-7 and periodicity 1e-3): integrator rtol (atol R/100), "
                         "harmonic truncation, transient decay and periodicity test "
                         "(gearjax.dynamics.sweep.tolerance_options); independent sweeps")
    sw.add_argument("--direction", default="independent", choices=DIRECTION_CHOICES,
                    help="independent (default, as before): every speed from the quasi-static "
                         "start; up/down/both: continuation, each speed started from its "
                         "neighbour's periodic orbit (shooting; --method not used), showing "
                         "jumps and coexisting branches near a critical speed with contact "
                         "loss (results.csv gains direction, orbit, spectral_radius, restarted)")
    sw.add_argument("--chunk", type=int, default=None,
                    help="speeds per compiled call (progress and CSV rows per chunk; default "
                         "gearjax.dynamics.sweep.default_chunk_size: on a CPU 16-64 speeds per "
                         "core by the model's size (the speeds of a chunk run in lockstep and "
                         "their solver stages must stay in cache), on a GPU every speed that "
                         "memory holds)")
    from .iso import add_iso_options

    add_iso_options(sw)
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
                         "of n columns, as the shooting's; ~20 s per speed for the 3D rig); "
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


def parse_speeds(text: str | None) -> np.ndarray:
    """The pinion speeds of ``--speeds A:B:N`` (rad/s): ``0 < A <= B``, ``N >= 1``; None
    (no ``--speeds``: the rig's default, :func:`gearjax.cli.scenario.speeds_of`) gives the
    paper's 20:900:45, which has the default's count of speeds."""
    if text is None:
        text = "20:900:45"
    return linspace_option(text, "--speeds", example="20:900:60", unit="rad/s")


def _parse_signal_speeds(text: str | None) -> list[float]:
    if not text:
        return []
    try:
        vals = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise ValueError(f"--signals={text!r}: expected comma-separated speeds in rad/s, "
                         "e.g. 100,400,800") from None
    if not vals or not all(math.isfinite(v) and v > 0 for v in vals):
        raise ValueError(f"--signals={text!r}: speeds must be finite and > 0 (rad/s)")
    return vals


def _check_damping(z: float):
    if not (math.isfinite(z) and 0.0 <= z < 1.0):
        raise ValueError(f"--damping={z!r}: the modal damping factor must lie in [0, 1)")


def case_name(args, scenario=None) -> str:
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
    return "-".join(parts)


def _forms(text: str) -> list[str]:
    forms = [f.strip() for f in text.split(",") if f.strip()]
    bad = [f for f in forms if f not in FORMULATIONS]
    if bad or not forms:
        raise ValueError(f"--formulations={text!r}: choose from reference,te,perturbation")
    return list(dict.fromkeys(forms))


def _check_cutoff(args, rig, cutoff_hz) -> None:
    """Refuse a 3D ``--max-frequency`` below the lowest natural frequency (it would keep no
    vibration mode), from the rig's modal analysis alone, before the model is built."""
    if args.model != "3d" or not cutoff_hz or args.max_frequency is None:
        return
    from ..rigs.figures import three_d_figures

    f1 = three_d_figures(rig, args.stiffness, args.encoders, n_frequencies=1)["natural_frequencies_hz"][0]
    if cutoff_hz < f1:
        raise ValueError(f"--max-frequency={args.max_frequency!r}: keeps no vibration mode (the "
                         f"lowest natural frequency of the 3D model is {f1:.1f} Hz); give a "
                         "cut-off above it, or 0 for all modes")


def cutoff_warning(args, rig, cutoff_hz, speeds_rad_s) -> str | None:
    """A warning where ``--max-frequency`` lies below the mesh frequency of the highest
    speed, ``f_m = z1 Omega_max / (2 pi)`` (Hz): the modes that the mesh fundamental
    excites there then answer quasi-statically (static corrections), so the response
    curves are not those of the structure (``benchmarks/results/cutoff.md``: a cut-off
    at 1 f_m already moved the peak dynamic factor by up to 8e-3 against all modes).
    None for the default cut-off, all modes or the torsional model."""
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


def _check_te_file(args, forms) -> None:
    """--te-file drives the te/perturbation formulations only (Section 6.2)."""
    if not args.te_file:
        return
    if "reference" in forms:
        raise ValueError(f"--te-file={args.te_file}: the reference formulation (Eqs. (14), (16): a "
                         "gap per contact cell) cannot use a TE file; choose --formulations "
                         "te,perturbation (the default with --te-file)")


def _tolerances(args) -> dict:
    """``--rtol`` as :func:`gearjax.dynamics.sweep.tolerance_options` reads it, its range
    error as a command-line error."""
    try:
        return tolerance_options(args.rtol)
    except SimulationError as exc:
        raise ValueError(f"--rtol={args.rtol!r}: must lie in [1e-13, 1e-2]") from exc


def cmd_sweep(args) -> int:
    from ..dynamics.results import CSV_COLUMNS, ORDER_COLUMNS, check_header
    from ..dynamics.sweep import sweep
    from .outputs import prepare_output_dir
    from .results import (RESULT_FILES, check_resume, done_speeds, max_force_by_speed,
                          method_counts, print_summary, read_rows, summarise_rows, write_case)
    from .scenario import scenario_modifications

    if args.resume and (args.distributed or args.coordinator is not None
                        or args.num_processes is not None):
        raise ValueError("--resume: not with several processes (resume on one process, or "
                         "start a new --out folder)")
    check_direction(args)
    lead = init_distributed(args)
    if args.speeds is not None:
        parse_speeds(args.speeds)  # a bad range is reported before the rig is read
    forms = _forms(args.formulations or ("te,perturbation" if args.te_file
                                         else "reference,te,perturbation"))
    _check_te_file(args, forms)
    sig_speeds = _parse_signal_speeds(args.signals)
    _check_damping(args.damping)
    if args.model == "torsional" and args.encoders != 1:
        raise ValueError("--encoders: the torsional model has no encoder positions (3d only)")
    reaction = nlte_reaction_of(args)
    if args.resume and args.overwrite:
        raise ValueError("--resume --overwrite: choose one (continue the run, or replace it)")
    if args.chunk is not None and args.chunk < 1:
        raise ValueError(f"--chunk={args.chunk}: must be >= 1")
    tolerances = _tolerances(args)
    if tolerances and args.direction != "independent":
        raise ValueError(f"--rtol={args.rtol!r}: for independent sweeps (the continuation of "
                         "--direction keeps its shooting tolerances)")
    rig = rig_of(args)
    spec = speeds_of(args, rig, "sweep", law=args.stiffness, model=args.model,
                     damping=args.damping)
    speeds = spec.rad_s
    scen = scenario_modifications(rig, args)
    mods = scen.mods
    te = read_te_csv(args.te_file, rig.pair.mesh_period_rad) if args.te_file else None
    case = case_name(args, scen)
    out = args.out or os.path.join("gearjax-out", case)
    # a plain re-run (no --out) replaces the earlier run of its own default folder
    replace = (args.out is None and not args.resume and not args.overwrite
               and any(os.path.exists(os.path.join(out, n)) for n in RESULT_FILES))
    csv_path = os.path.join(out, "results.csv")
    orders_path = os.path.join(out, "orders.csv")  # mesh orders 1-5 (gearjax.dynamics.orders)
    cutoff_hz, cutoff_source = (modal_cutoff(args, rig, np.concatenate([speeds, sig_speeds]))
                                if args.model == "3d" else (None, None))
    _check_cutoff(args, rig, cutoff_hz)
    warning = cutoff_warning(args, rig, cutoff_hz, speeds)
    if warning and lead:
        print(f"gearjax sweep: warning: {warning}", file=sys.stderr, flush=True)
    record = {
        "case": case, "rig": rig.name, "model": args.model, "stiffness_law": args.stiffness,
        **scen.summary(), "damping": args.damping,
        "nlte_terms": not args.zero_nlte, "nlte_reaction": reaction,
        **({"nlte_inertia": False} if args.no_nlte_terms else {}),
        "encoders": args.encoders, "max_frequency_hz": cutoff_hz, "formulations": forms,
        **({"te_file": os.path.abspath(args.te_file)} if args.te_file else {}),
        # the rig and TE files' contents, not only their names: an edited file is another case
        **input_digests(args), "pinion_torque_Nm": rig.pinion_torque_Nm,
        # the specification, not the speeds (ten million of them are 231 MB of JSON)
        **{k: v for k, v in spec.record().items() if k != "speeds_source"},
    }
    if args.rtol is not None:
        record["rtol"] = float(args.rtol)
    if args.direction != "independent":
        record["direction"] = args.direction
    done: dict = {}
    if lead:  # every output problem is reported now, before any computing
        prepare_output_dir("--out", out, results=RESULT_FILES, resume=args.resume,
                           overwrite=args.overwrite or replace)
        if replace:
            print(f"gearjax sweep: replacing the earlier run in {out} (this case's default "
                  "folder; --resume continues it instead, --out DIR keeps both)",
                  file=sys.stderr, flush=True)
        if args.resume:
            check_resume(out, record)
            for path, columns in ((csv_path, CSV_COLUMNS), (orders_path, ORDER_COLUMNS)):
                check_header(path, columns, "--resume")
            done = done_speeds(read_rows(csv_path, repair=True))
            read_rows(orders_path, repair=True)
        write_case(out, record)
    devices = sweep_devices(args.method)
    nlte = nlte_options_of(args)
    notes = rig_notes(rig, args.model)
    estimate = work_estimate(args.model, speeds.size, len(forms))
    if estimate:
        notes.append(estimate)
    if lead:
        for note in notes:
            print(f"gearjax sweep: note: {note}", file=sys.stderr, flush=True)
    summary = {
        "case": case, "rig": rig.name, "model": args.model,
        "stiffness_law": args.stiffness, "relief": args.relief or scen.key, **scen.summary(),
        "damping": args.damping,
        "nlte_terms": not args.zero_nlte, "nlte_inertia": nlte["nlte_inertia"],
        "nlte_reaction": reaction, "encoders": args.encoders, "te_file": args.te_file,
        "max_frequency_hz": cutoff_hz, "max_frequency_source": cutoff_source,
        "rtol": args.rtol, "devices": device_count(devices),
        "pinion_torque_Nm": rig.pinion_torque_Nm,
        "static_mesh_force_N": static_mesh_force(rig.pair, rig.pinion_torque_Nm),
        **spec.record(),
        **({"excitation": _excitation(args, te, scen)} if te is not None else {}),
        "formulations": {},
        **({"warnings": [warning]} if warning else {}),
        **({"notes": notes} if notes else {}),
        **({"replaced_earlier_run": True} if replace else {}),
    }
    if done:
        summary["resumed"] = {f: len(v) for f, v in done.items()}
    iso = iso_dynamic_factor(args, rig, mods, speeds)
    summary.update(iso)
    times, signals, methods, branches = {}, {}, {}, {}
    if lead:  # a stall (gearjax.runtime.watchdog) ends the process: say where the rows are
        watchdog.add_stall_hook(lambda: f"the speeds finished so far are in {csv_path}; continue "
                                        "with the same command and --resume")
    t_all = time.perf_counter()
    interrupted = False
    try:
        def build(form):
            return build_model(rig, mods, model=args.model, formulation=form, law=args.stiffness,
                               damping_ratio=args.damping, encoder_position=args.encoders, **nlte,
                               max_frequency_hz=cutoff_hz, nlte_reaction=reaction, te_table=te,
                               moving_events=False)  # forward only

        def todo_of(form):  # vectorised: ten million speeds in well under a second
            got = np.fromiter(done.get(form, ()), dtype=float)
            return speeds[~np.isin(speeds, got)] if got.size else speeds

        def sweep_options(model):
            size = None if args.chunk is None else min(args.chunk, todo_of(model.formulation).size)
            return dict(solver=solver_for(args.method, model, args.rtol, tolerances),
                        chunk_size=size, devices=devices)

        linear = None  # a 3D te/perturbation model: the other one shares its build
        early, ahead = {}, Ahead()  # programs compiling on threads, a model built ahead
        for form in forms:
            t0 = time.perf_counter()
            shared = linear is not None and form in LINEAR_FORMULATIONS
            if shared:
                model = linear.with_formulation(form)
            elif form in early:
                model, t_pre = early.pop(form)
                t0 -= t_pre  # its build's time, before the reference sweep
            else:
                model = build(form)
            t_build = time.perf_counter() - t0
            if ahead.own is None and ahead.nxt is None:
                ahead = build_and_compile_ahead(args, forms, form, model, build, todo_of,
                                                sweep_options, early)
                traced = ahead.own_trace_s  # this formulation's tracing, done ahead
            else:
                traced = 0.0
            built = (f"the {linear.formulation} build" if shared else
                     f"{args.model} model built in {t_build:.1f} s")
            if args.model == "3d" and form in LINEAR_FORMULATIONS and not shared:
                linear = model
            if "predicted" not in summary:
                summary["predicted"] = predicted_critical_speeds(model)
                missed = missed_critical_speed(summary["predicted"], speeds)
                if missed:
                    summary.setdefault("warnings", []).append(missed)
                    if lead:
                        print(f"gearjax sweep: warning: {missed}", file=sys.stderr, flush=True)
                # the k_m of the model (gearjax.rigs.loaded), as `gearjax info` names it
                summary["loaded_mean_mesh_stiffness_N_per_m"] = float(model.k_m)
                # its own critical speeds (gearjax campbell's marked crossings, orders 1-5):
                # gearjax paper judges "near a critical speed" by them
                summary["critical_speeds"] = campbell(model, float(np.max(speeds))).critical_speeds()
                if args.model == "3d":
                    summary["n_modes"] = int(model.n_modes)
                    summary["w_x0_m"] = float(model.w_x0)
            todo = todo_of(form)
            if lead and not args.json:
                left = f", {todo.size} left to compute" if todo.size < speeds.size else ""
                print(f"  {form}: {speeds.size} speeds {speeds[0]:.0f}-{speeds[-1]:.0f} rad/s{left} "
                      f"({built})", file=sys.stderr, flush=True)
            t0 = time.perf_counter()
            if todo.size and args.direction != "independent":
                branches[form] = run_branches(model, todo, args.direction, csv_path,
                                              progress=command_meter(not args.json))
            elif todo.size:
                # default: sweep's (CPU: 16-64 speeds per device; accelerators: memory)
                ahead.join(mine=form == "reference", linear=form in LINEAR_FORMULATIONS)
                res = sweep(model, todo, progress=command_meter(not args.json), out_csv=csv_path,
                            orders_csv=orders_path, **sweep_options(model))
                methods[form] = method_counts(res)
            times[form] = (t_build, time.perf_counter() - t0 + traced)
            if sig_speeds and lead:
                signals[form] = last_mesh_period_signals(model, sig_speeds)
    except KeyboardInterrupt:
        interrupted = True
    if not lead:
        return 130 if interrupted else 0  # process 0 writes the outputs
    rows = read_rows(csv_path)
    for form in forms:
        if not any(r["formulation"] == form for r in rows):
            continue
        s = summarise_rows(rows, form, speeds)
        t_build, elapsed = times.get(form, (float("nan"), float("nan")))
        s.update(build_time_s=t_build, wall_time_s=elapsed)
        if form in methods:
            s["method"] = methods[form]
        if form in branches:
            s["branches"] = branches[form]
        summary["formulations"][form] = s
    if "reference" in summary["formulations"]:
        ref = max_force_by_speed(rows, "reference")
        agree = {}
        for f in summary["formulations"]:
            if f == "reference":
                continue
            mine = max_force_by_speed(rows, f)
            rel = [abs(mine[w] - ref[w]) / ref[w] for w in mine if w in ref]
            if rel:
                agree[f] = {"max_rel_diff_max_mesh_force": float(np.nanmax(rel)),
                            "median_rel_diff_max_mesh_force": float(np.nanmedian(rel))}
        summary["agreement_with_reference"] = agree
    summary["results_csv"] = csv_path
    title = (f"{rig.name}, {args.model}, "
             f"{summary['excitation'] if te is not None else scen.label}"
             f"{', pitch errors' if scen.pitch_errors else ''}, damping {args.damping}"
             + (", NLTE = 0" if args.zero_nlte else ", NLTE'' = 0" if args.no_nlte_terms else "")
             + f"{' (interrupted)' if interrupted else ''}")
    if rows:
        from ..plotting import plot_branches, plot_response_curves

        fig_path = os.path.join(out, "response_curves.png")
        if args.direction == "independent":
            dense = np.linspace(float(speeds[0]), float(speeds[-1]), 400)  # ISO's ranges' kinks
            plot_response_curves(csv_path, fig_path, title=title,
                                 iso_kv=(dense, iso_dynamic_factor(args, rig, mods, dense)[
                                     "iso6336_kv"], iso["iso6336_resonance_speed_rad_s"]))
        else:
            plot_branches(csv_path, fig_path, title=title)
        summary["response_curves_png"] = fig_path
        summary.update(write_order_tracks(orders_path, out, title))
    if signals and not interrupted:
        summary.update(write_signals(signals, out, title))
    summary["total_time_s"] = time.perf_counter() - t_all
    if interrupted:
        summary["interrupted"] = True
    with open(os.path.join(out, "summary.json"), "w") as fh:
        json.dump(summary, fh, indent=2)
    if interrupted:
        n = len(rows)
        print(f"gearjax: interrupted (Ctrl-C); kept {n} result row{'s' * (n != 1)} in {out} "
              f"(summary.json{', response_curves.png' if rows else ''}); continue with the same "
              "command and --resume", file=sys.stderr)
        return 130
    if args.json:
        print(json.dumps(summary, indent=2))
        return 0
    print_summary(rig, summary, out)
    return 0


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

    from .scenario import scenario_modifications

    if args.speeds is not None:
        parse_speeds(args.speeds)  # a bad range is reported before the rig is read
    _check_damping(args.damping)
    _check_te_file(args, [args.formulation])
    # the monodromy's integrator takes --rtol (atol R/100): the accuracy of rho
    tols = {k: v for k, v in _tolerances(args).items() if k in ("rtol", "atol")}
    reaction = nlte_reaction_of(args)
    rig = rig_of(args)
    spec = speeds_of(args, rig, "stability", law=args.stiffness, model=args.model,
                     damping=args.damping)
    speeds = spec.rad_s
    scen = scenario_modifications(rig, args)
    mods = scen.mods
    te = read_te_csv(args.te_file, rig.pair.mesh_period_rad) if args.te_file else None
    cutoff_hz, cutoff_source = modal_cutoff(args, rig, speeds) if args.model == "3d" else (None, None)
    _check_cutoff(args, rig, cutoff_hz)
    warning = cutoff_warning(args, rig, cutoff_hz, speeds)
    if warning:
        print(f"gearjax stability: warning: {warning}", file=sys.stderr, flush=True)
    notes = rig_notes(rig, args.model)  # after every input check: an error stays one line
    for note in notes:
        print(f"gearjax stability: note: {note}", file=sys.stderr, flush=True)
    model = build_model(rig, mods, model=args.model, formulation=args.formulation,
                        law=args.stiffness, damping_ratio=args.damping,
                        encoder_position=args.encoders,
                        **nlte_options_of(args),
                        max_frequency_hz=cutoff_hz, nlte_reaction=reaction, te_table=te,
                        moving_events=False)
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
