"""Tooth shape modifications and errors (paper Section 2.2.1, Eq. (7), Fig. 4, Fig. 5).

A :class:`ToothModifications` is a pytree of arrays (differentiable design values) with the
relief *shape* and the *presence* of each error kind as static structure, so a scenario
without pitch errors or eccentricity compiles without those terms.

Sign convention
---------------
Every deviation is expressed as material **removed** from the nominal flank, measured
along the flank normal n (m), composite over pinion and gear: ``r(M) >= 0`` for a relief.
The paper's composite normal deviation is ``e(M) = -r(M)`` and the initial gap of Eq. (7)
is ``delta_e(M_i) = max_j e(M_j) - e(M_i) = r(M_i) - min_j r(M_j)`` over the cells inside
the path of contact (see :mod:`gearjax.gears.quasistatic`).

* Tip relief of gear k (Fig. 4): amplitude ``P_c`` at the tip, extent ``L_c`` as a fraction
  of the nominal path of contact ``g_alpha`` measured on the base plane, starting
  ``L_c g_alpha`` before the tip. Linear: ``P_c u``; parabolic: ``P_c u**2`` with
  ``u = (distance into the relief zone) / (L_c g_alpha)``. Pinion relief acts near the end
  of contact (pinion tip), gear relief near the start of contact (gear tip).
* Cumulative pitch deviations ``f_pk[tooth]`` (m, along the transverse line of action):
  positive means the flank stands *ahead* towards its mate (material excess), so it
  removes ``-f cos(beta_b)`` along the normal.
* Eccentricity of gear k, amplitude ``e_k`` (m) and phase ``lambda_k`` (rad): its centre
  offset projected on the line of action adds an excess ``e_k cos(beta_b) sin(phi_k -
  lambda_k)``, with ``phi_1 = theta`` and ``phi_2 = theta z1/z2`` the angles turned.
* Lead crowning (composite, symmetric): removes ``C_c (2 eta/b - 1)**2``.
"""

from __future__ import annotations

import math
import warnings
from typing import Literal

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from ..errors import ModificationError

__all__ = ["ToothModifications", "ModificationError"]

ReliefShape = Literal["linear", "parabolic"]


def _concrete(x) -> np.ndarray | None:
    """The value of ``x`` as NumPy when it is concrete (not traced), else None."""
    if isinstance(x, jax.core.Tracer):
        return None
    return np.asarray(x)


class ToothModifications(eqx.Module):
    """Tip reliefs, pitch errors, eccentricities and crowning of a gear pair.

    Array fields are design values (differentiable); ``relief_shape`` is static.

    Attributes
    ----------
    relief_amplitude_m : (2,) tip relief amplitudes P_c of pinion and gear (m).
    relief_extent : (2,) extents L_c as fractions of the path of contact (0 < L_c <= 1).
    relief_shape : ``"linear"`` or ``"parabolic"`` (static).
    pitch_errors_m : ``None`` or a pair ``(f_p1 (z1,), f_p2 (z2,))`` of cumulative pitch
        deviations (m). ``None`` removes the term at compile time.
    eccentricity_m, eccentricity_phase_rad : ``None`` or (2,) arrays (m, rad).
    crowning_m : scalar composite lead crowning amplitude (m).
    """

    relief_amplitude_m: jax.Array
    relief_extent: jax.Array
    relief_shape: str = eqx.field(static=True, default="linear")
    pitch_errors_m: tuple[jax.Array, jax.Array] | None = None
    eccentricity_m: jax.Array | None = None
    eccentricity_phase_rad: jax.Array | None = None
    # a NumPy zero by default: built inside a traced function it stays a known constant,
    # so the sdof build can still merge the cells of uncrowned spur contact lines
    crowning_m: jax.Array = eqx.field(default_factory=lambda: np.asarray(0.0))

    def __check_init__(self):
        if self.relief_shape not in ("linear", "parabolic"):
            raise ModificationError(
                f"relief_shape={self.relief_shape!r}: must be 'linear' or 'parabolic'"
            )
        amp = _concrete(self.relief_amplitude_m)
        if amp is not None:
            if amp.shape != (2,):
                raise ModificationError(
                    f"relief_amplitude_m has shape {amp.shape}: expected (2,) (pinion, gear)"
                )
            if not np.all(np.isfinite(amp)) or np.any(amp < 0):
                raise ModificationError(
                    f"relief_amplitude_m={amp.tolist()}: tip relief amplitudes must be >= 0 (m)"
                )
            if np.any(amp > 1e-3):
                raise ModificationError(
                    f"relief_amplitude_m={amp.tolist()}: above 1 mm; amplitudes are in metres "
                    "(13.3 um is 13.3e-6)"
                )
        ext = _concrete(self.relief_extent)
        if ext is not None:
            if ext.shape != (2,):
                raise ModificationError(
                    f"relief_extent has shape {ext.shape}: expected (2,) (pinion, gear)"
                )
            if not np.all(np.isfinite(ext)) or np.any(ext <= 0) or np.any(ext > 1):
                raise ModificationError(
                    f"relief_extent={ext.tolist()}: extents are fractions of the path of "
                    "contact and must lie in (0, 1]"
                )
        if (self.eccentricity_m is None) != (self.eccentricity_phase_rad is None):
            raise ModificationError(
                "eccentricity_m and eccentricity_phase_rad must be given together"
            )

    # ------------------------------------------------------------------ constructors
    @classmethod
    def none(cls) -> "ToothModifications":
        """Perfect gears (no relief, no error). The relief extent is a placeholder."""
        return cls(jnp.zeros(2), jnp.full(2, 0.5))

    @classmethod
    def tip_relief(
        cls,
        amplitude_m,
        extent,
        shape: ReliefShape = "linear",
        **errors,
    ) -> "ToothModifications":
        """The same tip relief (or per-gear values if 2-vectors are given) on both gears."""
        amp = jnp.broadcast_to(jnp.asarray(amplitude_m, dtype=float), (2,))
        ext = jnp.broadcast_to(jnp.asarray(extent, dtype=float), (2,))
        return cls(amp, ext, shape, **errors)

    def with_pitch_errors(self, f_p1_m, f_p2_m) -> "ToothModifications":
        return eqx.tree_at(
            lambda m: m.pitch_errors_m,
            self,
            (jnp.asarray(f_p1_m, dtype=float), jnp.asarray(f_p2_m, dtype=float)),
            is_leaf=lambda x: x is None,
        )

    def with_eccentricity(self, amplitude_m, phase_rad) -> "ToothModifications":
        amp = jnp.broadcast_to(jnp.asarray(amplitude_m, dtype=float), (2,))
        ph = jnp.broadcast_to(jnp.asarray(phase_rad, dtype=float), (2,))
        return eqx.tree_at(
            lambda m: (m.eccentricity_m, m.eccentricity_phase_rad),
            self,
            (amp, ph),
            is_leaf=lambda x: x is None,
        )

    # ------------------------------------------------------------------ evaluation
    def removed_material(self, pair, xi, eta, pinion_tooth, gear_tooth, theta):
        """Composite material removed along the normal at cells (m); see module docstring.

        Parameters
        ----------
        pair : :class:`gearjax.gears.geometry.GearPair`.
        xi, eta : cell positions on the base plane (m), any shape.
        pinion_tooth, gear_tooth : integer tooth indices, same shape.
        theta : pinion angle (rad), scalar.
        """
        xi_a, xi_e = pair.contact_limits_m
        g = pair.path_of_contact_m
        shape = (lambda u: u) if self.relief_shape == "linear" else (lambda u: u * u)
        amp = self.relief_amplitude_m
        ext = self.relief_extent * g
        u1 = jnp.maximum(xi - (xi_e - ext[0]), 0.0) / ext[0]
        u2 = jnp.maximum((xi_a + ext[1]) - xi, 0.0) / ext[1]
        r = amp[0] * shape(u1) + amp[1] * shape(u2)
        cos_bb = math.cos(pair.base_helix_angle_rad)
        if self.pitch_errors_m is not None:
            f1, f2 = self.pitch_errors_m
            r = r - cos_bb * (f1[pinion_tooth] + f2[gear_tooth])
        if self.eccentricity_m is not None:
            phi = jnp.stack([theta, theta * pair.z1 / pair.z2])
            excess = jnp.sum(self.eccentricity_m * jnp.sin(phi - self.eccentricity_phase_rad))
            r = r - cos_bb * excess
        b = pair.face_width_m
        r = r + self.crowning_m * (2.0 * eta / b - 1.0) ** 2
        return r

    def excitation_period_rad(self, pair) -> float:
        """Period of the excitation in theta (rad): the lcm of the mesh period and the
        rotations that carry errors (pinion: z1 mesh periods, gear: z2 mesh periods).

        Warns when errors on both gears make it the hunting period (costly simulations).
        """
        n = 1
        if self.pitch_errors_m is not None:
            for f, z in zip(self.pitch_errors_m, (pair.z1, pair.z2)):
                if np.any(np.diff(np.asarray(f)) != 0.0):
                    n = math.lcm(n, z)
        if self.eccentricity_m is not None:
            for e, z in zip(np.asarray(self.eccentricity_m), (pair.z1, pair.z2)):
                if e != 0.0:
                    n = math.lcm(n, z)
        if n > 4 * max(pair.z1, pair.z2):
            warnings.warn(
                f"the excitation period is {n} mesh periods (errors on both gears give the "
                "hunting period): simulations over whole periods will be costly",
                stacklevel=3,
            )
        return n * pair.mesh_period_rad

    def flat_relief_band_m(self, pair) -> float:
        """Length (m, on the transverse path of contact) of the band where the composite
        linear relief is constant (0 when there is none).

        Two linear tip reliefs overlap when ``L_c1 + L_c2 > 1``; there the composite relief
        ``P_c1 u1 + P_c2 u2`` changes along the path with slope ``P_c1/(L_c1 g) -
        P_c2/(L_c2 g)``. With equal slopes ``P_c1/L_c1 = P_c2/L_c2`` (e.g. the same relief on
        both gears) it is the constant ``min r`` over the whole overlap ``(L_c1 + L_c2 - 1)
        g``: a rigid shift of the flanks there (NLTE constant), not a relief. Needs concrete
        values (returns 0 for traced ones)."""
        amp, ext = _concrete(self.relief_amplitude_m), _concrete(self.relief_extent)
        if amp is None or ext is None or self.relief_shape != "linear" or np.any(amp <= 0):
            return 0.0
        s1, s2 = amp / ext
        if abs(s1 - s2) > 1e-9 * max(s1, s2):
            return 0.0
        return max(0.0, float(ext.sum()) - 1.0) * pair.path_of_contact_m

    def check_against(self, pair, *, dynamics: bool = True) -> None:
        """Check array sizes against the pair's tooth numbers (clear error if wrong).

        ``dynamics`` (default; the dynamic models' builds and rig files) also refuses
        linear reliefs of equal slope whose flat band (:meth:`flat_relief_band_m`) is
        longer than the transverse base pitch (spur: two teeth in it at once) or, for
        helical gears, not empty (two cells of the inclined contact lines in it at once).
        Their contacts then have *identical* gaps over whole intervals of theta: the
        contact-change (jump) angles the dynamic models locate by Newton on the gap
        difference are undefined (zero derivative) and come out NaN, and the integration
        runs to its step limit (examples: ``benchmarks/results/code_notes.md``, section
        gearjax.gears.modifications). The quasi-static solve (:func:`gearjax.quasi_static`,
        ``dynamics=False``) is exact for these reliefs.
        """
        if self.pitch_errors_m is not None:
            for k, (f, z) in enumerate(zip(self.pitch_errors_m, (pair.z1, pair.z2)), start=1):
                if f.shape != (z,):
                    raise ModificationError(
                        f"pitch_errors_m[{k - 1}] has shape {f.shape}: gear {k} has {z} teeth, "
                        f"expected ({z},)"
                    )
        band = self.flat_relief_band_m(pair) if dynamics else 0.0
        limit = pair.base_pitch_m if pair.base_helix_angle_rad == 0.0 else 0.0
        if band > limit:
            amp = np.asarray(self.relief_amplitude_m).tolist()
            ext = np.asarray(self.relief_extent).tolist()
            r_flat = float(np.asarray(self.relief_amplitude_m)[0]) * (
                1.0 - (1.0 - float(np.asarray(self.relief_extent)[1])) / float(np.asarray(self.relief_extent)[0]))
            raise ModificationError(
                f"relief_extent={ext} (relief_amplitude_m={amp}): linear reliefs of equal slope "
                f"P_c/L_c overlap on {band * 1e3:.3g} mm of the path of contact, longer than "
                + ("the base pitch " + f"{limit * 1e3:.3g} mm" if limit > 0 else "zero (helical)")
                + f"; the composite relief is the constant {r_flat:.3g} m there (a rigid shift, "
                "not a relief), so teeth in contact on it have identical gaps and the dynamic "
                "models cannot locate their contact-change angles (NaN). The quasi-static TE "
                "is exact (quasi_static accepts it). Use extents with L_c1 + L_c2 - 1 below "
                f"{(limit / pair.path_of_contact_m) if limit > 0 else 0.0:.3g}, unequal slopes "
                "P_c1/L_c1 != P_c2/L_c2, or the parabolic shape"
            )


def max_equal_slope_extent(pair) -> float:
    """Largest extent ``L_c`` of the same linear relief on both gears (equal slopes) that
    the dynamic models accept (:meth:`ToothModifications.check_against`): the flat band
    ``(2 L_c - 1) g_alpha`` must stay below the transverse base pitch for a spur pair,
    ``L_c <= (1 + p_b / g_alpha) / 2`` (0.7906 for the Table 1 spur pair), and be empty
    for a helical one, ``L_c <= 1/2``."""
    band = pair.base_pitch_m if pair.base_helix_angle_rad == 0.0 else 0.0
    return 0.5 * (1.0 + band / pair.path_of_contact_m)
