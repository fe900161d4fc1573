"""Switching events of the quasi-static solution: classification, bracketing, moving angles.

The speed-independent excitations (loaded stiffness ``(sum k_i)^S``, ``TE_S``, NLTE; paper
Eqs. (9), (17)-(19)) jump or kink at angles where the discrete state of the quasi-static
solution changes: a cell enters or leaves the path of contact (geometric, fixed), a cell
crosses the start of a tip-relief zone, the loaded set changes (a gap equals the approach,
Eq. (17)), or the cell realising NLTE changes (two removed materials equal, Eq. (9)).

The discrete state at an angle is an integer *code* row (:func:`code`): the NLTE cell,
then per cell loaded / inside / relief-zone bits. :func:`find_brackets` locates every code
change between adjacent floating-point angles by bisection from a uniform scan;
:func:`event_kinds` classifies each change (``EV_*``); :func:`moved_event_angles` moves the
design-dependent ones with the modifications by Newton iterations on their switching
function (:func:`switch_value`), differentiable by the implicit function theorem
``d theta_j = -(dg/d design) / (dg/d theta)``. All angles in rad (pinion angle theta).

Derivatives with respect to the design (why the events are moved)
-----------------------------------------------------------------
The switching angles ``theta_j`` move with the tip relief: where a relieved tooth starts
to carry load (its gap equals the approach, ``y = delta_e``, Eq. (17)), where two removed
materials are equal (NLTE, Eq. (9)), where a cell crosses the start of a relief zone
(``xi = xi_e - L_c1 g_alpha`` or ``xi_start + L_c2 g_alpha``). For an integral
``int f(theta, P) dtheta`` with a jump at ``theta_j(P)`` the derivative contains the
boundary term ``(f^- - f^+) dtheta_j/dP``, which AD through a solver whose steps end at
*fixed* angles never produces.

The fix is a change of the independent variable. The build records, for every jump angle
``s_j``, the kind of event and the cells involved (:func:`classify_events`);
:func:`moved_event_angles` recomputes ``theta_j(P)`` from ``s_j``, and the models integrate
in the simulation angle ``s`` with ``theta = phi(s)``,
:class:`gearjax.excitation.tables.AngleMap`, a periodic C^1 map with ``phi(s_j) =
theta_j(P)`` (``phi = identity`` at the build design). The jumps then stay at the fixed
``s_j`` given to the step-size controller, the tables are built in ``s`` (knots fixed,
values ``q(phi(s))``, means over theta taken with the factor ``phi'``), the vector field is
``dy/ds = phi'(s) dy/dtheta`` and outputs are evaluated at ``phi(s)``: everything is smooth
in the design between jumps, and AD differentiates the correct function.

The map is valid while the discrete structure of the quasi-static solution (the codes at
every table knot) is the build one; the models check it (``structure_ok``), and a design
where an event appears or vanishes needs a rebuilt model.
"""

from __future__ import annotations

import math
import warnings

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

__all__ = [
    "EV_FIXED", "EV_LOADED", "EV_NLTE", "EV_ZONE1", "EV_ZONE2", "NEWTON_STEPS",
    "code", "code_jnp", "event_kinds", "distinct_angles", "classify_events", "find_brackets", "engagement_angles",
    "quiet_origin", "switch_value", "moved_event_angles", "check_event_roots",
]

# kinds of switching events (see :func:`switch_value`): fixed (geometric), loaded set,
# NLTE cell, pinion relief zone start, gear relief zone start
EV_FIXED, EV_LOADED, EV_NLTE, EV_ZONE1, EV_ZONE2 = 0, 1, 2, 3, 4
# Newton steps that move an event with the design (the models' and the build check's)
NEWTON_STEPS = 4


def code_jnp(d):
    """:func:`code` of one angle's signature, traceable: (1 + 3 n_cells,) int array.

    ``d`` is a dict with ``nlte_arg`` (scalar), ``loaded``, ``inside``, ``zone`` ((n_cells,))."""
    return jnp.concatenate([
        jnp.reshape(d["nlte_arg"], (1,)).astype(jnp.int32),
        d["loaded"].astype(jnp.int32), d["inside"].astype(jnp.int32), d["zone"].astype(jnp.int32),
    ])


def code(d) -> np.ndarray:
    """Code matrix (n_angles, 1 + 3 n_cells) of a batch of signatures (NumPy, build time):
    columns NLTE cell, loaded bits, inside bits, zone codes (-1 outside the path)."""
    n = np.asarray(d["nlte_arg"]).shape[0]
    parts = [np.asarray(d["nlte_arg"]).reshape(n, 1)]
    parts += [np.asarray(d[k]).reshape(n, -1) for k in ("loaded", "inside", "zone")]
    return np.concatenate([q.astype(np.int64) for q in parts], axis=1)


def event_kinds(c_lo, c_hi, n):
    """Kind and cells of the switching event between adjacent angles with codes c_lo, c_hi.

    A change of ``inside`` is an engagement (geometric, fixed); otherwise a zone change
    (cell crossing a relief start, which moves with L_c), a change of the loaded set (a
    cell's gap equals the approach, moves with P_c and L_c), or of the cell realising NLTE
    (two removed materials equal). One event per bracket; the first changed cell wins."""
    d = c_lo != c_hi
    ins, zone, load = d[1 + n:1 + 2 * n], d[1 + 2 * n:], d[1:1 + n]
    if ins.any():
        return EV_FIXED, 0, 0
    z_lo, z_hi = c_lo[1 + 2 * n:], c_hi[1 + 2 * n:]
    if (zone & ((z_lo < 0) | (z_hi < 0))).any():
        # an engagement seen through the zone code (-1 = outside): XLA may evaluate the
        # ``inside`` flag of the same cell one float apart in the two fields (helical
        # cells), so the bracket holding the zone change need not hold the inside change
        return EV_FIXED, 0, 0
    if zone.any():
        c = int(np.argmax(zone))
        bits = int(c_lo[1 + 2 * n + c]) ^ int(c_hi[1 + 2 * n + c])
        return (EV_ZONE1 if bits & 1 else EV_ZONE2), c, c
    if load.any():
        c = int(np.argmax(load))
        return EV_LOADED, c, c
    if d[0]:
        return EV_NLTE, int(c_lo[0]), int(c_hi[0])
    return EV_FIXED, 0, 0



def distinct_angles(points, period, rtol: float = 1e-9) -> np.ndarray:
    """Sorted distinct angles in [0, period) (rad): ``points`` folded into the period,
    an angle within ``rtol * period`` of the last one kept merged into it, and the last
    one merged into the first across the period end."""
    ang = np.sort(np.mod(np.asarray(points, dtype=float).reshape(-1), period))
    out: list[float] = []
    for t in ang:
        if not out or t - out[-1] > rtol * period:
            out.append(float(t))
    if len(out) > 1 and out[0] + period - out[-1] <= rtol * period:
        out.pop()
    return np.asarray(out)


# which of coinciding state changes names the event (:func:`classify_events`)
_PRIORITY = {EV_ZONE1: 0, EV_ZONE2: 0, EV_LOADED: 1, EV_NLTE: 2}


def classify_events(angles, lo, hi, c_lo, c_hi, n_cells, period, rtol: float = 1e-9):
    """Kind and cells of the switching event at each of ``angles`` (rad), one rule for
    every model: the brackets ``(lo, hi)`` of :func:`find_brackets` whose angle lies
    within ``rtol * period`` of it (circularly) are classified by :func:`event_kinds`
    from their codes ``c_lo``/``c_hi``; coinciding brackets with a fixed (geometric) one
    among them pin the angle (``EV_FIXED``), else the one of the highest priority gives
    kind and cells: a relief-zone start, then a loaded-set change, then an NLTE-cell
    change (the order of :func:`event_kinds` within one bracket; the first bracket among
    equals). Not the first bracket by angle: two state changes of one event (a cell
    entering its relief zone, and the NLTE cell that the argmin of equal removed
    materials picks changing with it) lie a few floats apart in an order that the
    compiled code's rounding decides (XLA:CPU's legacy emitters put the NLTE change
    first on the Baud-Velex rig, whose Newton iteration on ``r_a - r_b`` then stepped
    onto the unrelieved side, where the function and its slope are both 0). An angle
    without a bracket (an engagement angle added from the geometry) is fixed.

    Returns
    -------
    (kinds, cells) : tuples of int and of (int, int), one per angle (concrete inputs; a
    build inside a program uses :func:`gearjax.excitation.layout.classify_events`, the
    same rule).
    """
    angles = np.asarray(angles, dtype=float).reshape(-1)
    at = np.mod(np.asarray(hi, dtype=float), period)
    classified = [event_kinds(np.asarray(c_lo[i]), np.asarray(c_hi[i]), n_cells)
                  for i in range(at.shape[0])]
    kinds, cells = [], []
    for t in angles:
        dist = np.abs(at - t)
        dist = np.minimum(dist, period - dist)
        near = [classified[i] for i in np.nonzero(dist <= rtol * period)[0]]
        if near and all(ev[0] != EV_FIXED for ev in near):
            kind, a, b = min(near, key=lambda ev: _PRIORITY[ev[0]])  # first among equals
            kinds.append(int(kind))
            cells.append((int(a), int(b)))
        else:
            kinds.append(EV_FIXED)
            cells.append((0, 0))
    return tuple(kinds), tuple(cells)


def find_brackets(code_fn, theta, codes, period):
    """Pairs of adjacent floats (lo, hi), ``theta[0] <= lo < hi <= theta[0] + period``,
    bracketing every change of the discrete state: bisection from the uniform scan
    ``theta`` (several changes in one scan interval are found one after the other).

    Parameters
    ----------
    code_fn : maps a (m,) array of angles (rad) to the (m, n_code) int code matrix.
    theta : (n,) uniform scan over one period (rad), spacing ``period / n``.
    codes : (n, n_code) code matrix of the scan (``code_fn(theta)``).
    period : the period (rad).

    Returns
    -------
    (lo, hi) : two (n_changes,) arrays.
    """
    c = np.asarray(codes)
    nxt = np.roll(c, -1, axis=0)
    changed = np.any(c != nxt, axis=1)
    h = period / len(theta)
    a = theta[changed].copy()
    b = a + h
    ca, cb = c[changed], nxt[changed]
    los, his = [], []
    for _ in range(64):  # rounds: one change per open interval per round
        if a.size == 0:
            break
        lo, hi = a.copy(), b.copy()
        for _ in range(80):
            mid = 0.5 * (lo + hi)
            interior = (mid > lo) & (mid < hi)
            if not np.any(interior):
                break
            same = np.all(np.asarray(code_fn(mid)) == ca, axis=1)
            lo = np.where(interior & same, mid, lo)
            hi = np.where(interior & ~same, mid, hi)
        los.append(lo)
        his.append(hi)
        c_hi = np.asarray(code_fn(hi))
        more = np.any(c_hi != cb, axis=1)  # another change between hi and b
        a, b, ca, cb = hi[more], b[more], c_hi[more], cb[more]
    if not los:
        return np.zeros(0), np.zeros(0)
    return np.concatenate(los), np.concatenate(his)


def engagement_angles(mesh, period) -> np.ndarray:
    """Angles where cells enter (xi = xi_start) or leave (xi = xi_end) the path of contact:
    ``Rb1 theta - n p_bt - eta tan(b_b) = 0`` or ``g_alpha`` (see :mod:`gearjax.gears.mesh`)."""
    p = mesh.pair
    pm = p.mesh_period_rad
    n_mesh = int(round(period / pm))
    eta = (np.arange(mesh.cells_per_line) + 0.5) * (p.face_width_m / mesh.cells_per_line)
    shift = eta * math.tan(abs(p.base_helix_angle_rad))
    base = np.concatenate([shift, shift + p.path_of_contact_m]) / p.base_radii_m[0]
    k = np.arange(-int(np.ceil(base.max() / pm)) - 1, n_mesh + 1)
    return np.mod((base[None, :] + pm * k[:, None]).ravel(), period)


def quiet_origin(points, period) -> float:
    """A table origin far from every jump (middle of the widest gap between them)."""
    if len(points) == 0:
        return 0.0
    p = np.sort(np.mod(points, period))
    gaps = np.diff(np.concatenate([p, [p[0] + period]]))
    i = int(np.argmax(gaps))
    return float(np.mod(p[i] + 0.5 * gaps[i], period))


def switch_value(mesh, mods, cells, theta, approach_minus_gap, kind, a, b):
    """The switching function g (m) of an event of ``kind`` at theta, whose root is
    the switching angle: loaded set (cell a): ``approach_minus_gap`` (``y - delta_e_a``,
    Eq. (17); the sdof and 3D quasi-static solutions give it differently); NLTE cell
    (a -> b): ``r_a - r_b`` (Eq. (9)); relief start of the pinion / gear (cell a):
    ``xi_a - (xi_e - L_c1 g_alpha)`` / ``xi_a - (xi_start + L_c2 g_alpha)``; 0 for fixed
    events."""
    r = mesh.removed_material(mods, cells, theta)
    xi_s, xi_e = mesh.pair.contact_limits_m
    ext = mods.relief_extent * mesh.pair.path_of_contact_m
    g = jnp.stack([
        jnp.zeros_like(approach_minus_gap),
        approach_minus_gap,
        r[a] - r[b],
        cells.xi_m[a] - (xi_e - ext[0]),
        cells.xi_m[a] - (xi_s + ext[1]),
    ])
    return g[kind]


def moved_event_angles(switch, s_j, kinds, cells, newton_steps: int = NEWTON_STEPS):
    """Event angles of the current design: ``newton_steps`` Newton iterations on
    ``switch(kind, a, b, theta)`` from each build angle ``s_j`` (events of kind
    ``EV_FIXED`` stay). Differentiable: at the root the iterations return
    ``d theta_j = -(dg/d design) / (dg/d theta)`` (implicit function theorem). A step
    where ``dg/d theta`` is 0 is not taken (a kinked switching function, e.g. a removed
    material that is 0 on one side of a relief start, whose iterate landed on the flat
    side: 0/0 there was NaN, and the NaN angle made the model's structure flag False
    at its own build design)."""
    s_j = jnp.asarray(s_j, dtype=float)
    kinds = jnp.asarray(kinds, dtype=jnp.int32)
    ab = jnp.asarray(cells, dtype=jnp.int32).reshape(-1, 2)

    def one(s, kind, a, b):
        fixed = kind == EV_FIXED

        def step(_, th):
            g, dg = jax.jvp(lambda t: switch(kind, a, b, t), (th,), (jnp.ones((), dtype=float),))
            hold = fixed | (dg == 0.0)
            return th - jnp.where(hold, 0.0, g / jnp.where(hold, 1.0, dg))

        # a loop of static length: one copy of the switching function in the program
        # (compiled once, not newton_steps times), differentiable as the unrolled steps
        return jax.lax.fori_loop(0, newton_steps, step, s)

    return jax.vmap(one)(s_j, kinds, ab[:, 0], ab[:, 1])


def check_event_roots(switch, s_j, kinds, cells, mesh_period: float, rtol: float = 1e-8):
    """Build-time self-check of the event classification: at the build design every
    moving event's switching function must vanish at its build angle, i.e. the Newton
    iterations the models take (:func:`moved_event_angles`, :data:`NEWTON_STEPS`) from
    ``s_j`` must stay within ``rtol`` mesh periods and finite. An event that fails (a
    misread bracket would make the angle map fold onto itself, giving a wrong mean
    stiffness; an iteration that leaves a kinked switching function's root can end in
    NaN, which makes the model's structure flag False at its own design) is kept fixed,
    with a warning: the forward model is then exact and only the derivative of that
    event's angle with respect to the design is lost.
    Returns the (kinds, cells) to store."""
    kinds, cells = list(kinds), list(cells)
    idx = [j for j, k in enumerate(kinds) if k != EV_FIXED]
    if not idx:
        return kinds, cells
    moved = np.asarray(_newton_steps(
        switch, jnp.asarray(np.asarray(s_j, dtype=float)[idx]),
        jnp.asarray([kinds[j] for j in idx], dtype=jnp.int32),
        jnp.asarray([cells[j] for j in idx], dtype=jnp.int32)))
    step = np.abs(moved - np.asarray(s_j, dtype=float)[idx])
    bad = [j for j, d in zip(idx, step) if not (d <= rtol * mesh_period)]
    if bad:
        warnings.warn(
            f"{len(bad)} of {len(idx)} design-dependent switching angles could not be "
            f"located by their switching function at the build design (e.g. angle "
            f"{s_j[bad[0]]:.6g} rad, kind {kinds[bad[0]]}, cells {cells[bad[0]]}); they are "
            "kept at their build angles (forward results exact, their design derivative "
            "is not followed)", RuntimeWarning, stacklevel=3)
        for j in bad:
            kinds[j], cells[j] = EV_FIXED, (0, 0)
    return kinds, cells


@eqx.filter_jit
def _newton_steps(switch, s, kinds, cells, steps: int = NEWTON_STEPS):
    """The ``steps`` Newton steps of :func:`moved_event_angles` in a loop (one step
    compiled), once per switching-function structure (``switch`` a pytree: an
    :class:`equinox.Partial` or a bound method of a model) and number of events, not
    once per build."""
    return jax.lax.fori_loop(0, steps,
                             lambda _, th: moved_event_angles(switch, th, kinds, cells, 1), s)
