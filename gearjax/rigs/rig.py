"""The :class:`Rig` record: what a test rig brings to a simulation (gear pair, torque,
structure, nodes, encoder positions, relief presets). The built-in rigs are made in
:mod:`gearjax.rigs.baud_velex`, rig files in :mod:`gearjax.rigs.rigfile`; both are found
by :func:`gearjax.rigs.registry.get_rig`."""

from __future__ import annotations

import dataclasses
from typing import Callable

import numpy as np

from ..errors import RigError
from ..gears.geometry import GearPair
from ..gears.iso6336 import AccuracyData
from ..gears.modifications import ToothModifications

__all__ = ["Rig"]


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
    structure_factory : ``f(pair) -> Structure`` building the 3D shaft lines (with
        ``pinion_node`` and ``gear_node`` set).
    motor_node : node whose torsional dof carries the motor torque C_m0.
    encoder_positions : ``{position: (node_I, node_II)}`` of the TE encoders (Fig. 7).
    modifications_default : tooth modifications of a rig file (``relief="file"``), or None.
    relief_presets : ``f(kind, shape) -> ToothModifications`` giving the named reliefs
        (``"short"``, ``"long"``) of :meth:`modifications`; the built-in rigs and rig files
        use Table 1's (:func:`gearjax.rigs.baud_velex.table1_relief`).
    accuracy : ISO 6336-1 method-B accuracy data (:class:`gearjax.gears.iso6336.AccuracyData`:
        f_pb, f_falpha, C_a, K_A, rated speed) of a rig file's ``[iso6336]`` table, or None
        (the defaults named in :mod:`gearjax.gears.iso6336`).
    backlash_m : clearance between the back flanks (m, normal backlash along the line of
        action, :mod:`gearjax.gears.backlash`) of a rig file's ``[gear_pair] backlash_m``,
        or None: no back flanks (the built-in rigs, the paper's model).
    """

    name: str
    pair: GearPair
    pinion_torque_Nm: float
    pinion_pitch_errors_m: np.ndarray
    description: str
    structure_factory: Callable | None = None
    motor_node: int | None = None
    encoder_positions: dict | None = None
    modifications_default: ToothModifications | None = None
    relief_presets: Callable | None = None
    accuracy: AccuracyData | None = None
    backlash_m: float | None = None

    def structure(self):
        """The rig's shafts, discs, bearings and couplings, with the centre line set by
        this rig's gear pair."""
        if self.structure_factory is None:
            raise RigError("structure_factory", None, f"rig {self.name!r} has no 3D structure")
        return self.structure_factory(self.pair)

    @property
    def torque_node(self) -> int:
        """Node carrying C_m0."""
        if self.motor_node is None:
            raise RigError("motor_node", None, f"rig {self.name!r} has no motor node")
        return int(self.motor_node)

    def encoder_nodes(self, position: int = 1) -> tuple[int, int]:
        """Nodes (I, II) of encoder position ``position`` (Fig. 7, Eq. (9))."""
        positions = self.encoder_positions or {}
        if position not in positions:
            raise RigError(f"encoders={position!r}: rig {self.name!r} defines encoder positions "
                           f"{sorted(positions)}")
        return tuple(int(n) for n in positions[position])

    def modifications(
        self,
        relief: str = "none",
        amplitude_m: float | None = None,
        extent: float | None = None,
        shape: str = "linear",
        pitch_errors: bool = False,
    ) -> ToothModifications:
        """Tooth modifications of a scenario.

        ``relief`` picks the rig's ``"short"`` / ``"long"`` relief preset (Table 1: 13.3 um,
        extent 0.2 / 0.5 on both gears) or ``"none"``; ``amplitude_m`` / ``extent`` override
        the amplitude and extent (same relief on both gears; the extent defaults to the
        short preset's). ``pitch_errors`` adds the pinion pitch errors.
        """
        if self.relief_presets is None:
            raise RigError("relief_presets", None, f"rig {self.name!r} has no relief presets")
        base = self.relief_presets(relief if relief != "none" else "short", shape)
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
