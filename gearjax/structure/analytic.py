"""Analytical quantities of Section 4.3 and Appendix A: C_v, C_vv, C_wv, X_0, X^_0, v_x0, w_x0.

With ``K_bar = K + k_m V V^T`` (averaged total stiffness, Eq. (27)):

* ``C_v = K_bar^{-1} V``, ``C_vv = V^T C_v`` (= 1/k_m, Eq. (33) / (A.3)),
* ``C_wv = W^T C_v`` (= 1/(k_m cos beta_b), Eq. (35) / (A.12)),
* ``X_0 = K_bar^{-1} F_0``, ``v_x0 = V^T X_0`` (= F_S/k_m, Eq. (34) / (A.5)),
  ``w_x0 = W^T X_0``,
* ``X^_0 = F_S C_v`` (Eq. (A.2)), whose bending/axial part vanishes (A.7) and whose
  ``W^T X^_0`` does not depend on where the encoders sit (A.8)-(A.10).

The relations hold exactly when ``K`` (the structure without the mesh) leaves the pinion
shaft line free in torsion (the motor torque is imposed), which is how the paper's rig is
loaded: then a rigid rotation ``r`` of that line satisfies ``K r = 0`` and
``K_bar (r / (k_m V^T r)) = V``, so ``C_v = r / (k_m V^T r)``.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["AnalyticRelations", "analytic_relations"]


class AnalyticRelations(dict):
    """The analytical quantities (a dict with attribute access); keys documented in
    :func:`analytic_relations`."""

    __getattr__ = dict.__getitem__


def analytic_relations(K, k_m, V, W, F0, static_force_N, base_helix_angle_rad) -> AnalyticRelations:
    """Compute the Appendix A quantities and their normalised forms.

    Parameters
    ----------
    K : (n, n) structure stiffness without the mesh (N/m, N m/rad).
    k_m : mean mesh stiffness (N/m).
    V : (n,) averaged structure vector.
    W : (n,) TE projection vector (Rb1, Rb2 at the encoder torsional dofs), Eq. (10).
    F0 : (n,) constant load vector (nominal torques).
    static_force_N : F_S (N).
    base_helix_angle_rad : beta_b.

    Returns
    -------
    AnalyticRelations with ``C_v, C_vv, C_wv, X_0, X_hat_0, v_x0, w_x0`` and the ratios
    ``C_vv_times_km`` (= 1), ``C_wv_times_km_cos_beta_b`` (= 1), ``v_x0_times_km_over_FS``
    (= 1), ``w_hat_x0`` (= W^T X^_0).
    """
    K, V, W, F0 = (np.asarray(a, dtype=float) for a in (K, V, W, F0))
    k_bar = K + k_m * np.outer(V, V)
    c_v = np.linalg.solve(k_bar, V)
    x_0 = np.linalg.solve(k_bar, F0)
    cos_bb = math.cos(base_helix_angle_rad)
    c_vv, c_wv = V @ c_v, W @ c_v
    v_x0, w_x0 = V @ x_0, W @ x_0
    return AnalyticRelations(
        K_bar=k_bar,
        C_v=c_v,
        C_vv=c_vv,
        C_wv=c_wv,
        X_0=x_0,
        X_hat_0=static_force_N * c_v,
        v_x0=v_x0,
        w_x0=w_x0,
        w_hat_x0=static_force_N * c_wv,
        C_vv_times_km=c_vv * k_m,
        C_wv_times_km_cos_beta_b=c_wv * k_m * cos_bb,
        v_x0_times_km_over_FS=v_x0 * k_m / static_force_N,
    )
