"""The ``gearjax`` command line.

Commands
--------
``gearjax info``        geometry and mesh figures of a rig at its nominal torque.
``gearjax quasistatic`` TE_S and NLTE over a mesh period (a pinion revolution with pitch
                        errors), load sharing, CSV/JSON/plot output.
``gearjax sweep``       response curves of Figs. 8-13 (:mod:`gearjax.cli.dynamics`).
``gearjax stability``   Floquet spectral radius over speeds (:mod:`gearjax.cli.dynamics`).
``gearjax optimise``, ``gearjax harris-map``  tip-relief design (:mod:`gearjax.cli.design`).
``gearjax campbell``    Campbell diagram and predicted critical speeds (:mod:`gearjax.cli.campbell`).

The CLI only parses arguments and formats results; all physics lives in the library.
"""

from __future__ import annotations

import argparse
import importlib
import json
import math
import os
import sys

import numpy as np

__all__ = ["main", "compile_bound", "configure_process"]


def _stiffness_laws():
    from ..gears.mesh import STIFFNESS_LAWS

    return list(STIFFNESS_LAWS)


def _add_rig(p: argparse.ArgumentParser):
    p.add_argument(
        "--rig",
        default="baud-velex-spur", metavar="RIG",
        help="built-in rig baud-velex-spur (default) or baud-velex-helical, or a rig file "
             "FILE.toml (schema: gearjax.rigs.rigfile; e.g. examples/rigs/baud_velex_spur.toml)",
    )
    p.add_argument(
        "--stiffness",
        default="iso6336",
        choices=_stiffness_laws(),
        help="mesh stiffness law (default iso6336: mean = ISO 6336-1 c_gamma_alpha * b; "
             "weber: Weber-Banaschek/O'Donnell tooth-pair compliance of the paper, Section 6.1)",
    )
    p.add_argument("--json", action="store_true", help="print machine-readable JSON only")


def _parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        prog="gearjax",
        description="Differentiable gear dynamics (Velex & Ajmi transmission-error models).",
        epilog=_EXAMPLES, formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    ap.add_argument("--version", action="version", version=f"gearjax {_version()}")
    sub = ap.add_subparsers(dest="command", required=True, metavar="COMMAND")

    info = sub.add_parser("info", help="geometry and mesh figures of a rig")
    _add_rig(info)
    info.add_argument("--model", default="3d", choices=["torsional", "3d"],
                      help="3d (default) adds the structure: dofs, Appendix A relations, "
                           "natural frequencies")
    info.add_argument("--encoders", type=int, default=1, choices=[1, 2, 3],
                      help="encoder positions of Fig. 7 for W and w_x0 (default 1)")
    from .iso import add_iso_options
    from .scenario import add_torque

    add_torque(info)
    add_iso_options(info)

    qs = sub.add_parser("quasistatic", help="quasi-static TE_S and NLTE (unilateral contact)")
    _add_rig(qs)
    qs.add_argument("--model", default="torsional", choices=["torsional"])
    add_torque(qs)
    _add_scenario(qs)
    qs.add_argument("--positions", type=int, default=256,
                    help="positions per mesh period (default 256)")
    qs.add_argument("--csv", metavar="FILE", help="write theta_rad, te_s_m, nlte_m, mesh_force_N, "
                    "mesh_stiffness_N_per_m (+ two rows at every jump: a --te-file)")
    qs.add_argument("--plot", metavar="FILE", help="write a PNG of TE_S, NLTE and load sharing")
    for name in _EXTENSIONS:
        importlib.import_module(name).register(sub, _add_rig, _add_scenario)
    for name, default in _stall_timeouts().items():
        if name in sub.choices:
            what = ("one vmapped call: default 0 (off); a value is a time limit"
                    if name in ("stability", "harris-map")
                    else f"default {default:g} s (GEARJAX_STALL_TIMEOUT); the first includes "
                         "compiling; 0 disables")
            sub.choices[name].add_argument(
                "--stall-timeout", type=float, default=default, metavar="SECONDS",
                help="end with a one-line message (exit 3) when no sweep chunk / optimiser "
                     f"step completes for this long ({what})")
    for name, examples in _COMMAND_EXAMPLES.items():  # every command's --help ends with them
        sub.choices[name].epilog = examples
        sub.choices[name].formatter_class = _ExamplesFormatter
    return ap


class _ExamplesFormatter(argparse.RawDescriptionHelpFormatter):
    """Text laid out on several lines (the examples) is printed as written, as
    RawDescriptionHelpFormatter does; a one-line description is wrapped as usual."""

    def _fill_text(self, text, width, indent):
        if "\n" in text:
            return super()._fill_text(text, width, indent)
        return argparse.HelpFormatter._fill_text(self, text, width, indent)


# The examples that end each command's --help (tests/test_cli_help.py parses every one).
_COMMAND_EXAMPLES = {
    "info": """examples:
  gearjax info                            the spur rig: geometry, mesh, natural frequencies
  gearjax info --rig examples/rigs/two_shafts.toml --json
                                          a rig file of your own, as JSON""",
    "quasistatic": """examples:
  gearjax quasistatic --relief long --plot te.png
                                          TE_S, NLTE and load sharing, Table 1's long relief
  gearjax quasistatic --relief-amplitude 20e-6 --relief-extent 0.4 --csv te.csv
                                          your relief, written as a --te-file for sweep""",
    "sweep": """examples:
  gearjax sweep                           the paper's spur case (Fig. 9): 3D rig, 45 speeds
  gearjax sweep --model torsional --damping 0.03 --speeds 300:900:25 --out sdof
                                          the sdof model; then sdof/response_curves.png
  gearjax sweep --model torsional --damping 0.03 --backlash 10e-6 --speeds 600:900:31
                                          10 um between the back flanks: double-sided impacts""",
    "stability": """examples:
  gearjax stability --model torsional --speeds 300:900:13
                                          Floquet spectral radius per speed (te)
  gearjax stability --model 3d --damping 0.03 --speeds 600:900:7 --json""",
    "optimise": """examples:
  gearjax optimise                        sdof te, peak mesh force over 660-900 rad/s
  gearjax optimise --model 3d --speeds 330:480:2 --objective dynamic-factor --out opt3d""",
    "harris-map": """examples:
  gearjax harris-map --amplitudes 0:30e-6:7 --extents 0.1:0.7:7 --out map
                                          peak mesh force over a relief grid (map.png)""",
    "campbell": """examples:
  gearjax campbell                        the spur rig's 3D modes against speed, orders 1-5
  gearjax campbell --model torsional --rig examples/rigs/two_shafts.toml --out camp
                                          the mesh mode of your own rig (camp/campbell.png)""",
    "paper": """examples:
  gearjax paper                           every Section 6.3 case into docs/paper
  gearjax paper --cases fig08,fig09 --out paper-check
                                          two cases into another folder""",
}


# Default --stall-timeout (s) of the long commands (gearjax.runtime.watchdog): sweep and
# optimise report progress per chunk / step; stability and harris-map are one vmapped call
# each, whose length depends on the model and grid, so their watchdog is opt-in.
# GEARJAX_STALL_TIMEOUT (seconds) replaces DEFAULT_STALL_TIMEOUT_S (e.g. 0 in a test suite
# that calls main() in-process, which a stall would end); read when the parser is built.
def _stall_timeouts() -> dict[str, float]:
    from ..runtime.watchdog import DEFAULT_STALL_TIMEOUT_S

    setting = os.environ.get("GEARJAX_STALL_TIMEOUT", str(DEFAULT_STALL_TIMEOUT_S))
    try:
        watched = float(setting or 0)
    except ValueError:
        raise ValueError(f"GEARJAX_STALL_TIMEOUT={setting!r}: must be a number of seconds "
                         "(0 disables the stall watchdog)") from None
    return {"sweep": watched, "optimise": watched, "stability": 0.0, "harris-map": 0.0}


# Modules adding sub-commands: each defines ``register(subparsers, add_rig, add_scenario)``
# that adds its parsers with ``set_defaults(func=...)``; ``func(args) -> int``.
_EXTENSIONS: tuple[str, ...] = ("gearjax.cli.dynamics", "gearjax.cli.design", "gearjax.cli.paper",
                                "gearjax.cli.campbell")


_EXAMPLES = """examples:
  gearjax info --rig baud-velex-helical            gear data, mesh stiffness, 3D natural frequencies
  gearjax quasistatic --csv te.csv --plot te.png   quasi-static TE_S and NLTE over a mesh period
  gearjax sweep --model torsional --speeds 100:900:40 --out sweep1
                                                   response curves (Figs. 8-13) beside ISO 6336-1's K_v;
                                                   --resume continues
  gearjax campbell --rig baud-velex-helical        Campbell diagram, predicted critical speeds
'gearjax COMMAND --help' lists the options of a command."""


def _version() -> str:
    from .. import __version__

    return __version__


def _add_scenario(p: argparse.ArgumentParser):
    p.add_argument("--relief", default=None, choices=["none", "short", "long"],
                   help="Table 1 tip relief on both gears (default: the rig file's "
                        "[modifications], else short)")
    p.add_argument("--relief-amplitude", type=float, metavar="METRES",
                   help="tip relief amplitude P_c on both gears (m), e.g. 13.3e-6")
    p.add_argument("--relief-extent", type=float, metavar="FRACTION",
                   help="relief extent L_c as a fraction of the path of contact, in (0, 1]")
    p.add_argument("--relief-shape", default=None, choices=["linear", "parabolic"],
                   help="relief shape (default: the rig file's, else linear)")
    p.add_argument("--pitch-errors", action="store_true",
                   help="add the pinion cumulative pitch errors (periods of a pinion revolution)")
    from .scenario import add_eccentricity

    add_eccentricity(p)


def _fail(msg: str) -> int:
    print(f"gearjax: error: {msg}", file=sys.stderr)
    return 2


def _cmd_info(args) -> int:
    from ..rigs.figures import three_d_figures, torsional_stiffness_figures

    from .scenario import rig_notes, rig_of

    rig = rig_of(args)
    out = {"rig": rig.name, "description": rig.description}
    out.update(rig.pair.summary())
    out.update(torsional_stiffness_figures(rig, args.stiffness))
    from ..rigs.iso_figures import info_figures
    from .iso import accuracy_of

    out.update(info_figures(rig, accuracy_of(args, rig)))  # ISO 6336-1's own c_gamma_alpha
    from ..rigs.iso_figures import default_modifications
    from ..rigs.loaded import loaded_stiffness_figures

    mods = default_modifications(rig)  # the dynamics' k_m: loaded, with the default relief
    out.update(loaded_stiffness_figures(rig, mods, args.stiffness))
    out["loaded_stiffness_modifications"] = (
        "rig file [modifications]" if rig.modifications_default is not None else "--relief short")
    if args.model == "3d":
        out.update(three_d_figures(rig, args.stiffness, args.encoders))
    out["notes"] = rig_notes(rig, args.model)
    if args.json:
        print(json.dumps(out, indent=2))
        return 0
    p = rig.pair
    rows = [
        ("rig", rig.description),
        ("teeth z1 / z2", f"{p.z1} / {p.z2}"),
        ("normal module", f"{p.normal_module_m * 1e3:.3f} mm"),
        ("helix / base helix angle", f"{math.degrees(p.helix_angle_rad):.2f} / "
                                     f"{math.degrees(p.base_helix_angle_rad):.3f} deg"),
        ("centre distance", f"{p.centre_distance_m * 1e3:.3f} mm"),
        ("base radii Rb1 / Rb2", f"{p.base_radii_m[0] * 1e3:.3f} / {p.base_radii_m[1] * 1e3:.3f} mm"),
        ("base pitch p_bt", f"{p.base_pitch_m * 1e3:.4f} mm"),
        ("path of contact g_alpha", f"{p.path_of_contact_m * 1e3:.4f} mm"),
        ("contact ratio eps_alpha", f"{p.transverse_contact_ratio:.4f}"),
        ("overlap ratio eps_beta", f"{p.overlap_ratio:.4f}"),
        ("mesh stiffness law", out["stiffness_law"]),
        ("mean mesh stiffness k_m, geometric", f"{out['mean_mesh_stiffness_N_per_m'] / 1e6:.2f} N/um "
                                               "(every cell in the path of contact)"),
        ("mean mesh stiffness k_m, loaded", f"{out['loaded_mean_mesh_stiffness_N_per_m'] / 1e6:.2f} N/um "
                                            f"(the dynamics' k_m; {out['loaded_stiffness_modifications']})"),
        ("sdof critical speed, loaded k_m", f"{out['loaded_torsional_critical_speed_rad_s']:.1f} rad/s"),
        ("stiffness variation alpha", f"{out['stiffness_variation_alpha']:.4f}"),
        ("ISO 6336-1 c' / c_gamma_alpha", f"{out['iso6336_c_prime_N_per_mm_um']:.4f} / "
                                          f"{out['iso6336_c_gamma_alpha_N_per_mm_um']:.4f} N/(mm um)"),
        ("ISO resonance speed n_E1", f"{out['iso6336_resonance_speed_rad_s']:.1f} rad/s "
                                     f"({out['iso6336_resonance_speed_rpm']:.0f} 1/min)"),
        ("ISO K_v (method B), main resonance", f"{out['iso6336_kv_main_resonance']:.4f}"),
        *([(f"ISO K_v at {out['iso6336_rated_speed_rad_s']:.1f} rad/s",
            f"{out['iso6336_kv_at_rated_speed']:.4f} (N = "
            f"{out['iso6336_resonance_ratio_at_rated_speed']:.4f})")]
          if "iso6336_kv_at_rated_speed" in out else []),
        ("ISO F_t (reference circle)", f"{out['iso6336_reference_tangential_force_N']:.1f} N"),
        ("pinion torque", f"{rig.pinion_torque_Nm:.1f} N m"),
        ("static mesh force F_S (base plane)", f"{out['static_mesh_force_N']:.1f} N"),
    ]
    if args.model == "3d":
        freqs = ", ".join(f"{f:.1f}" for f in out["natural_frequencies_hz"][:8])
        rows += [
            ("3D model dofs", f"{out['n_dof']}"),
            ("C_vv k_m  (Eq. 33, = 1)", f"{out['C_vv_times_km']:.12f}"),
            ("C_wv k_m cos b_b  (Eq. 35, = 1)", f"{out['C_wv_times_km_cos_beta_b']:.12f}"),
            ("v_x0 k_m / F_S  (Eq. 34, = 1)", f"{out['v_x0_times_km_over_FS']:.12f}"),
            (f"w_x0 (encoders {out['encoder_position']})", f"{out['w_x0_m'] * 1e6:.3f} um"),
            ("lowest natural frequencies", f"{freqs} Hz"),
        ]
    rows += [("note", n) for n in out["notes"]]
    w = max(len(r[0]) for r in rows)
    for k, v in rows:
        print(f"  {k:<{w}}  {v}")
    return 0


def _cmd_quasistatic(args) -> int:
    from ..gears.mesh import Mesh
    from ..gears.quasistatic import quasi_static, static_mesh_force

    from .outputs import check_output_file
    from .scenario import rig_of, scenario_modifications

    if args.positions < 8:
        return _fail(f"--positions={args.positions}: need at least 8 positions per mesh period")
    if args.csv:
        check_output_file("--csv", args.csv)
    if args.plot:
        check_output_file("--plot", args.plot, figure=True)
    rig = rig_of(args)
    scen = scenario_modifications(rig, args)
    mods = scen.mods
    # the excitation period: a revolution of each body carrying errors (pinion: z1 mesh periods)
    n_periods = round(mods.excitation_period_rad(rig.pair) / rig.pair.mesh_period_rad)
    _check_positions_memory(args.positions, n_periods)
    mesh = Mesh.build(rig.pair, args.stiffness, pinion_torque_Nm=rig.pinion_torque_Nm)
    theta = mesh.theta_grid(args.positions, n_periods)
    f_s = static_mesh_force(rig.pair, rig.pinion_torque_Nm)
    res = quasi_static(mesh, mods, theta, f_s)
    te, nlte = np.asarray(res.te_s_m), np.asarray(res.nlte_m)
    force = np.asarray(res.mesh_force_N)
    summary = {
        "rig": rig.name,
        "stiffness_law": args.stiffness,
        "pinion_torque_Nm": rig.pinion_torque_Nm,
        "relief": args.relief or scen.key,
        **scen.summary(),
        "pitch_errors": scen.pitch_errors,
        "positions": int(theta.shape[0]),
        "span_rad": float(n_periods * rig.pair.mesh_period_rad),
        "static_mesh_force_N": f_s,
        "te_s_mean_m": float(te.mean()),
        "te_s_ptp_m": float(np.ptp(te)),
        "te_s_rms_fluctuation_m": float(np.std(te)),
        "nlte_mean_m": float(nlte.mean()),
        "nlte_ptp_m": float(np.ptp(nlte)),
        "loaded_stiffness_mean_N_per_m": float(np.mean(res.loaded_stiffness_N_per_m)),
        "max_force_balance_error_N": float(np.max(np.abs(force - f_s))),
    }
    if args.csv:  # + both sides of every jump and kink: a file that --te-file reads exactly
        from ..excitation.te_file import with_jump_rows
        from ..rigs.factory import build_model

        sdof = build_model(rig, mods, model="torsional", formulation="te", law=args.stiffness,
                           n_table=max(16, args.positions))
        grid = np.column_stack([te, nlte, res.loaded_stiffness_N_per_m, force])
        th, rows = with_jump_rows(theta, grid, sdof.table, sdof.table_side, sdof.jump_thetas,
                                  rig.pair.mesh_period_rad, fill=[f_s])
        np.savetxt(args.csv, np.column_stack([th, rows[:, [0, 1, 3, 2]]]), delimiter=",",
                   header="theta_rad,te_s_m,nlte_m,mesh_force_N,mesh_stiffness_N_per_m",
                   comments="", fmt="%.10e")
        summary["csv"] = args.csv
    if args.plot:
        from ..plotting import plot_quasistatic

        plot_quasistatic(res, mesh, args.plot, title=f"{rig.name}, {scen.label}"
                                                    f"{', pitch errors' if scen.pitch_errors else ''}")
        summary["plot"] = args.plot
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        um = 1e6
        print(f"  {rig.description}")
        print(f"  {scen.label} [{scen.source}], amplitude "
              f"{summary['relief_amplitude_m'][0] * um:.2f} um, extent {summary['relief_extent'][0]:.3f}"
              f"{', pitch errors' if scen.pitch_errors else ''}; law {args.stiffness}")
        print(f"  TE_S  mean {summary['te_s_mean_m'] * um:8.3f} um   peak-to-peak "
              f"{summary['te_s_ptp_m'] * um:8.3f} um")
        print(f"  NLTE  mean {summary['nlte_mean_m'] * um:8.3f} um   peak-to-peak "
              f"{summary['nlte_ptp_m'] * um:8.3f} um")
        print(f"  static mesh force F_S {f_s:.1f} N over {summary['positions']} positions "
              f"(balance error {summary['max_force_balance_error_N']:.1e} N)")
        for key in ("csv", "plot"):
            if key in summary:
                print(f"  wrote {summary[key]}")
    return 0


# bytes of working memory per quasi-static position (measured: ~1.3 kB on the spur rig,
# doubled for margin); --positions is refused when the grid would not fit in memory
_BYTES_PER_POSITION = 4096


def _check_positions_memory(positions: int, n_periods: int) -> None:
    from ..errors import GearjaxError
    from .outputs import available_memory_bytes

    need = positions * n_periods * _BYTES_PER_POSITION
    have = available_memory_bytes()
    limit = 0.5 * have if have else 8 * 2**30
    if need > limit:
        span = f" x {n_periods} mesh periods (the errors' period)" if n_periods > 1 else ""
        raise GearjaxError("--positions", positions,
                           f"{positions}{span} positions need about {need / 2**30:.1f} GiB, more "
                           f"than half the available memory ({limit * 2 / 2**30:.1f} GiB); "
                           f"use at most {int(limit // (n_periods * _BYTES_PER_POSITION))}")


_SHARDED_COMMANDS = ("sweep", "paper")  # the commands whose transient sweeps use them

# A sweep that compiles more than it integrates takes XLA's legacy CPU emitters
# (gearjax.runtime.xla.use_legacy_emitters): the torsional model, or up to
# COMPILE_BOUND_3D_SPEEDS speeds of the 3D one over a mesh period (pitch errors,
# eccentricities and TE files lengthen the excitation period by up to a gear revolution)
# at a damping of at least COMPILE_BOUND_3D_DAMPING (lighter damping lengthens the
# transients and the contact-loss orbits); benchmarks/results/code_notes.md, section
# gearjax.cli.main, has the measurements behind both bounds.
COMPILE_BOUND_3D_SPEEDS = 300
COMPILE_BOUND_3D_DAMPING = 0.1


def compile_bound(args) -> bool:
    """Whether ``gearjax`` ``args`` ask for a sweep whose compilation outweighs its
    integration (the bounds above :data:`COMPILE_BOUND_3D_SPEEDS`), or an ``optimise`` of
    the torsional model (each model build there compiles the objective's value and
    gradient again, and each step then integrates briefly)."""
    if args.command == "optimise":
        return args.model == "torsional"
    if args.command != "sweep":
        return False
    if args.model == "torsional":
        return True
    if args.pitch_errors or args.eccentricity is not None or args.te_file is not None:
        return False
    if not args.damping >= COMPILE_BOUND_3D_DAMPING:
        return False
    from .case import parse_speeds

    try:
        n = parse_speeds(args.speeds).size
    except ValueError:
        return False  # the command reports the bad --speeds itself
    return n <= COMPILE_BOUND_3D_SPEEDS


def configure_process(args, own_process: bool) -> None:
    """The host process for ``args`` (:func:`gearjax.runtime.configure`), before JAX starts
    a backend: XLA's CPU workarounds; one CPU device per core for the commands that shard
    sweeps (:data:`_SHARDED_COMMANDS`); the persistent compilation cache. Where this
    process is the command (``own_process``: ``main()`` without ``argv``) also the legacy
    emitters for a compile-bound sweep (:func:`compile_bound`) and equinox's checks in a
    cacheable form (:func:`gearjax.runtime.use_cacheable_checks`), which would change a
    caller's own process: in a process whose backend already runs a flag would not apply,
    yet JAX's persistent-cache keys read ``XLA_FLAGS``, so that process's executables would
    be stored under the legacy emitters' keys.

    Raises ValueError for a bad ``GEARJAX_HOST_DEVICES``."""
    from .. import runtime

    devices = runtime.host_device_count() if args.command in _SHARDED_COMMANDS else None
    runtime.configure(host_devices=devices,
                      legacy_emitters=own_process and compile_bound(args))
    if runtime.compilation_cache_dir() is None:
        return
    if own_process:
        runtime.use_cacheable_checks()
    runtime.use_compilation_cache()


def main(argv: list[str] | None = None) -> int:
    """Run the ``gearjax`` command line; returns the exit status (0 done, 2 bad input,
    3 stalled: no progress for ``--stall-timeout`` seconds, 130 interrupted by Ctrl-C)."""
    try:
        parser = _parser()
    except ValueError as exc:  # a bad GEARJAX_STALL_TIMEOUT
        return _fail(str(exc))
    args = parser.parse_args(argv)
    try:
        configure_process(args, own_process=argv is None)
    except ValueError as exc:
        return _fail(str(exc))
    stall = getattr(args, "stall_timeout", None)
    if stall is not None and not (stall >= 0 and math.isfinite(stall)):
        return _fail(f"--stall-timeout={stall}: must be a finite number of seconds >= 0 "
                     "(0 disables the watchdog)")
    from ..runtime.watchdog import stall_guard

    # the GIL-free backstop only where this process is the command (see watchdog)
    with stall_guard(stall, what=f"gearjax {args.command}", backstop=argv is None):
        return _dispatch(args)


def _dispatch(args) -> int:
    try:
        if args.command == "info":
            return _cmd_info(args)
        if args.command == "quasistatic":
            return _cmd_quasistatic(args)
        if hasattr(args, "func"):
            return args.func(args)
    except ValueError as exc:  # GearjaxError and argument conversions
        return _fail(str(exc))
    except KeyboardInterrupt:
        print("gearjax: interrupted (Ctrl-C); nothing more was written", file=sys.stderr)
        return 130
    except OSError as exc:  # an output that became unwritable while computing
        return _fail(f"{exc.filename or ''}: {exc.strerror or exc}".lstrip(": "))
    return _fail(f"unknown command {args.command!r}")


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
