"""Inertial excitations of the 3D model (:class:`gearjax.models.geared3d.Geared3DModel`):
the right-hand side ``-Omega^2 [NLTE'' E + NLTE' F + G]`` of Eqs. (14), (42), (48a) in modal
coordinates.

``E = E_0 + E~(theta)``: ``E_0`` (Eq. (5) and the text after Eq. (14): ``J2 Rb1/Rb2^2`` at
the torque node, ``I_pi/Rb2`` at the gear shaft's torsional dofs) projected once at build
(``e_r = T^T E_0``), ``E~``, ``F~``, ``G~`` the eccentricity parts
(:class:`gearjax.structure.geared.Eccentricity`, at the 12 element dofs). The NLTE'' and
NLTE' terms exist when the model keeps the NLTE inertial terms (``nlte_terms`` and
``nlte_inertia``; Section 6.3.2 runs without them); ``G~`` (the unbalance of eccentric
bodies, no NLTE in it) stays whenever there is an eccentricity.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from ..gears.quasistatic import contact_gaps

__all__ = ["inertial_vectors", "nlte_derivatives"]


def inertial_vectors(m, theta):
    """``(e, e', f, g)`` (r,) in modal coordinates at the pinion angle ``theta`` (rad) of the
    3D model ``m``: ``T^T E``, its theta-derivative, ``T^T F~`` and ``T^T G~``; None for
    the terms that are absent (no eccentricity, or no NLTE inertial terms)."""
    use_e = m.nlte_inertial_terms
    if m.ecc is None:
        e = m.e_r if use_e else None
        return e, (jnp.zeros_like(m.e_r) if use_e else None), None, None
    tl = m.t_local.T
    rb1, rb2 = m.mesh.pair.base_radii_m

    def e_fun(t):
        return m.e_r + tl @ m.ecc.local_vectors(t, rb1, rb2)[0]

    _, f_loc, g_loc = m.ecc.local_vectors(theta, rb1, rb2)
    g = tl @ g_loc
    if not use_e:
        return None, None, None, g
    e, ep = jax.jvp(e_fun, (theta,), (jnp.ones_like(theta),))
    return e, ep, tl @ f_loc, g


def nlte_derivatives(m, s, order: int = 1):
    """NLTE (m) and its derivatives with respect to theta (1 or 2) at the simulation angle
    ``s`` of the 3D model ``m`` (chain rule through the angle map: d/dtheta = (d/ds) /
    phi'): from the excitation table (exact at the kinks, which are knots) or the exact
    :func:`gearjax.gears.quasistatic.contact_gaps`."""
    if m.table is not None:
        f = lambda t: m.table(t)[0][2]  # noqa: E731
    else:
        f = lambda t: contact_gaps(m.mesh, m.mods, t)[2]  # noqa: E731

    def d1(t):
        n0, n1 = jax.jvp(f, (t,), (jnp.ones_like(t),))
        dth = m.angle(t)[1]
        return n0, (n1 if dth is None else n1 / dth)

    if order == 1:
        return d1(s)
    (n0, n1), (_, n2) = jax.jvp(d1, (s,), (jnp.ones_like(s),))
    dth = m.angle(s)[1]
    return n0, n1, (n2 if dth is None else n2 / dth)
