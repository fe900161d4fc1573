"""The shaft lines of a rig file as ROSS rotors (optional dependency ``ross-rotordynamics``).

An independent check of :mod:`gearjax.structure`: the same shafts, discs, bearings and
couplings, read again from the TOML rig file (:mod:`gearjax.rigs.rigfile` schema) and
assembled by ROSS (https://github.com/petrobras/ross, ``pip install 'gearjax[ross]'``),
one :class:`ross.Rotor` per shaft line. ROSS has no pinion-gear element in a single rotor,
so the comparison is for the structure without the mesh: the undamped modes of ``(M, K)``,
which for our block-diagonal structure are the union of the lines' modes.

Matching the two models (differences of modelling, not of tolerance)
--------------------------------------------------------------------
* Node dofs: ROSS ``(x, y, z, alpha, beta, theta)`` = ours ``(v, w, u, phi, psi, theta)``
  (6 dof per node in both, axial and torsion included).
* Timoshenko shear coefficient: ROSS computes it from the section (``shear_method_calc``
  ``"cowper"`` or ``"hutchinson"``) and takes no override; ours defaults to Hutchinson
  (2001). ROSS 2.3's ``"hutchinson"`` formula lacks one factor ``(1 + nu)`` of
  Hutchinson's Eq. (for a solid section it gives ``6 (1 + nu) / (7 + 12 nu + 4 nu^2)`` =
  0.712 at nu = 0.3 instead of 0.925), so the comparison passes ROSS's ``kappa`` to our
  shafts (``shear_coefficient`` in the rig file, see :func:`ross_shear_coefficient`).
* Discs: both ``diag(m, m, m, I_d, I_d, I_p)``, no gyroscopic terms at speed 0.
* Bearings: ROSS ``BearingElement`` has ``kxx``, ``kyy``, ``kzz`` but no tilting or
  torsional stiffness. Our tilting stiffness (``k_phi``, ``k_psi``) and the torsional
  springs to ground (the resisting load) are given to ROSS as a ``CouplingElement`` from
  the node to an extra *seismic* node of mass ``m_g`` and inertias ``J_g``
  (``seismic_mass``): a standard way to ground a spring in a code without such an element.
  It adds near-zero modes (below 1 Hz for the default) and perturbs the others by about
  ``J_line / J_g`` (1e-7 relative), far below the 0.5 % of the cross-check.
* Couplings: ROSS ``CouplingElement`` is the same zero-length 6-dof spring; its station
  masses are zero and the hubs are discs, as in ours.
* Only the order of the chain is used: ROSS puts the elements of a rotor one after the
  other, so each line's shafts and couplings must form a chain in node order (true for the
  Baud-Velex rig), and a ground spring must sit on an end node of its line.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib  # type: ignore[no-redef]

__all__ = ["ross_rotors", "ross_geared_rotor", "ross_natural_frequencies_hz", "ross_shear_coefficient",
           "ross_mesh_modes", "periodic_mesh_force"]


def _ross():
    try:
        import ross
    except ImportError as exc:  # pragma: no cover - optional dependency
        raise ImportError("the ROSS cross-check needs `pip install 'gearjax[ross]'`") from exc
    return ross


def ross_shear_coefficient(outer_diameter_m: float, inner_diameter_m: float = 0.0, *,
                           nu: float = 0.3, method: str = "cowper") -> float:
    """The shear coefficient ROSS uses for a section (read from a ROSS element)."""
    rs = _ross()
    mat = rs.Material(name="gearjax_probe", rho=7800.0, E=2.1e11, Poisson=nu)
    el = rs.ShaftElement(L=0.1, idl=inner_diameter_m, odl=outer_diameter_m, material=mat,
                         shear_effects=True, rotary_inertia=True, gyroscopic=False,
                         shear_method_calc=method)
    return float(el.kappa)


def ross_rotors(path: str | Path, *, shear_method: str = "cowper",
                seismic_mass: float = 1e9, gears: dict | None = None) -> dict[str, object]:
    """One ``ross.Rotor`` per shaft line of a rig file, keyed by line name.

    Each rotor also carries ``gearjax_nodes`` (the file's node number of every ROSS node,
    None for a seismic node). Load the file with :func:`gearjax.load_rig` first to validate
    it; this function assumes a valid file. ``gears`` maps a file node to the keyword
    arguments of ``ross.GearElement`` (``n_teeth``, ``base_diameter``, ``pr_angle``): the
    disc at that node becomes a gear element of the same mass and inertias (what
    ``ross.MultiRotor`` couples).
    """
    gears = gears or {}
    rs = _ross()
    data = tomllib.loads(Path(path).read_text())
    mats = {"steel": dict(E_Pa=2.1e11, nu=0.3, rho_kg_per_m3=7800.0)}
    mats.update(data.get("materials", {}))
    ross_mats = {name: rs.Material(name=f"gearjax_{name}", rho=m["rho_kg_per_m3"], E=m["E_Pa"],
                                   Poisson=m["nu"]) for name, m in mats.items()}

    # node -> line, and the chain of each line: (first node, last node, element)
    line_of: dict[int, str] = {}
    links: dict[str, list] = {}
    for sh in data["shaft"]:
        line = sh.get("line", sh.get("name"))
        nodes = sh["nodes"] if "nodes" in sh else list(range(sh["node_range"][0], sh["node_range"][1] + 1))
        if "z_m" in sh:
            lengths = np.diff(np.asarray(sh["z_m"], dtype=float))
        else:
            lengths = np.broadcast_to(np.asarray(sh["lengths_m"], dtype=float), (len(nodes) - 1,))
        do = np.broadcast_to(np.asarray(sh["outer_diameter_m"], dtype=float), lengths.shape)
        di = np.broadcast_to(np.asarray(sh.get("inner_diameter_m", 0.0), dtype=float), lengths.shape)
        mat = ross_mats[sh.get("material", "steel")]
        for i, L in enumerate(lengths):
            el = rs.ShaftElement(L=float(L), idl=float(di[i]), odl=float(do[i]), material=mat,
                                 shear_effects=True, rotary_inertia=True, gyroscopic=False,
                                 shear_method_calc=shear_method)
            links.setdefault(line, []).append((nodes[i], nodes[i + 1], el))
        for n in nodes:
            line_of[n] = line
    for nd in data.get("node", []):
        if "line" in nd:
            line_of[nd["node"]] = nd["line"]
    for cp in data.get("coupling", []):
        a, b = cp["nodes"]
        el = rs.CouplingElement(m_l=0.0, m_r=0.0, Ip_l=0.0, Ip_r=0.0,
                                kt_x=cp.get("k_radial_N_per_m", 0.0), kt_y=cp.get("k_radial_N_per_m", 0.0),
                                kt_z=cp.get("k_axial_N_per_m", 0.0), kr_x=cp.get("k_tilt_Nm_per_rad", 0.0),
                                kr_y=cp.get("k_tilt_Nm_per_rad", 0.0), kr_z=cp["k_torsion_Nm_per_rad"])
        links.setdefault(line_of[a], []).append((min(a, b), max(a, b), el))

    # springs to ground that ROSS bearings cannot hold: tilt and torsion -> seismic node
    ground: dict[int, dict] = {}
    for br in data.get("bearing", []):
        kphi, kpsi = br.get("k_phi_Nm_per_rad", 0.0), br.get("k_psi_Nm_per_rad", 0.0)
        if kphi or kpsi:
            ground.setdefault(br["node"], {}).update(kr_x=kphi, kr_y=kpsi)
    for sp in data.get("torsional_spring", []):
        ground.setdefault(sp["node"], {})["kr_z"] = sp["k_Nm_per_rad"]

    rotors = {}
    for line, chain in links.items():
        chain.sort(key=lambda t: t[0])
        order = [chain[0][0]] + [t[1] for t in chain]
        for (a, b, _), (c, _, _) in zip(chain, chain[1:]):
            if b != c:
                raise ValueError(f"line {line!r}: elements {a}-{b} and {c}-... do not form a chain")
        elements = [t[2] for t in chain]
        ross_nodes: list[int | None] = list(order)
        for n, springs in ground.items():
            if n not in order:
                continue
            el = rs.CouplingElement(m_l=0.0, m_r=0.0, Ip_l=0.0, Ip_r=0.0, **springs)
            if n == order[0]:
                elements.insert(0, el)
                ross_nodes.insert(0, None)
            elif n == order[-1]:
                elements.append(el)
                ross_nodes.append(None)
            else:
                raise ValueError(f"node {n}: a tilting/torsional ground spring must sit on an end "
                                 f"node of line {line!r} for the ROSS model")
        index = {n: i for i, n in enumerate(ross_nodes) if n is not None}
        disks = []
        for ds in data.get("disc", []):
            if ds["node"] not in index:
                continue
            if "mass_kg" in ds:
                m, it, ip = ds["mass_kg"], ds["transverse_inertia_kg_m2"], ds["polar_inertia_kg_m2"]
            else:
                rho = mats[ds.get("material", "steel")]["rho_kg_per_m3"]
                R2, r2 = (ds["outer_diameter_m"] / 2) ** 2, (ds.get("inner_diameter_m", 0.0) / 2) ** 2
                b = ds["width_m"]
                m = rho * math.pi * (4 * R2 - 4 * r2) * b / 4
                it, ip = m * (3 * (R2 + r2) + b * b) / 12, m * (R2 + r2) / 2
            if ds["node"] in gears:
                disks.append(rs.GearElement(n=index[ds["node"]], m=m, Id=it, Ip=ip, **gears[ds["node"]]))
            else:
                disks.append(rs.DiskElement(n=index[ds["node"]], m=m, Id=it, Ip=ip))
        for i, n in enumerate(ross_nodes):
            if n is None:  # the seismic node: huge mass and inertias (its free motions are rigid)
                disks.append(rs.DiskElement(n=i, m=seismic_mass, Id=seismic_mass, Ip=seismic_mass))
        bearings = []
        for br in data.get("bearing", []):
            if br["node"] in index:
                bearings.append(rs.BearingElement(n=index[br["node"]], kxx=br["k_S_N_per_m"],
                                                  kyy=br["k_T_N_per_m"], kzz=br.get("k_axial_N_per_m", 0.0),
                                                  cxx=0.0))
        rotor = rs.Rotor(shaft_elements=elements, disk_elements=disks, bearing_elements=bearings)
        rotor.gearjax_nodes = ross_nodes
        rotors[line] = rotor
    return rotors


def ross_natural_frequencies_hz(rotor, *, min_hz: float = 1.0) -> np.ndarray:
    """Undamped natural frequencies (Hz) of a ROSS rotor at speed 0, above ``min_hz``
    (drops rigid-body and seismic-node modes), each once, sorted."""
    modal = rotor.run_modal(speed=0.0, num_modes=rotor.ndof, sparse=False)
    f = np.sort(np.abs(np.asarray(modal.wn, dtype=float))) / (2 * math.pi)
    return f[f > min_hz]


def ross_geared_rotor(path: str | Path, mesh_stiffness_N_per_m: float, *,
                      shear_method: str = "cowper", update_mesh_stiffness: bool = False,
                      seismic_mass: float = 1e9):
    """The rig's pinion and gear lines coupled by ROSS's own gear mesh (``ross.MultiRotor``,
    spur pairs): ``(multi_rotor, dof)`` with ``dof(file_node, k)`` the ROSS index of dof
    ``k`` (0..5: x, y, z, alpha, beta, theta) of a file node.

    The pinion and gear discs become ``ross.GearElement`` with the pair's base diameters
    and working pressure angle, so ROSS's mesh (Stringer's coupling matrix, its torsional
    arms ``pitch_radius cos(alpha)`` = base radii) acts along a line of action as ours;
    the mesh stiffness is ``mesh_stiffness_N_per_m`` (constant), or, with
    ``update_mesh_stiffness``, ROSS interpolates ``multi_rotor.mesh.stiffness_range`` over
    ``multi_rotor.mesh.theta_range`` (pinion angle, one mesh period) at every Newmark step:
    overwrite both with the stiffness table to be compared. ROSS's Newmark samples the
    table once per step at the step's end, so a jump of k inside a step acts at its middle
    (first order in the step): align the steps on the jumps and tabulate k at the step
    angles (``benchmarks/bench_ross.py``). Helical pairs are not mapped (ROSS's helix
    convention is not checked here).
    """
    from .rigfile import load_rig

    rs = _ross()
    rig = load_rig(path)
    pair = rig.pair
    if pair.base_helix_angle_rad != 0.0:
        raise ValueError("ross_geared_rotor maps spur pairs only")
    data = tomllib.loads(Path(path).read_text())
    pn, gn = int(data["pinion_node"]), int(data["gear_node"])
    alpha = pair.working_pressure_angle_rad
    rb1, rb2 = pair.base_radii_m
    gears = {pn: dict(n_teeth=pair.z1, base_diameter=2 * rb1, pr_angle=alpha),
             gn: dict(n_teeth=pair.z2, base_diameter=2 * rb2, pr_angle=alpha)}
    rotors = ross_rotors(path, shear_method=shear_method, seismic_mass=seismic_mass, gears=gears)
    line = {n: name for name, r in rotors.items() for n in r.gearjax_nodes if n is not None}
    drv, drn = rotors[line[pn]], rotors[line[gn]]
    ip, ig = drv.gearjax_nodes.index(pn), drn.gearjax_nodes.index(gn)
    mr = rs.MultiRotor(drv, drn, coupled_nodes=(ip, ig), gear_mesh_stiffness=float(mesh_stiffness_N_per_m),
                       update_mesh_stiffness=update_mesh_stiffness)
    shift = mr.driven_nodes[0]  # ROSS renumbers the driven rotor's nodes from here

    def dof(node: int, k: int) -> int:
        if node in drv.gearjax_nodes:
            i = drv.gearjax_nodes.index(node)
        else:
            i = drn.gearjax_nodes.index(node) + shift
        return 6 * i + k

    return mr, dof


def ross_mesh_modes(multi_rotor, *, speed: float = 0.0, min_rad_s: float = 1.0):
    """Undamped modes of a ``ross.MultiRotor`` at its current ``mesh.stiffness`` and their
    mesh participations: ``(omega, v, c, phi)`` with ``omega`` (rad/s, ascending), ``v =
    phi^T c`` (``phi`` mass-normalised) and ``c`` the mesh vector of ROSS's rank-one gear
    coupling (``coupling_matrix() = c c^T``, ROSS dofs; its sign is arbitrary). Modes below
    ``min_rad_s`` (rigid motions, seismic nodes) are dropped, ``phi`` keeps all of them."""
    import scipy.linalg as sl

    M, K = multi_rotor.M(), multi_rotor.K(speed)
    w2, phi = sl.eigh(K, M)
    omega = np.sqrt(np.clip(w2, 0.0, None))
    dofs = [*multi_rotor.mesh.driving_gear.dof_global_index.values(),
            *multi_rotor.mesh.driven_gear.dof_global_index.values()]
    lam, U = np.linalg.eigh(multi_rotor.coupling_matrix())
    c = np.zeros(M.shape[0])
    c[dofs] = U[:, -1] * np.sqrt(lam[-1])
    keep = omega >= min_rad_s
    return omega[keep], (phi.T @ c)[keep], c, phi


def periodic_mesh_force(omega, v, zeta: float, k_split: float, static_force_N: float, stiffness,
                        jumps_rad, period_rad: float, speed_rad_s: float, steps: int = 1024):
    """Periodic steady state of a linear geared system with a time-varying mesh stiffness,
    computed exactly (shooting), independently of any time-marching code.

    In the modal coordinates ``q`` of ``(M, K + k_split c c^T)`` (``omega``, mesh
    participations ``v = phi^T c``, modal damping ``zeta`` on every mode), the deviation from
    the static state under the period mean ``k_bar`` of ``k(theta)``, ``theta = speed t``::

        q'' + 2 zeta omega q' + omega^2 q + (k(theta) - k_split) v (v^T q) = -(k(theta) - k_bar) v delta_s

    with ``delta_s = F_S / k_bar`` the static mesh deflection (exact when one line is free in
    torsion, so that the static mesh force is ``F_S`` whatever the stiffness); the mesh force
    is ``k(theta) (delta_s + v^T q)``. Classical RK4 with ``steps`` per period, its steps
    aligned on the jumps of ``k`` (``jumps_rad``, one-sided values there, so the scheme
    keeps its fourth order), ``k`` evaluated by ``stiffness(theta_array)`` at every stage;
    the orbit is the fixed point of the period map (monodromy matrix, one linear solve).
    Returns ``(theta, force / F_S)`` over one period starting at 0, both one-sided values
    at every step end (so the maximum at a jump is seen exactly). Accuracy and cost:
    ``benchmarks/results/code_notes.md``, section gearjax.rigs.ross_bridge.
    """
    P = float(period_rad)
    omega, v = np.asarray(omega, dtype=float), np.asarray(v, dtype=float)
    js = sorted({float(np.mod(j, P)) for j in jumps_rad} | {0.0})
    js = [j for j in js if j == 0.0 or min(j, P - j) > 1e-9 * P]
    bounds = js + [P]
    th0, th1 = [], []
    for a, b in zip(bounds[:-1], bounds[1:]):
        g = np.linspace(a, b, max(4, int(round(steps * (b - a) / P))) + 1)
        th0.append(g[:-1])
        th1.append(g[1:])
    th0, th1 = np.concatenate(th0), np.concatenate(th1)
    eps = 1e-11 * P  # one-sided values at the segment ends
    k = np.asarray(stiffness(np.concatenate([th0 + eps, 0.5 * (th0 + th1), th1 - eps])), dtype=float)
    k0, kh, k1 = np.split(k, 3)
    k_bar = float(np.sum(0.5 * (k0 + k1) * (th1 - th0)) / P)  # only splits k: any value works
    ds = static_force_N / k_bar
    h = (th1 - th0) / speed_rad_s
    n = omega.size
    cd, w2 = 2.0 * zeta * omega, omega**2

    def f(x, kk):  # x: (2n, m); the last column carries the forcing
        q, p = x[:n], x[n:]
        acc = -cd[:, None] * p - w2[:, None] * q - (kk - k_split) * np.outer(v, v @ q)
        acc[:, -1] -= (kk - k_bar) * ds * v
        return np.concatenate([p, acc])

    def step(x, i):
        a1 = f(x, k0[i])
        a2 = f(x + 0.5 * h[i] * a1, kh[i])
        a3 = f(x + 0.5 * h[i] * a2, kh[i])
        a4 = f(x + h[i] * a3, k1[i])
        return x + h[i] / 6.0 * (a1 + 2 * a2 + 2 * a3 + a4)

    x = np.concatenate([np.eye(2 * n), np.zeros((2 * n, 1))], axis=1)
    for i in range(h.size):
        x = step(x, i)
    x0 = np.linalg.solve(np.eye(2 * n) - x[:, :-1], x[:, -1])
    xs = x0[:, None]  # one column: the forced state (f adds the forcing to the last column)
    theta, force = [], []
    for i in range(h.size):
        force.append(k0[i] * (ds + v @ xs[:n, 0]))
        theta.append(th0[i])
        xs = step(xs, i)
        force.append(k1[i] * (ds + v @ xs[:n, 0]))
        theta.append(th1[i])
    return np.asarray(theta), np.asarray(force) / static_force_N
