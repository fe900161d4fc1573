"""The time signals and order tracks that ``gearjax sweep`` writes beside its results:
``signals.csv`` / ``mesh_force_signals.png`` (``--signals``: the last mesh period at chosen
speeds) and ``order_tracks.png`` (from ``orders.csv``)."""

from __future__ import annotations

import csv
import os

import numpy as np

from ..dynamics.simulate import simulate

__all__ = ["parse_signal_speeds", "last_mesh_period_signals", "write_signals",
           "write_order_tracks"]

SAMPLES_PER_MESH_PERIOD = 128


def parse_signal_speeds(text: str | None) -> list[float]:
    """The pinion speeds (rad/s) of ``--signals A,B,...`` (none without it); ``ValueError``
    (one line) unless they are finite and > 0."""
    if not text:
        return []
    try:
        vals = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise ValueError(f"--signals={text!r}: expected comma-separated speeds in rad/s, "
                         "e.g. 100,400,800") from None
    if not vals or not all(np.isfinite(v) and v > 0 for v in vals):
        raise ValueError(f"--signals={text!r}: speeds must be finite and > 0 (rad/s)")
    return vals


def write_order_tracks(orders_path, out, title) -> dict:
    """``order_tracks.png`` from ``orders.csv`` (mesh-order amplitudes in dB against speed)."""
    from ..plotting import plot_order_tracks  # matplotlib: imported where a figure is drawn

    if not os.path.exists(orders_path):
        return {}
    fig_path = os.path.join(out, "order_tracks.png")
    plot_order_tracks(orders_path, fig_path, title=title)
    return {"orders_csv": orders_path, "order_tracks_png": fig_path}


def last_mesh_period_signals(model, speeds):
    """Signals over the last mesh period at each speed (mesh force, DTE, acceleration)."""
    import equinox as eqx
    import jax.numpy as jnp

    # compiled once for all speeds: run op by op, simulate costs more than its compilation,
    # and again at every speed (benchmarks/results/code_notes.md, gearjax.cli.signals)
    run = eqx.filter_jit(simulate)
    out = []
    for w in speeds:
        r = run(model, jnp.asarray(float(w)), save_signals=True, n_measured_periods=2,
                samples_per_mesh_period=SAMPLES_PER_MESH_PERIOD)
        sig = r.signals
        th = np.asarray(sig.theta_rad)
        tm = model.mesh_period_rad
        keep = slice(th.size - SAMPLES_PER_MESH_PERIOD, th.size)  # the last mesh period
        acc = None if sig.accel_m_s2 is None else np.asarray(sig.accel_m_s2)[keep]
        out.append({"speed_rad_s": float(w), "t_over_Tm": (th[keep] - th[keep][0]) / tm,
                    "mesh_force_N": np.asarray(sig.mesh_force_N)[keep],
                    "dte_m": np.asarray(sig.dte_m)[keep], "accel_m_s2": acc,
                    "converged": bool(r.converged)})
    return out


def write_signals(signals, out, title) -> dict:
    """``signals.csv`` and ``mesh_force_signals.png`` from
    :func:`last_mesh_period_signals` by formulation."""
    path = os.path.join(out, "signals.csv")
    with open(path, "w", newline="") as fh:
        wr = csv.writer(fh)
        wr.writerow(["formulation", "speed_rad_s", "t_over_mesh_period", "mesh_force_N", "dte_m",
                     "accel_m_s2"])
        for form, sigs in signals.items():
            for s in sigs:
                acc = s["accel_m_s2"] if s["accel_m_s2"] is not None else [None] * len(s["t_over_Tm"])
                for t, f, d, a in zip(s["t_over_Tm"], s["mesh_force_N"], s["dte_m"], acc):
                    wr.writerow([form, f"{s['speed_rad_s']:.6g}", f"{t:.6f}", f"{f:.8e}", f"{d:.8e}",
                                 "" if a is None else f"{a:.8e}"])
    from ..plotting import plot_mesh_force_signals

    fig = os.path.join(out, "mesh_force_signals.png")
    plot_mesh_force_signals(signals, fig, title=title)
    return {"signals_csv": path, "mesh_force_signals_png": fig}
