"""The Baud & Velex test rig of Velex & Ajmi, Section 6.1: every piece of its data.

* :func:`baud_velex_pair`: the Table 1 gear pair (spur or helical);
* :func:`table1_relief`: the Table 1 tip reliefs; :func:`fig5_pitch_errors`: the pinion
  pitch errors standing in for Fig. 5;
* :data:`PINION_TORQUE_NM`: the operating torque (254.8 N m on the pinion);
* :func:`baud_velex_structure`: the shaft lines, bearings (Table 2), nodes and encoder
  positions (Fig. 6, Fig. 7), described below;
* :func:`baud_velex_rig`: all of it as a :class:`gearjax.rigs.rig.Rig` (the built-in rigs
  ``baud-velex-spur`` and ``baud-velex-helical``).

Shaft-line structure (Fig. 6)
-----------------------------

The paper's model has 43 nodes x 6 dof = 258 dof and "40 elements (including a
pinion-gear element)"; only the bearing data (Table 2) and gear data (Table 1) are
printed. This module builds the shafts, discs, bearings, couplings and the resisting
load; the pinion-gear element is added by the mesh core at :data:`PINION_NODE` and
:data:`GEAR_NODE`.

Layout (paper numbers are 1-based; code indices are 0-based = paper - 1)
------------------------------------------------------------------------
::

    pinion line (nodes 1-21)                      gear line (nodes 22-43)

    1   free end of pinion shaft (encoder pos. 2) 22  free end of load shaft; resisting
    5   bearing, 1e9 N/m in S and T                   load = torsional spring to ground
    7   PINION CENTRE O1 (encoder pos. 1)         23  bearing 7e7 N/m in S and T
    9   bearing, 1e9 N/m in S and T               25  bearing 7e7 N/m in S and T
    13  thrust bearing, 3.5e7 N/m axial           27  load-shaft coupling hub
    20  coupling hub on pinion shaft (enc. pos 3) 28  gear-shaft coupling hub (enc. pos 3)
    21  motor rotor (input torque C_m)            33  bearing 1e9 N/m in S and T
                                                  35  GEAR CENTRE O2 (encoder pos. 1)
                                                  37  bearing 1e9 N/m in S and T
                                                  41  thrust bearing, 6e7 N/m axial
                                                  43  free end of gear shaft (encoder pos 2)

* Pinion shaft: Timoshenko chain 1-20 (19 elements); flexible coupling 20-21;
  motor rotor 21 (a single node).
* Gear line: load (output) shaft 22-27 (5 elements), flexible coupling 27-28, gear
  shaft 28-43 (15 elements).
* 39 shaft elements + the pinion-gear element = the 40 elements of the paper; the two
  couplings are counted as connection springs, like the bearings.

The bearings of Table 2 are applied exactly (zero tilting stiffness). With this
topology the structure alone has exactly one rigid-body mode: the rotation of the
whole pinion line (motor + pinion shaft) about its axis, which the pinion-gear element
removes (``K + k_m V V^T`` is invertible, Section 4.2).

Assumptions (the paper does not print them; chosen for a 4 mm module, z = 26/157 rig)
----------------------------------------------------------------------------------------
* Steel everywhere: E = 210 GPa, nu = 0.3, rho = 7800 kg/m^3.
* Pinion shaft (z from -0.25 m to +0.65 m, pinion centre at z = 0): diameter 45 mm from
  the free end to bearing 5, 60 mm between bearings 5 and 9 (bearing seats and pinion
  core), 50 mm from bearing 9 to the coupling. Bearings at z = -/+0.10 m, thrust
  bearing at z = 0.30 m, coupling at z = 0.65 m.
* Pinion body: rigid annulus, outer diameter = pitch diameter 104 mm, bore 60 mm,
  face width 50 mm (Table 1): m = 2.21 kg, I_p = 4.0e-3 kg m^2. The pinion body's
  contribution to shaft bending stiffness is ignored (the shaft under it keeps 60 mm).
* Gear shaft (z from -0.60 m to +0.45 m, gear centre at z = 0): diameter 65 mm, 80 mm
  between bearings 33 and 37. Bearings at z = -/+0.11 m, thrust bearing at z = 0.35 m.
* Gear body: rigid solid-web annulus, outer diameter = pitch diameter 628 mm, bore 80 mm,
  face width 40 mm (Table 1): m = 95.1 kg, I_p = 4.76 kg m^2.
* Load shaft: 60 mm, z from -1.10 m to -0.60 m, bearings (Table 2, 7e7 N/m) at
  z = -1.00 and -0.80 m, coupling at z = -0.60 m.
* Couplings are zero-length 6-dof springs between coincident nodes. Motor side
  (20-21): torsion 5e4 N m/rad, radial 2e7 N/m, axial 5e6 N/m, tilt 1e4 N m/rad. Load
  side (27-28): torsion 2e5 N m/rad, radial 5e7 N/m, axial 1e7 N/m, tilt 5e4 N m/rad.
  Coupling hubs: annuli 120 mm x shaft bore x 60 mm at nodes 20, 27, 28 (3.7-4.4 kg).
* Helical variant: pass ``centre_distance_m=pair.centre_distance_m`` (0.3895 m for
  beta = 20 deg); the shafts are unchanged.
* Motor rotor (node 21): steel cylinder 160 mm x 300 mm (m = 47 kg, I_p = 0.15 kg m^2).
  The motor's own bearings are not in Table 2; they are taken as rigid-ish supports of
  the rotor node in every dof but torsion (1e9 N/m radial, 1e8 N/m axial, 1e7 N m/rad
  tilting), so the motor adds its inertia to the torsional dynamics only.
* Resisting load: torsional stiffness 1e5 N m/rad from node 22 to ground ("the
  resisting load is given by a torsional stiffness at one free end of the gear shaft").
* Geometry: shafts parallel to z. The pinion axis is the z axis (S = T = 0); the gear
  axis passes through ``O2 = O1 + a (cos g, sin g, 0)`` with ``a`` the centre distance
  (default 0.366 m = m (z1 + z2) / 2 for the spur pair, x1 + x2 = 0) and ``g`` the
  centre-line angle measured from S towards T. The default ``g = alpha_w - pi/2``
  (``alpha_w`` the working transverse pressure angle, 20 deg for the spur pair) matches the
  frame of :mod:`gearjax.structure.element`: S along the line of action from T1 to T2 and
  ``O2 = O1 + a (sin alpha_w S - cos alpha_w T)``. The pinion and gear centres share the
  plane z = 0. The positions are metadata (the dofs are the same in any layout).

Encoder positions (Fig. 7; the figure is not reproduced in the text)
--------------------------------------------------------------------
1. pinion centre 7 and gear centre 35 (the reference of Section 6.2);
2. the free ends 1 and 43, outside the torque path (same static twist as position 1,
   different dynamic one);
3. the coupling-side hubs 20 and 28, on the torque path between the mesh and the
   motor / load (a different static twist, hence a different ``w_x0``).
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import ModificationError
from ..gears.geometry import GearPair
from ..gears.modifications import ReliefShape, ToothModifications
from ..structure.assembly import Structure, StructureBuilder, StructureInputError
from ..structure.beams import STEEL, Material, disc_properties
from .rig import Rig

__all__ = [
    "PINION_TORQUE_NM",
    "baud_velex_pair",
    "table1_relief",
    "fig5_pitch_errors",
    "baud_velex_rig",
    "BAUD_VELEX_BEARINGS",
    "ENCODER_POSITIONS",
    "GEAR_NODE",
    "LOAD_NODE",
    "MOTOR_NODE",
    "N_NODES",
    "PINION_NODE",
    "baud_velex_structure",
    "encoder_nodes",
    "paper_node",
]

PINION_TORQUE_NM: float = 254.8
"""Operating torque on the pinion C_m0 (N m), Section 6.1."""


def baud_velex_pair(helical: bool = False) -> GearPair:
    """Table 1 gear pair of the Baud & Velex test rig (Section 6.1).

    Module 4 mm, 26/157 teeth, 20 deg pressure angle, helix 0 (spur) or 20 deg (helical),
    addendum 1, dedendum 1.46, shifts +0.16/-0.16, face widths 50/40 mm. The module is
    taken as the normal module for the helical variant.
    """
    return GearPair(
        normal_module_m=4e-3,
        z1=26,
        z2=157,
        normal_pressure_angle_rad=math.radians(20.0),
        helix_angle_rad=math.radians(20.0) if helical else 0.0,
        profile_shift1=0.16,
        profile_shift2=-0.16,
        addendum_coeff1=1.0,
        addendum_coeff2=1.0,
        dedendum_coeff1=1.46,
        dedendum_coeff2=1.46,
        face_width1_m=0.050,
        face_width2_m=0.040,
    )


def table1_relief(kind: str = "short", shape: ReliefShape = "linear") -> ToothModifications:
    """Table 1 tip reliefs: 13.3 um on both gears, extent 0.2 (short) or 0.5 (long)."""
    extents = {"short": 0.2, "long": 0.5}
    if kind == "none":
        return ToothModifications.none()
    if kind not in extents:
        raise ModificationError(f"relief={kind!r}: expected 'none', 'short' or 'long'")
    return ToothModifications.tip_relief(13.3e-6, extents[kind], shape)


def fig5_pitch_errors(z1: int = 26, amplitude_m: float = 12e-6) -> np.ndarray:
    """Cumulative pitch deviations of the pinion (m), standing in for the paper's Fig. 5.

    The paper prints the distribution only as a figure. We use a realistic
    cumulative pattern for a ground 26-tooth pinion: a once-per-revolution sinusoid of
    ``amplitude_m`` (runout-like envelope) plus a fixed pattern of individual single-pitch
    deviations of about 2 um (seeded, reproducible), with the first tooth as datum (0).
    """
    n = np.arange(z1)
    rng = np.random.default_rng(1995)
    single = rng.normal(0.0, 2e-6, z1)
    cumulative = amplitude_m * np.sin(2 * np.pi * n / z1) + np.cumsum(single - single.mean())
    return cumulative - cumulative[0]


N_NODES: int = 43


def paper_node(n: int) -> int:
    """0-based index of the paper's (1-based) node number ``n``."""
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or not 1 <= n <= N_NODES:
        raise StructureInputError(f"n must be a paper node number in [1, {N_NODES}], got {n!r}")
    return int(n) - 1


PINION_NODE: int = paper_node(7)
"""Pinion centre O1 (0-based; paper node 7)."""
GEAR_NODE: int = paper_node(35)
"""Gear centre O2 (0-based; paper node 35)."""
MOTOR_NODE: int = paper_node(21)
"""Motor rotor, where the input torque C_m (254.8 N m) is applied (0-based; paper 21)."""
LOAD_NODE: int = paper_node(22)
"""Free end of the gear line carrying the resisting torsional stiffness (paper 22)."""

BAUD_VELEX_BEARINGS: dict[int, tuple[float, float, float]] = {
    5: (1e9, 1e9, 0.0),
    9: (1e9, 1e9, 0.0),
    13: (0.0, 0.0, 3.5e7),
    23: (7e7, 7e7, 0.0),
    25: (7e7, 7e7, 0.0),
    33: (1e9, 1e9, 0.0),
    37: (1e9, 1e9, 0.0),
    41: (0.0, 0.0, 6e7),
}
"""Table 2: paper node (1-based) -> (k_S, k_T, k_axial) in N/m."""

ENCODER_POSITIONS: dict[int, tuple[int, int]] = {
    1: (PINION_NODE, GEAR_NODE),
    2: (paper_node(1), paper_node(43)),
    3: (paper_node(20), paper_node(28)),
}
"""Fig. 7 encoder positions -> (node I on the pinion line, node II on the gear line), 0-based."""


def encoder_nodes(position: int) -> tuple[int, int]:
    """Nodes ``(I, II)`` (0-based) of encoder position 1, 2 or 3 (Fig. 7, Eq. (9))."""
    if position not in ENCODER_POSITIONS:
        raise StructureInputError(
            f"position must be one of {sorted(ENCODER_POSITIONS)}, got {position!r}"
        )
    return ENCODER_POSITIONS[position]


# Axial coordinates (m) of the three shaft chains, paper node numbers in comments.
_PINION_Z = np.array(
    [-0.250, -0.210, -0.170, -0.135, -0.100, -0.025, 0.000, 0.025, 0.100, 0.150,  # 1-10
     0.200, 0.250, 0.300, 0.350, 0.400, 0.450, 0.500, 0.550, 0.600, 0.650]  # 11-20
)  # fmt: skip
_PINION_D = np.array([0.045] * 4 + [0.060] * 4 + [0.050] * 11)
_LOAD_Z = np.array([-1.100, -1.000, -0.900, -0.800, -0.700, -0.600])  # 22-27
_GEAR_Z = np.array(
    [-0.600, -0.500, -0.400, -0.300, -0.200, -0.110, -0.020, 0.000, 0.020, 0.110,  # 28-37
     0.170, 0.230, 0.290, 0.350, 0.400, 0.450]  # 38-43
)  # fmt: skip
_GEAR_D = np.array([0.065] * 5 + [0.080] * 4 + [0.065] * 6)


def baud_velex_structure(
    *,
    centre_distance_m: float = 0.366,
    centre_line_angle_rad: float | None = None,
    working_pressure_angle_rad: float = math.radians(20.0),
    load_torsional_stiffness: float = 1e5,
    material: Material = STEEL,
) -> Structure:
    """Shafts, discs, bearings and couplings of the Baud & Velex rig (Fig. 6, Table 2).

    43 nodes, 258 dof, everything except the pinion-gear element. See the module
    docstring for the layout and every assumed dimension.

    Parameters
    ----------
    centre_distance_m : float
        Distance between the pinion and gear axes (m).
    centre_line_angle_rad : float, optional
        Direction of ``O1 -> O2`` in the (S, T) plane, from S towards T (rad). Default
        ``working_pressure_angle_rad - pi/2`` (S along the line of action, as in
        :mod:`gearjax.structure.element`).
    working_pressure_angle_rad : float
        Working transverse pressure angle ``alpha_w`` (rad) used by the default above
        (``pair.working_pressure_angle_rad``; 20 deg for the spur pair of Table 1).
    load_torsional_stiffness : float
        Resisting-load torsional stiffness at node 22 (N m/rad).
    material : Material
        Shaft and disc material.

    Returns
    -------
    Structure
        With ``pinion_node = PINION_NODE`` (paper 7) and ``gear_node = GEAR_NODE``
        (paper 35); node lines ``"pinion"`` (paper 1-21) and ``"gear"`` (22-43).
    """
    a = float(centre_distance_m)
    if not (math.isfinite(a) and a > 0.0):
        raise StructureInputError(
            f"centre_distance_m must be finite and > 0, got {centre_distance_m!r}"
        )
    aw = float(working_pressure_angle_rad)
    if not (math.isfinite(aw) and 0.0 < aw < math.pi / 2):
        raise StructureInputError(
            f"working_pressure_angle_rad must lie in (0, pi/2), got {working_pressure_angle_rad!r}"
        )
    g = aw - math.pi / 2 if centre_line_angle_rad is None else float(centre_line_angle_rad)
    if not math.isfinite(g):
        raise StructureInputError(
            f"centre_line_angle_rad must be finite, got {centre_line_angle_rad!r}"
        )
    gear_axis = (a * math.cos(g), a * math.sin(g))
    rho = material.rho
    P = paper_node

    b = StructureBuilder(n_nodes=N_NODES)
    # --- pinion line ------------------------------------------------------------
    b.add_shaft(
        [P(i) for i in range(1, 21)],
        positions_m=_PINION_Z,
        outer_diameters_m=_PINION_D,
        material=material,
        line="pinion",
        name="pinion_shaft",
    )
    b.set_node(P(21), position_m=(0.0, 0.0, _PINION_Z[-1]), line="pinion")
    m, it, ip = disc_properties(0.104, 0.060, 0.050, rho)
    b.add_disc(P(7), mass_kg=m, transverse_inertia_kg_m2=it, polar_inertia_kg_m2=ip, name="pinion")
    m, it, ip = disc_properties(0.120, 0.050, 0.060, rho)
    b.add_disc(P(20), mass_kg=m, transverse_inertia_kg_m2=it, polar_inertia_kg_m2=ip,
               name="motor_coupling_hub_pinion_side")  # fmt: skip
    m, it, ip = disc_properties(0.160, 0.0, 0.300, rho)
    b.add_disc(P(21), mass_kg=m, transverse_inertia_kg_m2=it, polar_inertia_kg_m2=ip,
               name="motor_rotor")  # fmt: skip
    b.add_coupling(P(20), P(21), k_torsion=5e4, k_radial=2e7, k_axial=5e6, k_tilt=1e4,
                   name="motor_coupling")  # fmt: skip
    b.add_bearing(P(21), 1e9, 1e9, 1e8, k_phi=1e7, k_psi=1e7, name="motor_support (assumed)")

    # --- gear line ------------------------------------------------------------------
    b.add_shaft(
        [P(i) for i in range(22, 28)],
        positions_m=_LOAD_Z,
        outer_diameters_m=0.060,
        material=material,
        axis_st_m=gear_axis,
        line="gear",
        name="load_shaft",
    )
    b.add_shaft(
        [P(i) for i in range(28, 44)],
        positions_m=_GEAR_Z,
        outer_diameters_m=_GEAR_D,
        material=material,
        axis_st_m=gear_axis,
        line="gear",
        name="gear_shaft",
    )
    m, it, ip = disc_properties(0.628, 0.080, 0.040, rho)
    b.add_disc(P(35), mass_kg=m, transverse_inertia_kg_m2=it, polar_inertia_kg_m2=ip, name="gear")
    m, it, ip = disc_properties(0.120, 0.060, 0.060, rho)
    b.add_disc(P(27), mass_kg=m, transverse_inertia_kg_m2=it, polar_inertia_kg_m2=ip,
               name="load_coupling_hub_load_side")  # fmt: skip
    m, it, ip = disc_properties(0.120, 0.065, 0.060, rho)
    b.add_disc(P(28), mass_kg=m, transverse_inertia_kg_m2=it, polar_inertia_kg_m2=ip,
               name="load_coupling_hub_gear_side")  # fmt: skip
    b.add_coupling(P(27), P(28), k_torsion=2e5, k_radial=5e7, k_axial=1e7, k_tilt=5e4,
                   name="load_coupling")  # fmt: skip
    b.add_torsional_spring_to_ground(P(22), load_torsional_stiffness, name="resisting_load")

    # --- Table 2 bearings ----------------------------------------------------------------
    for n, (ks, kt, kz) in BAUD_VELEX_BEARINGS.items():
        b.add_bearing(P(n), ks, kt, kz, name=f"bearing_{n}")

    labels = {
        1: "pinion shaft free end (encoder pos. 2)",
        7: "pinion centre O1",
        20: "motor coupling hub, pinion side (encoder pos. 3)",
        21: "motor rotor",
        22: "load shaft free end (resisting load)",
        27: "load coupling hub, load side",
        28: "load coupling hub, gear side (encoder pos. 3)",
        35: "gear centre O2",
        43: "gear shaft free end (encoder pos. 2)",
    }
    for n, (ks, kt, kz) in BAUD_VELEX_BEARINGS.items():
        labels.setdefault(n, "thrust bearing" if kz else "radial bearing")
    for n in range(1, N_NODES + 1):
        b.set_node(P(n), label=f"P{n}: {labels.get(n, 'shaft')}")
    b.set_pinion_node(PINION_NODE).set_gear_node(GEAR_NODE)
    return b.build()


def _rig_structure(pair: GearPair) -> Structure:
    """The rig's structure with the centre line of ``pair`` (centre distance, working
    pressure angle)."""
    return baud_velex_structure(
        centre_distance_m=pair.centre_distance_m,
        working_pressure_angle_rad=pair.working_pressure_angle_rad,
    )


def baud_velex_rig(helical: bool = False) -> Rig:
    """The Baud & Velex rig (Section 6.1): Table 1 gears, 254.8 N m on the pinion (applied
    at the motor node), the Table 2 structure, the Fig. 7 encoder positions, the Table 1
    relief presets and the Fig. 5 stand-in pitch errors."""
    pair = baud_velex_pair(helical)
    kind = "helical (beta = 20 deg)" if helical else "spur"
    return Rig(
        name="baud-velex-helical" if helical else "baud-velex-spur",
        pair=pair,
        pinion_torque_Nm=PINION_TORQUE_NM,
        pinion_pitch_errors_m=fig5_pitch_errors(pair.z1),
        description=f"Baud & Velex test rig, {kind}, Table 1 gears, 254.8 N m on the pinion",
        structure_factory=_rig_structure,
        motor_node=MOTOR_NODE,
        encoder_positions=dict(ENCODER_POSITIONS),
        relief_presets=table1_relief,
    )
