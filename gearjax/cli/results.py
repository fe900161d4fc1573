"""A sweep's output folder: the case record (``case.json``), resuming from ``results.csv``
and the summary of whatever rows it holds (a finished, an interrupted or a resumed run)
with its closing table on the terminal.

``case.json`` is written before the first speed is computed; ``gearjax sweep --resume``
compares it with the new command (same case, same speeds, same formulations) and skips
the (formulation, speed) rows already in ``results.csv``.
"""

from __future__ import annotations

import csv
import json
import math
import os

import numpy as np

from ..errors import GearjaxError

__all__ = ["RESULT_FILES", "CASE_FILE", "write_case", "check_resume", "read_rows",
           "rewrite_rows", "done_speeds", "summarise_rows", "method_counts", "print_summary"]

CASE_FILE = "case.json"
MAX_LISTED = 1000  # speeds listed by name in summary.json (counts are always whole)
# files a sweep writes in its folder (an earlier run is recognised by any of them)
RESULT_FILES = ("results.csv", "summary.json", CASE_FILE, "response_curves.png",
                "signals.csv", "mesh_force_signals.png", "orders.csv", "order_tracks.png",
                "branches.csv")


def write_case(out: str, record: dict) -> None:
    with open(os.path.join(out, CASE_FILE), "w") as fh:
        json.dump(record, fh, indent=2)


def check_resume(out: str, record: dict) -> None:
    """Refuse ``--resume`` unless ``out`` holds a run of the same case (``record``)."""
    path = os.path.join(out, CASE_FILE)
    has_csv = os.path.exists(os.path.join(out, "results.csv"))
    if not os.path.exists(path):
        if has_csv:
            raise GearjaxError("--resume", out, f"{CASE_FILE} is missing, so the results.csv there "
                                                "cannot be checked to belong to this case; use "
                                                "--overwrite or another --out folder")
        return  # nothing to resume: a fresh run
    try:
        with open(path) as fh:
            old = json.load(fh)
    except (OSError, ValueError) as exc:
        raise GearjaxError("--resume", out, f"cannot read {CASE_FILE} ({exc})") from None
    diff = [k for k in sorted(set(old) | set(record)) if old.get(k) != record.get(k)]
    if diff:
        k = diff[0]
        if k.endswith("_file_sha256"):
            what = k[: -len("_file_sha256")].replace("te", "TE")
            raise GearjaxError("--resume", out, f"the folder holds another case: the {what} "
                                                f"file's contents changed since that run "
                                                f"({k} was {_short(old.get(k))}, now "
                                                f"{_short(record.get(k))}); resume with the same "
                                                "file, or use --overwrite or another --out")
        raise GearjaxError("--resume", out, f"the folder holds another case: {k} was "
                                            f"{_short(old.get(k))}, now {_short(record.get(k))}; resume with "
                                            "the same options, or use --overwrite or another --out")


def _short(value) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _float(text: str) -> float:
    return float(text) if text not in ("", None) else math.nan


def read_rows(csv_path: str, *, repair: bool = False) -> list[dict]:
    """The complete rows of a ``results.csv`` (an interrupted write may leave a partial
    last line: ``repair`` rewrites the file without it so that appending can go on)."""
    if not os.path.exists(csv_path) or os.path.getsize(csv_path) == 0:
        return []
    with open(csv_path, newline="") as fh:
        reader = csv.DictReader(fh)
        fields = reader.fieldnames
        rows, bad = [], 0
        for r in reader:
            try:
                if None in r or any(v is None for v in r.values()):
                    raise ValueError
                float(r["speed_rad_s"])
                rows.append(r)
            except (ValueError, KeyError, TypeError):
                bad += 1
    if repair and (bad or not open(csv_path).read().endswith("\n")):
        rewrite_rows(csv_path, fields, rows)
    return rows


def rewrite_rows(csv_path: str, fields, rows) -> None:
    """Replace the CSV file ``csv_path`` by ``rows`` (dicts keyed by ``fields``), through a
    temporary file and an atomic rename: an interrupted rewrite leaves the old file."""
    tmp = csv_path + ".tmp"
    with open(tmp, "w", newline="") as fh:
        wr = csv.DictWriter(fh, fieldnames=fields)
        wr.writeheader()
        wr.writerows(rows)
    os.replace(tmp, csv_path)


def done_speeds(rows: list[dict]) -> dict[str, set[float]]:
    """``{formulation: speeds already in the file}``."""
    out: dict[str, set[float]] = {}
    for r in rows:
        out.setdefault(r["formulation"], set()).add(float(r["speed_rad_s"]))
    return out


def summarise_rows(rows: list[dict], formulation: str, speeds: np.ndarray) -> dict:
    """Summary of one formulation's rows. The peak dynamic factor is taken over converged
    speeds only (an unconverged run's maximum is not a steady-state response; those speeds
    are listed, and the peak is NaN when none converged). The speeds not yet computed are
    counted and the first :data:`MAX_LISTED` listed; the time is linear in the speeds."""
    rs = sorted((r for r in rows if r["formulation"] == formulation),
                key=lambda r: float(r["speed_rad_s"]))
    w = np.array([float(r["speed_rad_s"]) for r in rs])
    df = np.array([_float(r["dynamic_factor"]) for r in rs])
    fmax = np.array([_float(r["max_mesh_force_N"]) for r in rs])
    conv = np.array([r["converged"] == "True" for r in rs], dtype=bool)
    resid = np.array([_float(r.get("convergence", "nan")) for r in rs])
    loss = np.array([r["contact_loss"] == "True" for r in rs], dtype=bool)
    back = np.array([r.get("back_contact") == "True" for r in rs], dtype=bool)
    period = np.array([_float(r.get("period_multiple", "")) for r in rs])
    finite = np.isfinite(df)
    ok = conv & finite
    i = int(np.argmax(np.where(ok, df, -np.inf))) if ok.any() else None
    # linear in the speeds (a Ctrl-C of ten million speeds summarises in seconds); the list
    # is cut at MAX_LISTED, the count is whole
    missing = np.asarray(speeds, dtype=float)[~np.isin(speeds, w)]
    return {
        "peak_dynamic_factor": float(df[i]) if i is not None else float("nan"),
        "critical_speed_rad_s": float(w[i]) if i is not None else float("nan"),
        "peak_over": "converged speeds only",
        "max_mesh_force_N": float(np.max(fmax[ok])) if ok.any() else float("nan"),
        "speeds_done": int(w.size),
        "missing_speeds": [float(v) for v in missing[:MAX_LISTED]],
        "missing_speeds_count": int(missing.size),
        "contact_loss_speeds": [float(v) for v in w[loss]],
        "back_contact_speeds": [float(v) for v in w[back]],  # double-sided impacts (backlash)
        "unconverged_speeds": [float(v) for v in w[~conv]],
        # of those, the sub-harmonic orbits: speed -> period in excitation periods
        "subharmonic_speeds": {repr(float(v)): int(m) for v, m in zip(w, period)
                               if np.isfinite(m) and m >= 2},
        "failed_speeds": [float(v) for v in w[~finite]],
        # the achieved periodicity residual (results.csv's convergence column), worst speed
        "max_convergence_measure": (float(np.nanmax(resid)) if np.any(np.isfinite(resid))
                                    else float("nan")),
    }


def max_force_by_speed(rows: list[dict], formulation: str) -> dict[float, float]:
    return {float(r["speed_rad_s"]): _float(r["max_mesh_force_N"])
            for r in rows if r["formulation"] == formulation}


def method_counts(res) -> dict:
    """Speeds solved by each solver in one sweep (``summary.json``; the result's
    ``solver`` per speed: a frequency-domain or shooting sweep's fallback speeds are
    ``transient``)."""
    names, counts = np.unique(np.asarray(res.solver), return_counts=True)
    return {str(k): int(v) for k, v in zip(names, counts)}


def _listed(speeds, tags=None) -> str:
    """The first 8 speeds (rad/s, with their tags) and how many more."""
    tags = tags or [""] * len(speeds)
    text = ", ".join(f"{w:.0f}{t}" for w, t in list(zip(speeds, tags))[:8])
    return text + (f" (+{len(speeds) - 8} more)" if len(speeds) > 8 else "")


def print_summary(rig, summary: dict, out: str) -> None:
    """The closing table of a sweep (stdout) from its ``summary.json`` record ``summary``:
    the case, warnings and notes, the predicted critical speed, per formulation the peak
    K_v and where, and the files written to ``out``."""
    pred = summary["predicted"]
    print(f"\n  {rig.description}")
    excitation = summary.get("excitation") or (f"{summary['relief_label']} "
                                               f"[{summary['relief_source']}]")
    print(f"  {summary['model']} model, {excitation}, "
          f"damping {summary['damping']}, NLTE'' reaction at the {summary['nlte_reaction']}, "
          f"torque {summary['pinion_torque_Nm']:g} N m, law {summary['stiffness_law']}, "
          f"speeds {summary['speeds_rad_s'][0]:.0f}-{summary['speeds_rad_s'][1]:.0f} rad/s "
          f"({summary['speeds_rad_s'][2]}; {summary['speeds_source']})")
    if summary["model"] == "3d":
        fc = summary["max_frequency_hz"]
        print(f"  modes {'below %.0f Hz' % fc if fc else 'all'} ({summary['max_frequency_source']})"
              f": {summary['n_modes']} modes")
    for w in summary.get("warnings", ()):
        print(f"  warning: {w}")
    for n in summary.get("notes", ()):
        print(f"  note: {n}")
    print(f"  predicted main tooth critical speed {pred['critical_speed_rad_s']:.0f} rad/s (peak of "
          f"the mesh receptance; mode with most mesh energy: {pred['mode_frequency_hz']:.0f} Hz, "
          f"{100 * pred['mesh_energy_share']:.0f} %, i.e. {pred['mode_critical_speed_rad_s']:.0f} rad/s)")
    if "iso6336_kv" in summary:
        kv = summary["iso6336_kv"]
        print(f"  ISO 6336-1 method B: resonance speed n_E1 "
              f"{summary['iso6336_resonance_speed_rad_s']:.0f} rad/s, K_v {min(kv):.3f}-"
              f"{max(kv):.3f} over the speeds (response_curves.png, first panel)")
    print(f"  {'formulation':13s} {'peak K_v':>9s} {'at [rad/s]':>11s} {'contact loss':>13s} "
          f"{'unconverged':>12s} {'vs reference':>13s} {'time [s]':>9s}")
    agree = summary.get("agreement_with_reference", {})
    for form, r in summary["formulations"].items():
        a = agree.get(form)
        vs = f"{100 * a['max_rel_diff_max_mesh_force']:.1f} % max" if a else "-"
        print(f"  {form:13s} {r['peak_dynamic_factor']:9.3f} {r['critical_speed_rad_s']:11.1f} "
              f"{len(r['contact_loss_speeds']):13d} {len(r['unconverged_speeds']):12d} {vs:>13s} "
              f"{r['build_time_s'] + r['wall_time_s']:9.1f}")
    for form, r in summary["formulations"].items():
        if r.get("back_contact_speeds"):
            print(f"  note: {form} strikes the back flanks (double-sided impacts, backlash "
                  f"{summary.get('backlash_m')} m) at {_listed(r['back_contact_speeds'])} rad/s")
        sub = r.get("subharmonic_speeds") or {}
        rest = [w for w in r["unconverged_speeds"] if repr(float(w)) not in sub]
        if rest:
            print(f"  note: {form} not converged to steady state at {_listed(rest)} rad/s "
                  "(converged=False in results.csv); the peak K_v is over the converged "
                  "speeds only")
        if sub:
            print(f"  note: {form} periodic over m excitation periods (sub-harmonic, "
                  f"period_multiple m in results.csv; converged=False, out of the peak K_v) "
                  f"at {_listed([float(w) for w in sub], [f' ({m}P)' for m in sub.values()])} "
                  "rad/s")
    files = [summary["results_csv"]] + [summary[k] for k in (
        "response_curves_png", "orders_csv", "order_tracks_png") if k in summary]
    files += [os.path.join(out, "summary.json")]
    files += [summary[k] for k in ("signals_csv", "mesh_force_signals_png") if k in summary]
    print(f"  wrote {', '.join(files)}  ({summary['total_time_s']:.0f} s in all)")
