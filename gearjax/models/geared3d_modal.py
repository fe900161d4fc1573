"""Products with the reduced modal matrices of :class:`gearjax.models.geared3d.Geared3DModel`.

The basis holds the modes of ``(M, K_bar)`` and static corrections orthogonalised against
them, so ``kbar_r = T^T K_bar T`` is diagonal (to round-off) and modal damping makes
``c_r = T^T C T`` diagonal except on the trailing static-correction block. The vector field
applies them as such (:func:`stiffness_product`, :func:`damping_product`), since the two
dense products take most of a step (``benchmarks/results/code_notes.md``, section
gearjax.models.geared3d_modal, and ``modal_products.md`` there). :func:`modal_structure`
decides at build which form holds; a rig whose damping couples modes keeps the dense one.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from ..excitation.mesh3d import fourier_coefficients, harmonic_response

__all__ = ["modal_structure", "stiffness_product", "damping_product", "harmonic_modal_state"]


def modal_structure(kbar_r, c_r, n_modes: int, tol: float = 1e-6) -> dict:
    """How the vector field may apply the reduced matrices (static fields of
    :class:`Geared3DModel`): ``diagonal_stiffness`` when every off-diagonal entry of
    ``kbar_r`` is below ``tol`` of the geometric mean of its two diagonal entries (the modes
    of ``(M, K_bar)``, static corrections orthogonalised: round-off, ~1e-8 for the slowest
    mode of the Baud-Velex rig); ``damping_split = n_modes`` when ``c_r`` passes the same
    test except on its trailing static-correction block (modal damping), else 0 (dense). A
    step of the 3D rig (146 coordinates) spent most of its time in these two dense
    products."""
    k, c = np.asarray(kbar_r, dtype=float), np.asarray(c_r, dtype=float)

    def diagonal(a):  # off-diagonal entries small against sqrt(a_ii a_jj)
        d = np.sqrt(np.abs(np.diag(a)))
        off = np.abs(a - np.diag(np.diag(a)))
        return bool(np.all(off <= tol * np.outer(d, d)))

    p = int(n_modes)
    head = np.array(c, copy=True)
    head[p:, p:] = np.diag(np.diag(c)[p:])  # the static-correction block may be dense
    split = p if 0 < p <= c.shape[0] and diagonal(head) else 0
    return {"diagonal_stiffness": diagonal(k), "damping_split": split}


def stiffness_product(model, z):
    """``kbar_r @ z`` (modal coordinates), as the diagonal product where
    ``model.diagonal_stiffness``."""
    if model.diagonal_stiffness:
        return jnp.diagonal(model.kbar_r) * z
    return model.kbar_r @ z


def damping_product(model, qp):
    """``c_r @ qp``: diagonal on the first ``model.damping_split`` (modal) coordinates,
    dense on the static-correction block after them (0: dense everywhere)."""
    p = model.damping_split
    if p == 0:
        return model.c_r @ qp
    head = jnp.diagonal(model.c_r)[:p] * qp[:p]
    return jnp.concatenate([head, model.c_r[p:, p:] @ qp[p:]])


def harmonic_modal_state(m, d, omega, theta0=0.0, n_harmonics: int | None = None):
    """Scaled periodic state of the constant-coefficient Eq. (48a) of the model ``m`` at
    ``theta0`` (:meth:`Geared3DModel.harmonic_state`): the forcing ``d(theta) = TE_S - NLTE
    - w_x0`` (m) sampled 8x finer than the table knots (aliasing of a kinked signal),
    ``n_harmonics`` (default 128 per mesh period) each answered by the modal receptance."""
    n_mesh = max(1, round(m.period_rad / m.mesh_period_rad))
    n_h = 128 * n_mesh if n_harmonics is None else int(n_harmonics)
    c = fourier_coefficients(d, m.table_origin, m.period_rad,
                             8 * max(m.table_cells, 2 * n_h + 2), n_h, theta0)
    z, zp = harmonic_response(m.kbar_r, m.c_r, m.v_r, m.k_m * m.cos_bb * c, m.period_rad, omega)
    rr = m.omega_r / omega
    return jnp.concatenate([z / m.scale_a, zp / (rr * m.scale_a)])
