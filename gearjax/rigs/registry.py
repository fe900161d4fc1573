"""Built-in test rigs: the Baud & Velex spur and helical rig of Section 6.1.

A :class:`Rig` bundles the gear pair (Table 1), the operating torque (254.8 N m on the
pinion, Section 6.1), the Table 1 reliefs and the pinion pitch errors standing in for
Fig. 5. The 3D structure of the rig (shafts, bearings, Table 2) lives in
:mod:`gearjax.structure`.
"""

from __future__ import annotations

import dataclasses
import math
import os

import numpy as np

from ..gears.geometry import GearPair, baud_velex_pair
from ..gears.modifications import ToothModifications, fig5_pitch_errors, table1_relief
from ..errors import RigError

__all__ = ["Rig", "RIGS", "get_rig", "RigError", "system_3d", "three_d_figures",
           "iso6336_resonance_speed"]


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
        ``pinion_node`` and ``gear_node`` set); default the Baud-Velex structure.
    motor_node : node whose torsional dof carries the motor torque C_m0.
    encoder_positions : ``{position: (node_I, node_II)}`` of the TE encoders (Fig. 7).
    modifications_default : tooth modifications of a rig file (``relief="file"``), or None.
    """

    name: str
    pair: GearPair
    pinion_torque_Nm: float
    pinion_pitch_errors_m: np.ndarray
    description: str
    structure_factory: object = None
    motor_node: int | None = None
    encoder_positions: dict | None = None
    modifications_default: ToothModifications | None = None

    def structure(self):
        """The rig's shafts, discs, bearings and couplings, with the centre line set by
        this rig's gear pair (default :func:`gearjax.rigs.baud_velex.baud_velex_structure`)."""
        if self.structure_factory is not None:
            return self.structure_factory(self.pair)
        from .baud_velex import baud_velex_structure

        return baud_velex_structure(
            centre_distance_m=self.pair.centre_distance_m,
            working_pressure_angle_rad=self.pair.working_pressure_angle_rad,
        )

    @property
    def torque_node(self) -> int:
        """Node carrying C_m0 (default the Baud-Velex motor node)."""
        if self.motor_node is not None:
            return int(self.motor_node)
        from .baud_velex import MOTOR_NODE

        return MOTOR_NODE

    def encoder_nodes(self, position: int = 1) -> tuple[int, int]:
        """Nodes (I, II) of encoder position ``position`` (Fig. 7, Eq. (9))."""
        if self.encoder_positions is None:
            from .baud_velex import encoder_nodes

            try:
                return encoder_nodes(position)
            except ValueError as exc:
                raise RigError(f"encoders={position!r}: {exc}") from None
        if position not in self.encoder_positions:
            raise RigError(f"encoders={position!r}: rig {self.name!r} defines encoder positions "
                           f"{sorted(self.encoder_positions)}")
        return tuple(int(n) for n in self.encoder_positions[position])

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
    """A built-in rig by name (``baud-velex-spur`` or ``baud-velex-helical``), or a rig
    file (a name ending in ``.toml`` or an existing path; see :mod:`gearjax.rigs.rigfile`)."""
    if name not in RIGS and (str(name).endswith(".toml") or os.path.isfile(name)):
        from .rigfile import load_rig

        return load_rig(name)
    try:
        return RIGS[name]()
    except KeyError:
        raise RigError(f"rig={name!r}: unknown rig; built-in rigs are {sorted(RIGS)}") from None


def torsional_stiffness_figures(rig: Rig, law: str = "iso6336") -> dict:
    """Mesh figures of a rig at its nominal torque (used by ``gearjax info``)."""
    from ..gears.mesh import Mesh
    from ..gears.quasistatic import static_mesh_force

    from ..models.torsional import solid_cylinder_inertias

    mesh = Mesh.build(rig.pair, law)
    k_m, alpha, _ = mesh.stiffness_variation(mesh.theta_grid(512))
    pair = rig.pair
    cos_bb = math.cos(pair.base_helix_angle_rad)
    j1, j2 = solid_cylinder_inertias(pair)
    rb1, rb2 = pair.base_radii_m
    m_eq = j1 * j2 / (j1 * rb2**2 + j2 * rb1**2)  # Eq. (16)
    omega_n = math.sqrt(float(k_m) * cos_bb**2 / m_eq)
    return {
        "torsional_inertias_kg_m2": [j1, j2],
        "equivalent_mass_kg": m_eq,
        "torsional_natural_frequency_rad_s": omega_n,
        "torsional_critical_speed_rad_s": omega_n / pair.z1,
        "iso6336_resonance_speed_rad_s": iso6336_resonance_speed(pair, float(k_m)),
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


def iso6336_resonance_speed(pair: GearPair, mean_stiffness_N_per_m: float,
                            density_kg_m3: float = 7800.0) -> float:
    """Pinion resonance speed of ISO 6336-1 (method B, solid gear bodies), in rad/s.

    ``n_E1 = 30000 / (pi z1) sqrt(c_gamma_alpha / m_red)`` (1/min) with the reduced mass per
    unit face width ``m_red = m1* m2* / (m1* + m2*)``, ``m_i* = pi rho d_mi^4 / (8 d_bi^2)``
    (``d_m`` the mean of tip and root diameters) and ``c_gamma_alpha = k_m / b``; in rad/s
    ``Omega_E1 = sqrt(c_gamma_alpha / m_red) / z1``.
    """
    m_star = []
    for ra, rf, rb in zip(pair.tip_radii_m, pair.root_radii_m, pair.base_radii_m):
        dm, db = ra + rf, 2.0 * rb
        m_star.append(math.pi * density_kg_m3 * dm**4 / (8.0 * db**2))
    m_red = m_star[0] * m_star[1] / (m_star[0] + m_star[1])
    c_ga = mean_stiffness_N_per_m / pair.face_width_m
    return math.sqrt(c_ga / m_red) / pair.z1


def system_3d(rig: Rig, law: str = "iso6336", encoder_position: int = 1):
    """The 3D pieces of a rig shared by ``gearjax info`` and the 3D model.

    Returns a dict with ``structure``, ``mesh``, ``element`` (pinion-gear element),
    ``V`` (averaged structure vector), ``W`` (TE projection at the encoder nodes of Fig. 7
    position ``encoder_position``), ``F0`` (pinion torque on the motor's torsional dof,
    N m), ``k_m`` (mean mesh stiffness, N/m) and ``F_S`` (N).
    """
    from ..gears.mesh import Mesh
    from ..structure.element import PinionGearElement
    from ..gears.quasistatic import static_mesh_force
    structure = rig.structure()
    mesh = Mesh.build(rig.pair, law)
    element = PinionGearElement.at_nodes(mesh, structure.n_dof, structure.pinion_node, structure.gear_node)
    node_i, node_ii = rig.encoder_nodes(encoder_position)
    W = element.torsional_vector(structure.dof(node_i, "theta"), structure.dof(node_ii, "theta"))
    F0 = np.zeros(structure.n_dof)
    F0[structure.dof(rig.torque_node, "theta")] = rig.pinion_torque_Nm
    return {
        "structure": structure,
        "mesh": mesh,
        "element": element,
        "V": np.asarray(element.mean_vector()),
        "W": np.asarray(W),
        "F0": F0,
        "k_m": float(mesh.mean_stiffness()),
        "F_S": static_mesh_force(rig.pair, rig.pinion_torque_Nm),
    }


def three_d_figures(rig: Rig, law: str = "iso6336", encoder_position: int = 1, n_frequencies: int = 10) -> dict:
    """3D figures of a rig for ``gearjax info --model 3d``: dof count, the Appendix A
    relations normalised to 1 (Eqs. (33)-(35)), w_x0 and the lowest natural frequencies of
    (M, K_bar) with K_bar = K + k_m V V^T."""
    from ..structure.analytic import analytic_relations
    from ..structure import modal_basis

    sys3 = system_3d(rig, law, encoder_position)
    rel = analytic_relations(
        sys3["structure"].K, sys3["k_m"], sys3["V"], sys3["W"], sys3["F0"], sys3["F_S"],
        rig.pair.base_helix_angle_rad,
    )
    modes = modal_basis(np.asarray(sys3["structure"].M), rel["K_bar"], n_modes=n_frequencies)
    return {
        "n_dof": int(sys3["structure"].n_dof),
        "encoder_position": encoder_position,
        "C_vv_times_km": float(rel["C_vv_times_km"]),
        "C_wv_times_km_cos_beta_b": float(rel["C_wv_times_km_cos_beta_b"]),
        "v_x0_times_km_over_FS": float(rel["v_x0_times_km_over_FS"]),
        "w_x0_m": float(rel["w_x0"]),
        "natural_frequencies_hz": [float(f) for f in modes.frequencies_hz],
    }
