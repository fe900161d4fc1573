"""Unilateral contact of the mesh cells: every solve of ``sum_i k_i max(0, y - gap_i) = F``.

Paper Eq. (17): with ``y`` the normal approach (m), the loaded cells satisfy
``sum_i k_i max(0, y - delta_e_i) = F_S``. The solve is exact, not a penalty
approximation: ``f(y) = sum_i k_i max(0, y - delta_e_i)`` is increasing and piecewise
linear, and for *any* prefix ``j`` of the cells sorted by gap, ``f(y) >= f_j(y) =
sum_{l<=j} k_l (y - delta_e_l)`` because ``max(0, z) >= z`` and the dropped terms are
>= 0. Hence the root is ``y* = min_j (F_S + sum_{l<=j} k_l delta_e_l) / sum_{l<=j} k_l``,
attained by the true active set: branch-free, jit/vmap/grad friendly and differentiable
almost everywhere.

* :func:`solve_unilateral` -- one sort and two cumulative sums, O(n log n) (table knots,
  quasi-static solutions);
* :func:`unilateral_solve_pairwise` -- the same root without a sort, O(n^2) (inside a
  vector field, where it vectorises better for n <= ~200);
* :func:`active_set_solve` -- unilateral contact of cells acting along *different*
  structure vectors on a condensed elastic system (the 3D quasi-static solution, Eq. (25)):
  an active-set iteration, exact at convergence;
* :func:`te_contact` -- the contact algorithm of the TE-based formulations (Eqs. (20),
  (42), (47a), (48a)): the mesh acts only while it is in compression;
* :func:`three_state_force` -- the same with a clearance between the back flanks
  (backlash): drive-flank contact, free flight, back-flank contact; used per mesh by
  :func:`te_backlash_contact` (te and perturbation formulations) and with the cell sums of
  both flanks by the sdof reference formulation.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from ..linalg import solve as dense_solve

__all__ = ["solve_unilateral", "unilateral_solve_pairwise", "active_set_solve", "te_contact",
           "three_state_force", "te_backlash_contact"]


def solve_unilateral(k, gap, force):
    """Exact unilateral contact of parallel springs under a total force (Eq. (17)).

    Parameters
    ----------
    k : (n,) cell stiffnesses (N/m); cells with ``k == 0`` are ignored.
    gap : (n,) initial gaps delta_e_i (m).
    force : total normal force F_S (N), > 0.

    Returns
    -------
    (y, loads) : the normal approach y (m) and the cell loads ``k_i max(0, y - gap_i)`` (N).
    """
    active = k > 0
    key = jnp.where(active, gap, jnp.inf)
    order = jnp.argsort(key)
    ks = k[order]
    gs = jnp.where(active[order], gap[order], 0.0)
    kc = jnp.cumsum(ks)
    sc = jnp.cumsum(ks * gs)
    ok = kc > 0
    y_j = jnp.where(ok, (force + sc) / jnp.where(ok, kc, 1.0), jnp.inf)
    y = jnp.min(y_j)
    loads = jnp.where(active, k * jnp.maximum(y - gap, 0.0), 0.0)
    return y, loads



def unilateral_solve_pairwise(k, gap, force):
    """Exact unilateral contact of parallel springs, without a sort (Eq. (17)).

    Same root as :func:`solve_unilateral`: for every active cell j the
    candidate active set is ``{l : gap_l <= gap_j}`` (a prefix of the gap-sorted cells) and
    ``y = min_j (F + sum_l k_l gap_l) / sum_l k_l`` over those sets. O(n^2) operations with
    no data-dependent ordering, which vectorises better than a sort for n <= ~200.

    Parameters
    ----------
    k : (n,) cell stiffnesses (N/m); cells with ``k == 0`` are ignored.
    gap : (n,) initial gaps (m).
    force : total normal force (N), > 0.

    Returns
    -------
    (y, k_loaded) : normal approach (m) and the stiffness of the loaded cells (N/m).
    """
    active = k > 0
    le = (gap[None, :] <= gap[:, None]) & active[None, :]  # [j, l]: l in set of j
    ksum = jnp.sum(jnp.where(le, k[None, :], 0.0), axis=1)
    ksg = jnp.sum(jnp.where(le, (k * gap)[None, :], 0.0), axis=1)
    ok = active & (ksum > 0)
    y_j = jnp.where(ok, (force + ksg) / jnp.where(ok, ksum, 1.0), jnp.inf)
    y = jnp.min(y_j)
    k_loaded = jnp.sum(jnp.where(active & (gap < y), k, 0.0))
    return y, k_loaded


def active_set_solve(k_cc, f_c, vecs, k, gap, active0, max_iter: int):
    """Exact unilateral contact of cells on a linear elastic system (Eq. (25)).

    Solves ``[K_cc + sum_{i in A} k_i V_i V_i^T] x = f_c + sum_{i in A} k_i gap_i V_i`` for
    the active set ``A = {i : k_i > 0, V_i^T x > gap_i}`` by iterating the set from
    ``active0`` until it is stable (``lax.while_loop``, at most ``max_iter`` solves).

    Parameters
    ----------
    k_cc : (m, m) stiffness of the system without the cells (N/m, N m/rad); singular
        directions must be held by the loaded cells.
    f_c : (m,) load (N, N m).
    vecs : (n, m) structure vector V_i of every cell (the approach of cell i is V_i^T x, m).
    k : (n,) cell stiffnesses (N/m); cells with ``k == 0`` never carry load.
    gap : (n,) initial gaps (m).
    active0 : (n,) bool starting set (e.g. the torsional root ``gap < y``).
    max_iter : maximum number of set updates.

    Returns
    -------
    (x, active, iterations, converged) : ``x`` (m,) is a final solve with the converged set
    (no gradient through the set itself: differentiable almost everywhere); ``converged``
    is False when the set still changed at the last iteration.
    """

    def solve(active):
        ka = jnp.where(active, k, 0.0)
        kt = k_cc + (vecs.T * ka[None, :]) @ vecs
        rhs = f_c + vecs.T @ (ka * gap)
        return dense_solve(kt, rhs)  # no LAPACK under vmap (gearjax.linalg)

    def new_set(x):
        return (k > 0) & (vecs @ x - gap > 0)

    def body(c):
        active, _, it = c
        nxt = new_set(solve(active))
        return nxt, jnp.any(nxt != active), it + 1

    def cond_fn(c):
        return c[1] & (c[2] < max_iter)

    active, changed, it = jax.lax.while_loop(
        cond_fn, body, (active0, jnp.asarray(True), jnp.asarray(0))
    )
    active = jax.lax.stop_gradient(active)
    x = solve(active)
    return x, active, it, ~changed


def te_contact(f_equation, f_loaded):
    """The paper's contact algorithm (Section 6.2) in the TE-based formulations.

    Eqs. (20)/(42) and (47a)/(48a) are linear: their mesh force, ``f_equation = F_S +
    k cos(b_b) x_D`` (Eq. (24) / (41), with ``k`` the loaded quasi-static stiffness
    ``(sum k_i)^S`` in (20)/(42) and the mean ``k_m`` in (47a)/(48a); N), turns tensile
    when the dynamic approach falls below the separation approach ``x_S - F_S / (k
    cos b_b)``. Section 6.2 evaluates the stiffness of every formulation "at each step
    depending on the instantaneous contact conditions". These formulations know the mesh
    only through ``TE_S``, ``NLTE`` and ``k(theta)`` (what a measured transmission error
    gives), so the contact state they can resolve is the mesh's: in contact while the
    linear force is compressive, and then the equations are unchanged; separated
    otherwise, and then the mesh stiffness and its transmission-error forcing are both
    zero, so the mesh force is zero, never tensile. Partial loss of contact along the
    lines (some cells unloading) needs each cell's gap, which is the reference
    formulation (Eq. (14)/(16)).

    Parameters
    ----------
    f_equation : the linear mesh force of the equation of motion (N).
    f_loaded : the reported linear mesh force ``F_S + (sum k_i)^S cos(b_b) x_D`` (N, the
        same as ``f_equation`` for te; for the perturbation formulation the tooth load
        is read with the loaded stiffness, Eq. (41)).

    Returns
    -------
    (cut, f_d) : ``cut = min(0, f_equation)``, the force to remove from the linear
    equation (0 while in contact, so the linear equations are kept bit for bit), and the
    reported mesh force ``f_d`` (N): ``max(0, f_loaded)`` in contact, 0 when separated.
    """
    in_contact = f_equation > 0.0
    return (jnp.minimum(f_equation, 0.0),
            jnp.where(in_contact, jnp.maximum(f_loaded, 0.0), 0.0))


def three_state_force(delta, clearance, drive, back=None):
    """The mesh force of a gear pair with backlash: drive flanks, free flight, back flanks.

    With ``delta`` the dynamic displacement along the line of action (m; the normal approach
    of the drive flanks beyond their first contact, > 0 loads the drive flanks) and
    ``b = clearance`` (m, >= 0) the clearance between the back flanks when the drive flanks
    just touch, measured along the line of action (normal to the flanks)::

        F = k(delta)             delta > 0         drive-flank contact
        F = 0                    -b <= delta <= 0  free flight (both flanks open)
        F = -k_b(-(delta + b))   delta < -b        back-flank contact

    ``k(u)``, ``k_b(u)`` are the force-approach laws of the drive and back flanks (N for an
    approach u >= 0, zero at u = 0 and non-decreasing), ``drive`` and ``back`` (default:
    the drive law, the same stiffness law on both flanks). For a linear mesh of stiffness
    k (N/m) this is ``F = k delta``, ``0``, ``k (delta + b)``; the force is continuous in
    ``delta`` and negative (a back-flank load, acting on the drive line of action's
    opposite sense) in back-flank contact. Written as ``k(max(delta, 0)) - k_b(max(-delta
    - b, 0))``: branch-free, traceable, differentiable almost everywhere.

    Parameters
    ----------
    delta : approach of the drive flanks beyond first contact (m), any shape.
    clearance : b (m), broadcastable against ``delta``.
    drive, back : callables ``u -> force`` (N) of a non-negative approach ``u`` (m).

    Returns
    -------
    The signed mesh force F (N), > 0 on the drive flanks, < 0 on the back flanks.
    """
    back = drive if back is None else back
    return drive(jnp.maximum(delta, 0.0)) - back(jnp.maximum(-delta - clearance, 0.0))


def te_backlash_contact(f_equation, f_loaded, k_equation, k_loaded, clearance):
    """The contact algorithm of :func:`te_contact` with a clearance between the back flanks
    (:func:`three_state_force` for a linear mesh).

    The linear mesh force of the equation ``f_equation = F_S + k cos(b_b) x_D`` (N) is
    ``k delta`` with ``delta = f_equation / k`` the approach beyond the drive flanks'
    no-load contact (m, along the line of action, ``k = k_equation`` (N/m): the loaded
    stiffness in (20)/(42), ``k_m`` in (47a)/(48a)). With the clearance ``b`` the equation's
    force becomes ``k delta`` (drive flanks), 0 (free flight, ``-b <= delta <= 0``) and
    ``k (delta + b)`` (back flanks, ``delta < -b``): the back flanks take the drive
    flanks' stiffness law, and the clearance follows the drive flanks' no-load position
    (the tooth thickness is constant: the mesh-level law of Kahraman & Singh, 1991).

    Parameters
    ----------
    f_equation, k_equation : the equation's linear mesh force (N) and its stiffness (N/m, > 0).
    f_loaded, k_loaded : the reported linear mesh force ``F_S + (sum k_i)^S cos(b_b) x_D``
        and the loaded stiffness (as in :func:`te_contact`).
    clearance : b (m), >= 0.

    Returns
    -------
    (cut, f_d) : the force to remove from the linear equation (``f_equation -
    three_state_force(...)``) and the reported mesh force: ``max(0, f_loaded)`` on the drive
    flanks, 0 in free flight, ``min(0, f_loaded + k_loaded b)`` on the back flanks (N).
    """
    delta = f_equation / k_equation
    f = three_state_force(delta, clearance, lambda u: k_equation * u)
    drive, back = delta > 0.0, delta < -clearance
    f_d = jnp.where(drive, jnp.maximum(f_loaded, 0.0),
                    jnp.where(back, jnp.minimum(f_loaded + k_loaded * clearance, 0.0), 0.0))
    return f_equation - f, f_d
