"""The claims of Velex & Ajmi's Section 6.3 judged on every panel of each figure, for the
README that ``gearjax paper`` writes (:func:`panel_claims`).

The paper's Figs. 8-13 have three panels (maximum dynamic mesh force, peak-to-peak DTE,
peak-to-peak pinion-centre acceleration) and speak of contact losses; its sentences judge
the curves as a whole. For each comparison the paper makes (a formulation against the
reference, or a case against another) and each panel, this module gives the relative
difference at the speeds both curves converged (max, median, and where the max sits), the
speeds where the two disagree about contact loss, a verdict with its criterion, and, where
the verdict is "disagree", its cause as far as the numbers show it:

* **assumption (contact law)**: the largest difference sits at a speed where one curve
  loses contact and the other does not. te and perturbation apply the contact law to the
  whole mesh (Section 6.2 read at mesh level): their contact-loss flags and the response
  where they lose contact are not comparable with the reference's cell-by-cell law (the
  per-cell reading: :mod:`gearjax.cli.paper_readings`).
* **assumption (18a)**: the te acceleration. Under assumption (18a) te's mesh force steps by
  ``Delta k v_xD`` at every quasi-static stiffness switch (issue 48 measured 1,574 N and
  2,172 N steps at 800 rad/s, long relief); the steps reach the acceleration, not the force
  envelope.
* **assumption (48a) truncation**: the perturbation method's main-order approximation at a
  speed near one of the model's critical speeds.
* **open**: none of the above.

"Near a critical speed" is the model's own: within 10 % of a crossing of mesh order 1 with
a mode holding at least :data:`NEAR_SHARE` of the mesh strain energy (the sweep's
``summary.json`` ``critical_speeds``, from :mod:`gearjax.rigs.campbell`). A case folder
written before the sweep recorded them falls back to the reference's peak speed, as the
first claims table does.

The minimum-force panel compares the minimum mesh force as a fraction of the static force
F_S (``max force / dynamic factor``): its difference is in % of F_S, not relative to a
minimum that reaches zero where contact is lost.
"""

from __future__ import annotations

import csv
import json
import os
from typing import NamedTuple

import numpy as np

__all__ = ["case_rows", "PANELS", "COMPARISONS", "AGREE_TOLERANCE", "NEAR_SHARE", "panel_claims",
           "critical_speeds", "panel_curve", "compare_curves"]

# (results.csv column, panel name)
PANELS = (("max_mesh_force_N", "max force"), ("dte_ptp_m", "DTE p-p"),
          ("accel_ptp_m_s2", "acceleration p-p"), ("min_mesh_force_N", "min force / F_S"))
AGREE_TOLERANCE = 0.05  # "agree": every difference within 5 %
DIFFER_FACTOR = 3.0  # "significantly different": at least 3x the agreeing curve's max
NEAR_SHARE = 0.10  # a mode with >= 10 % of the mesh strain energy makes a critical speed
NEAR_BAND = 0.10  # within 10 % of such a critical speed is "near"


class Comparison(NamedTuple):
    section: str
    figure: str
    case: str
    formulation: str
    ref_case: str
    ref_formulation: str
    statement: str  # "agree", "agree-away", "differ", "worse-near", "worse"
    words: str


COMPARISONS = (
    Comparison("6.3.1", "Fig. 8", "fig08", "te", "fig08", "reference", "agree-away",
               "agreement except near the major critical speed (damping 0.03)"),
    Comparison("6.3.1", "Fig. 8", "fig08", "perturbation", "fig08", "reference", "agree-away",
               "agreement except near the major critical speed (damping 0.03)"),
    Comparison("6.3.1", "Fig. 9", "fig09", "te", "fig09", "reference", "agree",
               "better at damping 0.1"),
    Comparison("6.3.1", "Fig. 9", "fig09", "perturbation", "fig09", "reference", "agree",
               "perturbation reasonably satisfactory at damping 0.1"),
    Comparison("6.3.2", "Figs. 10a-c", "fig10", "te", "fig10", "reference", "agree",
               "very close agreement (long relief)"),
    Comparison("6.3.2", "Figs. 10a-c", "fig10-no-nlte", "te", "fig10", "reference", "differ",
               "NLTE'' = 0: significantly different"),
    Comparison("6.3.3", "Fig. 12", "fig12", "te", "fig12", "reference", "agree",
               "soundness of the formulations (pitch errors)"),
    Comparison("6.3.3", "Fig. 12", "fig12", "perturbation", "fig12", "reference", "worse-near",
               "perturbation less accurate near critical speeds"),
    Comparison("6.3.4", "Fig. 13", "fig13", "te", "fig13", "reference", "agree",
               "te and reference accord well (helical)"),
    Comparison("6.3.4", "Fig. 13", "fig13", "perturbation", "fig13", "reference", "worse",
               "perturbation less satisfactory than te"),
)


def case_rows(out, key):
    """The rows of case ``key``'s ``results.csv`` under ``out`` (dicts), or None where the
    case has not run."""
    path = os.path.join(out, key, "results.csv")
    if not os.path.exists(path):
        return None
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def panel_curve(rows, form, col):
    """{speed: (value, contact_loss)} of one formulation at its converged speeds; the
    minimum force relative to F_S."""
    out = {}
    for r in rows or ():
        if r["formulation"] != form or r["converged"] != "True" or r.get(col, "") in ("", "nan"):
            continue
        v = float(r[col])
        if col == "min_mesh_force_N":
            f_s = float(r["max_mesh_force_N"]) / float(r["dynamic_factor"])
            v = v / f_s
        out[float(r["speed_rad_s"])] = (v, r["contact_loss"] == "True")
    return out


def critical_speeds(out: str, key: str, rows) -> tuple[list[tuple[float, float, float]], str]:
    """The model's order-1 critical speeds of case ``key`` with a mesh-energy share of at
    least :data:`NEAR_SHARE`: ``[(speed rad/s, mode Hz, share)]`` and where they come from;
    without them in ``summary.json``, the reference's peak dynamic factor."""
    path = os.path.join(out, key, "summary.json")
    if os.path.exists(path):
        with open(path) as fh:
            crit = json.load(fh).get("critical_speeds")
        if crit:
            sel = [(float(c["crossing_speed_rad_s"]), float(c["frequency_hz"]),
                    float(c["mesh_energy_share"])) for c in crit
                   if int(c["mesh_order"]) == 1 and float(c["mesh_energy_share"]) >= NEAR_SHARE]
            if sel:
                return sel, "the model's modes"
    df = {}
    for r in rows or ():
        if r["formulation"] == "reference" and r["dynamic_factor"] not in ("", "nan"):
            df[float(r["speed_rad_s"])] = float(r["dynamic_factor"])
    if not df:
        return [], "none"
    return [(max(df, key=df.get), float("nan"), float("nan"))], "the reference's peak"


def _near(w: float, crit) -> float | None:
    """The critical speed within :data:`NEAR_BAND` of ``w``, or None."""
    close = [c[0] for c in crit if abs(w - c[0]) <= NEAR_BAND * c[0]]
    return min(close, key=lambda c: abs(w - c)) if close else None


def compare_curves(mine: dict, ref: dict, absolute: bool = False):
    """(speeds, differences, speeds where the contact-loss flags differ): relative
    differences, or with ``absolute`` plain ones (the minimum force / F_S, which reaches 0)."""
    w = np.array(sorted(set(mine) & set(ref)))
    if w.size == 0:
        return w, np.array([]), []
    scale = {x: 1.0 if absolute else max(abs(ref[x][0]), 1e-300) for x in w}
    d = np.array([abs(mine[x][0] - ref[x][0]) / scale[x] for x in w])
    flags = [float(x) for x in w if mine[x][1] != ref[x][1]]
    return w, d, flags


def _cause(c: Comparison, col: str, worst_w: float, flags, crit) -> str:
    if worst_w in flags:
        return ("assumption (contact law): at the worst speed one curve loses contact and the "
                "other does not; te/perturbation apply the contact law to the whole mesh (the "
                "per-cell reading: \"Two readings of Section 6.2\" below)")
    if c.formulation == "te" and col == "accel_ptp_m_s2":
        return ("assumption (18a): te's force steps by Delta k v_xD at each quasi-static "
                "stiffness switch, which the acceleration shows")
    if c.formulation == "perturbation" and _near(worst_w, crit) is not None:
        return "assumption (48a): main-order truncation near a critical speed"
    return "open"


def _judge(c: Comparison, d, w, crit, agreeing_max) -> tuple[bool, str]:
    """(holds, criterion) of the paper's statement on one panel."""
    tol = f"{100 * AGREE_TOLERANCE:g} %"
    if c.statement == "agree":
        return bool(np.max(d) <= AGREE_TOLERANCE), f"every difference <= {tol}"
    near = np.array([_near(float(x), crit) is not None for x in w])
    if c.statement == "agree-away":
        away = d[~near]
        return bool(away.size == 0 or np.max(away) <= AGREE_TOLERANCE), \
            f"every difference away from the critical speeds <= {tol}"
    if c.statement == "worse-near":
        ok = bool(near.any() and (~near).any() and np.max(d[near]) > np.max(d[~near]))
        return ok, "largest difference near a critical speed"
    if c.statement == "differ":
        ok = agreeing_max is not None and np.max(d) >= DIFFER_FACTOR * agreeing_max
        return bool(ok), f"at least {DIFFER_FACTOR:g}x the te curve's max difference"
    ok = agreeing_max is not None and np.max(d) > agreeing_max
    return bool(ok), "larger max difference than te's"


def panel_claims(out: str) -> list[dict]:
    """One row per (comparison, panel) whose cases exist under ``out``: section, figure,
    comparison, panel, numbers, verdict (agree / disagree / incomplete), criterion, cause
    (disagreements only) and the critical speeds used."""
    R = {}
    rows = []
    for c in COMPARISONS:
        for k in (c.case, c.ref_case):
            if k not in R:
                R[k] = case_rows(out, k)
        if R[c.case] is None or R[c.ref_case] is None:
            continue
        crit, source = critical_speeds(out, c.ref_case, R[c.ref_case])
        for col, panel in PANELS:
            mine = panel_curve(R[c.case], c.formulation, col)
            ref = panel_curve(R[c.ref_case], c.ref_formulation, col)
            absolute = col == "min_mesh_force_N"
            w, d, flags = compare_curves(mine, ref, absolute)
            row = {"section": c.section, "figure": c.figure, "panel": panel,
                   "comparison": (f"{c.formulation} ({c.case}) vs {c.ref_formulation}"
                                  + (f" ({c.ref_case})" if c.ref_case != c.case else "")),
                   "paper": c.words, "critical_speeds": crit, "critical_source": source,
                   "cause": ""}
            if w.size == 0:
                row.update(numbers="no converged speed in common", verdict="incomplete",
                           criterion="")
                rows.append(row)
                continue
            i = int(np.argmax(d))
            worst = float(w[i])
            at = _near(worst, crit)
            where = f"near {at:.0f} rad/s" if at is not None else "away from the critical speeds"
            agreeing = None
            if c.statement in ("differ", "worse"):  # against te on the same case
                te = panel_curve(R[c.ref_case if c.statement == "differ" else c.case], "te", col)
                _, dt, _ = compare_curves(te, ref, absolute)
                agreeing = float(np.max(dt)) if dt.size else None
            ok, criterion = _judge(c, d, w, crit, agreeing)
            unit = " of F_S" if absolute else ""
            numbers = (f"median {100 * np.median(d):.1f} %{unit}, max {100 * d[i]:.1f} %{unit} at "
                       f"{worst:.0f} rad/s ({where})")
            if flags:
                numbers += (f"; contact-loss flags differ at {len(flags)} speed"
                            f"{'s' * (len(flags) != 1)} ({', '.join(f'{x:.0f}' for x in flags[:5])}"
                            f"{' ...' if len(flags) > 5 else ''})")
            if agreeing is not None:
                numbers += f"; te's max {100 * agreeing:.1f} %"
            row.update(numbers=numbers, verdict="agree" if ok else "disagree", criterion=criterion)
            if not ok:
                row["cause"] = _cause(c, col, worst, flags, crit)
            rows.append(row)
    return rows


def panel_table(out: str) -> list[str]:
    """Markdown lines of the per-panel table (empty when no case was run)."""
    rows = panel_claims(out)
    if not rows:
        return []
    lines = ["## Every panel", "",
             "Each comparison the paper makes, on each panel of its figure (differences at the "
             "speeds both curves converged, relative; the minimum force's in % of F_S). \"Near\" a "
             f"critical speed: within {100 * NEAR_BAND:g} % of a mesh-order-1 crossing of a mode "
             f"holding at least {100 * NEAR_SHARE:g} % of the mesh strain energy "
             "(`gearjax campbell`), listed per case below the table. A disagreement names its "
             "cause where the numbers show one (module `gearjax.cli.paper_panels`).", "",
             "| section | comparison | panel | the paper | our numbers | verdict | criterion | cause |",
             "|---|---|---|---|---|---|---|---|"]
    seen = {}
    for r in rows:
        lines.append(f"| {r['section']} {r['figure']} | {r['comparison']} | {r['panel']} | "
                     f"{r['paper']} | {r['numbers']} | **{r['verdict']}** | {r['criterion']} | "
                     f"{r['cause'] or '-'} |")
        seen.setdefault(r["figure"], (r["critical_speeds"], r["critical_source"]))
    lines += [""]
    for fig, (crit, source) in seen.items():
        if source == "the model's modes":
            txt = ", ".join(f"{w:.0f} rad/s ({f:.0f} Hz, {100 * s:.0f} %)" for w, f, s in crit)
        else:
            txt = ", ".join(f"{w:.0f} rad/s" for w, _, _ in crit) + f" ({source}; the case "
            txt += "predates the recorded critical speeds)"
        lines.append(f"- {fig}: critical speeds {txt or 'none'}")
    return lines + [""]
