"""Figures: quasi-static transmission errors and load sharing (more come with the sweeps).

Matplotlib is imported lazily with the non-interactive Agg backend so that the CLI works on
machines without a display.
"""

from __future__ import annotations

import numpy as np

__all__ = ["plot_quasistatic"]


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
    ax1.set_ylabel("transmission error on base plane [um]")
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
        fig.suptitle(title)
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plot_response_curves(csv_path: str, path: str, title: str = ""):
    """Response curves laid out like Figs. 8-13 from a sweep's ``results.csv``: maximum
    dynamic tooth load, peak-to-peak DTE and peak-to-peak pinion-centre acceleration (S)
    against pinion speed, one curve per formulation (the acceleration panel is left out for
    torsional models, which have none)."""
    import csv

    plt = _pyplot()
    rows = list(csv.DictReader(open(csv_path)))
    forms = list(dict.fromkeys(r["formulation"] for r in rows))
    has_acc = any(r["accel_ptp_m_s2"] not in ("", "nan") for r in rows)
    panels = [("max_mesh_force_N", "max dynamic tooth load [N]", 1.0),
              ("dte_ptp_m", "peak-to-peak DTE [um]", 1e6)]
    if has_acc:
        panels.append(("accel_ptp_m_s2", "p-p pinion acceleration S [m/s$^2$]", 1.0))
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
            ax.plot(x, y, marker=markers.get(form, "o"), ms=3.5, lw=1.2, label=labels.get(form, form))
        ax.set_ylabel(ylabel)
        ax.grid(alpha=0.3)
    np.atleast_1d(axes)[0].legend(loc="best", fontsize=8)
    np.atleast_1d(axes)[-1].set_xlabel("pinion speed $\\Omega_1$ [rad/s]")
    if title:
        fig.suptitle(title)
    fig.savefig(path, dpi=120)
    plt.close(fig)


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
        fig.suptitle(title)
    fig.savefig(path, dpi=120)
    plt.close(fig)
