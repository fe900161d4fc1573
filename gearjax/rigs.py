"""Built-in test rigs: the Baud & Velex spur and helical rig of Section 6.1.

A :class:`Rig` bundles the gear pair (Table 1), the operating torque (254.8 N m on the
pinion, Section 6.1), the Table 1 reliefs and the pinion pitch errors standing in for
Fig. 5. The 3D structure of the rig (shafts, bearings, Table 2) lives in
:mod:`gearjax.structure`.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from .geometry import GearPair, baud_velex_pair
from .modifications import ToothModifications, fig5_pitch_errors, table1_relief

__all__ = ["Rig", "RIGS", "get_rig", "RigError"]


class RigError(ValueError):
    """Unknown rig or bad rig data."""


@dataclasses.dataclass(frozen=True)
class Rig:
    """A geared test rig.

    Attributes
    ----------
    name : registry name.
    pair : the gear pair.
    pinion_torque_Nm : nominal torque on the pinion C_m0 (N m).
    pinion_pitch_errors_m : (z1,) cumulative pitch deviations of the pinion (m), used by
        ``--pitch-errors``.
    description : one line for reports.
    """

    name: str
    pair: GearPair
    pinion_torque_Nm: float
    pinion_pitch_errors_m: np.ndarray
    description: str

    def modifications(
        self,
        relief: str = "none",
        amplitude_m: float | None = None,
        extent: float | None = None,
        shape: str = "linear",
        pitch_errors: bool = False,
    ) -> ToothModifications:
        """Tooth modifications of a scenario.

        ``relief`` picks Table 1's ``"short"`` / ``"long"`` relief (13.3 um, extent 0.2 /
        0.5 on both gears) or ``"none"``; ``amplitude_m`` / ``extent`` override the amplitude
        and extent (same relief on both gears). ``pitch_errors`` adds the pinion pitch errors.
        """
        base = table1_relief(relief if relief != "none" else "short", shape)
        amp = base.relief_amplitude_m if relief != "none" else np.zeros(2)
        ext = base.relief_extent
        if amplitude_m is not None:
            amp = np.full(2, float(amplitude_m))
        if extent is not None:
            ext = np.full(2, float(extent))
        mods = ToothModifications.tip_relief(amp, ext, shape)
        if pitch_errors:
            mods = mods.with_pitch_errors(self.pinion_pitch_errors_m, np.zeros(self.pair.z2))
        return mods


def _baud_velex(helical: bool) -> Rig:
    pair = baud_velex_pair(helical)
    kind = "helical (beta = 20 deg)" if helical else "spur"
    return Rig(
        name="baud-velex-helical" if helical else "baud-velex-spur",
        pair=pair,
        pinion_torque_Nm=254.8,
        pinion_pitch_errors_m=fig5_pitch_errors(pair.z1),
        description=f"Baud & Velex test rig, {kind}, Table 1 gears, 254.8 N m on the pinion",
    )


RIGS = {
    "baud-velex-spur": lambda: _baud_velex(False),
    "baud-velex-helical": lambda: _baud_velex(True),
}


def get_rig(name: str) -> Rig:
    """A built-in rig by name (``baud-velex-spur`` or ``baud-velex-helical``)."""
    try:
        return RIGS[name]()
    except KeyError:
        raise RigError(f"rig={name!r}: unknown rig; built-in rigs are {sorted(RIGS)}") from None


def torsional_stiffness_figures(rig: Rig, law: str = "iso6336") -> dict:
    """Mesh figures of a rig at its nominal torque (used by ``gearjax info``)."""
    from .mesh import Mesh
    from .quasistatic import static_mesh_force

    mesh = Mesh.build(rig.pair, law)
    k_m, alpha, _ = mesh.stiffness_variation(mesh.theta_grid(512))
    return {
        "stiffness_law": law,
        "mean_mesh_stiffness_N_per_m": float(k_m),
        "stiffness_variation_alpha": float(alpha),
        "static_mesh_force_N": static_mesh_force(rig.pair, rig.pinion_torque_Nm),
        "tangential_force_N": rig.pinion_torque_Nm / rig.pair.base_radii_m[0],
        "pinion_torque_Nm": rig.pinion_torque_Nm,
        "cells_per_line": mesh.cells_per_line,
        "tooth_pair_slots": mesh.n_slots,
        "base_helix_cos": math.cos(rig.pair.base_helix_angle_rad),
    }
