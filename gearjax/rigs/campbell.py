"""Campbell diagram of a geared rig: its natural frequencies against pinion speed with the
mesh-order lines, each mode weighted by its share of mesh strain energy.

A mode j of the model (3D: the retained modes of ``(M, K + k_m V V^T)``, Eq. (33); sdof: the
mesh mode ``omega_n^2 = k_m cos^2(beta_b) / m_eq``) is excited by mesh order k (k times the
mesh frequency ``z1 Omega1``) at the pinion speed

    Omega1 = omega_j / (k z1)          (rad/s)

where its frequency line crosses the order line. How strongly the mesh excites it is
measured by its share of mesh strain energy ``s_j = k_m (phi_j^T V)^2 / omega_j^2``
(mass-normalised modes; over all modes the shares sum to ``k_m C_vv = 1``, Eq. (33); the
sdof mode holds all of it). Crossings whose share reaches a threshold are the predicted
critical speeds: order 1 gives the main tooth critical speeds (the peaks of Figs. 8-13),
orders 2-5 the secondary ones at 1/k of those speeds. The shares are those of
:func:`gearjax.rigs.figures.predicted_critical_speeds`, which also ranks modes by them;
both read :func:`mesh_energy_shares`. The rig's shafts do not spin their modes
(no gyroscopic terms, Eq. (13)), so the frequency lines are horizontal.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..models.torsional import TorsionalModel

__all__ = ["mode_shares", "mesh_energy_shares", "Campbell", "campbell", "MESH_ORDERS", "DEFAULT_MIN_SHARE"]

MESH_ORDERS = (1, 2, 3, 4, 5)
DEFAULT_MIN_SHARE = 0.05  # a crossing is a predicted critical speed from 5 % of the mesh energy


def mode_shares(omega_rad_s, v, k_m: float) -> np.ndarray:
    """Shares of mesh strain energy ``k_m (phi^T V)^2 / omega^2`` of mass-normalised modes
    of natural frequencies ``omega_rad_s`` (rad/s; a rigid mode's share is 0) whose mesh
    components are ``v = phi^T V``; they sum to ``k_m C_vv = 1`` over every mode, Eq. (33)."""
    w = np.asarray(omega_rad_s, dtype=np.float64)
    return float(k_m) * np.asarray(v, dtype=np.float64) ** 2 / np.where(w > 0, w, np.inf) ** 2


def mesh_energy_shares(model) -> tuple[np.ndarray, np.ndarray]:
    """``(omega_rad_s, share)`` of the model's vibration modes: natural frequencies (rad/s)
    and shares of mesh strain energy ``k_m (phi^T V)^2 / omega^2`` (3D: the ``n_modes``
    retained modes, Eq. (33); :class:`TorsionalModel`: its one mesh mode, share 1)."""
    if isinstance(model, TorsionalModel):
        return np.array([float(model.natural_frequency_rad_s())]), np.array([1.0])
    n = int(model.n_modes)
    w = np.asarray(model.omega_r, dtype=np.float64)[:n]
    return w, mode_shares(w, np.asarray(model.v_r)[:n], float(model.k_m))


@dataclasses.dataclass(frozen=True)
class Campbell:
    """The Campbell diagram of a model over pinion speeds ``0 .. max_speed_rad_s``.

    ``omega_rad_s`` and ``share`` per mode (:func:`mesh_energy_shares`), ``z1`` the pinion
    tooth number, ``orders`` the mesh orders drawn, ``min_share`` the share from which a
    crossing is a predicted critical speed.
    """

    omega_rad_s: np.ndarray
    share: np.ndarray
    z1: int
    max_speed_rad_s: float
    orders: tuple = MESH_ORDERS
    min_share: float = DEFAULT_MIN_SHARE

    @property
    def frequencies_hz(self) -> np.ndarray:
        return self.omega_rad_s / (2.0 * math.pi)

    def crossing_speeds(self) -> np.ndarray:
        """``(modes, orders)`` pinion speeds ``omega_j / (k z1)`` (rad/s) of every crossing."""
        k = np.asarray(self.orders, dtype=np.float64)
        return self.omega_rad_s[:, None] / (k[None, :] * self.z1)

    def rows(self) -> list[dict]:
        """One row per mode and order (the CSV): mode index, frequency (Hz), share, order,
        crossing speed (rad/s), whether it lies in the speed range and is a predicted
        critical speed (``share >= min_share``)."""
        speeds = self.crossing_speeds()
        out = []
        for j, (f, s) in enumerate(zip(self.frequencies_hz, self.share)):
            for i, k in enumerate(self.orders):
                w = float(speeds[j, i])
                inside = w <= self.max_speed_rad_s
                out.append({"mode": j + 1, "frequency_hz": float(f), "mesh_energy_share": float(s),
                            "mesh_order": int(k), "crossing_speed_rad_s": w,
                            "in_range": bool(inside),
                            "predicted_critical": bool(inside and s >= self.min_share)})
        return out

    def critical_speeds(self) -> list[dict]:
        """The predicted critical speeds: crossings in range with ``share >= min_share``,
        by increasing speed."""
        rows = [r for r in self.rows() if r["predicted_critical"]]
        return sorted(rows, key=lambda r: r["crossing_speed_rad_s"])


def campbell(model, max_speed_rad_s: float, orders=MESH_ORDERS,
             min_share: float = DEFAULT_MIN_SHARE) -> Campbell:
    """The :class:`Campbell` diagram of a built model (sdof or 3D) up to ``max_speed_rad_s``."""
    w, share = mesh_energy_shares(model)
    return Campbell(omega_rad_s=w, share=share, z1=int(model.mesh.pair.z1),
                    max_speed_rad_s=float(max_speed_rad_s), orders=tuple(int(k) for k in orders),
                    min_share=float(min_share))
