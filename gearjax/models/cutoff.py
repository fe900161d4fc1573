"""Default modal cut-off of the reduced 3D model (:mod:`gearjax.models.geared3d`).

The reduced model keeps the modes of ``(M, K_bar)`` below a cut-off plus static
corrections, so the static mesh response (Eqs. (33)-(36)) stays exact and a dropped mode
only loses its dynamic amplification at the mesh harmonics. Accuracy and cost of the rule:
``benchmarks/results/cutoff.md`` and ``benchmarks/results/model_notes.md``.
"""

from __future__ import annotations

import math

__all__ = ["default_max_frequency_hz", "CUTOFF_MESH_HARMONICS", "CUTOFF_MARGIN", "CUTOFF_FLOOR_HZ"]

# default modal cut-off of the 3D model: 3 mesh harmonics of the highest speed x 1.5
# (benchmarks/bench_cutoff.py, benchmarks/results/cutoff.md)
CUTOFF_MESH_HARMONICS = 3
CUTOFF_MARGIN = 1.5
CUTOFF_FLOOR_HZ = 6000.0


def default_max_frequency_hz(max_speed_rad_s: float, z1: int, *,
                             n_harmonics: int = CUTOFF_MESH_HARMONICS,
                             margin: float = CUTOFF_MARGIN,
                             floor_hz: float = CUTOFF_FLOOR_HZ) -> float:
    """Modal cut-off (Hz) of the reduced 3D model for pinion speeds up to
    ``max_speed_rad_s`` (rad/s): ``max(floor_hz, margin * n_harmonics * f_m)`` with the
    mesh frequency of the highest speed ``f_m = z1 Omega_max / (2 pi)`` (Hz, ``z1`` pinion
    teeth). The reduced model keeps the modes of ``(M, K_bar)`` below the cut-off plus
    static corrections (Eqs. (33)-(36) stay exact), so a dropped mode only loses its
    dynamic amplification at the mesh harmonics; the margin keeps the modes just above
    the highest harmonic of interest. Accuracy and cost: ``benchmarks/results/cutoff.md``.
    """
    f_mesh_hz = z1 * float(max_speed_rad_s) / (2 * math.pi)
    return max(float(floor_hz), margin * n_harmonics * f_mesh_hz)
