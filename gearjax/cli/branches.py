"""``gearjax sweep --direction up|down|both``: the rows and the summary of continuation
sweeps (:mod:`gearjax.dynamics.continuation`, natural parameter) and, for ``both``, of the
traced curve (:func:`gearjax.dynamics.arclength.trace_speed`, pseudo-arclength);
formatting only.

``results.csv`` of a direction sweep has the columns of the default sweep
(:data:`gearjax.dynamics.results.CSV_COLUMNS`) plus :data:`EXTRA_COLUMNS`: ``direction``
(``up``/``down``), ``orbit`` (``followed``: the orbit the sweep follows at that speed;
``unstable``: an unstable periodic orbit the continuation met there, see
:data:`gearjax.dynamics.continuation.BRANCH_STATS`), ``spectral_radius`` (Floquet) and
``restarted``. The default ``--direction independent`` (each speed from the quasi-static
start, as before) writes the default columns only.

``--direction both`` also traces the whole curve of periodic orbits over the speed range,
stable and unstable, and writes ``branches.csv`` (:data:`BRANCH_COLUMNS`: speed, formulation,
the metrics in SI units, ``stable``, ``branch``, ``floquet_radius``, the multiplier of
largest modulus, ``point`` and ``segment``; one row per traced point, in the order traced,
and the bifurcation point that ends a branch once more as the first row of the next, so
that the rows of one ``branch`` are its whole polyline) and, in ``summary.json``, per
formulation ``branches.traced``: the folds and other bifurcations (speed, kind,
multiplier, metrics), the jumps (where a sweep leaves a stable branch, where it lands),
``jump_up_rad_s`` / ``jump_down_rad_s`` (the speeds of the jumps to a larger / smaller max
mesh force), the branches and the coexistence (hysteresis) bands.
"""

from __future__ import annotations

import math
import os

import numpy as np

from ..dynamics.continuation import (
    JUMP_THRESHOLD,
    branch_jumps,
    continuation_sweep,
    hysteresis_band,
)
from ..dynamics.arclength import Arclength, trace_speed
from ..dynamics.results import CSV_COLUMNS, append_rows, csv_rows, fmt_value

__all__ = ["DIRECTION_CHOICES", "EXTRA_COLUMNS", "BRANCH_COLUMNS", "BRANCHES_FILE",
           "run_branches", "check_direction", "traced_rows", "traced_summary", "plot_directions"]

DIRECTION_CHOICES = ("independent", "up", "down", "both")
EXTRA_COLUMNS = ("direction", "orbit", "spectral_radius", "restarted")
BRANCHES_FILE = "branches.csv"
BRANCH_COLUMNS = CSV_COLUMNS + ("stable", "branch", "floquet_radius", "multiplier_re",
                                "multiplier_im", "point", "segment")
# the metrics a summary entry of a bifurcation or a jump gives (SI units)
_SUMMARY_METRICS = ("max_mesh_force_N", "min_mesh_force_N", "dynamic_factor", "dte_ptp_m",
                    "accel_ptp_m_s2", "contact_loss", "back_contact", "converged")


def check_direction(args) -> None:
    """Refuse option combinations a continuation cannot honour (one line each)."""
    if args.direction == "independent":
        return
    if args.resume:
        raise ValueError(f"--direction={args.direction}: --resume is for independent speeds; a "
                         "continuation restarts from its first speed (use --overwrite)")
    if args.distributed or args.coordinator is not None or args.num_processes is not None:
        raise ValueError(f"--direction={args.direction}: a continuation is sequential in speed "
                         "and runs on one process")


def _rows(branch, direction: str) -> list[dict]:
    rows = []
    base = csv_rows(branch)
    st = branch.stats
    for i, r in enumerate(base):
        rows.append({**r, "direction": direction, "orbit": "followed",
                     "spectral_radius": fmt_value(branch.spectral_radius[i]),
                     "restarted": str(bool(st["restarted"][i]))})
        if np.isfinite(st["unstable_max_mesh_force_N"][i]):
            rows.append({**{k: "" for k in CSV_COLUMNS}, "speed_rad_s": r["speed_rad_s"],
                         "formulation": r["formulation"],
                         "max_mesh_force_N": fmt_value(st["unstable_max_mesh_force_N"][i]),
                         "dte_ptp_m": fmt_value(st["unstable_dte_ptp_m"][i]),
                         "contact_loss": "", "converged": "False",
                         "direction": direction, "orbit": "unstable",
                         "spectral_radius": fmt_value(st["unstable_spectral_radius"][i]),
                         "restarted": "False"})
    return rows


def _peak(branch) -> float:
    f = np.asarray(branch.max_mesh_force_N)[np.asarray(branch.stats["stable"], bool)]
    f = f[np.isfinite(f)]
    return float(f.max()) if f.size else float("nan")


def run_branches(model, speeds, direction: str, csv_path: str, progress) -> dict:
    """Run the ``up``/``down`` (or both) continuation sweeps of ``model`` over ``speeds``,
    append their rows to ``csv_path`` (sorted by speed per direction) and return the
    formulation's summary entries: per direction the jumps (:func:`branch_jumps`, threshold
    :data:`JUMP_THRESHOLD`), restarts and unstable orbits found, and for ``both`` the
    hysteresis band (:func:`hysteresis_band`). ``jump_up_rad_s`` / ``jump_down_rad_s``:
    the ``[from, to]`` speed pairs (rad/s, in sweep order) of the jumps to a higher / lower
    max mesh force, over both sweeps. ``progress``: the continuation's meter."""
    dirs = ("up", "down") if direction == "both" else (direction,)
    speeds = np.sort(np.asarray(speeds, dtype=float))
    traced = None
    if direction == "both":
        traced = trace_speed(model, speeds, progress=progress)
        path = os.path.join(os.path.dirname(csv_path), BRANCHES_FILE)
        append_rows(path, BRANCH_COLUMNS, traced_rows(traced))
    # the natural sweeps at the arclength corrector's tolerance (the 3D model's shooting
    # never reaches continuation_sweep's default: benchmarks/results/code_notes.md)
    tol = Arclength().corrector.newton_tol
    branches = {d: continuation_sweep(model, speeds, d, newton_tol=tol, progress=progress)
                for d in dirs}
    append_rows(csv_path, CSV_COLUMNS + EXTRA_COLUMNS,
                [row for d, br in branches.items() for row in _rows(br, d)])
    out = {"direction": direction, "jump_threshold": JUMP_THRESHOLD,
           "jump_definition": ("neighbouring speeds of one sweep whose max mesh force differs "
                               "by more than jump_threshold times the smaller one")}
    for d, br in branches.items():
        out[f"{d}_sweep"] = {
            "jumps": branch_jumps(br, d),
            "restarted_speeds": [float(w) for w in br.speed_rad_s[br.stats["restarted"]]],
            "no_stable_orbit_speeds": [float(w) for w in br.speed_rad_s[~br.stats["stable"]]],
            "unstable_orbit_speeds": [float(w) for w in br.speed_rad_s[
                np.isfinite(br.stats["unstable_max_mesh_force_N"])]],
            "peak_max_mesh_force_N": _peak(br),
        }
    jumps = [j for d in dirs for j in out[f"{d}_sweep"]["jumps"]]
    rise = lambda j: j["max_mesh_force_after_N"] > j["max_mesh_force_before_N"]  # noqa: E731
    out["jump_up_rad_s"] = [[j["from_rad_s"], j["to_rad_s"]] for j in jumps if rise(j)]
    out["jump_down_rad_s"] = [[j["from_rad_s"], j["to_rad_s"]] for j in jumps if not rise(j)]
    if direction == "both":
        out["hysteresis_band_rad_s"] = hysteresis_band(branches["up"], branches["down"])
        out["traced"] = traced_summary(traced, path)
    return out


def _num(v):
    """A JSON number, None for NaN."""
    v = float(v)
    return None if math.isnan(v) else v


def _metrics(m: dict) -> dict:
    return {k: (_num(m[k]) if isinstance(m[k], float) else m[k])
            for k in _SUMMARY_METRICS if k in m}


def traced_rows(res) -> list[dict]:
    """``branches.csv`` rows (:data:`BRANCH_COLUMNS`) of a
    :class:`~gearjax.dynamics.bifurcation.TracedBranches` (module docstring)."""
    base = csv_rows(res.points)
    rows = []
    kinds = {b.index for b in res.bifurcations}
    for i, r in enumerate(base):
        mu = complex(res.multipliers[i][0])
        row = {**r, "stable": str(bool(res.stable[i])), "branch": str(int(res.branch[i])),
               "floquet_radius": fmt_value(res.points.spectral_radius[i]),
               "multiplier_re": fmt_value(mu.real), "multiplier_im": fmt_value(mu.imag),
               "point": str(res.point[i]), "segment": str(int(res.segment[i]))}
        rows.append(row)
        nxt = i + 1
        if i in kinds and nxt < len(base) and res.segment[nxt] == res.segment[i]:
            rows.append({**row, "branch": str(int(res.branch[nxt]))})
    return rows


def traced_summary(res, path: str) -> dict:
    """The ``summary.json`` entry of a traced curve (module docstring)."""
    def bif(b):
        return {"speed_rad_s": b.speed_rad_s, "kind": b.kind,
                "multiplier": [b.multiplier.real, b.multiplier.imag],
                "located": b.located, "ends_stable_branch": b.ends_stable_branch,
                "metrics": _metrics(b.metrics)}

    stable = res.branch_stable()
    branches = []
    for b, ok in stable.items():
        sel = res.branch_indices(b)
        w = res.points.speed_rad_s[sel]
        branches.append({"branch": b, "stable": ok, "speed_min_rad_s": float(w.min()),
                         "speed_max_rad_s": float(w.max()), "n_points": int(sel.size),
                         "max_mesh_force_N": _num(np.nanmax(res.points.max_mesh_force_N[sel]))})
    return {
        "method": "pseudo-arclength continuation of the shooting residual in speed",
        "branches_csv": path, "n_points": int(res.points.speed_rad_s.size),
        "speed_scale_rad_s": res.speed_scale_rad_s,
        "folds": [bif(b) for b in res.folds()],
        "bifurcations": [bif(b) for b in res.bifurcations],
        "jumps": [{"sweep": j.sweep, "kind": j.kind, "from_rad_s": j.from_rad_s,
                   "to_rad_s": j.to_rad_s,
                   "max_mesh_force_before_N": _num(j.max_mesh_force_before_N),
                   "max_mesh_force_after_N": _num(j.max_mesh_force_after_N),
                   "landed_branch": j.landed_branch, "landed_periodic": j.landed_periodic,
                   "discontinuous": j.discontinuous,
                   "metrics_before": _metrics(res.point_metrics(j.index)),
                   "metrics_after": _metrics(j.metrics_after)} for j in res.jumps],
        "jump_up_rad_s": res.jump_up_rad_s(), "jump_down_rad_s": res.jump_down_rad_s(),
        "coexistence_rad_s": res.coexistence_rad_s(),
        "branches": branches,
        "stopped_rad_s": [float(w) for w in res.points.speed_rad_s[res.point == "stop"]],
    }


def plot_directions(direction: str, out_dir: str, summary: dict, fig_path: str,
                    title: str) -> str:
    """The figure of ``--direction``: for ``both`` the traced curves of ``branches.csv``
    with their jumps and the up/down sweeps of ``results.csv``
    (:func:`gearjax.plotting.plot_traced_branches`), else the sweep's branch
    (:func:`gearjax.plotting.plot_branches`)."""
    from ..plotting import plot_branches, plot_traced_branches

    csv_path = os.path.join(out_dir, "results.csv")
    if direction != "both":
        return plot_branches(csv_path, fig_path, title=title)
    jumps = {form: s["branches"]["traced"]["jumps"]
             for form, s in summary["formulations"].items()
             if "traced" in s.get("branches", {})}
    return plot_traced_branches(os.path.join(out_dir, BRANCHES_FILE), fig_path, title=title,
                                jumps=jumps, sweeps_csv=csv_path)
