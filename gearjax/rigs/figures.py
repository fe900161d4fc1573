"""Figures of a rig: what ``gearjax info`` prints (mesh stiffness, torsional and ISO 6336
resonance speeds, the 3D dof count, the Appendix A relations, natural frequencies) and the
critical speeds predicted from a model's modes (the mesh receptance C_vv(omega))."""

from __future__ import annotations

import math

import numpy as np

from ..gears.geometry import STEEL_DENSITY_KG_M3, GearPair
from ..gears.iso6336 import resonance_speed
from ..gears.mesh import Mesh
from ..gears.quasistatic import static_mesh_force
from ..models.torsional import TorsionalModel, solid_cylinder_inertias
from ..structure import modal_basis
from ..structure.analytic import analytic_relations
from ..structure.element import PinionGearElement
from .campbell import mode_shares
from .rig import Rig

__all__ = ["torsional_stiffness_figures", "iso6336_resonance_speed", "system_3d",
           "three_d_figures", "predicted_critical_speeds", "rig_critical_speeds"]


def torsional_stiffness_figures(rig: Rig, law: str = "iso6336") -> dict:
    """Mesh figures of a rig at its nominal torque (used by ``gearjax info``)."""
    mesh = Mesh.build(rig.pair, law, pinion_torque_Nm=rig.pinion_torque_Nm)
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
                            density_kg_m3: float = STEEL_DENSITY_KG_M3) -> float:
    """Pinion resonance speed of ISO 6336-1 (method B, solid gear bodies), in rad/s.

    ``n_E1 = 30000 / (pi z1) sqrt(c_gamma_alpha / m_red)`` (1/min) with the reduced mass per
    unit face width ``m_red = m1* m2* / (m1* + m2*)``, ``m_i* = pi rho d_mi^4 / (8 d_bi^2)``
    (``d_m`` the mean of tip and root diameters) and ``c_gamma_alpha = k_m / b``; in rad/s
    ``Omega_E1 = sqrt(c_gamma_alpha / m_red) / z1``.
    """
    return resonance_speed(pair, mean_stiffness_N_per_m / pair.face_width_m, density_kg_m3)


def system_3d(rig: Rig, law: str = "iso6336", encoder_position: int = 1):
    """The 3D pieces of a rig used by ``gearjax info``.

    Returns a dict with ``structure``, ``mesh``, ``element`` (pinion-gear element),
    ``V`` (averaged structure vector), ``W`` (TE projection at the encoder nodes of Fig. 7
    position ``encoder_position``), ``F0`` (pinion torque on the motor's torsional dof,
    N m), ``k_m`` (mean mesh stiffness, N/m) and ``F_S`` (N).
    """
    structure = rig.structure()
    mesh = Mesh.build(rig.pair, law, pinion_torque_Nm=rig.pinion_torque_Nm)
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


# the receptance peak search: this many speeds from 0 to SPAN x the highest critical
# speed of a mode carrying at least MIN_SHARE of the mesh strain energy
GRID_POINTS = 6000
GRID_SPAN = 1.5
MIN_SHARE = 0.01


def _receptance_peak(w, v, k_m: float, zeta: float, z1: int, n: int, speeds_rad_s=None) -> dict:
    """The critical speeds of modes ``w`` (rad/s, mass-normalised, the first ``n`` true
    modes) with mesh components ``v = phi^T V``: see :func:`predicted_critical_speeds`."""
    w = np.asarray(w, dtype=float)
    v = np.asarray(v, dtype=float)
    share = mode_shares(w[:n], v[:n], k_m)
    j = int(np.argmax(share))
    top = GRID_SPAN * float(np.max(w[:n][share >= MIN_SHARE * share[j]])) / z1
    speeds = np.linspace(top / GRID_POINTS, top, GRID_POINTS)
    if speeds_rad_s is not None:
        speeds = np.union1d(speeds, np.asarray(speeds_rad_s, dtype=float).reshape(-1))
    om = z1 * speeds
    c = np.sum(v[None, :] ** 2 / (w[None, :] ** 2 - om[:, None] ** 2
                                  + 2j * zeta * w[None, :] * om[:, None]), axis=1)
    amp = np.abs(k_m * c - 1.0)
    i = int(np.argmax(amp))
    return {"mode_frequency_hz": float(w[j] / (2 * math.pi)), "mesh_energy_share": float(share[j]),
            "mode_critical_speed_rad_s": float(w[j] / z1),
            "critical_speed_rad_s": float(speeds[i]), "mesh_amplification_at_peak": float(amp[i]),
            "searched_rad_s": [float(speeds[0]), float(speeds[-1])]}


def predicted_critical_speeds(model, speeds_rad_s=None) -> dict:
    """Main tooth critical pinion speed predicted from the modes (``Omega1 = omega / z1``).

    * ``mode_*``: the mode with the largest share of strain energy in the mesh,
      ``k_m (phi^T V)^2 / omega^2`` (mass-normalised modes of ``(M, K_bar)``; the shares sum
      to ``k_m C_vv = 1``, Eq. (33)).
    * ``critical_speed_rad_s``: the peak of the mesh dynamic amplification ``|k_m
      C_vv(omega) - 1|`` at the mesh frequency ``omega = z1 Omega1``, with the receptance
      ``C_vv(omega) = sum_j (phi_j^T V)^2 / (omega_j^2 - omega^2 + 2 i zeta omega_j
      omega)`` (Eq. (33) at frequency omega): the ratio of the dynamic to the quasi-static
      mesh deflection for the first mesh harmonic of a TE excitation (Eq. (48a)); it
      accounts for close modes sharing the mesh energy. Searched over the model's own
      range: :data:`GRID_POINTS` speeds up to :data:`GRID_SPAN` times the highest critical
      speed of a mode with at least :data:`MIN_SHARE` of the largest mesh-energy share
      (``searched_rad_s``), plus ``speeds_rad_s`` (rad/s) if given.
    * sdof model (:class:`TorsionalModel`): ``omega_n`` for both.
    """
    z1 = model.mesh.pair.z1
    if isinstance(model, TorsionalModel):
        w = float(model.natural_frequency_rad_s())
        return {"mode_frequency_hz": w / (2 * math.pi), "mesh_energy_share": 1.0,
                "mode_critical_speed_rad_s": w / z1, "critical_speed_rad_s": w / z1}
    return _receptance_peak(model.omega_r, model.v_r, float(model.k_m),
                            float(model.damping_ratio), z1, model.n_modes, speeds_rad_s)


def rig_critical_speeds(rig: Rig, law: str = "iso6336", model: str = "3d",
                        damping_ratio: float = 0.1) -> dict:
    """:func:`predicted_critical_speeds` of a rig before any dynamic model is built (the
    default speed ranges of the command line): ``"torsional"``, ``omega_n / z1`` of the
    sdof model with its default inertias (:func:`torsional_stiffness_figures`); ``"3d"``,
    the receptance peak of every mode of ``(M, K + k_m V V^T)`` (no modal cut-off) at
    modal damping ``damping_ratio``. Speeds in rad/s."""
    if model == "torsional":
        w = torsional_stiffness_figures(rig, law)["torsional_critical_speed_rad_s"]
        return {"mode_frequency_hz": w * rig.pair.z1 / (2 * math.pi), "mesh_energy_share": 1.0,
                "mode_critical_speed_rad_s": w, "critical_speed_rad_s": w}
    sys3 = system_3d(rig, law)
    V, k_m = sys3["V"], sys3["k_m"]
    modes = modal_basis(np.asarray(sys3["structure"].M),
                        np.asarray(sys3["structure"].K) + k_m * np.outer(V, V), warn=False)
    phi = np.asarray(modes.modes)
    return _receptance_peak(modes.omegas_rad_s, phi.T @ V, k_m, damping_ratio, rig.pair.z1,
                            phi.shape[1])
