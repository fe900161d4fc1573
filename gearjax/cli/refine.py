"""``gearjax sweep --refine [MAX_SPEEDS]``: the speed grid refined around the peaks and
jumps of the response curves (:mod:`gearjax.dynamics.refine`), off by default.

After every formulation has swept the requested speeds, their curves (read back from
``results.csv``, so a ``--resume`` refines from every row already there) propose new
speeds around the peaks of the maximum mesh force, the DTE and the acceleration
peak-to-peak and around jumps and contact-loss edges; every formulation is swept at every
proposed speed (one common grid: the formulations stay comparable speed by speed), and
again, until each peak is located to 1 % of its speed and its amplitude to 1e-3, or the
grid holds ``MAX_SPEEDS`` speeds (default 300). ``results.csv`` and ``orders.csv`` are then
sorted by speed within each formulation; ``summary.json``'s ``refinement`` lists the speeds
added, why and in which round, and every peak with its location and amplitude errors.
"""

from __future__ import annotations

import csv
import os

import numpy as np

from ..dynamics.refine import Refinement, refine_common
from ..dynamics.orbit import metric_status
from ..dynamics.results import SweepResult, empty_metrics
from .results import read_rows, rewrite_rows

__all__ = ["add_refine", "refinement_of", "result_of_rows", "sort_rows", "refine_runner",
           "refine_sweeps"]


def add_refine(p) -> None:
    """Add ``--refine [MAX_SPEEDS]`` to ``p``."""
    p.add_argument("--refine", nargs="?", const=str(Refinement.max_speeds), default=None,
                   metavar="MAX_SPEEDS",
                   help="refine the speed grid around the peaks (max force, DTE, acceleration) "
                        "and the jumps and contact-loss edges of every formulation, all "
                        "formulations at every added speed, until each peak is located to 1 %% "
                        "of its speed and its amplitude to 1e-3, or the grid holds MAX_SPEEDS "
                        f"speeds (default {Refinement.max_speeds}); off by default; "
                        "summary.json says which speeds were added and why")


def refinement_of(args, n_speeds: int) -> Refinement | None:
    """The :class:`Refinement` of ``--refine`` (None without it) for a sweep of
    ``n_speeds`` speeds; ``ValueError`` (one line) for a cap that is not an integer above
    ``n_speeds`` or a continuation sweep (``--direction``)."""
    text = getattr(args, "refine", None)
    if text is None:
        return None
    try:
        cap = int(text)
    except ValueError:
        raise ValueError(f"--refine={text!r}: expected the most speeds the refined grid may "
                         f"hold, an integer (default {Refinement.max_speeds})") from None
    if cap <= n_speeds:
        raise ValueError(f"--refine={cap}: the grid already holds {n_speeds} speeds; give a cap "
                         "above that")
    if getattr(args, "direction", "independent") != "independent":
        raise ValueError(f"--refine: for independent sweeps (--direction {args.direction} "
                         "continues each speed from its neighbour on the grid given)")
    if getattr(args, "distributed", False) or getattr(args, "coordinator", None) is not None:
        raise ValueError("--refine: on one process (the refinement reads the rows that "
                         "process 0 writes)")
    return Refinement(max_speeds=cap)


def _float(text) -> float:
    return float(text) if text not in ("", None) else float("nan")


def result_of_rows(rows: list[dict], formulation: str) -> SweepResult:
    """The :class:`SweepResult` of ``formulation``'s ``results.csv`` rows (the columns
    there; the rest NaN), sorted by speed."""
    rs = sorted((r for r in rows if r["formulation"] == formulation),
                key=lambda r: float(r["speed_rad_s"]))
    kw = empty_metrics(len(rs))
    for col in ("speed_rad_s", "max_mesh_force_N", "min_mesh_force_N", "dynamic_factor",
                "dte_ptp_m", "accel_ptp_m_s2", "convergence", "period_multiple"):
        kw[col] = np.array([_float(r[col]) for r in rs], dtype=float)
    for col in ("contact_loss", "back_contact", "converged"):
        kw[col] = np.array([r.get(col) == "True" for r in rs], dtype=bool)
    kw["solver_ok"] = kw["converged"] | np.isfinite(kw["max_mesh_force_N"])
    return SweepResult(**kw, formulation=formulation,
                       solver=np.array(["" for _ in rs], dtype=object),
                       spectral_radius=np.full(len(rs), np.nan),
                       status=metric_status(kw["solver_ok"], kw["converged"]))


def sort_rows(path: str) -> None:
    """Rewrite the CSV file ``path`` (``results.csv``, ``orders.csv``) with its rows sorted
    by speed within each formulation, the formulations in their first order."""
    if not os.path.exists(path) or os.path.getsize(path) == 0:
        return
    with open(path, newline="") as fh:
        reader = csv.DictReader(fh)
        fields, rows = reader.fieldnames, list(reader)
    first = {}
    for r in rows:
        first.setdefault(r["formulation"], len(first))
    rows.sort(key=lambda r: (first[r["formulation"]], float(r["speed_rad_s"])))
    rewrite_rows(path, fields, rows)


def refine_runner(sweep_fn, options_of, n_grid: int):
    """``run(model, speeds)`` for :func:`refine_sweeps`: ``sweep_fn(model, speeds,
    **options)`` with the command's options ``options_of(model)`` (solver, devices, chunk)
    and, without ``--chunk``, the chunk of the grid's sweep
    (:func:`gearjax.dynamics.sweep.planned_chunk` for ``n_grid`` speeds), so that the added
    speeds run the program compiled for the grid instead of one per round's count."""
    from ..dynamics.sweep import planned_chunk

    def run(model, speeds):
        opts = dict(options_of(model))
        if opts.get("chunk_size") is None:
            opts["chunk_size"] = planned_chunk(model, n_grid, opts["solver"], opts.get("devices"))
        else:
            opts["chunk_size"] = max(1, int(opts["chunk_size"]))
        return sweep_fn(model, speeds, **opts)

    return run


def refine_sweeps(models: dict, csv_path: str, paths, run, refinement: Refinement,
                  progress) -> dict:
    """Refine the sweeps of ``models`` (formulation -> model) from their rows in
    ``csv_path`` (:func:`gearjax.dynamics.refine.refine_common`, ``run(model, speeds)``
    sweeping and writing one formulation's speeds), sort the CSV files ``paths`` and
    return ``summary.json``'s ``refinement``."""
    rows = read_rows(csv_path)
    out = refine_common(lambda form, w: run(models[form], w),
                        {f: result_of_rows(rows, f) for f in models}, refinement,
                        progress=progress)
    for path in paths:
        sort_rows(path)
    return {
        "max_speeds": refinement.max_speeds, "speed_tol": refinement.speed_tol,
        "amplitude_tol": refinement.amplitude_tol, "stopped": out.stopped,
        "speeds_added": len(out.added), "added": out.added,
        "peaks": {f: [p._asdict() for p in peaks] for f, peaks in out.peaks.items()},
    }
