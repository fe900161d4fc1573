"""``gearjax paper``: every case of Velex & Ajmi's Section 6.3 on the 3D Baud–Velex rig,
written under one folder (default ``docs/paper/``) with a generated ``README.md`` that
sets each claim of Sections 6.3.1–6.3.5 beside our numbers.

Each case is one ``gearjax sweep`` (:data:`CASES`, the command line is printed and stored),
so its folder holds the sweep's ``results.csv``, ``response_curves.png``, ``orders.csv``
and ``summary.json``; an interrupted run continues with ``--resume``. The claims
(:func:`claims`) compare formulations on the *same* model, which is what the paper's
sentences are about: the relative difference of the maximum dynamic mesh force between two
curves at every common speed (max and median), near a critical speed (within ±10 % of the
model's own critical speeds, the order-1 crossings of modes holding at least 10 % of the mesh
strain energy that the sweep records; the reference's peak for a case that predates them)
and away from it, and the speeds where the reference loses contact. The verdict says
whether the inequality the paper states holds in our numbers. A second table
(:mod:`gearjax.cli.paper_panels`) judges every panel (force, DTE, acceleration, minimum
force and contact loss) and names the cause of each disagreement.

Every case runs the paper's mesh model by default (Section 6.1, Weber-Banaschek/O'Donnell:
``--stiffness weber``); ``paper.json`` and the README record the law. The law matters to the
comparisons, not only to the critical speeds: Fig. 8's case (zeta 0.03, 340-460 rad/s) with
``weber`` keeps contact and te stays within 3.3 % of the reference, where ``iso6336`` puts te
23.7 % off at 420 rad/s (issue 48's measurement). ``--compare DIR`` sets the verdicts of a
second run (e.g. ``--stiffness iso6336``) beside this one's; ``--readme-only`` rewrites the
README from the stored cases without running anything.

Each case's grid is refined around the peaks and jumps of its curves (``gearjax sweep
--refine``, :data:`PAPER_REFINE` speeds a case by default), so the claims near the critical
speeds and the contact-loss edges rest on speeds within 1 % of them. The cases
``fig08-cells`` and ``fig09-cells`` run te and perturbation with the per-cell contact law
(``--te-contact cells``) beside their reference: the third table
(:mod:`gearjax.cli.paper_readings`) sets the two readings of Section 6.2 side by side.
"""

from __future__ import annotations

import json
import os
import sys
import time
from typing import NamedTuple

import numpy as np

__all__ = ["CASES", "register", "cmd_paper", "claims"]


class Case(NamedTuple):
    key: str
    section: str
    figure: str
    title: str
    argv: tuple[str, ...]
    needs_3d: bool = False
    default: bool = True  # run without --cases (False: only when named)
    max_refine: int = 10**9  # at most this many speeds with --refine


PITCH_REFINE = 75  # the refined grid of a case with pitch errors (45 + 30 speeds)
# Pitch errors make the excitation period a pinion revolution (26 mesh periods): the
# frequency-domain solver then escalates to thousands of harmonics per revolution, one 3D
# compile per size, and took longer than the transient (benchmarks/results/code_notes.md,
# section gearjax.cli.paper); these cases run the transient for every formulation (issue 14:
# harmonics per mesh period).
CASES = (
    Case("fig08", "6.3.1", "Fig. 8", "spur, short relief, damping 0.03", ("--damping", "0.03")),
    Case("fig09", "6.3.1", "Fig. 9", "spur, short relief, damping 0.1", ()),
    Case("fig10", "6.3.2", "Figs. 10-11", "spur, long relief, damping 0.1",
         ("--relief", "long", "--formulations", "reference,te", "--signals", "100,400,800")),
    Case("fig10-no-nlte", "6.3.2", "Figs. 10-11", "long relief, NLTE'' terms set to zero (te)",
         ("--relief", "long", "--no-nlte-terms", "--formulations", "te", "--signals", "100,400,800")),
    Case("encoders2", "6.3.5", "Fig. 7", "encoder position 2 (free shaft ends), te",
         ("--encoders", "2", "--formulations", "te"), needs_3d=True),
    Case("encoders3", "6.3.5", "Fig. 7", "encoder position 3 (coupling hubs), te",
         ("--encoders", "3", "--formulations", "te"), needs_3d=True),
    # with pitch errors every added speed costs a pinion revolution (26 mesh periods) per
    # period of transient: their grids get one round around the main peaks (30 speeds)
    Case("fig12", "6.3.3", "Fig. 12", "spur, short relief, pinion pitch errors, damping 0.1",
         ("--pitch-errors", "--method", "transient"), max_refine=PITCH_REFINE),
    Case("fig12-no-nlte", "6.3.3", "Fig. 12", "pitch errors, NLTE'' terms set to zero (te)",
         ("--pitch-errors", "--no-nlte-terms", "--formulations", "te", "--method", "transient"),
         max_refine=PITCH_REFINE),
    Case("fig13", "6.3.4", "Fig. 13", "helical, short relief, pinion pitch errors, damping 0.03",
         ("--rig", "baud-velex-helical", "--pitch-errors", "--damping", "0.03",
          "--method", "transient"), max_refine=PITCH_REFINE),
    # the other reading of Section 6.2: te and perturbation with the contact resolved cell by
    # cell (gearjax sweep --te-contact cells), the reference beside them on the same grid
    Case("fig08-cells", "6.2", "Fig. 8", "damping 0.03, te/perturbation with the per-cell "
         "contact law", ("--damping", "0.03", "--te-contact", "cells")),
    Case("fig09-cells", "6.2", "Fig. 9", "damping 0.1, te/perturbation with the per-cell "
         "contact law", ("--te-contact", "cells")),
    # Fig. 8's jumps: the reference and te followed up and down in speed from each
    # neighbour's periodic orbit (gearjax sweep --direction both, shooting) over the critical
    # band at 20 rad/s. Opt-in: the 3D continuation is the longest case by far
    # (benchmarks/results/iso6336_campbell.md).
    Case("fig08-branches", "6.3.1", "Fig. 8", "damping 0.03, followed up and down (jumps)",
         ("--damping", "0.03", "--direction", "both", "--formulations", "reference,te",
          "--speeds", "600:900:16"), default=False),
)
_KEYS = tuple(c.key for c in CASES)
_DEFAULT_KEYS = tuple(c.key for c in CASES if c.default)


# Section 6.1: "The tooth mesh model is based on the analytical formulae of Weber and
# Banaschek [17] and O'Donnell [18]" -- gearjax's "weber" law (gearjax.gears.weber)
PAPER_LAW = "weber"
# each case's grid refined around its peaks and jumps up to this many speeds (gearjax sweep
# --refine): the claims near the critical speeds and the contact-loss edges then rest on
# speeds within 1 % of them instead of the 20 rad/s grid
PAPER_REFINE = 120


def _laws():
    from ..gears.mesh import STIFFNESS_LAWS

    return list(STIFFNESS_LAWS)


def register(sub, add_rig, add_scenario):
    """Add ``paper`` to the ``gearjax`` sub-command parser."""
    p = sub.add_parser(
        "paper", help="every Section 6.3 case on the 3D rig, with the paper's claims table",
        description="Runs the sweeps of Figs. 8-13 and Section 6.3.5 (one gearjax sweep "
                    "each, printed) into --out and writes --out/README.md: each claim of "
                    "Sections 6.3.1-6.3.5, the paper's words, our numbers, agree/disagree.")
    p.add_argument("--out", default=os.path.join("docs", "paper"), metavar="DIR",
                   help="output folder (default docs/paper), one sub-folder per case")
    p.add_argument("--speeds", default="20:900:45", metavar="A:B:N",
                   help="pinion speeds of every case (default 20:900:45, the paper's range)")
    p.add_argument("--cases", default=",".join(_DEFAULT_KEYS),
                   help=f"comma-separated subset of {','.join(_KEYS)} (default all but "
                        f"{','.join(k for k in _KEYS if k not in _DEFAULT_KEYS)})")
    p.add_argument("--model", default="3d", choices=["3d", "torsional"],
                   help="3d (default, the paper's rig); torsional for a quick look (no "
                        "encoder cases)")
    p.add_argument("--stiffness", default=PAPER_LAW, choices=_laws(),
                   help=f"mesh stiffness law of every case (default {PAPER_LAW}: the paper's "
                        "Section 6.1 mesh model, Weber-Banaschek and O'Donnell; iso6336: the "
                        "ISO 6336-1 calibrated parabola, gearjax sweep's default)")
    p.add_argument("--refine", type=int, default=PAPER_REFINE, metavar="MAX_SPEEDS",
                   help="every case but the up/down one: the speed grid refined around the "
                        "peaks and jumps of its curves (gearjax sweep --refine) up to MAX_SPEEDS "
                        f"speeds (default {PAPER_REFINE}, the pitch-error cases at most "
                        f"{PITCH_REFINE}; 0: the uniform grid alone)")
    p.add_argument("--compare", default=None, metavar="DIR",
                   help="a second gearjax paper folder (e.g. the same cases run with "
                        "--stiffness iso6336): the README adds both folders' verdicts side by side")
    p.add_argument("--readme-only", action="store_true",
                   help="run nothing: write --out/README.md again from the case folders there "
                        "(the claims tables of the results already computed)")
    p.add_argument("--resume", action="store_true",
                   help="continue: cases whose folder holds results continue with --resume")
    p.add_argument("--overwrite", action="store_true",
                   help="replace the results of an earlier run in the case folders")
    p.set_defaults(func=cmd_paper)


def _grid_size(speeds: str) -> int:
    """N of ``--speeds A:B:N`` (0 when it does not parse: the sweep reports that)."""
    try:
        return int(speeds.split(":")[2])
    except (IndexError, ValueError):
        return 0


def cmd_paper(args) -> int:
    from .main import main

    keys = [k.strip() for k in args.cases.split(",") if k.strip()]
    bad = [k for k in keys if k not in _KEYS]
    if bad or not keys:
        raise ValueError(f"--cases={args.cases}: unknown case(s) {bad}; choose from {','.join(_KEYS)}")
    if args.resume and args.overwrite:
        raise ValueError("--resume --overwrite: choose one (continue the run, or replace it)")
    if args.refine < 0:
        raise ValueError(f"--refine={args.refine}: need a number of speeds (0: no refinement)")
    cases = [c for c in CASES if c.key in keys and not (c.needs_3d and args.model != "3d")]
    os.makedirs(args.out, exist_ok=True)
    t_all = time.perf_counter()
    if args.readme_only:
        cases = []
    for c in cases:
        folder = os.path.join(args.out, c.key)
        argv = ["sweep", "--model", args.model, "--speeds", args.speeds, "--stiffness",
                args.stiffness, *c.argv, "--out", folder]
        cap = min(args.refine, c.max_refine)
        if cap > _grid_size(args.speeds) and "--direction" not in c.argv:
            argv[-2:-2] = ["--refine", str(cap)]
        # a run stopped before its first rows leaves case.json only: the same folder state
        if any(os.path.exists(os.path.join(folder, f)) for f in ("results.csv", "case.json")):
            if args.resume:
                argv.append("--resume")
            elif args.overwrite:
                argv.append("--overwrite")
        print(f"[gearjax paper] {c.section} {c.figure}: gearjax {' '.join(argv)}",
              file=sys.stderr, flush=True)
        t0 = time.perf_counter()
        code = main(argv)
        if code != 0:
            print(f"gearjax paper: case {c.key} stopped (exit {code}); the cases done are in "
                  f"{args.out}; continue with the same command and --resume", file=sys.stderr)
            return code
        meta = os.path.join(folder, "paper.json")
        before = 0.0  # a resumed case adds its earlier runs' time
        if args.resume and os.path.exists(meta):
            with open(meta) as fh:
                before = float(json.load(fh).get("seconds", 0.0))
        with open(meta, "w") as fh:
            json.dump({"command": "gearjax " + " ".join(
                a for a in argv if a not in ("--resume", "--overwrite")),
                "stiffness_law": args.stiffness, "refine_max_speeds": args.refine,
                "seconds": before + time.perf_counter() - t0}, fh, indent=1)
    path = write_readme(args.out, args, time.perf_counter() - t_all)
    print(f"  wrote {path}")
    return 0


# ---------------------------------------------------------------------------- claims
def _curve(rows, form, col="max_mesh_force_N", converged_only=True):
    """{speed: value} of one formulation (converged speeds only, unless told)."""
    out = {}
    for r in rows or ():
        if (r["formulation"] == form and r[col] not in ("", "nan")
                and (r["converged"] == "True" or not converged_only)):
            out[float(r["speed_rad_s"])] = float(r[col])
    return out


def _unconverged(rows, form="reference"):
    return sum(1 for r in rows or () if r["formulation"] == form and r["converged"] != "True")


def _diff(a, b):
    """(speeds, |a - b| / b) at the speeds of both curves."""
    w = np.array(sorted(set(a) & set(b)))
    if w.size == 0:
        return w, np.array([])
    return w, np.array([abs(a[x] - b[x]) / abs(b[x]) for x in w])


def _critical(rows, form="reference"):
    """The speed of the formulation's peak dynamic factor over every speed (an unconverged
    speed near resonance still locates it; the differences use converged speeds only)."""
    c = _curve(rows, form, "dynamic_factor", converged_only=False)
    return max(c, key=c.get) if c else float("nan")


def _pct(x):
    return "n/a" if x is None or not np.size(x) or not np.isfinite(np.max(x)) else f"{100 * np.max(x):.1f} %"


def _med(x):
    return "n/a" if not np.size(x) else f"{100 * np.median(x):.1f} %"


def _near(w, wc):
    """Speeds within ±10 % of the critical speed ``wc`` (or of any of a list of them)."""
    wcs = np.atleast_1d(np.asarray(wc, dtype=float))
    return np.any(np.abs(np.asarray(w, dtype=float)[..., None] - wcs) <= 0.1 * wcs, axis=-1)


def _model_critical(out, key, rows):
    """The critical speeds that "near" means for case ``key``: the model's own (order-1
    crossings of modes with >= 10 % of the mesh strain energy, recorded by the sweep,
    :func:`gearjax.cli.paper_panels.critical_speeds`) with the words that say so, or None
    for a case that predates them (then the reference's peak, :func:`_critical`)."""
    from .paper_panels import critical_speeds

    crit, source = critical_speeds(out, key, rows)
    if source != "the model's modes":
        return None, ""
    speeds = np.array([c[0] for c in crit])
    words = ("the model's critical speeds " + ", ".join(
        f"{w:.0f} ({f:.0f} Hz, {100 * sh:.0f} %)" for w, f, sh in crit) + " rad/s")
    return speeds, words


def _split(w, d, wc):
    near = _near(w, wc)
    return d[near], d[~near]


def _loss(rows, form="reference"):
    return [float(r["speed_rad_s"]) for r in rows or () if r["formulation"] == form
            and r["contact_loss"] == "True"]


def _at_max(rows, w, d, wc, forms=("reference", "te")) -> str:
    """Where the largest of ``d`` (relative differences at speeds ``w``) sits: its speed, as
    a fraction of the critical speed ``wc``, and which formulations lose contact there."""
    if not np.size(d):
        return ""
    x = float(w[int(np.argmax(d))])
    lost = [f for f in forms if x in _loss(rows, f)]
    kept = [f for f in forms if f not in lost]
    where = ("contact held there" if not lost else
             f"{' and '.join(lost)} lose{'s' if len(lost) == 1 else ''} contact there"
             + (f", {' and '.join(kept)} keep{'s' if len(kept) == 1 else ''} it" if kept else ""))
    return f" at {x:.0f} rad/s ({x / wc:.2f} x critical; {where})"


def _verdict(ok, *compared) -> str:
    """agree / disagree, or "incomplete" when a compared curve has no converged speed in
    common with its reference (a formulation not run, or every speed unconverged)."""
    if any(np.size(a) == 0 for a in compared):
        return "incomplete"
    return "agree" if ok else "disagree"


def claims(out: str) -> list[tuple[str, str, str, str, str]]:
    """(section, the paper's words, our numbers, verdict, criterion) per claim, from the
    case folders under ``out`` (a claim whose cases were not run says so)."""
    from .paper_panels import case_rows

    R = {k: case_rows(out, k) for k in _KEYS}
    res = []

    def missing(section, words, *keys):
        """True (and a "not run" row) when one of the cases ``keys`` has no results."""
        gone = [k for k in keys if R[k] is None]
        if gone:
            res.append((section, words, f"not run ({', '.join(gone)})", "-", ""))
        return bool(gone)

    def vs(key, form, ref_key=None, ref_form="reference"):
        return _diff(_curve(R[key], form), _curve(R[ref_key or key], ref_form))

    # 6.3.1
    words = ("\"A high degree of agreement was found between the three solution methodologies "
             "except near the major tooth critical speed where contacts between the teeth were "
             "momentarily lost\" (damping 0.03, Fig. 8)")
    if not missing("6.3.1", words, "fig08", "fig09"):
        w, d = vs("fig08", "te")
        wc = _critical(R["fig08"])
        own, own_words = _model_critical(out, "fig08", R["fig08"])
        band = wc if own is None else own
        near, away = _split(w, d, band)
        loss = _loss(R["fig08"])
        ok = np.size(near) and np.size(away) and np.max(near) > np.max(away)
        res.append(("6.3.1", words,
                    f"te vs reference, damping 0.03: median {_med(d)}, max {_pct(d)}; within ±10 % of "
                    + (f"the critical speed {wc:.0f} rad/s" if own is None else own_words)
                    + f": max {_pct(near)}, away: max {_pct(away)}"
                    f"{_at_max(R['fig08'], w[~_near(w, band)], away, wc)}; "
                    f"reference loses contact at {len(loss)} speeds "
                    f"({', '.join(f'{x:.0f}' for x in loss[:6])}{' ...' if len(loss) > 6 else ''}); "
                    f"unconverged speeds (left out): reference {_unconverged(R['fig08'])}, te "
                    f"{_unconverged(R['fig08'], 'te')}",
                    _verdict(ok, near, away), "largest difference near the critical speed"))
        w1, d1 = vs("fig09", "te")
        wp, dp = vs("fig09", "perturbation")
        ok = np.size(d1) and np.max(d1) <= np.max(d)
        res.append(("6.3.1", "\"For a larger damping level (modal damping factor of 0.1), the results "
                    "were better and even the solutions derived from the perturbation method at the "
                    "main order look reasonably satisfactory\" (Fig. 9)",
                    f"te vs reference, damping 0.1: median {_med(d1)}, max {_pct(d1)} (0.03: max "
                    f"{_pct(d)}); perturbation vs reference: median {_med(dp)}, max {_pct(dp)}",
                    _verdict(ok, d1, d), "te's largest difference at 0.1 <= at 0.03"))
    # 6.3.2
    words = ("\"a very close agreement was observed (Figs. 10a-c) when comparing ... Eq. (42) and ... "
             "(14) ... when NLTE'' was set at zero in the equations of motion, the dynamic responses "
             "were significantly different from the reference curves\" (long relief)")
    if not missing("6.3.2", words, "fig10", "fig10-no-nlte"):
        _, d = vs("fig10", "te")
        _, dn = vs("fig10-no-nlte", "te", "fig10", "reference")
        ok = np.size(d) and np.size(dn) and np.max(dn) >= 3 * np.max(d)
        res.append(("6.3.2", words,
                    f"te vs reference: median {_med(d)}, max {_pct(d)}; te with NLTE'' = 0 vs "
                    f"reference: median {_med(dn)}, max {_pct(dn)}",
                    _verdict(ok, d, dn), "NLTE'' = 0 at least 3x further from the reference"))
    # 6.3.3
    words = ("\"show the soundness of the proposed formulations. However, the results derived from "
             "the main order approximation of the perturbation method (48a) appear as less accurate "
             "near critical speeds. ... the influence of NLTE'' is less pronounced than in the case of "
             "long reliefs\" (pitch errors, Fig. 12)")
    if not missing("6.3.3", words, "fig12"):
        w, d = vs("fig12", "te")
        wp, dp = vs("fig12", "perturbation")
        wc = _critical(R["fig12"])
        own, own_words = _model_critical(out, "fig12", R["fig12"])
        near, away = _split(wp, dp, wc if own is None else own)
        txt = (f"te vs reference: median {_med(d)}, max {_pct(d)}; perturbation vs reference within "
               + (f"±10 % of {wc:.0f} rad/s" if own is None else f"±10 % of {own_words}")
               + f": max {_pct(near)}, away: max {_pct(away)}"
               + f"{_at_max(R['fig12'], wp, dp, wc, ('reference', 'perturbation'))}")
        ok = np.size(near) and np.size(away) and np.max(near) > np.max(away)
        compared = [d, near, away]
        crit = "perturbation worst near the critical speed"
        if all(R[k] is not None for k in ("fig12-no-nlte", "fig10", "fig10-no-nlte")):
            _, n12 = vs("fig12-no-nlte", "te", "fig12", "te")
            _, n10 = vs("fig10-no-nlte", "te", "fig10", "te")
            txt += f"; NLTE'' = 0 vs te: max {_pct(n12)} (long relief: {_pct(n10)})"
            compared += [n12, n10]
            ok = ok and np.size(n12) and np.size(n10) and np.max(n12) < np.max(n10)
            crit += "; NLTE'' effect smaller than with long relief"
        res.append(("6.3.3", words, txt, _verdict(ok, *compared), crit))
    # 6.3.4
    words = ("\"the dynamic response curves by the method of reference and the method based on "
             "transmission errors accord well, while the solutions by the truncated perturbation "
             "method are less satisfactory\" (helical, Fig. 13)")
    if not missing("6.3.4", words, "fig13"):
        _, d = vs("fig13", "te")
        _, dp = vs("fig13", "perturbation")
        ok = np.size(d) and np.size(dp) and np.max(dp) > np.max(d)
        res.append(("6.3.4", words, f"te vs reference: median {_med(d)}, max {_pct(d)}; perturbation "
                    f"vs reference: median {_med(dp)}, max {_pct(dp)}",
                    _verdict(ok, d, dp), "perturbation further from the reference than te"))
    # 6.3.5
    words = ("\"the calculated dynamic forces and accelerations are independent of the section of "
             "reference (or encoder positions)\" (w_x0, Fig. 7)")
    if not missing("6.3.5", words, "fig09", "encoders2", "encoders3"):
        parts, worst = [], 0.0
        for k in ("encoders2", "encoders3"):
            for col, name in (("max_mesh_force_N", "max force"), ("accel_ptp_m_s2", "accel p-p")):
                _, d = _diff(_curve(R[k], "te", col), _curve(R["fig09"], "te", col))
                worst = max(worst, float(np.max(d)) if np.size(d) else np.inf)
                parts.append(f"{k[-1]} vs 1, {name}: max "
                             + (f"{np.max(d):.1e}" if np.size(d) else "n/a"))
            parts.append(f"{k[-1]}: {_unconverged(R[k], 'te')} unconverged speeds left out")
        res.append(("6.3.5", words, "te; " + "; ".join(parts), "agree" if worst < 1e-3 else "disagree",
                    "every difference below 0.1 %"))
    return res


def _law_of(out) -> str:
    """The stiffness law(s) of the cases under ``out`` (their paper.json; iso6336 before the
    law was recorded)."""
    laws = set()
    for c in CASES:
        meta = os.path.join(out, c.key, "paper.json")
        if os.path.exists(meta):
            with open(meta) as fh:
                laws.add(json.load(fh).get("stiffness_law", "iso6336"))
    return ", ".join(sorted(laws)) or "?"


def verdicts_side_by_side(out, other) -> list[str]:
    """Markdown lines: the first claims table's verdicts of ``out`` and of ``other`` (e.g. the
    paper's mesh law against ``iso6336``), claim by claim, with each folder's numbers."""
    mine, theirs = claims(out), claims(other)
    a, b = _law_of(out), _law_of(other)
    lines = ["## Verdicts under both mesh laws", "",
             f"The claims above ({a}, this folder) against the same cases in `{other}` ({b}): "
             "the law moves the critical speeds and contact losses, hence the comparisons.", "",
             f"| section | criterion | verdict, {a} | verdict, {b} | numbers, {b} |",
             "|---|---|---|---|---|"]
    for (sec, _, _, v1, crit), (_, _, n2, v2, _) in zip(mine, theirs):
        lines.append(f"| {sec} | {crit} | **{v1}** | **{v2}** | {n2} |")
    return lines + [""]


def write_readme(out, args, seconds) -> str:
    """``out/README.md``: the claims table, then every case found under ``out`` with its
    command (``paper.json``) and figure."""
    runs, laws = [], set()
    law = getattr(args, "stiffness", PAPER_LAW)
    for c in CASES:
        meta = os.path.join(out, c.key, "paper.json")
        if os.path.exists(meta):
            with open(meta) as fh:
                m = json.load(fh)
            runs.append((c, m["command"], float(m["seconds"])))
            laws.add(m.get("stiffness_law", "iso6336"))  # before --stiffness: the sweep default
    model, speeds = args.model, args.speeds
    if getattr(args, "readme_only", False) and runs:  # the stored runs' settings and times
        words = runs[0][1].split()
        model = words[words.index("--model") + 1] if "--model" in words else model
        speeds = words[words.index("--speeds") + 1] if "--speeds" in words else speeds
        seconds = sum(t for _, _, t in runs)
    refined = sorted({c.split("--refine ")[1].split()[0] for _, c, _ in runs if "--refine " in c})
    lines = [
        "# Section 6.3 of Velex & Ajmi on gearjax's Baud–Velex rig",
        "",
        "Generated by `gearjax paper` (do not edit by hand: rerun it; `--resume` continues). "
        f"Last run: model `{model}`, speeds `{speeds}` rad/s, {seconds / 60:.1f} min; "
        f"{len(runs)} cases below, each with its own command and time (2-core CPU)."
        + (f" Each grid is refined around the peaks and jumps of its curves (`--refine`, up to "
           f"{' or '.join(sorted(refined, key=int, reverse=True))} speeds a case: peaks "
           "located to 1 % of their speed, "
           "amplitudes to 1e-3, jumps and contact-loss edges to 1 %; every formulation of a "
           "case at every added speed), so medians weigh the peaks more than a uniform grid "
           "would; each case's summary.json lists the speeds added and why."
           if refined else ""),
        "Rig data the paper does not print are stand-ins (documentation, "
        "`docs/concepts/baud-velex-data.md`), so critical speeds and amplitudes are ours; the claims compare "
        "formulations on the same model. In the first table differences are relative "
        "differences of the maximum dynamic mesh force between two curves at their common "
        "converged speeds; the second judges every panel.",
        "",
        f"Mesh stiffness law: **{', '.join(sorted(laws or {law}))}**"
        + (" -- the paper's (Section 6.1: Weber and Banaschek's tooth-pair compliance with "
           "O'Donnell's foundation term, `gearjax.gears.weber`)." if (laws or {law}) <= {PAPER_LAW}
           else " -- not the mesh model of the paper, whose Section 6.1 uses Weber-Banaschek/"
                "O'Donnell (`gearjax paper --stiffness weber`, the default); its k_m and "
                "critical speeds differ."),
        "",
        "## Claims",
        "",
        "| section | the paper | our numbers | verdict | criterion |",
        "|---|---|---|---|---|",
    ]
    for sec, words, nums, verdict, crit in claims(out):
        lines.append(f"| {sec} | {words} | {nums} | **{verdict}** | {crit} |")
    from .paper_panels import panel_table
    from .paper_readings import readings_table

    lines += [""] + panel_table(out) + readings_table(out)
    other = getattr(args, "compare", None)
    if other:
        lines += verdicts_side_by_side(out, other)
    done = {c.key for c, _, _ in runs}
    todo = [c.key for c in CASES if c.key not in done and c.default]
    if todo:
        lines += ["", f"**Not finished:** {', '.join(todo)} (no complete run yet; "
                  "`gearjax paper --resume` continues).", ""]
    lines += ["", "## Cases", ""]
    for c, cmd, t in runs:
        lines += [f"### {c.section} {c.figure}: {c.title}", "", f"`{cmd}` ({t:.0f} s)", "",
                  f"![{c.key}]({c.key}/response_curves.png)", ""]
    path = os.path.join(out, "README.md")
    with open(path, "w") as fh:
        fh.write("\n".join(lines) + "\n")
    return path
