"""``gearjax campbell``: the Campbell diagram of a rig (:mod:`gearjax.rigs.campbell`), its
natural frequencies against pinion speed with mesh orders 1-5, each mode coloured by its
share of mesh strain energy, and the predicted critical speeds (``campbell.csv``,
``campbell.png``, ``campbell.json``).

    gearjax campbell                                 # 3D spur rig, retained modes, 0-1000 rad/s
    gearjax campbell --rig baud-velex-helical --max-speed 1500
    gearjax campbell --model torsional               # the sdof mesh mode
"""

from __future__ import annotations

import csv
import json
import math
import os

__all__ = ["register"]

CAMPBELL_FILES = ("campbell.csv", "campbell.png", "campbell.json")


def register(sub, add_rig, add_scenario):
    """Add ``campbell`` to the ``gearjax`` sub-command parser."""
    from ..rigs.campbell import DEFAULT_MIN_SHARE

    p = sub.add_parser(
        "campbell", help="Campbell diagram: natural frequencies vs pinion speed, mesh orders 1-5",
        description="Natural frequencies of the rig's model (3D: the retained modes; torsional: "
                    "the mesh mode) against pinion speed with mesh orders 1-5, each mode coloured "
                    "by its share of mesh strain energy; crossings with a high share are the "
                    "predicted critical speeds.")
    add_rig(p)
    add_scenario(p)  # the relief sets the loaded mean mesh stiffness k_m of the modes
    p.add_argument("--model", default="3d", choices=["torsional", "3d"],
                   help="3d (default: the retained modes of (M, K + k_m V V^T)) or torsional")
    p.add_argument("--encoders", type=int, default=1, choices=[1, 2, 3],
                   help="3d: encoder positions of Fig. 7 (default 1)")
    p.add_argument("--max-speed", type=float, default=1000.0, metavar="RAD_S",
                   help="highest pinion speed drawn (rad/s, default 1000)")
    p.add_argument("--max-frequency", type=float, default=None, metavar="HZ",
                   help="3d: modal cut-off (default the sweep's rule at --max-speed; 0: all modes)")
    p.add_argument("--min-share", type=float, default=DEFAULT_MIN_SHARE, metavar="S",
                   help="share of mesh strain energy from which a crossing is a predicted "
                        f"critical speed (default {DEFAULT_MIN_SHARE:g})")
    p.add_argument("--out", default=None, metavar="DIR",
                   help="output folder (default ./gearjax-out/campbell-<rig>-<model>/)")
    p.add_argument("--overwrite", action="store_true",
                   help="replace campbell.* files of an earlier run in --out")
    p.set_defaults(func=cmd_campbell)


def cmd_campbell(args) -> int:
    from ..errors import GearjaxError
    from ..rigs.campbell import campbell
    from ..rigs.factory import build_model
    from ..rigs.registry import get_rig
    from .case import modal_cutoff
    from .outputs import prepare_output_dir
    from .scenario import scenario_modifications

    w_max = args.max_speed
    if not (math.isfinite(w_max) and w_max > 0):
        raise GearjaxError("--max-speed", w_max, "must be a finite speed > 0 rad/s")
    if not (0.0 < args.min_share <= 1.0):
        raise GearjaxError("--min-share", args.min_share, "must lie in (0, 1]")
    rig = get_rig(args.rig)
    scen = scenario_modifications(rig, args)
    name = os.path.splitext(os.path.basename(args.rig))[0]
    out = args.out or os.path.join("gearjax-out", f"campbell-{name}-{args.model}")
    prepare_output_dir("--out", out, results=CAMPBELL_FILES, overwrite=args.overwrite)
    cutoff, source = (modal_cutoff(args, rig, [w_max]) if args.model == "3d" else (None, None))
    model = build_model(rig, scen.mods, model=args.model, formulation="te", law=args.stiffness,
                        encoder_position=args.encoders, max_frequency_hz=cutoff,
                        **({"moving_events": False} if args.model == "3d" else {}))
    diagram = campbell(model, w_max, min_share=args.min_share)
    rows = diagram.rows()
    csv_path = os.path.join(out, "campbell.csv")
    with open(csv_path, "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    title = f"{rig.name}, {args.model}, {scen.label}, law {args.stiffness}"
    png = os.path.join(out, "campbell.png")
    from ..plotting import plot_campbell

    plot_campbell(diagram, png, title=title)
    crit = diagram.critical_speeds()
    summary = {
        "rig": rig.name, "model": args.model, "stiffness_law": args.stiffness, **scen.summary(),
        "mean_mesh_stiffness_N_per_m": float(model.k_m),
        "max_speed_rad_s": w_max, "mesh_orders": list(diagram.orders),
        "min_share": args.min_share, "max_frequency_hz": cutoff, "max_frequency_source": source,
        "n_modes": int(diagram.omega_rad_s.size),
        "retained_mesh_energy_share": float(diagram.share.sum()),
        "predicted_critical_speeds": crit,
        "campbell_csv": csv_path, "campbell_png": png,
    }
    with open(os.path.join(out, "campbell.json"), "w") as fh:
        json.dump(summary, fh, indent=2)
    if args.json:
        print(json.dumps(summary, indent=2))
        return 0
    print(f"  {rig.description}")
    print(f"  {args.model} model, {summary['n_modes']} mode(s), k_m {model.k_m / 1e6:.1f} N/um; "
          f"{100 * summary['retained_mesh_energy_share']:.1f} % of the mesh strain energy in them")
    print(f"  predicted critical speeds up to {w_max:g} rad/s (share >= {args.min_share:g}):")
    print(f"  {'speed [rad/s]':>14s} {'order':>6s} {'mode [Hz]':>10s} {'share':>7s}")
    for r in crit:
        print(f"  {r['crossing_speed_rad_s']:14.1f} {r['mesh_order']:6d} {r['frequency_hz']:10.1f} "
              f"{r['mesh_energy_share']:7.3f}")
    print(f"  wrote {csv_path}, {png}, {os.path.join(out, 'campbell.json')}")
    return 0
