"""What a speed sweep returns: :class:`SweepResult` (one entry per speed), the names of its
per-speed metric fields and its CSV rows (``results.csv``; the mesh-order amplitudes in
``orders.csv``: :data:`ORDER_COLUMNS`). Shared by :mod:`gearjax.dynamics.sweep` (transient
sweeps), :mod:`gearjax.dynamics.steady` (periodic steady-state sweeps) and
:mod:`gearjax.dynamics.harmonic` (frequency domain)."""

from __future__ import annotations

import csv
import math
import os

import equinox as eqx
import numpy as np

from ..errors import GearjaxError
from .orders import N_MESH_ORDERS

__all__ = ["SweepResult", "merge_results", "CSV_COLUMNS", "METRIC_FIELDS", "FLAG_FIELDS",
           "ORDER_FIELDS", "SOLVE_FIELDS", "ORDER_COLUMNS",
           "csv_rows", "order_rows", "empty_metrics", "append_rows", "check_header"]

CSV_COLUMNS = (
    "speed_rad_s",
    "formulation",
    "max_mesh_force_N",
    "dynamic_factor",
    "dte_ptp_m",
    "accel_ptp_m_s2",
    "min_mesh_force_N",
    "contact_loss",
    "back_contact",  # the back flanks met (backlash): min_mesh_force_N < 0
    "converged",
    "convergence",  # the periodicity measure behind `converged` (the achieved residual)
    "period_multiple",  # the response's period in excitation periods (0: not periodic)
)


class SweepResult(eqx.Module):
    """Metrics of a speed sweep, one entry per requested speed (caller's order).

    Attributes
    ----------
    speed_rad_s, max_mesh_force_N, min_mesh_force_N, dynamic_factor, dte_ptp_m,
    accel_ptp_m_s2, contact_loss, back_contact, convergence, converged, solver_ok,
    n_steps, transient_periods, period_multiple : NumPy arrays of shape (n_speeds,), see
        :class:`gearjax.dynamics.simulate.SimulationResult`.
    mesh_force_orders_N, dte_orders_m, accel_orders_m_s2 : (n_speeds, 5) single-sided
        peak amplitudes of mesh orders 1..5 (column k-1: order k, k times the mesh
        frequency) of the dynamic mesh force (N), the DTE (m) and the acceleration
        (m/s^2; NaN for models without one), :mod:`gearjax.dynamics.orders`.
    formulation : the model's formulation (str).
    solver : (n_speeds,) name of the solver whose orbit gave each speed's metrics
        (``"transient"``, ``"steady"`` (shooting), ``"harmonic"`` (frequency domain),
        ``"continuation"``: :mod:`gearjax.dynamics.solvers`).
    spectral_radius : (n_speeds,) Floquet radius of the orbit (NaN where the solver did not
        compute it: the transient).
    status : (n_speeds,) :class:`gearjax.dynamics.orbit.RESULTS` code of each speed (why
        its solve ended: ``successful``, ``not_periodic``, ``integration_failed``,
        ``newton_failed``, ``unstable``, ``contact_lost``).
    stats : solver-specific per-speed diagnostics, ``{name: (n_speeds, ...) array}`` (as
        diffrax's ``Solution.stats``), each documented by the solver that writes it (e.g.
        the frequency domain's harmonic count and small-gain bound); empty for the
        transient.
    """

    speed_rad_s: np.ndarray
    max_mesh_force_N: np.ndarray
    min_mesh_force_N: np.ndarray
    dynamic_factor: np.ndarray
    dte_ptp_m: np.ndarray
    accel_ptp_m_s2: np.ndarray
    contact_loss: np.ndarray
    back_contact: np.ndarray
    convergence: np.ndarray
    converged: np.ndarray
    solver_ok: np.ndarray
    n_steps: np.ndarray
    transient_periods: np.ndarray
    period_multiple: np.ndarray
    mesh_force_orders_N: np.ndarray
    dte_orders_m: np.ndarray
    accel_orders_m_s2: np.ndarray
    formulation: str = eqx.field(static=True)
    solver: np.ndarray = eqx.field(kw_only=True)
    spectral_radius: np.ndarray = eqx.field(kw_only=True)
    status: np.ndarray = eqx.field(kw_only=True)
    stats: dict = eqx.field(kw_only=True, default_factory=dict)

    def rows(self):
        """CSV rows (dicts keyed by :data:`CSV_COLUMNS`)."""
        return csv_rows(self, slice(None))

    def order_rows(self):
        """``orders.csv`` rows (dicts keyed by :data:`ORDER_COLUMNS`)."""
        return order_rows(self)

    def take(self, idx) -> "SweepResult":
        """The speeds ``idx`` (indices or a mask) of this result, as a plain
        :class:`SweepResult` (a subclass's extra fields are dropped)."""
        kw = {f: np.asarray(getattr(self, f))[idx] for f in METRIC_FIELDS + SOLVE_FIELDS}
        return SweepResult(**kw, formulation=self.formulation,
                           stats={k: np.asarray(v)[idx] for k, v in self.stats.items()})


def merge_results(a: SweepResult, b: SweepResult, from_b) -> SweepResult:
    """One :class:`SweepResult` over ``a``'s speeds, taking the speeds where the mask
    ``from_b`` is True, in order, from ``b`` (which holds exactly those speeds); a
    ``stats`` entry only one of them reports is NaN at the other's speeds."""
    from_b = np.asarray(from_b, dtype=bool)
    kw = {}
    for f in METRIC_FIELDS + SOLVE_FIELDS:
        va, vb = np.asarray(getattr(a, f)), np.asarray(getattr(b, f))
        out = va.astype(np.result_type(va, vb), copy=True)
        out[from_b] = vb
        kw[f] = out
    stats = {}
    for k in sorted(set(a.stats) | set(b.stats)):  # NaN where a solver did not report it
        va = np.asarray(a.stats[k], dtype=float) if k in a.stats else None
        vb = np.asarray(b.stats[k], dtype=float) if k in b.stats else None
        shape = (from_b.size,) + (va if va is not None else vb).shape[1:]
        out = va.copy() if va is not None else np.full(shape, np.nan)
        out[from_b] = vb if vb is not None else np.nan
        stats[k] = out
    return SweepResult(**kw, formulation=a.formulation, stats=stats)


ORDER_FIELDS = ("mesh_force_orders_N", "dte_orders_m", "accel_orders_m_s2")
# per speed, how it was solved: the solver's name, the Floquet radius, the RESULTS code
SOLVE_FIELDS = ("solver", "spectral_radius", "status")
METRIC_FIELDS = (
    "speed_rad_s", "max_mesh_force_N", "min_mesh_force_N", "dynamic_factor", "dte_ptp_m",
    "accel_ptp_m_s2", "contact_loss", "back_contact", "convergence", "converged", "solver_ok",
    "n_steps", "transient_periods", "period_multiple",
) + ORDER_FIELDS
# the boolean fields (stored as floats, NaN where a speed was not computed, while a sweep runs)
FLAG_FIELDS = ("contact_loss", "back_contact", "converged", "solver_ok")

# orders.csv: order<k>_<signal>_<unit>, single-sided peak amplitudes (SI), DTE first
_CSV_ORDER = (("dte", "m"), ("force", "N"), ("accel", "m_s2"))
ORDER_COLUMNS = ("speed_rad_s", "formulation") + tuple(
    f"order{k}_{name}_{unit}" for name, unit in _CSV_ORDER
    for k in range(1, N_MESH_ORDERS + 1)) + ("converged",)


def empty_metrics(n: int) -> dict:
    """``{field: NaN array}`` for :data:`METRIC_FIELDS` over ``n`` speeds: shape (n,),
    (n, 5) for the order amplitudes."""
    return {f: np.full((n, N_MESH_ORDERS) if f in ORDER_FIELDS else n, np.nan)
            for f in METRIC_FIELDS}


def fmt_value(v):
    """A metric as CSV text: ``repr`` of the float, empty for NaN."""
    v = float(v)
    return "" if math.isnan(v) else repr(v)


def _fmt_int(v):
    """An integer metric as CSV text, empty for NaN (a speed not computed)."""
    v = float(v)
    return "" if math.isnan(v) else str(int(v))


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
            "back_contact": str(bool(g("back_contact"))),
            "converged": str(bool(g("converged"))),
            "convergence": fmt_value(g("convergence")),
            "period_multiple": _fmt_int(g("period_multiple")),
        })
    return out


def order_rows(res, sl=slice(None)):
    """``orders.csv`` rows (dicts keyed by :data:`ORDER_COLUMNS`) of ``res`` restricted to
    the slice ``sl``: the amplitudes of DTE (m), mesh force (N) and acceleration (m/s^2,
    empty where the model has none) at mesh orders 1..5."""
    out = []
    arrays = {"dte": res.dte_orders_m, "force": res.mesh_force_orders_N,
              "accel": res.accel_orders_m_s2}
    speeds = np.asarray(res.speed_rad_s)[sl]
    for i in range(len(speeds)):
        row = {"speed_rad_s": repr(float(speeds[i])), "formulation": res.formulation}
        for name, unit in _CSV_ORDER:
            amp = np.asarray(arrays[name])[sl][i]
            for k in range(N_MESH_ORDERS):
                row[f"order{k + 1}_{name}_{unit}"] = fmt_value(amp[k])
        row["converged"] = str(bool(np.asarray(res.converged)[sl][i]))
        out.append(row)
    return out


def check_header(path, columns, field: str = "results file") -> None:
    """Refuse (:class:`GearjaxError` on ``field``) a non-empty CSV file ``path`` whose header
    is not ``columns``: rows appended under another header (an earlier version's run)
    would be read into the wrong columns."""
    if not os.path.exists(path) or os.path.getsize(path) == 0:
        return
    with open(path, newline="") as fh:
        header = next(csv.reader(fh), [])
    if tuple(header) != tuple(columns):
        raise GearjaxError(
            field, str(path), f"the columns of {os.path.basename(path)} "
            f"({', '.join(header)}) are not those this gearjax writes "
            f"({', '.join(columns)}): an earlier version's run; use --overwrite or another "
            "--out folder")


def append_rows(path, columns, rows) -> None:
    """Append ``rows`` (dicts keyed by ``columns``) to the CSV file ``path``, its header
    first when the file is new or empty (``results.csv``, ``orders.csv``: rows are written
    as speeds finish, so an interrupted sweep keeps them); a file under another header is
    refused (:func:`check_header`)."""
    check_header(path, columns)
    new = not os.path.exists(path) or os.path.getsize(path) == 0
    with open(path, "a", newline="") as fh:
        wr = csv.DictWriter(fh, fieldnames=columns)
        if new:
            wr.writeheader()
        wr.writerows(rows)
