"""User rig files in TOML: :func:`load_rig` turns a file into a :class:`gearjax.rigs.rig.Rig`.

A rig file describes everything Section 6.1 of Velex & Ajmi needs for a geared test rig:
the gear pair (Table 1), the operating torque, the shaft lines (Timoshenko elements), the
rigid discs, the bearings (Table 2), the couplings, the resisting-load torsional spring, the
pinion / gear / motor nodes, the encoder positions of Fig. 7 and, optionally, the tooth
modifications. ``examples/rigs/baud_velex_spur.toml`` reproduces the built-in
``baud-velex-spur`` rig (same ``M`` and ``K``); every CLI command accepts
``--rig FILE.toml``.

Any problem in a file raises :class:`gearjax.errors.RigError` whose message names the
field path (``bearing[2].k_S_N_per_m``; array-of-table indices are 0-based, in file
order), the value found and why it is wrong. Unknown keys are errors too (with a
"did you mean" suggestion), so a typo never silently falls back to a default.

Schema (SI units; the unit is in each key name)
-----------------------------------------------
::

    name = "my-rig"            # optional, default the file stem
    description = "..."        # optional
    first_node = 1             # optional (0 or 1, default 0): number of the first node
    pinion_node = 7            # node of the pinion centre O1            (required)
    gear_node = 35             # node of the gear centre O2              (required)
    motor_node = 21            # node whose torsion carries C_m0         (required)

    [gear_pair]                # gearjax.GearPair fields
    normal_module_m = 4e-3     # required
    z1 = 26                    # required
    z2 = 157                   # required
    normal_pressure_angle_deg = 20.0   # or normal_pressure_angle_rad (default 20 deg)
    helix_angle_deg = 0.0              # or helix_angle_rad (default 0)
    profile_shift1 = 0.16      # optional, as the GearPair defaults:
    profile_shift2 = -0.16     #   profile_shift1/2, addendum_coeff1/2,
    addendum_coeff1 = 1.0      #   dedendum_coeff1/2, face_width1_m/face_width2_m
    ...
    backlash_m = 1e-4          # optional: clearance between the back flanks (normal
                               #   backlash along the line of action, m, in [0, m_n]);
                               #   default none: the back flanks never meet

    [operating]
    pinion_torque_Nm = 254.8   # required, > 0

    [materials.steel]          # optional; "steel" (210 GPa, 0.3, 7800 kg/m^3) is predefined
    E_Pa = 2.1e11
    nu = 0.3
    rho_kg_per_m3 = 7800.0

    [[shaft]]                  # a chain of Timoshenko elements along z
    name = "pinion_shaft"      # optional
    line = "pinion"            # shaft line of its nodes (default: name); all nodes that
                               #   turn with the pinion share one line, same for the gear
    nodes = [1, 2, 3, 4]       # or node_range = [1, 20] (inclusive)
    z_m = [0.0, 0.1, 0.2, 0.3] # node positions, strictly increasing
                               #   or lengths_m = [...] (one per element) + start_z_m = 0.0
    outer_diameter_m = 0.05    # one value, or one per element
    inner_diameter_m = 0.0     # optional, idem
    material = "steel"         # optional
    axis = "pinion"            # optional: "pinion" (S = T = 0) or "gear" (centre distance
                               #   of the gear pair, along the centre line); or
                               #   axis_st_m = [S, T] (positions are metadata only)
    shear_coefficient = 0.9    # optional (default Hutchinson's value for the section)

    [[node]]                   # a node that is on no shaft (motor rotor), or a label
    node = 21
    line = "pinion"            # optional
    z_m = 0.65                 # optional; axis / axis_st_m as for shafts
    label = "motor rotor"      # optional

    [[disc]]                   # rigid disc lumped at a node (Eq. (13), no gyroscopic terms)
    node = 7
    outer_diameter_m = 0.104   # annulus: outer_diameter_m, inner_diameter_m, width_m
    inner_diameter_m = 0.060   #   (+ material), or mass_kg, transverse_inertia_kg_m2,
    width_m = 0.050            #   polar_inertia_kg_m2 directly
    name = "pinion"            # optional

    [[bearing]]                # node to rigid housing (Table 2); never restrains torsion
    node = 5
    k_S_N_per_m = 1e9          # required
    k_T_N_per_m = 1e9          # required
    k_axial_N_per_m = 0.0      # optional
    k_phi_Nm_per_rad = 0.0     # optional tilting stiffness about S
    k_psi_Nm_per_rad = 0.0     # optional tilting stiffness about T

    [[coupling]]               # zero-length 6-dof spring between two nodes
    nodes = [20, 21]
    k_torsion_Nm_per_rad = 5e4 # required
    k_radial_N_per_m = 2e7     # optional (S and T)
    k_axial_N_per_m = 5e6      # optional
    k_tilt_Nm_per_rad = 1e4    # optional (about S and T)

    [[torsional_spring]]       # node torsion to ground: the resisting load (Section 6.1)
    node = 22
    k_Nm_per_rad = 1e5

    [encoders]                 # optional: Fig. 7 position -> [node I (pinion line),
    1 = [7, 35]                #   node II (gear line)]; default 1 = [pinion_node, gear_node]
    2 = [1, 43]

    [iso6336]                  # optional: ISO 6336-1 method-B data (gearjax.gears.iso6336)
    accuracy_grade = 5         # ISO 1328-1 grade for f_pb, f_falpha when not given (default 5)
    base_pitch_deviation_m = 9e-6      # f_pb (optional)
    profile_form_deviation_m = 12e-6   # f_falpha (optional)
    tip_relief_m = 70e-6       # C_a (optional; default the scenario's tip relief, else C_ay)
    application_factor = 1.0   # K_A (default 1)
    sigma_hlim_Pa = 1.5e9      # sigma_Hlim for C_ay (default 1500 N/mm^2)
    rated_speed_rad_s = 37.7   # pinion speed of the K_v that `gearjax info` reports

    [modifications]            # optional: the rig's default tooth modifications
    relief_shape = "linear"    # "linear" or "parabolic" (both gears)
    crowning_m = 0.0           # optional composite lead crowning
    [modifications.pinion]     # and [modifications.gear], each optional:
    relief_amplitude_m = 13.3e-6   # tip relief P_c (default 0)
    relief_extent = 0.2            # L_c, fraction of the path of contact (default 0.5)
    pitch_errors_m = [...]         # z1 (z2) cumulative pitch deviations
    eccentricity_m = 0.0           # with eccentricity_phase_rad

Nodes are declared by the shafts' node lists and the ``[[node]]`` tables; they must be
numbered ``first_node, first_node + 1, ...`` without gaps, and every other reference
(disc, bearing, coupling, pinion/gear/motor node, encoders) must name a declared node.
Internally nodes are 0-based (``index = number - first_node``); the returned
:class:`~gearjax.rigs.rig.Rig` uses internal indices, messages use the file's numbers.

Checks made at load time, beyond types and ranges: the gear pair is valid
(:class:`~gearjax.gears.geometry.GearPair`), every dof of every node has mass, the pinion and
gear nodes are on different shaft lines, no node is on two shaft lines, every number is in
its physical range (:data:`gearjax.rigs.rigfile_checks.RANGES`: stiffnesses up to 1e16 N/m and
1e9 N m/rad, diameters 1 mm-10 m, elements at least 0.1 mm long, ...; a value outside is named
with its range before any modal analysis), and the structure without the mesh has at most one
rigid-body mode (the free rotation of the driving line, which the pinion-gear element removes,
Section 4.2; extra zero-frequency modes that are only round-off of a too wide stiffness range
are reported as such, not as missing supports).
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any

import numpy as np

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib  # type: ignore[no-redef]

from ..gears.geometry import GearPair, GeometryError
from ..gears.iso6336 import AccuracyData
from ..gears.modifications import ModificationError, ToothModifications
from ..errors import RigError
from .baud_velex import table1_relief
from .rig import Rig
from .rigfile_checks import (AXIS_KEYS, MIN_ELEMENT_LENGTH_M, REQUIRED, Nodes, Reader,
                             per_element, read_axis, read_backlash, table_list)
from ..structure.assembly import Structure, StructureBuilder
from ..structure.modal import modal_basis, scaled_null_dimension
from ..structure.beams import DOF_NAMES, STEEL, ElementInputError, Material, disc_properties

__all__ = ["load_rig", "parse_rig"]

# ---------------------------------------------------------------------------- sections
_PAIR_ANGLES = ("normal_pressure_angle", "helix_angle")
_PAIR_NUMBERS = ("profile_shift1", "profile_shift2", "addendum_coeff1", "addendum_coeff2",
                 "dedendum_coeff1", "dedendum_coeff2", "face_width1_m", "face_width2_m")


def _gear_pair(root: Reader) -> GearPair:
    allowed = (("normal_module_m", "z1", "z2", "backlash_m") + _PAIR_NUMBERS
               + tuple(f"{a}_{u}" for a in _PAIR_ANGLES for u in ("rad", "deg")))
    if not root.has("gear_pair"):
        root.missing("gear_pair", "the [gear_pair] table")
    r = Reader(root.source, "gear_pair", root.data["gear_pair"], allowed)
    kw: dict[str, Any] = {
        "normal_module_m": r.get("normal_module_m", "positive", "normal module, m"),
        "z1": r.get("z1", "int", "pinion tooth number"),
        "z2": r.get("z2", "int", "gear tooth number"),
    }
    for a in _PAIR_ANGLES:
        if r.has(f"{a}_rad") and r.has(f"{a}_deg"):
            r.fail(r.sub(f"{a}_deg"), r.data[f"{a}_deg"], f"give either {a}_rad or {a}_deg, not both")
        if r.has(f"{a}_deg"):
            kw[f"{a}_rad"] = math.radians(r.get(f"{a}_deg", "real", "degrees"))
        elif r.has(f"{a}_rad"):
            kw[f"{a}_rad"] = r.get(f"{a}_rad", "real", "radians")
    for k in _PAIR_NUMBERS:
        if r.has(k):
            kw[k] = r.get(k, "real", "see gearjax.GearPair")
    try:
        return GearPair(**kw)
    except GeometryError as exc:
        field = exc.field
        for a in _PAIR_ANGLES:  # report the key the user wrote
            if field == f"{a}_rad" and r.has(f"{a}_deg"):
                field = f"{a}_deg"
        value = r.data.get(field, exc.value)
        reason = str(exc).split(": ", 1)[-1]
        r.fail(r.sub(field), value, reason)


def _materials(root: Reader) -> dict[str, Material]:
    mats = {"steel": STEEL}
    if not root.has("materials"):
        return mats
    table = root.data["materials"]
    if not isinstance(table, dict):
        root.fail("materials", table, "must be a table of [materials.NAME] tables")
    for name, data in table.items():
        r = Reader(root.source, f"materials.{name}", data, ("E_Pa", "nu", "rho_kg_per_m3"))
        E = r.get("E_Pa", "positive", "Young's modulus, Pa")
        nu = r.get("nu", "real", "Poisson's ratio")
        rho = r.get("rho_kg_per_m3", "positive", "density, kg/m^3")
        if not -1.0 < nu < 0.5:
            r.fail(r.sub("nu"), nu, "must lie in (-1, 0.5)")
        mats[name] = Material(E=E, nu=nu, rho=rho, name=name)
    return mats


def _material(r: Reader, mats: dict[str, Material]) -> Material:
    name = r.get("material", "str", "a material name", "steel")
    if name not in mats:
        r.fail(r.sub("material"), name, f"unknown material; defined: {sorted(mats)}")
    return mats[name]


_SHAFT_KEYS = ("name", "line", "nodes", "node_range", "z_m", "lengths_m", "start_z_m",
               "outer_diameter_m", "inner_diameter_m", "material", "shear_coefficient") + AXIS_KEYS


def _shaft_nodes(r: Reader) -> list[int]:
    if r.has("nodes") == r.has("node_range"):
        r.missing("nodes", "give exactly one of nodes = [...] and node_range = [first, last]")
    if r.has("nodes"):
        nodes = r.get("nodes", "ints", "node numbers along the shaft")
    else:
        ends = r.get("node_range", "ints", "[first, last] node numbers")
        if len(ends) != 2 or ends[1] <= ends[0]:
            r.fail(r.sub("node_range"), r.data["node_range"], "must be [first, last] with last > first")
        nodes = list(range(ends[0], ends[1] + 1))
    key = "nodes" if r.has("nodes") else "node_range"
    if len(nodes) < 2:
        r.fail(r.sub(key), r.data[key], "a shaft needs at least 2 nodes")
    if len(set(nodes)) != len(nodes):
        r.fail(r.sub(key), r.data[key], "node numbers must be distinct")
    return nodes


# ----------------------------------------------------------------------------- parse
def parse_rig(data: dict, source: str = "<string>", default_name: str = "rig-file") -> Rig:
    """A :class:`~gearjax.rigs.rig.Rig` from the parsed TOML ``data`` (see the module
    docstring for the schema); ``source`` names the file in error messages."""
    root = Reader(source, "", data, (
        "name", "description", "first_node", "pinion_node", "gear_node", "motor_node",
        "gear_pair", "operating", "materials", "shaft", "node", "disc", "bearing", "coupling",
        "torsional_spring", "encoders", "modifications", "iso6336"))
    name = root.get("name", "str", "rig name", default_name)
    description = root.get("description", "str", "one line", f"rig file {source}")
    first = root.get("first_node", "int", "0 or 1", 0)
    if first not in (0, 1):
        root.fail("first_node", first, "must be 0 or 1")

    pair = _gear_pair(root)
    if not root.has("operating"):
        root.missing("operating", "the [operating] table with pinion_torque_Nm")
    op = Reader(source, "operating", root.data["operating"], ("pinion_torque_Nm",))
    torque = op.get("pinion_torque_Nm", "positive", "motor torque on the pinion C_m0, N m")
    mats = _materials(root)

    # ---- declare nodes: shaft node lists and [[node]] tables
    shafts = [(p, Reader(source, p, d, _SHAFT_KEYS)) for p, d in table_list(root, "shaft")]
    node_tabs = [(p, Reader(source, p, d, ("node", "line", "z_m", "label") + AXIS_KEYS))
                 for p, d in table_list(root, "node")]
    if not shafts:
        root.missing("shaft", "at least one [[shaft]]")
    declared: set[int] = set()
    shaft_nodes = []
    for _, r in shafts:
        shaft_nodes.append(_shaft_nodes(r))
        declared.update(shaft_nodes[-1])
    for _, r in node_tabs:
        declared.add(r.get("node", "int", "node number"))
    expected = set(range(first, first + len(declared)))
    if declared != expected:
        bad = sorted(declared - expected)
        gap = sorted(expected - declared)
        detail = f"node {bad[0]} is out of sequence" if bad and bad[0] < first else (
            f"node {gap[0]} is never declared" if gap else f"node {bad[0]} is out of sequence")
        root.fail("nodes", sorted(declared), f"nodes must be numbered {first}, {first + 1}, ... "
                                             f"without gaps; {detail}")
    nodes = Nodes(first, declared)
    n_nodes = len(declared)

    # ---- element specifications (checked now, assembled by the structure factory)
    shaft_specs = []
    for (path, r), numbers in zip(shafts, shaft_nodes):
        idx = [n - first for n in numbers]
        n_el = len(idx) - 1
        if r.has("z_m") == r.has("lengths_m"):
            r.missing("z_m", "give exactly one of z_m (node positions) and lengths_m")
        if r.has("z_m"):
            z = r.get("z_m", "reals", "node positions along the shaft, m")
            if len(z) != len(idx):
                r.fail(r.sub("z_m"), r.data["z_m"], f"must list {len(idx)} positions (one per node)")
            if r.has("start_z_m"):
                r.fail(r.sub("start_z_m"), r.data["start_z_m"], "only with lengths_m")
        else:
            lengths = per_element(r, "lengths_m", n_el, "positive", "element length, m", None)
            z = list(r.get("start_z_m", "real", "position of the first node, m", 0.0)
                     + np.concatenate([[0.0], np.cumsum(lengths)]))
        for i in range(n_el):
            if not z[i + 1] > z[i]:
                r.fail(f"{r.sub('z_m')}[{i + 1}]", z[i + 1],
                       f"positions must increase strictly (previous {z[i]!r})")
            if z[i + 1] - z[i] < MIN_ELEMENT_LENGTH_M:
                r.fail(f"{r.sub('z_m')}[{i + 1}]", z[i + 1],
                       f"element {i} would be {z[i + 1] - z[i]:.3g} m long, below "
                       f"{MIN_ELEMENT_LENGTH_M:g} m (0.1 mm); positions are in metres")
        do = per_element(r, "outer_diameter_m", n_el, "positive", "outer diameter, m", REQUIRED)
        di = per_element(r, "inner_diameter_m", n_el, "nonneg", "bore diameter, m", 0.0)
        for i in range(n_el):
            if di[i] >= do[i]:
                key = "inner_diameter_m"
                r.fail(r.sub(key) + (f"[{i}]" if isinstance(r.data[key], list) else ""), di[i],
                       f"must be smaller than the outer diameter {do[i]!r} m")
        k_shear = r.get("shear_coefficient", "positive", "Timoshenko shear coefficient", None)
        shaft_name = r.get("name", "str", "element-name prefix", None)
        shaft_specs.append((path, dict(
            nodes=idx, positions_m=np.asarray(z, dtype=float), outer_diameters_m=np.asarray(do),
            inner_diameters_m=np.asarray(di), material=_material(r, mats),
            line=r.get("line", "str", "shaft line", shaft_name), shear_coeff=k_shear, name=shaft_name,
        ), read_axis(r)))

    # a node turns with one shaft line: a node listed on two lines (e.g. on the pinion and
    # the gear shafts) would join them rigidly, and the mesh relations would be meaningless
    line_of: dict[int, tuple[str, str]] = {}
    for (path, spec, _), numbers in zip(shaft_specs, shaft_nodes):
        line = spec["line"] if spec["line"] is not None else path
        for n in numbers:
            prev = line_of.setdefault(n, (line, path))
            if prev[0] != line:
                root.fail(f"{path}.nodes", n, f"node {n} is on shaft line {prev[0]!r} "
                                              f"({prev[1]}) and on shaft line {line!r} ({path}); "
                                              "a node belongs to one line (join lines with a "
                                              "[[coupling]] between two nodes)")

    node_specs = []
    for path, r in node_tabs:
        n = nodes.index(r, r.sub("node"), r.data["node"])
        z = r.get("z_m", "real", "axial position, m", None)
        node_specs.append((path, n, dict(label=r.get("label", "str", "free text", None),
                                         line=r.get("line", "str", "shaft line", None)),
                           z, read_axis(r)))

    disc_specs = []
    geo = ("outer_diameter_m", "inner_diameter_m", "width_m", "material")
    explicit = ("mass_kg", "transverse_inertia_kg_m2", "polar_inertia_kg_m2")
    for path, d in table_list(root, "disc"):
        r = Reader(source, path, d, ("node", "name") + geo + explicit)
        n = nodes.index(r, r.sub("node"), r.get("node", "int", "node number"))
        if any(r.has(k) for k in explicit):
            for k in geo:
                if r.has(k):
                    r.fail(r.sub(k), r.data[k], f"give either the annulus ({', '.join(geo[:3])}) "
                                                f"or the inertias ({', '.join(explicit)}), not both")
            m = r.get("mass_kg", "nonneg", "disc mass, kg")
            it = r.get("transverse_inertia_kg_m2", "nonneg", "inertia about a diameter, kg m^2")
            ip = r.get("polar_inertia_kg_m2", "nonneg", "polar inertia, kg m^2")
        else:
            do = r.get("outer_diameter_m", "positive", "disc outer diameter, m (or give mass_kg, ...)")
            di = r.get("inner_diameter_m", "nonneg", "disc bore, m", 0.0)
            b = r.get("width_m", "positive", "disc width, m")
            if di >= do:
                r.fail(r.sub("inner_diameter_m"), di, f"must be smaller than outer_diameter_m {do!r}")
            m, it, ip = disc_properties(do, di, b, _material(r, mats).rho)
        disc_specs.append((path, n, dict(mass_kg=m, transverse_inertia_kg_m2=it,
                                         polar_inertia_kg_m2=ip,
                                         name=r.get("name", "str", "element name", None))))

    bearing_specs = []
    for path, d in table_list(root, "bearing"):
        r = Reader(source, path, d, ("node", "name", "k_S_N_per_m", "k_T_N_per_m",
                                      "k_axial_N_per_m", "k_phi_Nm_per_rad", "k_psi_Nm_per_rad"))
        n = nodes.index(r, r.sub("node"), r.get("node", "int", "node number"))
        bearing_specs.append((path, n, dict(
            k_s=r.get("k_S_N_per_m", "nonneg", "radial stiffness along S, N/m"),
            k_t=r.get("k_T_N_per_m", "nonneg", "radial stiffness along T, N/m"),
            k_axial=r.get("k_axial_N_per_m", "nonneg", "axial stiffness, N/m", 0.0),
            k_phi=r.get("k_phi_Nm_per_rad", "nonneg", "tilting stiffness about S, N m/rad", 0.0),
            k_psi=r.get("k_psi_Nm_per_rad", "nonneg", "tilting stiffness about T, N m/rad", 0.0),
            name=r.get("name", "str", "element name", None))))

    coupling_specs = []
    for path, d in table_list(root, "coupling"):
        r = Reader(source, path, d, ("nodes", "name", "k_torsion_Nm_per_rad", "k_radial_N_per_m",
                                      "k_axial_N_per_m", "k_tilt_Nm_per_rad"))
        pair_nodes = r.get("nodes", "ints", "[node 1, node 2]")
        if len(pair_nodes) != 2:
            r.fail(r.sub("nodes"), pair_nodes, "must be 2 node numbers [n1, n2]")
        a, b = (nodes.index(r, f"{r.sub('nodes')}[{i}]", v) for i, v in enumerate(pair_nodes))
        if a == b:
            r.fail(r.sub("nodes"), pair_nodes, "a coupling joins two different nodes")
        coupling_specs.append((path, a, b, dict(
            k_torsion=r.get("k_torsion_Nm_per_rad", "nonneg", "torsional stiffness, N m/rad"),
            k_radial=r.get("k_radial_N_per_m", "nonneg", "radial stiffness, N/m", 0.0),
            k_axial=r.get("k_axial_N_per_m", "nonneg", "axial stiffness, N/m", 0.0),
            k_tilt=r.get("k_tilt_Nm_per_rad", "nonneg", "tilting stiffness, N m/rad", 0.0),
            name=r.get("name", "str", "element name", None))))

    spring_specs = []
    for path, d in table_list(root, "torsional_spring"):
        r = Reader(source, path, d, ("node", "name", "k_Nm_per_rad"))
        n = nodes.index(r, r.sub("node"), r.get("node", "int", "node number"))
        spring_specs.append((path, n, r.get("k_Nm_per_rad", "nonneg", "torsional stiffness to ground, N m/rad"),
                             r.get("name", "str", "element name", None)))

    special = {}
    for key, what in (("pinion_node", "node of the pinion centre O1"),
                      ("gear_node", "node of the gear centre O2"),
                      ("motor_node", "node carrying the motor torque")):
        special[key] = nodes.index(root, key, root.get(key, "int", what))
    if special["pinion_node"] == special["gear_node"]:
        root.fail("gear_node", root.data["gear_node"], "must differ from pinion_node")

    encoders = _encoders(root, nodes, special)
    mods, pitch1 = _modifications(root, pair)

    def build_structure(pair_: GearPair) -> Structure:
        return _assemble(source, pair_, n_nodes, nodes, shaft_specs, node_specs, disc_specs,
                         bearing_specs, coupling_specs, spring_specs, special)

    structure = build_structure(pair)  # assembled once now, so a bad file fails at load
    _check_structure(root, structure, nodes, special)
    return Rig(
        name=name,
        pair=pair,
        pinion_torque_Nm=torque,
        pinion_pitch_errors_m=pitch1,
        description=description,
        structure_factory=build_structure,
        motor_node=special["motor_node"],
        encoder_positions=encoders,
        modifications_default=mods,
        relief_presets=table1_relief,  # --relief short/long: the Table 1 reliefs
        accuracy=_accuracy(root),
        backlash_m=read_backlash(root, pair),
    )


_ACCURACY_KEYS = {  # key: (kind, what)
    "accuracy_grade": ("int", "ISO 1328-1 accuracy grade 1-12"),
    "base_pitch_deviation_m": ("nonneg", "base pitch deviation f_pb, m"),
    "profile_form_deviation_m": ("nonneg", "profile form deviation f_falpha, m"),
    "tip_relief_m": ("nonneg", "tip relief C_a, m"),
    "application_factor": ("positive", "application factor K_A"),
    "sigma_hlim_Pa": ("positive", "allowable contact stress sigma_Hlim, Pa"),
    "rated_speed_rad_s": ("positive", "pinion speed, rad/s"),
}


def _accuracy(root: Reader) -> AccuracyData | None:
    """The ``[iso6336]`` table as :class:`~gearjax.gears.iso6336.AccuracyData`, or None."""
    if not root.has("iso6336"):
        return None
    r = Reader(root.source, "iso6336", root.data["iso6336"], tuple(_ACCURACY_KEYS))
    kw = {k: r.get(k, kind, what) for k, (kind, what) in _ACCURACY_KEYS.items() if r.has(k)}
    try:
        return AccuracyData(**kw)
    except GeometryError as exc:
        r.fail(r.sub(exc.field), r.data.get(exc.field, exc.value), str(exc).split(": ", 1)[-1])


def _encoders(root: Reader, nodes: Nodes, special: dict) -> dict[int, tuple[int, int]]:
    if not root.has("encoders"):
        return {1: (special["pinion_node"], special["gear_node"])}
    table = root.data["encoders"]
    if not isinstance(table, dict):
        root.fail("encoders", table, "must be a table: position = [node I, node II]")
    r = Reader(root.source, "encoders", table, tuple(table))
    out = {}
    for key, value in table.items():
        if not key.isdigit() or int(key) < 1:
            r.fail(r.sub(key), value, "encoder positions are numbered 1, 2, 3, ...")
        pair_nodes = r.get(key, "ints", "[node I on the pinion line, node II on the gear line]")
        if len(pair_nodes) != 2:
            r.fail(r.sub(key), value, "must be 2 node numbers [node I, node II]")
        out[int(key)] = tuple(nodes.index(r, f"{r.sub(key)}[{i}]", v) for i, v in enumerate(pair_nodes))
    return out


def _modifications(root: Reader, pair: GearPair) -> tuple[ToothModifications | None, np.ndarray]:
    if not root.has("modifications"):
        return None, np.zeros(pair.z1)
    r = Reader(root.source, "modifications", root.data["modifications"],
                ("relief_shape", "crowning_m", "pinion", "gear"))
    shape = r.get("relief_shape", "str", '"linear" or "parabolic"', "linear")
    if shape not in ("linear", "parabolic"):
        r.fail(r.sub("relief_shape"), shape, 'must be "linear" or "parabolic"')
    crowning = r.get("crowning_m", "nonneg", "composite lead crowning, m", 0.0)
    keys = ("relief_amplitude_m", "relief_extent", "pitch_errors_m", "eccentricity_m",
            "eccentricity_phase_rad")
    amp, ext, pitch, ecc, phase = [0.0, 0.0], [0.5, 0.5], [None, None], [0.0, 0.0], [0.0, 0.0]
    any_pitch = any_ecc = False
    for k, (gear, z) in enumerate((("pinion", pair.z1), ("gear", pair.z2))):
        if not r.has(gear):
            pitch[k] = np.zeros(z)
            continue
        g = Reader(root.source, r.sub(gear), r.data[gear], keys)
        amp[k] = g.get("relief_amplitude_m", "nonneg", "tip relief amplitude, m", 0.0)
        if amp[k] > 1e-3:
            g.fail(g.sub("relief_amplitude_m"), amp[k], "above 1 mm; amplitudes are in metres "
                                                        "(13.3 um is 13.3e-6)")
        ext[k] = g.get("relief_extent", "positive", "fraction of the path of contact", 0.5)
        if ext[k] > 1.0:
            g.fail(g.sub("relief_extent"), ext[k], "must lie in (0, 1] (fraction of the path of contact)")
        if g.has("pitch_errors_m"):
            errs = g.get("pitch_errors_m", "reals", "cumulative pitch deviations, m")
            if len(errs) != z:
                g.fail(g.sub("pitch_errors_m"), g.data["pitch_errors_m"],
                       f"must list {z} values (one per tooth of the {gear}, z = {z}), got {len(errs)}")
            pitch[k] = np.asarray(errs, dtype=float)
            any_pitch = True
        else:
            pitch[k] = np.zeros(z)
        if g.has("eccentricity_m") or g.has("eccentricity_phase_rad"):
            ecc[k] = g.get("eccentricity_m", "nonneg", "eccentricity amplitude, m")
            phase[k] = g.get("eccentricity_phase_rad", "real", "eccentricity phase, rad")
            any_ecc = True
    try:
        mods = ToothModifications.tip_relief(np.asarray(amp), np.asarray(ext), shape)
        if any_pitch:
            mods = mods.with_pitch_errors(pitch[0], pitch[1])
        if any_ecc:
            mods = mods.with_eccentricity(np.asarray(ecc), np.asarray(phase))
        if crowning:
            import jax.numpy as jnp

            mods = ToothModifications(mods.relief_amplitude_m, mods.relief_extent, shape,
                                      mods.pitch_errors_m, mods.eccentricity_m,
                                      mods.eccentricity_phase_rad, jnp.asarray(crowning))
        mods.check_against(pair)
    except ModificationError as exc:
        r.fail("modifications", "...", str(exc))
    return mods, pitch[0]


def _assemble(source, pair, n_nodes, nodes, shaft_specs, node_specs, disc_specs, bearing_specs,
              coupling_specs, spring_specs, special) -> Structure:
    """Assemble the structure; any builder error is reported with its file path."""
    a = float(pair.centre_distance_m)
    g = float(pair.working_pressure_angle_rad) - math.pi / 2  # as baud_velex_structure
    axes = {"pinion": (0.0, 0.0), "gear": (a * math.cos(g), a * math.sin(g))}

    def where(axis):
        return axes[axis] if isinstance(axis, str) else axis

    b = StructureBuilder(n_nodes=n_nodes)
    path = ""
    try:
        for path, spec, axis in shaft_specs:
            b.add_shaft(spec["nodes"], positions_m=spec["positions_m"],
                        outer_diameters_m=spec["outer_diameters_m"],
                        inner_diameters_m=spec["inner_diameters_m"], material=spec["material"],
                        axis_st_m=where(axis), line=spec["line"], shear_coeff=spec["shear_coeff"],
                        name=spec["name"])
        for path, n, kw, z, axis in node_specs:
            pos = None if z is None else (*where(axis), z)
            b.set_node(n, position_m=pos, **kw)
        for path, n, kw in disc_specs:
            b.add_disc(n, **kw)
        for path, n1, n2, kw in coupling_specs:
            b.add_coupling(n1, n2, **kw)
        for path, n, k, name in spring_specs:
            b.add_torsional_spring_to_ground(n, k, name=name)
        for path, n, kw in bearing_specs:
            b.add_bearing(n, **kw)
        path = "pinion_node"
        b.set_pinion_node(special["pinion_node"]).set_gear_node(special["gear_node"])
        path = "nodes"
        return b.build()
    except ElementInputError as exc:  # StructureInputError and element range errors
        msg = str(exc)
        for i in range(n_nodes - 1, -1, -1):  # report the file's node numbers
            msg = msg.replace(f"node(s) [{i}]", f"node(s) [{nodes.number(i)}]")
        raise RigError(f"{path}: {msg} (rig file {source})") from None


def _check_structure(root: Reader, s: Structure, nodes: Nodes, special: dict) -> None:
    M = np.asarray(s.M)
    diag = np.diag(M)
    empty = np.flatnonzero(diag <= 0.0)
    if empty.size:
        i = int(empty[0])
        root.fail("nodes", nodes.number(i // 6),
                  f"dof {DOF_NAMES[i % 6]!r} of node {nodes.number(i // 6)} has no mass (a node "
                  "carried only by a disc needs its inertias, or a shaft)")
    lines = s.node_lines
    pn, gn = special["pinion_node"], special["gear_node"]
    if lines[pn] == lines[gn]:
        root.fail("gear_node", nodes.number(gn),
                  f"the pinion and gear nodes are both on shaft line {lines[pn]!r}; give the "
                  "pinion line and the gear line different `line` names")
    K = np.asarray(s.K)
    basis = modal_basis(M, K, warn=False)
    if basis.n_rigid > 1 and scaled_null_dimension(K) <= 1:
        # K itself has at most one free motion: the extra "rigid-body" modes are soft modes
        # lost in the round-off of a too wide stiffness range, not missing supports
        d = np.diag(K)
        hi = int(np.argmax(d))
        f_max = float(np.max(basis.omegas_rad_s)) / (2 * math.pi)
        root.fail("structure", f"{basis.n_rigid} apparent rigid-body modes",
                  f"K has at most one free motion, but the stiffest dof (node "
                  f"{nodes.number(hi // 6)} {DOF_NAMES[hi % 6]!r}, K = {d[hi]:.3g}) puts the "
                  f"highest natural frequency at {f_max:.3g} Hz, too far above the soft modes "
                  "for the modal analysis to resolve them; bring the extreme bearing, coupling "
                  "or spring stiffnesses into a physical range")
    if basis.n_rigid > 1:
        # kinetic-energy share of each (shaft line, dof name) in the rigid-body modes
        rigid = np.asarray(basis.modes)[:, : basis.n_rigid]
        energy = np.sum(rigid * (M @ rigid), axis=1)
        share: dict[tuple[str, str], float] = {}
        for i, e in enumerate(energy):
            key = (lines[i // 6], DOF_NAMES[i % 6])
            share[key] = share.get(key, 0.0) + float(e) / basis.n_rigid
        free = ", ".join(f"line {ln!r} {d}" for (ln, d), e in sorted(share.items()) if e > 0.05)
        root.fail("structure", f"{basis.n_rigid} rigid-body modes",
                  "the structure without the mesh may have at most one rigid-body mode (the "
                  "free rotation of the driving line); missing bearings, couplings or a "
                  f"resisting torsional_spring? Free motions: {free}")


def load_rig(path: str | os.PathLike) -> Rig:
    """Load a user rig from a TOML file (schema in the module docstring).

    Raises
    ------
    RigError
        Unreadable file, TOML syntax error, or a field that is missing, of the wrong type,
        out of range, unknown, or referring to an undeclared node; the message names the
        field path (e.g. ``bearing[2].k_S_N_per_m``), the value and the reason.
    """
    p = Path(path)
    try:
        text = p.read_bytes()
    except OSError as exc:
        raise RigError(f"rig={str(path)!r}: cannot read the rig file ({exc.strerror})") from None
    try:
        data = tomllib.loads(text.decode("utf-8-sig"))  # a byte-order mark (Windows editors) reads
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise RigError(f"rig={str(path)!r}: not valid TOML: {exc}") from None
    return parse_rig(data, source=str(path), default_name=p.stem)

