"""Every figure: quasi-static transmission errors and load sharing, response curves and
mesh-force signals of the sweeps, design maps, optimisation histories and Harris plots.

Matplotlib is imported lazily with the non-interactive Agg backend so that the CLI works on
machines without a display.
"""

from __future__ import annotations

import numpy as np

from .design.maps import HarrisMap
from .design.optimise import OptimisationResult

__all__ = ["plot_campbell", "plot_quasistatic", "plot_response_curves", "plot_order_tracks", "plot_branches",
           "plot_traced_branches", "plot_mesh_force_signals",
           "plot_design_map", "plot_history", "plot_harris", "impact_regimes", "REGIMES"]


def _mu(text: str) -> str:
    """Micrometres as ``µm`` in a figure's text (titles built from CLI labels say ``um``)."""
    import re

    return re.sub(r"(?<=[0-9]) um\b", " µm", text or "")


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_quasistatic(result, mesh, path: str, title: str = ""):
    """TE_S and NLTE (um) and the load carried by each tooth pair (N) against theta.

    ``result`` is a :class:`gearjax.gears.quasistatic.QuasiStatic`; the abscissa is the pinion
    angle in mesh periods.
    """
    plt = _pyplot()
    t = np.asarray(result.theta_rad) / mesh.pair.mesh_period_rad
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(8, 6.5), sharex=True, constrained_layout=True)
    ax1.plot(t, np.asarray(result.te_s_m) * 1e6, label="TE$_S$ (under load)", lw=1.6)
    ax1.plot(t, np.asarray(result.nlte_m) * 1e6, label="NLTE (no load)", lw=1.2, ls="--")
    ax1.set_ylabel("transmission error on base plane [µm]")
    ax1.legend(loc="best")
    ax1.grid(alpha=0.3)
    loads, idx = result.pair_loads(mesh.n_slots)
    loads, idx = np.asarray(loads), np.asarray(idx)
    for n in np.unique(idx):
        present = idx == n  # pair n occupies at most one slot at each angle
        y = np.where(present.any(axis=1), (loads * present).sum(axis=1), np.nan)
        ax2.plot(t, y, lw=1.0)
    ax2.plot(t, np.asarray(result.mesh_force_N), color="k", lw=1.0, ls=":", label="total")
    ax2.set_xlabel("pinion angle [mesh periods]")
    ax2.set_ylabel("load per tooth pair [N]")
    ax2.legend(loc="best")
    ax2.grid(alpha=0.3)
    if title:
        fig.suptitle(_mu(title))
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plot_response_curves(csv_path: str, path: str, title: str = "", iso_kv=None):
    """Response curves laid out like Figs. 8-13 from a sweep's ``results.csv``: maximum
    dynamic tooth load, peak-to-peak DTE and peak-to-peak pinion-centre acceleration (S)
    against pinion speed, one curve per formulation (the acceleration panel is left out for
    torsional models, which have none).

    ``iso_kv = (speeds_rad_s, kv, resonance_speed_rad_s)`` (ISO 6336-1 method B,
    :func:`gearjax.rigs.iso_figures.rig_dynamic_factor`) adds a first panel: the computed
    dynamic factor ``max F / F_S`` of each formulation beside ISO's K_v, and marks ISO's
    resonance speed n_E1 on every panel (up to 10 % beyond the highest speed; in the legend
    only when it lies further out).

    Impact regimes (:func:`impact_regimes`): on the first panel, a speed where the teeth
    separate (single-sided impacts, ``contact_loss``) is ringed and one where the back
    flanks are struck too (double-sided impacts, ``back_contact``: a model with backlash)
    is crossed; speeds without either are the no-impact regime (plain markers)."""
    import csv

    plt = _pyplot()
    rows = list(csv.DictReader(open(csv_path)))
    forms = list(dict.fromkeys(r["formulation"] for r in rows))
    has_acc = any(r["accel_ptp_m_s2"] not in ("", "nan") for r in rows)
    panels = [("max_mesh_force_N", "max dynamic tooth load [N]", 1.0),
              ("dte_ptp_m", "peak-to-peak DTE [µm]", 1e6)]
    if has_acc:
        panels.append(("accel_ptp_m_s2", "p-p pinion acceleration S [m/s$^2$]", 1.0))
    if iso_kv is not None:
        panels.insert(0, ("dynamic_factor", "dynamic factor: max F / F$_S$, ISO K$_v$", 1.0))
    fig, axes = plt.subplots(len(panels), 1, figsize=(7.5, 2.6 * len(panels) + 0.6), sharex=True,
                             constrained_layout=True)
    markers = {"reference": "D", "te": "s", "perturbation": "^"}
    labels = {"reference": "reference, Eq. (14)/(16)", "te": "TE-based, Eq. (42)/(20)",
              "perturbation": "perturbation, Eq. (48a)/(47a)"}
    for ax, (key, ylabel, scale) in zip(np.atleast_1d(axes), panels):
        for form in forms:
            sel = [r for r in rows if r["formulation"] == form]
            x = np.array([float(r["speed_rad_s"]) for r in sel])
            y = np.array([float(r[key]) if r[key] not in ("",) else np.nan for r in sel]) * scale
            line, = ax.plot(x, y, marker=markers.get(form, "o"), ms=3.5, lw=1.2,
                            label=labels.get(form, form))
            if ax is np.atleast_1d(axes)[0]:
                _mark_regimes(ax, x, y, impact_regimes(sel), line.get_color())
        if iso_kv is not None and key == "dynamic_factor":
            ax.plot(np.asarray(iso_kv[0]), np.asarray(iso_kv[1]), "k--", lw=1.4,
                    label="ISO 6336-1 K$_v$ (method B)")
        if iso_kv is not None:
            speeds = [float(r["speed_rad_s"]) for r in rows]
            w_e = float(iso_kv[2])
            text = f"ISO n$_{{E1}}$ = {w_e:.0f} rad/s"
            if speeds and min(speeds) <= w_e <= 1.1 * max(speeds):  # the axis may stretch 10 %
                ax.axvline(w_e, color="0.4", ls=":", lw=1.2,
                           label=text if key == "dynamic_factor" else None)
            elif key == "dynamic_factor":
                ax.plot([], [], " ", label=text + " (beyond the speeds)")
        ax.set_ylabel(ylabel)
        ax.grid(alpha=0.3)
    np.atleast_1d(axes)[0].legend(loc="best", fontsize=8)
    np.atleast_1d(axes)[-1].set_xlabel("pinion speed $\\Omega_1$ [rad/s]")
    if title:
        fig.suptitle(_mu(title))
    fig.savefig(path, dpi=120)
    plt.close(fig)


REGIMES = ("no impact", "single-sided", "double-sided")


def impact_regimes(rows) -> np.ndarray:
    """The impact regime of each ``results.csv`` row (index into :data:`REGIMES`): 2 where
    the back flanks carried load (``back_contact``, double-sided impacts), 1 where the teeth
    separated (``contact_loss``, single-sided impacts), else 0 (no impact). Files written
    before the ``back_contact`` column read as without back-flank contact."""
    flag = lambda r, k: r.get(k, "") == "True"  # noqa: E731
    return np.array([2 if flag(r, "back_contact") else 1 if flag(r, "contact_loss") else 0
                     for r in rows], dtype=int)


def _mark_regimes(ax, x, y, regimes, color) -> None:
    """Ring the single-sided and cross the double-sided speeds of one curve (legend entries
    once per axis)."""
    have = {t.get_label() for t in ax.get_lines()}
    if np.any(regimes > 0) and "no impact (plain markers)" not in have:
        ax.plot([], [], ls="none", marker=".", color="0.3", label="no impact (plain markers)")
    for k, marker in ((1, "o"), (2, "X")):
        sel = regimes == k
        if not np.any(sel):
            continue
        ax.plot(x[sel], y[sel], ls="none", marker=marker, ms=8, color=color, mfc="none", mew=1.0)
        label = f"{REGIMES[k]} impacts" + (" (contact loss)" if k == 1 else " (back flanks)")
        if label not in have:  # one neutral legend entry per regime
            ax.plot([], [], ls="none", marker=marker, ms=8, color="0.3", mfc="none", label=label)


# order-track panels: (column stem, y label, dB reference in the column's SI unit)
# (two-line labels: one line of the acceleration's was taller than its panel and ran into
# the next panel's label)
ORDER_TRACK_PANELS = (("dte_m", "DTE\n[dB re 1 µm]", 1e-6),
                      ("force_N", "dynamic mesh force\n[dB re 1 N]", 1.0),
                      ("accel_m_s2", "pinion-centre accel.\n[dB re 1e-6 m/s$^2$]", 1e-6))


def plot_order_tracks(csv_path: str, path: str, title: str = "", n_orders: int = 5):
    """Order tracks from a sweep's ``orders.csv``: the single-sided peak amplitude of mesh
    orders 1..``n_orders`` (k times the mesh frequency) in dB, ``20 log10(A / A_ref)``
    (references in the axis labels: 1 µm, 1 N, 1e-6 m/s^2), against pinion speed; one
    panel per quantity (DTE, dynamic mesh force, and the acceleration where the model has
    one), one colour per order, one line style per formulation. A speed written twice
    (a resumed run) is drawn once, from its last row."""
    import csv

    plt = _pyplot()
    rows = {}
    for r in csv.DictReader(open(csv_path)):
        rows[(r["formulation"], float(r["speed_rad_s"]))] = r
    forms = list(dict.fromkeys(f for f, _ in rows))
    panels = [p for p in ORDER_TRACK_PANELS
              if any(r[f"order1_{p[0]}"] not in ("", "nan") for r in rows.values())]
    panels = panels or list(ORDER_TRACK_PANELS[:2])  # nothing finite: empty DTE, force axes
    fig, axes = plt.subplots(len(panels), 1, figsize=(7.5, 2.6 * len(panels) + 0.6),
                             sharex=True, squeeze=False, constrained_layout=True)
    styles = ("-", "--", ":", "-.")
    for ax, (stem, ylabel, ref) in zip(axes[:, 0], panels):
        for j, form in enumerate(forms):
            sel = sorted((w, r) for (f, w), r in rows.items() if f == form)
            x = np.array([w for w, _ in sel])
            for k in range(1, n_orders + 1):
                a = np.array([float(r[f"order{k}_{stem}"] or "nan") for _, r in sel])
                with np.errstate(divide="ignore", invalid="ignore"):
                    db = 20.0 * np.log10(np.where(a > 0, a, np.nan) / ref)
                ax.plot(x, db, ls=styles[j % len(styles)], color=f"C{k - 1}", lw=1.2,
                        marker="o" if x.size < 30 else None, ms=2.5,
                        label=f"order {k}" if j == 0 else None)
        ax.set_ylabel(ylabel)
        ax.grid(alpha=0.3)
    first = axes[0, 0].legend(loc="best", fontsize=8, ncol=n_orders)
    if len(forms) > 1:  # the line styles: a second legend, without colours
        from matplotlib.lines import Line2D

        handles = [Line2D([], [], color="k", ls=styles[j % len(styles)]) for j in range(len(forms))]
        axes[-1, 0].legend(handles, forms, loc="lower right", fontsize=8, title="formulation")
        if len(panels) == 1:
            axes[0, 0].add_artist(first)
    axes[-1, 0].set_xlabel("pinion speed $\\Omega_1$ [rad/s]")
    fig.align_ylabels(axes[:, 0])
    if title:
        fig.suptitle(_mu(title))
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plot_branches(csv_path: str, path: str, title: str = ""):
    """Response curves of up and down continuation sweeps (``gearjax sweep --direction``,
    :mod:`gearjax.dynamics.continuation`) from their ``results.csv``: max dynamic tooth load
    and peak-to-peak DTE against pinion speed, per formulation (colour) and direction (up
    triangles, down triangles pointing down). Stable followed orbits: solid lines; jumps
    (max force changing by more than ``JUMP_THRESHOLD`` between neighbours,
    :func:`gearjax.dynamics.continuation.forces_differ`): dotted
    arrows in the sweep's direction, so the hysteresis band lies between the two sweeps'
    arrows; unstable periodic orbits met by the continuation: dashed, open markers; a speed
    without a stable orbit: open marker."""
    import csv

    from .dynamics.continuation import forces_differ

    plt = _pyplot()
    rows = list(csv.DictReader(open(csv_path)))
    val = lambda r, k: float(r[k]) if r.get(k, "") not in ("",) else np.nan  # noqa: E731
    forms = list(dict.fromkeys(r["formulation"] for r in rows))
    panels = [("max_mesh_force_N", "max dynamic tooth load [N]", 1.0),
              ("dte_ptp_m", "peak-to-peak DTE [µm]", 1e6)]
    fig, axes = plt.subplots(2, 1, figsize=(7.5, 5.8), sharex=True, constrained_layout=True)
    marks = {"up": "^", "down": "v"}
    for ax, (key, ylabel, scale) in zip(axes, panels):
        for c, form in enumerate(forms):
            color = f"C{c}"
            for d in ("up", "down"):
                sel = [r for r in rows if r["formulation"] == form and r.get("direction") == d]
                fol = sorted((r for r in sel if r["orbit"] == "followed"),
                             key=lambda r: float(r["speed_rad_s"]), reverse=d == "down")
                if fol:
                    w = np.array([val(r, "speed_rad_s") for r in fol])
                    f = np.array([val(r, "max_mesh_force_N") for r in fol])
                    y = np.array([val(r, key) for r in fol]) * scale
                    ok = np.array([r["converged"] == "True" for r in fol])
                    for a in range(len(fol) - 1):
                        b = a + 1
                        if forces_differ(f[a], f[b]):
                            ax.annotate("", (w[b], y[b]), (w[a], y[a]), arrowprops=dict(
                                arrowstyle="->", ls=":", color=color, lw=1.2))
                        elif ok[a] and ok[b]:
                            ax.plot(w[a:b + 1], y[a:b + 1], "-", color=color, lw=1.3)
                    ax.plot(w[ok], y[ok], marks[d], color=color, ms=4, ls="none",
                            label=f"{form}, sweep {d}")
                    ax.plot(w[~ok], y[~ok], marks[d], mfc="none", color=color, ms=5, ls="none")
                uns = sorted((r for r in sel if r["orbit"] == "unstable"),
                             key=lambda r: float(r["speed_rad_s"]))
                if uns:
                    ax.plot([val(r, "speed_rad_s") for r in uns],
                            np.array([val(r, key) for r in uns]) * scale, "--" + marks[d],
                            mfc="none", color=color, ms=5, lw=1.0,
                            label=f"{form}, unstable orbit ({d})")
        ax.set_ylabel(ylabel)
        ax.grid(alpha=0.3)
    return _finish_speed_axes(fig, axes, path, title, legend_size=8)


def _finish_speed_axes(fig, axes, path: str, title: str, legend_size: int) -> str:
    """Legend on the first panel, the pinion-speed label on the last, the title; save."""
    axes[0].legend(loc="best", fontsize=legend_size)
    axes[-1].set_xlabel("pinion speed $\\Omega_1$ [rad/s]")
    if title:
        fig.suptitle(_mu(title))
    fig.savefig(path, dpi=120)
    _pyplot().close(fig)
    return path


_BIFURCATION_MARKS = {"fold": "o", "branch_point": "X", "period_doubling": "s", "torus": "D"}


def plot_traced_branches(branches_csv: str, path: str, title: str = "", jumps=None,
                         sweeps_csv: str | None = None):
    """The curves of periodic orbits traced by pseudo-arclength continuation
    (``branches.csv`` of ``gearjax sweep --direction both``,
    :func:`gearjax.dynamics.arclength.trace_speed`): max dynamic tooth load and peak-to-peak
    DTE against pinion speed, per formulation (colour) and branch: solid where the branch is
    stable, dashed where unstable; bifurcations marked (fold: circle, period doubling:
    square, torus: diamond, branch point: cross); ``jumps`` (per formulation, the jump
    entries of ``summary.json``: ``metrics_before``, ``metrics_after``, ``from_rad_s``,
    ``to_rad_s``, ``discontinuous``) as arrows from the end of a stable branch to the
    response a sweep lands on (the discontinuous ones);
    the up/down sweeps of ``sweeps_csv`` (``results.csv``, followed stable orbits) as
    small triangles."""
    import csv

    plt = _pyplot()
    rows = list(csv.DictReader(open(branches_csv)))
    val = lambda r, k: float(r[k]) if r.get(k, "") != "" else np.nan  # noqa: E731
    forms = list(dict.fromkeys(r["formulation"] for r in rows))
    sweeps = list(csv.DictReader(open(sweeps_csv))) if sweeps_csv else []
    panels = [("max_mesh_force_N", "max dynamic tooth load [N]", 1.0),
              ("dte_ptp_m", "peak-to-peak DTE [µm]", 1e6)]
    fig, axes = plt.subplots(2, 1, figsize=(7.5, 5.8), sharex=True, constrained_layout=True)
    for ax, (key, ylabel, scale) in zip(axes, panels):
        for c, form in enumerate(forms):
            color = f"C{c}"
            mine = [r for r in rows if r["formulation"] == form]
            regular = [r for r in mine if r["point"] not in _BIFURCATION_MARKS]
            labelled = set()
            for b in dict.fromkeys(r["branch"] for r in mine):
                pts = [r for r in mine if r["branch"] == b]
                ok = all(r["stable"] == "True" for r in regular if r["branch"] == b)
                style = "stable" if ok else "unstable"
                ax.plot([val(r, "speed_rad_s") for r in pts],
                        np.array([val(r, key) for r in pts]) * scale, "-" if ok else "--",
                        color=color, lw=1.4 if ok else 1.0,
                        label=None if style in labelled else f"{form}, {style}")
                labelled.add(style)
            for kind, mark in _BIFURCATION_MARKS.items():
                pts = list({r["speed_rad_s"]: r for r in mine if r["point"] == kind}.values())
                if pts:
                    ax.plot([val(r, "speed_rad_s") for r in pts],
                            np.array([val(r, key) for r in pts]) * scale, mark, mfc="none",
                            color=color, ms=6, ls="none",
                            label=f"{form}, {kind.replace('_', ' ')}")
            for j in (jumps or {}).get(form, []):
                y0, y1 = j["metrics_before"].get(key), j["metrics_after"].get(key)
                if y0 is None or y1 is None or not j.get("discontinuous", True):
                    continue
                ax.annotate("", (j["to_rad_s"], y1 * scale), (j["from_rad_s"], y0 * scale),
                            arrowprops=dict(arrowstyle="->", ls=":", color=color, lw=1.2))
            for d, mark in (("up", "^"), ("down", "v")):
                pts = [r for r in sweeps if r["formulation"] == form
                       and r.get("direction") == d and r.get("orbit") == "followed"]
                if pts:
                    ax.plot([val(r, "speed_rad_s") for r in pts],
                            np.array([val(r, key) for r in pts]) * scale, mark, color=color,
                            ms=3, alpha=0.6, ls="none", label=f"{form}, sweep {d}")
        ax.set_ylabel(ylabel)
        ax.grid(alpha=0.3)
    return _finish_speed_axes(fig, axes, path, title, legend_size=7)


def plot_mesh_force_signals(signals: dict, path: str, title: str = ""):
    """Instantaneous total mesh force over one mesh period at a few speeds, one panel per
    speed and one curve per formulation (Fig. 11). ``signals[formulation]`` is a list of
    dicts with ``speed_rad_s``, ``t_over_Tm`` and ``mesh_force_N``."""
    plt = _pyplot()
    forms = list(signals)
    speeds = [s["speed_rad_s"] for s in signals[forms[0]]]
    fig, axes = plt.subplots(1, len(speeds), figsize=(3.6 * len(speeds) + 0.6, 3.2), squeeze=False,
                             constrained_layout=True)
    styles = {"reference": dict(ls="--", color="k"), "te": dict(ls="-", color="C0"),
              "perturbation": dict(ls="-.", color="C2")}
    for j, w in enumerate(speeds):
        ax = axes[0, j]
        for form in forms:
            s = signals[form][j]
            ax.plot(s["t_over_Tm"], s["mesh_force_N"], lw=1.2, label=form, **styles.get(form, {}))
        ax.set_title(f"{w:.0f} rad/s")
        ax.set_xlabel("$t / T_m$")
        ax.grid(alpha=0.3)
    axes[0, 0].set_ylabel("total mesh force [N]")
    axes[0, 0].legend(loc="best", fontsize=8)
    if title:
        fig.suptitle(_mu(title))
    fig.savefig(path, dpi=120)
    plt.close(fig)


# ---------------------------------------------------------------------------- design
_UNITS = {"peak-force": ("peak dynamic mesh force", 1e-3, "kN"),
          "dynamic-factor": ("peak dynamic factor", 1.0, "-"),
          "dte-ptp": ("peak DTE peak-to-peak", 1e6, "µm"),
          "te-ptp": ("TE$_S$ peak-to-peak", 1e6, "µm"),
          "te-rms": ("TE$_S$ RMS fluctuation", 1e6, "µm")}


def plot_design_map(hmap: HarrisMap, path: str, results=(), marks: dict | None = None,
                    title: str = ""):
    """Contour map of the exact objective over (extent, amplitude), its refined patches
    drawn over the grid (dashed outlines), with optimiser paths (``results``:
    :class:`OptimisationResult` of a shared relief) and named points (``marks``:
    ``{label: (amplitude_m, extent)}``)."""
    plt = _pyplot()
    label, f, unit = _UNITS.get(hmap.objective, (hmap.objective, 1.0, ""))
    fig, ax = plt.subplots(figsize=(7, 5.5), constrained_layout=True)
    # one colour scale for the grid and its refined patches (drawn over it, outlined)
    allv = np.concatenate([np.ravel(hmap.exact)] + [np.ravel(q.exact) for q in hmap.patches])
    allv = allv[np.isfinite(allv)] * f
    levels = np.linspace(allv.min(), allv.max(), 25) if allv.size and np.ptp(allv) > 0 else 24
    cs = ax.contourf(hmap.extents, hmap.amplitudes_m * 1e6, hmap.exact * f, levels=levels,
                     cmap="viridis")
    for q in hmap.patches:
        if q.extents.size > 1 and q.amplitudes_m.size > 1:
            ax.contourf(q.extents, q.amplitudes_m * 1e6, q.exact * f, levels=levels,
                        cmap="viridis")
            e0, e1, a0, a1 = q.extents[0], q.extents[-1], q.amplitudes_m[0] * 1e6, q.amplitudes_m[-1] * 1e6
            ax.plot([e0, e1, e1, e0, e0], [a0, a0, a1, a1, a0], "w--", lw=0.5)
    fig.colorbar(cs, ax=ax, label=f"{label} [{unit}]")
    pts = [(float(hmap.extents[0]), float(hmap.amplitudes_m[0]) * 1e6),
           (float(hmap.extents[-1]), float(hmap.amplitudes_m[-1]) * 1e6)]
    for k, r in enumerate(results):
        xs = np.array([h["x"] for h in r.history])
        ax.plot(xs[:, 1], xs[:, 0] * 1e6, "w.-", lw=1.0, ms=3,
                label="optimiser paths" if k == 0 else None)
        ax.plot(xs[0, 1], xs[0, 0] * 1e6, "wo", ms=5, label="starts" if k == 0 else None)
        ax.plot(xs[-1, 1], xs[-1, 0] * 1e6, "r*", ms=10, label="ends" if k == 0 else None)
        pts += [(float(e), float(a) * 1e6) for a, e in xs[:, :2]]
    for name, (a, e) in (marks or {}).items():
        ax.plot(e, a * 1e6, "o", mfc="none", mec="w", ms=9)
        ax.annotate(name, (e, a * 1e6), color="w", xytext=(5, 5), textcoords="offset points")
        pts.append((e, a * 1e6))
    # every start, path and end inside the axes (the map's grid may be smaller than the
    # optimiser's bounds; outside it the background is blank)
    pe, pa = np.array(pts).T
    mx, my = 0.03 * np.ptp(pe) + 1e-3, 0.03 * np.ptp(pa) + 1e-3
    ax.set_xlim(pe.min() - mx, pe.max() + mx)
    ax.set_ylim(pa.min() - my, pa.max() + my)
    ax.set_xlabel("relief extent L$_c$ [fraction of path of contact]")
    ax.set_ylabel("relief amplitude P$_c$ [µm]")
    ax.set_title(_mu(title) or f"Harris map: {label}")
    if results:  # white paths: a dark legend box, so that they read
        ax.legend(loc="best", facecolor="0.3", edgecolor="0.3", labelcolor="w",
                  framealpha=0.85)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def _start_label(k: int, x) -> str:
    x = np.asarray(x, dtype=float)
    if x.size == 2:
        return f"start {k + 1}: P$_c$ {x[0] * 1e6:.3g} µm, L$_c$ {x[1]:.3g}"
    return (f"start {k + 1}: P$_c$ {x[0] * 1e6:.3g}/{x[1] * 1e6:.3g} µm, "
            f"L$_c$ {x[2]:.3g}/{x[3]:.3g}")


def plot_history(results, path: str, objective: str = "", title: str = ""):
    """Exact (solid) and smoothed (dashed) objective against iteration, one colour per
    optimiser start (labelled with its starting design; the best run's end starred)."""
    from matplotlib.lines import Line2D

    plt = _pyplot()
    if isinstance(results, OptimisationResult):
        results = [results]
    label, f, unit = _UNITS.get(objective, (objective or "objective", 1.0, ""))
    fig, ax = plt.subplots(figsize=(7.5, 4.8), constrained_layout=True)
    best = int(np.argmin([r.exact for r in results])) if results else -1
    for k, r in enumerate(results):
        it = [h["iteration"] for h in r.history]
        (ln,) = ax.plot(it, [h["exact"] * f for h in r.history], "-", lw=1.4, marker=".",
                        label=_start_label(k, r.x0) + (" (best)" if k == best else ""))
        ax.plot(it, [h["smooth"] * f for h in r.history], "--", lw=1.0, color=ln.get_color())
        if k == best:
            ax.plot(it[-1], r.history[-1]["exact"] * f, "*", color=ln.get_color(), ms=12)
    ax.set_xlabel("iteration")
    ax.set_ylabel(f"{label} [{unit}]")
    ax.grid(alpha=0.3)
    first = ax.legend(loc="upper right", fontsize=8, title="colour: optimiser start")
    ax.add_artist(first)
    ax.legend([Line2D([], [], color="k", ls="-"), Line2D([], [], color="k", ls="--")],
              ["exact maximum", "smoothed (descended)"], loc="lower left", fontsize=8)
    ax.set_title(_mu(title) or f"optimisation history: {len(results)} start(s) on a coarse "
                               "grid of the design space")
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def plot_harris(curves: dict, path: str, title: str = ""):
    """Classic Harris plot: TE_S peak-to-peak (um) against pinion torque (N m)."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7, 4.5), constrained_layout=True)
    t = curves["torques_Nm"]
    for name, v in curves.items():
        if name != "torques_Nm":
            ax.plot(t, np.asarray(v) * 1e6, "-o", ms=3, label=name)
    ax.set_xlabel("pinion torque C$_{m0}$ [N m]")
    ax.set_ylabel("TE$_S$ peak-to-peak [µm]")
    ax.grid(alpha=0.3)
    ax.legend()
    ax.set_title(_mu(title) or "Harris plot")
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def plot_campbell(diagram, path: str, title: str = ""):
    """Campbell diagram (:class:`gearjax.rigs.campbell.Campbell`): natural frequencies [Hz]
    against pinion speed [rad/s] as horizontal lines coloured by their share of mesh strain
    energy, the mesh orders ``k z1 Omega1 / (2 pi)`` as grey lines, and the predicted critical
    speeds (crossings with ``share >= min_share``) circled and labelled."""
    from matplotlib import colors

    plt = _pyplot()
    d = diagram
    w_max = d.max_speed_rad_s
    f_top = max(d.orders) * d.z1 * w_max / (2 * np.pi)
    fig, ax = plt.subplots(figsize=(8.0, 5.6), constrained_layout=True)
    norm = colors.Normalize(0.0, max(float(np.max(d.share)), d.min_share))
    cmap = plt.get_cmap("viridis_r")
    order = np.argsort(d.share)  # the strong modes drawn last, on top
    for j in order:
        f = float(d.frequencies_hz[j])
        if f > f_top:
            continue
        s = float(d.share[j])
        ax.plot([0.0, w_max], [f, f], color=cmap(norm(s)), lw=0.6 + 2.4 * norm(s),
                alpha=0.35 + 0.65 * norm(s), zorder=1 + s)
    for k in d.orders:
        ax.plot([0.0, w_max], [0.0, k * d.z1 * w_max / (2 * np.pi)], color="0.45", lw=0.9, ls="--",
                zorder=0.5)
        ax.annotate(f"{k}x mesh", (w_max, k * d.z1 * w_max / (2 * np.pi)), fontsize=7,
                    color="0.3", ha="right", va="bottom")
    for r in d.critical_speeds():
        ax.plot(r["crossing_speed_rad_s"], r["frequency_hz"], "o", mfc="none", mec="crimson",
                ms=5 + 8 * r["mesh_energy_share"], mew=1.3, zorder=10)
        if r["mesh_order"] == 1:
            ax.annotate(f"{r['crossing_speed_rad_s']:.0f}", (r["crossing_speed_rad_s"],
                        r["frequency_hz"]), xytext=(4, 4), textcoords="offset points",
                        fontsize=7, color="crimson")
    sm = plt.cm.ScalarMappable(norm=norm, cmap=cmap)
    fig.colorbar(sm, ax=ax, label="share of mesh strain energy")
    ax.set_xlim(0.0, w_max)
    ax.set_ylim(0.0, f_top)
    ax.set_xlabel("pinion speed $\\Omega_1$ [rad/s]")
    ax.set_ylabel("frequency [Hz]")
    ax.plot([], [], "o", mfc="none", mec="crimson",
            label=f"predicted critical speed (share >= {d.min_share:g}; order 1 labelled, rad/s)")
    ax.legend(loc="upper left", fontsize=8)
    ax.grid(alpha=0.25)
    if title:
        ax.set_title(title)
    fig.savefig(path, dpi=120)
    plt.close(fig)
