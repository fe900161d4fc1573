"""The two readings of Section 6.2's contact algorithm side by side, for the README that
``gearjax paper`` writes (:func:`readings_table`).

Section 6.2: "the contact algorithm is applied in all cases so that the time-varying
stiffness matrix in Eqs. (14) and (42) as well as the average stiffness matrix in Eq.
(48a) are evaluated at each step depending on the instantaneous contact conditions". Read
at mesh level (gearjax's default, :func:`gearjax.gears.contact.te_contact`) te and
perturbation switch the whole mesh on and off; read cell by cell
(:func:`gearjax.gears.contact.te_cell_contact`, ``gearjax sweep --te-contact cells``) every
cell opens and closes by its own approach. The cases ``fig08``/``fig09`` hold the first,
``fig08-cells``/``fig09-cells`` the second, each with its reference on the same grid; this
table gives, per formulation and panel, each reading's difference to its reference
(relative; the minimum force's in % of F_S) and the speeds where its contact-loss flags and
the reference's differ.
"""

from __future__ import annotations

import numpy as np

from .paper_panels import PANELS, case_rows, compare_curves, panel_curve

__all__ = ["READINGS", "reading_rows", "readings_table"]

# (damping, mesh-level case, per-cell case)
READINGS = (("0.1", "fig09", "fig09-cells"), ("0.03", "fig08", "fig08-cells"))


def _pct(x: float) -> str:
    """A fraction in %: one decimal from 1 %, two significant digits below."""
    return f"{100 * x:.1f}" if x >= 0.01 else f"{100 * x:.2g}"


def _numbers(rows, form, col):
    """(text, max difference or None) of ``form`` against the reference of the same
    rows on panel ``col``."""
    absolute = col == "min_mesh_force_N"
    w, d, flags = compare_curves(panel_curve(rows, form, col),
                                 panel_curve(rows, "reference", col), absolute)
    if w.size == 0:
        return "no converged speed in common", None
    unit = " of F_S" if absolute else ""
    i = int(np.argmax(d))
    text = (f"max {_pct(d[i])} %{unit} at {w[i]:.0f} rad/s, median "
            f"{_pct(np.median(d))} %{unit}")
    if flags:
        text += (f"; contact-loss flags differ at {len(flags)} speed{'s' * (len(flags) != 1)}"
                 f" ({', '.join(f'{x:.0f}' for x in flags[:4])}{' ...' if len(flags) > 4 else ''})")
    else:
        text += "; contact-loss flags as the reference's"
    return text, float(d[i])


def reading_rows(out: str) -> list[dict]:
    """One row per (damping, formulation, panel) whose two cases exist under ``out``:
    ``damping, formulation, panel, mesh, cells`` (texts) and ``closer`` (the reading with
    the smaller max difference, or "tie")."""
    res = []
    for zeta, mesh_key, cell_key in READINGS:
        mesh, cells = case_rows(out, mesh_key), case_rows(out, cell_key)
        if mesh is None or cells is None:
            continue
        for form in ("te", "perturbation"):
            for col, panel in PANELS:
                (tm, dm), (tc, dc) = _numbers(mesh, form, col), _numbers(cells, form, col)
                closer = ("-" if dm is None or dc is None else "tie" if abs(dm - dc) < 1e-3
                          else "per cell" if dc < dm else "mesh level")
                res.append(dict(damping=zeta, formulation=form, panel=panel, mesh=tm,
                                cells=tc, closer=closer))
    return res


def readings_table(out: str) -> list[str]:
    """Markdown lines of the table (empty when no pair of cases was run)."""
    rows = reading_rows(out)
    if not rows:
        return []
    lines = ["## Two readings of Section 6.2", "",
             "The contact algorithm of te and perturbation applied to the whole mesh (the "
             "default; cases fig08, fig09) or cell by cell (`--te-contact cells`; cases "
             "fig08-cells, fig09-cells), each against the reference of its own case. Cell by "
             "cell, te is Eq. (37) with each cell's unilateral law: the reference's force "
             "law up to the averaged structure vector of the dynamic approach (on the sdof "
             "model exactly Eq. (16)), so it cannot miss the reference's contact losses and "
             "jumps, which the paper says the TE-based formulations did miss (Section "
             "6.3.1), and it needs each cell's gap, which a measured TE does not give: the "
             "default stays the mesh-level reading (`docs/concepts/formulations.md`).", "",
             "| damping | formulation | panel | mesh-level law vs reference | per-cell law vs "
             "reference | closer |", "|---|---|---|---|---|---|"]
    lines += [f"| {r['damping']} | {r['formulation']} | {r['panel']} | {r['mesh']} | "
              f"{r['cells']} | {r['closer']} |" for r in rows]
    return lines + [""]
