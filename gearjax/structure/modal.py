"""Modal tools of the structure: mass-normalised modal basis, modal damping, reduced
(modal + static correction) models of ``(M, K)``. NumPy float64, built once outside
``jit``; SI units (rad/s, Hz).
"""

from __future__ import annotations

import math
import warnings

import equinox as eqx
import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import StructureInputError

__all__ = [
    "ModalBasis",
    "ReducedModel",
    "RigidBodyModeWarning",
    "modal_basis",
    "modal_damping_matrix",
    "reduced_model",
]


class RigidBodyModeWarning(UserWarning):
    """The structure has zero-frequency (rigid-body) modes."""


class ModalBasis(eqx.Module):
    """Mass-normalised modes of ``(M, K)``: ``Phi^T M Phi = I``, ``Phi^T K Phi = diag(w^2)``.

    Attributes
    ----------
    modes : ndarray, shape (n_dof, n_modes)
        Mode shapes ``Phi`` (columns), mass-normalised, sorted by frequency.
    omegas_rad_s : ndarray, shape (n_modes,)
        Natural angular frequencies (rad/s); rigid-body modes are exactly 0.
    n_rigid : int
        Number of rigid-body (zero-frequency) modes, which come first.
    """

    modes: NDArray[np.float64]
    omegas_rad_s: NDArray[np.float64]
    n_rigid: int = eqx.field(static=True)

    @property
    def frequencies_hz(self) -> NDArray[np.float64]:
        """Natural frequencies (Hz)."""
        return np.asarray(self.omegas_rad_s) / (2.0 * math.pi)

    @property
    def n_modes(self) -> int:
        """Number of modes kept."""
        return int(np.shape(self.omegas_rad_s)[0])


def _check_pair(M: ArrayLike, K: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    Mn = np.asarray(M, dtype=np.float64)
    Kn = np.asarray(K, dtype=np.float64)
    if Mn.ndim != 2 or Mn.shape[0] != Mn.shape[1]:
        raise StructureInputError(f"M must be a square matrix, got shape {Mn.shape}")
    if Kn.shape != Mn.shape:
        raise StructureInputError(f"K must have the shape of M {Mn.shape}, got {Kn.shape}")
    if not (np.all(np.isfinite(Mn)) and np.all(np.isfinite(Kn))):
        raise StructureInputError("M and K must be finite")
    return 0.5 * (Mn + Mn.T), 0.5 * (Kn + Kn.T)


def _full_eig(
    M: NDArray[np.float64], K: NDArray[np.float64], rigid_body_tol: float
) -> tuple[NDArray[np.float64], NDArray[np.float64], int]:
    """All eigenpairs of ``K x = w^2 M x`` via Cholesky ``M = L L^T``."""
    try:
        L = np.linalg.cholesky(M)
    except np.linalg.LinAlgError as exc:
        raise StructureInputError(
            "M must be symmetric positive definite (a dof without mass?)"
        ) from exc
    Linv = np.linalg.inv(L)
    A = Linv @ K @ Linv.T
    lam, Y = np.linalg.eigh(0.5 * (A + A.T))
    scale = max(float(np.abs(lam).max()), np.finfo(float).tiny)
    if lam[0] < -rigid_body_tol * scale:
        raise StructureInputError(
            f"K must be positive semi-definite; smallest eigenvalue {lam[0]!r} (rad/s)^2"
        )
    # at most as many rigid-body modes as K has free motions once Jacobi-scaled: a very
    # stiff support (1e14 N/m, "rigid") lifts max(w^2) so far that a soft but real mode
    # would otherwise fall below rigid_body_tol * max(w^2) and be zeroed
    rigid = lam <= rigid_body_tol * scale
    n_rigid = min(int(rigid.sum()), scaled_null_dimension(K, rigid_body_tol))
    rigid = np.arange(lam.size) < n_rigid
    lam = np.where(rigid, 0.0, np.maximum(lam, 0.0))
    modes = Linv.T @ Y
    return np.sqrt(lam), modes, n_rigid


def scaled_null_dimension(K: NDArray[np.float64], tol: float = 1e-10) -> int:
    """Number of free motions of the stiffness matrix ``K`` (the dimension of its null
    space) after Jacobi scaling ``D^-1/2 K D^-1/2`` (``D = diag K``; a dof without
    stiffness is its own free motion): a stiffness contrast between dofs (a 1e14 N/m
    bearing next to a 1e5 N m/rad torsional spring) no longer drowns the soft directions
    in round-off. An eigenvalue of the scaled matrix below ``tol`` times its largest is
    a free motion."""
    d = np.diag(K).copy()
    scale = 1.0 / np.sqrt(np.where(d > 0, d, 1.0))
    lam = np.linalg.eigvalsh(K * scale[:, None] * scale[None, :])
    return int(np.sum(lam <= tol * max(float(lam[-1]), 1e-300)))


def modal_basis(
    M: ArrayLike,
    K: ArrayLike,
    n_modes: int | None = None,
    max_frequency_hz: float | None = None,
    *,
    rigid_body_tol: float = 1e-10,
    warn: bool = True,
) -> ModalBasis:
    """Mass-normalised modes of the generalized symmetric problem ``K phi = w^2 M phi``.

    Solved densely with NumPy: ``M = L L^T`` (Cholesky), ``eigh(L^-1 K L^-T)``. The
    structures of interest have a few hundred dof, so all pairs are computed and then
    truncated.

    Parameters
    ----------
    M, K : array_like, shape (n, n)
        Symmetric mass (positive definite) and stiffness (positive semi-definite).
    n_modes : int, optional
        Keep at most this many modes (lowest first).
    max_frequency_hz : float, optional
        Keep only modes with ``f <= max_frequency_hz``.
    rigid_body_tol : float
        An eigenvalue ``w^2 <= rigid_body_tol * max(w^2)`` is a rigid-body mode; its
        frequency is set to exactly 0.
    warn : bool
        Emit a :class:`RigidBodyModeWarning` when rigid-body modes are found.

    Returns
    -------
    ModalBasis
    """
    Mn, Kn = _check_pair(M, K)
    if n_modes is not None and (
        isinstance(n_modes, bool) or not isinstance(n_modes, (int, np.integer)) or n_modes < 1
    ):
        raise StructureInputError(f"n_modes must be a positive integer, got {n_modes!r}")
    if max_frequency_hz is not None:
        f = float(max_frequency_hz)
        if not (math.isfinite(f) and f > 0.0):
            raise StructureInputError(
                f"max_frequency_hz must be finite and > 0, got {max_frequency_hz!r}"
            )
    omegas, modes, n_rigid = _full_eig(Mn, Kn, rigid_body_tol)
    keep = np.ones(omegas.shape, dtype=bool)
    if max_frequency_hz is not None:
        keep &= omegas <= 2.0 * math.pi * float(max_frequency_hz)
    idx = np.flatnonzero(keep)
    if n_modes is not None:
        idx = idx[: int(n_modes)]
    if warn and n_rigid:
        warnings.warn(
            f"{n_rigid} rigid-body mode(s) (zero frequency): K is singular. A geared "
            "system needs the pinion-gear element (K + k_m V V^T, Eq. (27)) or a "
            "torsional datum to remove the free shaft-line rotation.",
            RigidBodyModeWarning,
            stacklevel=2,
        )
    return ModalBasis(modes=modes[:, idx], omegas_rad_s=omegas[idx], n_rigid=min(n_rigid, idx.size))


def modal_damping_matrix(
    M: ArrayLike,
    modes: ArrayLike,
    omegas_rad_s: ArrayLike,
    zeta: float | ArrayLike,
) -> NDArray[np.float64]:
    """Viscous damping matrix with modal damping factor(s) ``zeta``.

    .. math::  C = M \\Phi \\, \\mathrm{diag}(2 \\zeta_j \\omega_j) \\, \\Phi^T M

    With mass-normalised modes this gives ``Phi^T C Phi = diag(2 zeta_j omega_j)``, i.e.
    each retained mode has damping ratio ``zeta_j``; modes not in ``modes`` are undamped
    and rigid-body modes (``omega = 0``) get no damping. Section 6.1 of the paper uses a
    unique factor ``zeta = 0.03`` or ``0.1`` on all modes; the damping matrix ``[C]`` then
    enters Eq. (42).

    Parameters
    ----------
    M : array_like, shape (n, n)
        Mass matrix.
    modes : array_like, shape (n, m)
        Mass-normalised modes.
    omegas_rad_s : array_like, shape (m,)
        Their natural frequencies (rad/s).
    zeta : float or array_like, shape (m,)
        Modal damping factor(s), >= 0.
    """
    Mn = np.asarray(M, dtype=np.float64)
    Phi = np.asarray(modes, dtype=np.float64)
    w = np.asarray(omegas_rad_s, dtype=np.float64)
    if Phi.ndim != 2 or Phi.shape[0] != Mn.shape[0] or w.shape != (Phi.shape[1],):
        raise StructureInputError(
            f"modes must be (n, m) with n = {Mn.shape[0]} and omegas_rad_s (m,), got "
            f"{Phi.shape} and {w.shape}"
        )
    z = np.broadcast_to(np.asarray(zeta, dtype=np.float64), w.shape)
    if not np.all(np.isfinite(z)) or np.any(z < 0.0):
        raise StructureInputError(f"zeta must be finite and >= 0, got {zeta!r}")
    MP = Mn @ Phi
    C = (MP * (2.0 * z * w)[None, :]) @ MP.T
    return 0.5 * (C + C.T)


class ReducedModel(eqx.Module):
    """Modal model truncated at a cut-off frequency, with static correction.

    The full model ``M X'' + C X' + K(t) X = F`` (Eqs. (14), (42) after the change of
    variable) is projected on ``X = T q``:

    .. math::

        T = [\\Phi_k \\; | \\; \\Psi], \\qquad
        M_r = T^T M T = I, \\quad K_r = T^T K T, \\quad C_r = T^T C T, \\quad
        f_r = T^T F .

    ``Phi_k`` are the modes with ``f <= max_frequency_hz`` (rigid-body modes included).
    ``Psi`` are static-correction (residual-flexibility) vectors: for each load pattern
    ``F_j`` given at construction, ``G_res F_j`` with
    ``G_res = sum_{truncated elastic j} phi_j phi_j^T / w_j^2``, i.e. the part of the
    static response ``K^+ F_j`` that the kept modes miss. They are M-orthonormalised and
    rotated so that ``M_r = I`` and ``K_r`` is diagonal (the correction vectors become
    "pseudo-modes" above the cut-off). Consequently ``T K_r^+ T^T F`` reproduces the full
    static response exactly for any ``F`` in the span of the load patterns, and the kept
    natural frequencies are exact.

    Intended use: pass as load patterns the nominal torque vector ``F_0`` and the averaged
    structure vector ``V`` (Eq. (A.1)); then the reduced system reproduces the quasi-static
    solution ``X_S`` of Eq. (25) with ``K + k_m V V^T`` exactly (Sherman-Morrison: the
    solution lies in span ``{K^+ F_0, K^+ V}`` plus the kept modes), and the mesh term
    becomes ``k(t) (T^T V)(T^T V)^T`` of size ``r x r``.

    Attributes
    ----------
    basis : ndarray, shape (n_dof, r)
        ``T``.
    M, K, C : ndarray, shape (r, r)
        Reduced mass (identity), stiffness (diagonal) and damping (``T^T C T``).
    omegas_rad_s : ndarray, shape (r,)
        ``sqrt(diag(K))`` (rad/s): kept modes first, then the pseudo-modes.
    n_modes : int
        Number of true modes (first columns of ``basis``).
    n_static : int
        Number of static-correction vectors (last columns).
    """

    basis: NDArray[np.float64]
    M: NDArray[np.float64]
    K: NDArray[np.float64]
    C: NDArray[np.float64]
    omegas_rad_s: NDArray[np.float64]
    n_modes: int = eqx.field(static=True)
    n_static: int = eqx.field(static=True)

    def project_force(self, F: ArrayLike) -> NDArray[np.float64]:
        """Generalised force ``T^T F`` for ``F`` of shape (n_dof,) or (n_dof, k)."""
        return np.asarray(self.basis).T @ np.asarray(F, dtype=np.float64)

    def project_matrix(self, A: ArrayLike) -> NDArray[np.float64]:
        """``T^T A T`` for an extra ``(n_dof, n_dof)`` matrix (e.g. ``k_m V V^T``)."""
        T = np.asarray(self.basis)
        return T.T @ np.asarray(A, dtype=np.float64) @ T

    def expand(self, q: ArrayLike) -> NDArray[np.float64]:
        """Physical displacements ``X = T q``."""
        return np.asarray(self.basis) @ np.asarray(q, dtype=np.float64)


def reduced_model(
    M: ArrayLike,
    K: ArrayLike,
    static_loads: ArrayLike | None = None,
    *,
    max_frequency_hz: float | None = None,
    n_modes: int | None = None,
    zeta: float = 0.0,
    rigid_body_tol: float = 1e-10,
) -> ReducedModel:
    """Build a :class:`ReducedModel` (modal truncation plus static correction).

    Parameters
    ----------
    M, K : array_like, shape (n, n)
        Full mass and stiffness.
    static_loads : array_like, shape (n,) or (n, p), optional
        Load patterns whose static response must be reproduced exactly.
    max_frequency_hz : float, optional
        Cut-off: keep modes with ``f <= max_frequency_hz``.
    n_modes : int, optional
        Keep at most this many modes.
    zeta : float
        Unique modal damping factor; ``C = modal_damping_matrix(M, all modes, zeta)``
        is built on the full model and projected (``C_r = T^T C T``), so the kept modes
        have damping ratio ``zeta`` exactly.
    rigid_body_tol : float
        See :func:`modal_basis`.
    """
    Mn, Kn = _check_pair(M, K)
    omegas, modes, n_rigid = _full_eig(Mn, Kn, rigid_body_tol)
    keep = np.ones(omegas.shape, dtype=bool)
    if max_frequency_hz is not None:
        f = float(max_frequency_hz)
        if not (math.isfinite(f) and f > 0.0):
            raise StructureInputError(
                f"max_frequency_hz must be finite and > 0, got {max_frequency_hz!r}"
            )
        keep &= omegas <= 2.0 * math.pi * f
    if n_modes is not None:
        if isinstance(n_modes, bool) or not isinstance(n_modes, (int, np.integer)) or n_modes < 1:
            raise StructureInputError(f"n_modes must be a positive integer, got {n_modes!r}")
        keep &= np.arange(omegas.size) < int(n_modes)
    keep[:n_rigid] = True
    kept = np.flatnonzero(keep)
    trunc = np.flatnonzero(~keep)
    Phi_k = modes[:, kept]
    basis = [Phi_k]
    n_static = 0
    if static_loads is not None and trunc.size:
        F = np.asarray(static_loads, dtype=np.float64)
        if F.ndim == 1:
            F = F[:, None]
        if F.ndim != 2 or F.shape[0] != Mn.shape[0] or not np.all(np.isfinite(F)):
            raise StructureInputError(
                f"static_loads must be finite with shape ({Mn.shape[0]},) or ({Mn.shape[0]}, p), "
                f"got {F.shape}"
            )
        Phi_t = modes[:, trunc]
        Y = Phi_t @ ((Phi_t.T @ F) / (omegas[trunc] ** 2)[:, None])
        # M-orthonormalise (drop load patterns already spanned by the kept modes).
        S = Y.T @ Mn @ Y
        s, U = np.linalg.eigh(0.5 * (S + S.T))
        ok = s > 1e-12 * max(float(s.max(initial=0.0)), np.finfo(float).tiny)
        if np.any(ok):
            Yo = Y @ (U[:, ok] / np.sqrt(s[ok])[None, :])
            Kb = Yo.T @ Kn @ Yo
            lam, R = np.linalg.eigh(0.5 * (Kb + Kb.T))
            basis.append(Yo @ R)
            n_static = int(ok.sum())
    T = np.concatenate(basis, axis=1)
    C_full = modal_damping_matrix(Mn, modes, omegas, zeta)
    Mr = T.T @ Mn @ T
    Kr = T.T @ Kn @ T
    Cr = T.T @ C_full @ T
    sym = lambda A: 0.5 * (A + A.T)  # noqa: E731
    Kr = sym(Kr)
    return ReducedModel(
        basis=T,
        M=sym(Mr),
        K=Kr,
        C=sym(Cr),
        omegas_rad_s=np.sqrt(np.clip(np.diag(Kr), 0.0, None)),
        n_modes=int(kept.size),
        n_static=n_static,
    )
