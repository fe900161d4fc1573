"""What a speed sweep returns: :class:`SweepResult` (one entry per speed), the names of its
per-speed metric fields and its CSV rows. Shared by :mod:`gearjax.dynamics.sweep` (transient
sweeps) and :mod:`gearjax.dynamics.steady` (periodic steady-state sweeps)."""

from __future__ import annotations

import math

import equinox as eqx
import numpy as np

__all__ = ["SweepResult", "CSV_COLUMNS", "METRIC_FIELDS", "csv_rows"]

CSV_COLUMNS = (
    "speed_rad_s",
    "formulation",
    "max_mesh_force_N",
    "dynamic_factor",
    "dte_ptp_m",
    "accel_ptp_m_s2",
    "min_mesh_force_N",
    "contact_loss",
    "converged",
)


class SweepResult(eqx.Module):
    """Metrics of a speed sweep, one entry per requested speed (caller's order).

    Attributes
    ----------
    speed_rad_s, max_mesh_force_N, min_mesh_force_N, dynamic_factor, dte_ptp_m,
    accel_ptp_m_s2, contact_loss, convergence, converged, solver_ok, n_steps,
    transient_periods : NumPy arrays of shape (n_speeds,), see
        :class:`gearjax.dynamics.simulate.SimulationResult`.
    formulation : the model's formulation (str).
    """

    speed_rad_s: np.ndarray
    max_mesh_force_N: np.ndarray
    min_mesh_force_N: np.ndarray
    dynamic_factor: np.ndarray
    dte_ptp_m: np.ndarray
    accel_ptp_m_s2: np.ndarray
    contact_loss: np.ndarray
    convergence: np.ndarray
    converged: np.ndarray
    solver_ok: np.ndarray
    n_steps: np.ndarray
    transient_periods: np.ndarray
    formulation: str = eqx.field(static=True)

    def rows(self):
        """CSV rows (dicts keyed by :data:`CSV_COLUMNS`)."""
        return csv_rows(self, slice(None))


METRIC_FIELDS = (
    "speed_rad_s", "max_mesh_force_N", "min_mesh_force_N", "dynamic_factor", "dte_ptp_m",
    "accel_ptp_m_s2", "contact_loss", "convergence", "converged", "solver_ok", "n_steps",
    "transient_periods",
)


def fmt_value(v):
    """A metric as CSV text: ``repr`` of the float, empty for NaN."""
    v = float(v)
    return "" if math.isnan(v) else repr(v)


def csv_rows(res, sl=slice(None)):
    """CSV rows (dicts keyed by :data:`CSV_COLUMNS`) of ``res`` restricted to the slice ``sl``."""
    out = []
    for i in range(len(np.asarray(res.speed_rad_s)[sl])):
        g = lambda name: np.asarray(getattr(res, name))[sl][i]
        out.append({
            "speed_rad_s": repr(float(g("speed_rad_s"))),
            "formulation": res.formulation,
            "max_mesh_force_N": fmt_value(g("max_mesh_force_N")),
            "dynamic_factor": fmt_value(g("dynamic_factor")),
            "dte_ptp_m": fmt_value(g("dte_ptp_m")),
            "accel_ptp_m_s2": fmt_value(g("accel_ptp_m_s2")),
            "min_mesh_force_N": fmt_value(g("min_mesh_force_N")),
            "contact_loss": str(bool(g("contact_loss"))),
            "converged": str(bool(g("converged"))),
        })
    return out
