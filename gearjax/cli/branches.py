"""``gearjax sweep --direction up|down|both``: the rows and the summary of continuation
sweeps (:mod:`gearjax.dynamics.continuation`); formatting only.

``results.csv`` of a direction sweep has the columns of the default sweep
(:data:`gearjax.dynamics.results.CSV_COLUMNS`) plus :data:`EXTRA_COLUMNS`: ``direction``
(``up``/``down``), ``orbit`` (``followed``: the orbit the sweep follows at that speed;
``unstable``: an unstable periodic orbit the continuation met there, see
:class:`gearjax.dynamics.continuation.BranchResult`), ``spectral_radius`` (Floquet) and
``restarted``. The default ``--direction independent`` (each speed from the quasi-static
start, as before) writes the default columns only.
"""

from __future__ import annotations

import numpy as np

from ..dynamics.continuation import (
    JUMP_THRESHOLD,
    branch_jumps,
    continuation_sweep,
    hysteresis_band,
)
from ..dynamics.results import CSV_COLUMNS, append_rows, csv_rows, fmt_value

__all__ = ["DIRECTION_CHOICES", "EXTRA_COLUMNS", "run_branches", "check_direction"]

DIRECTION_CHOICES = ("independent", "up", "down", "both")
EXTRA_COLUMNS = ("direction", "orbit", "spectral_radius", "restarted")


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


def _rows(branch) -> list[dict]:
    rows = []
    base = csv_rows(branch)
    for i, r in enumerate(base):
        rows.append({**r, "direction": branch.direction, "orbit": "followed",
                     "spectral_radius": fmt_value(branch.spectral_radius[i]),
                     "restarted": str(bool(branch.restarted[i]))})
        if np.isfinite(branch.unstable_max_mesh_force_N[i]):
            rows.append({**{k: "" for k in CSV_COLUMNS}, "speed_rad_s": r["speed_rad_s"],
                         "formulation": r["formulation"],
                         "max_mesh_force_N": fmt_value(branch.unstable_max_mesh_force_N[i]),
                         "dte_ptp_m": fmt_value(branch.unstable_dte_ptp_m[i]),
                         "contact_loss": "", "converged": "False",
                         "direction": branch.direction, "orbit": "unstable",
                         "spectral_radius": fmt_value(branch.unstable_spectral_radius[i]),
                         "restarted": "False"})
    return rows


def _peak(branch) -> float:
    f = np.asarray(branch.max_mesh_force_N)[np.asarray(branch.stable, bool)]
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
    branches = {d: continuation_sweep(model, speeds, d, progress=progress) for d in dirs}
    append_rows(csv_path, CSV_COLUMNS + EXTRA_COLUMNS,
                [row for br in branches.values() for row in _rows(br)])
    out = {"direction": direction, "jump_threshold": JUMP_THRESHOLD,
           "jump_definition": ("neighbouring speeds of one sweep whose max mesh force differs "
                               "by more than jump_threshold times the smaller one")}
    for d, br in branches.items():
        out[f"{d}_sweep"] = {
            "jumps": branch_jumps(br),
            "restarted_speeds": [float(w) for w in br.speed_rad_s[br.restarted]],
            "no_stable_orbit_speeds": [float(w) for w in br.speed_rad_s[~br.stable]],
            "unstable_orbit_speeds": [float(w) for w in
                                      br.speed_rad_s[np.isfinite(br.unstable_max_mesh_force_N)]],
            "peak_max_mesh_force_N": _peak(br),
        }
    jumps = [j for d in dirs for j in out[f"{d}_sweep"]["jumps"]]
    rise = lambda j: j["max_mesh_force_after_N"] > j["max_mesh_force_before_N"]  # noqa: E731
    out["jump_up_rad_s"] = [[j["from_rad_s"], j["to_rad_s"]] for j in jumps if rise(j)]
    out["jump_down_rad_s"] = [[j["from_rad_s"], j["to_rad_s"]] for j in jumps if not rise(j)]
    if direction == "both":
        out["hysteresis_band_rad_s"] = hysteresis_band(branches["up"], branches["down"])
    return out
