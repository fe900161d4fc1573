"""Tip-relief design spaces: :class:`ReliefSpace` (shared or separate amplitude and
extent of pinion and gear, linear or parabolic) and its bounds (see :mod:`gearjax.design`)."""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np

from ..errors import DesignError
from ..gears.modifications import ToothModifications, max_equal_slope_extent

__all__ = ["ReliefSpace"]


@dataclasses.dataclass(frozen=True)
class ReliefSpace:
    """Tip-relief design variables and their bounds.

    Attributes
    ----------
    shape : ``"linear"`` or ``"parabolic"`` relief (Fig. 4).
    shared : one relief on both gears, ``x = (P_c (m), L_c)``; else per gear,
        ``x = (P_c1, P_c2, L_c1, L_c2)``.
    amplitude_bounds_m : (lo, hi) for the amplitudes (m), lo >= 0.
    extent_bounds : (lo, hi) for the extents, inside (0, 1).
    """

    shape: str = "linear"
    shared: bool = True
    amplitude_bounds_m: tuple = (0.0, 40e-6)
    extent_bounds: tuple = (0.02, 0.98)

    def __post_init__(self):
        if self.shape not in ("linear", "parabolic"):
            raise DesignError("shape", self.shape, "must be 'linear' or 'parabolic'")
        a0, a1 = self.amplitude_bounds_m
        if not (0.0 <= a0 < a1 <= 1e-3):
            raise DesignError("amplitude_bounds_m", self.amplitude_bounds_m,
                              "need 0 <= lo < hi <= 1e-3 (m)")
        e0, e1 = self.extent_bounds
        if not (0.0 < e0 < e1 < 1.0):
            raise DesignError("extent_bounds", self.extent_bounds, "need 0 < lo < hi < 1")

    @property
    def names(self) -> tuple:
        if self.shared:
            return ("amplitude_m", "extent")
        return ("amplitude1_m", "amplitude2_m", "extent1", "extent2")

    @property
    def size(self) -> int:
        return len(self.names)

    def _bounds(self):
        a, e = self.amplitude_bounds_m, self.extent_bounds
        if self.shared:
            return np.array([a[0], e[0]]), np.array([a[1], e[1]])
        return np.array([a[0], a[0], e[0], e[0]]), np.array([a[1], a[1], e[1], e[1]])

    @property
    def lower(self) -> np.ndarray:
        return self._bounds()[0]

    @property
    def upper(self) -> np.ndarray:
        return self._bounds()[1]

    def check(self, x, field: str = "x") -> np.ndarray:
        """``x`` as a float array, or :class:`DesignError` naming ``field``."""
        x = np.asarray(x, dtype=float)
        if x.shape != (self.size,):
            raise DesignError(field, x.tolist(), f"expected {self.size} values {self.names}")
        lo, hi = self._bounds()
        if not np.all(np.isfinite(x)) or np.any(x < lo) or np.any(x > hi):
            raise DesignError(field, x.tolist(), f"outside the bounds {lo.tolist()} .. {hi.tolist()} "
                                                 f"of {self.names}")
        return x

    def mods(self, x) -> ToothModifications:
        """The :class:`ToothModifications` of design ``x`` (traceable)."""
        x = jnp.asarray(x, dtype=float)
        if self.shared:
            amp, ext = jnp.stack([x[0], x[0]]), jnp.stack([x[1], x[1]])
        else:
            amp, ext = x[0:2], x[2:4]
        return ToothModifications(amp, ext, self.shape)

    def for_dynamics(self, pair, margin: float = 0.005) -> "ReliefSpace":
        """This space with the upper extent bound lowered to ``margin`` below
        :func:`gearjax.gears.modifications.max_equal_slope_extent` for linear reliefs: beyond it
        the same relief on both gears has a flat band the dynamic models refuse (0.7906
        for the Table 1 spur pair, 0.5 for a helical pair; with separate reliefs each
        extent below it keeps ``L_c1 + L_c2 - 1`` below the limit for equal slopes)."""
        if self.shape != "linear":
            return self
        cap = max_equal_slope_extent(pair) - margin
        lo, hi = self.extent_bounds
        if hi <= cap:
            return self
        if lo >= cap:
            raise DesignError("extent_bounds", self.extent_bounds,
                              f"the dynamic models need linear relief extents below {cap:.4g} "
                              "for this pair (equal-slope reliefs overlapping on a flat band)")
        return dataclasses.replace(self, extent_bounds=(lo, cap))

    def from_unconstrained(self, u):
        """``x = lo + (hi - lo) sigmoid(u)`` (traceable)."""
        lo, hi = self._bounds()
        return jnp.asarray(lo) + jnp.asarray(hi - lo) * jax.nn.sigmoid(u)

    def to_unconstrained(self, x):
        lo, hi = self._bounds()
        p = np.clip((np.asarray(x, dtype=float) - lo) / (hi - lo), 1e-12, 1 - 1e-12)
        return np.log(p) - np.log1p(-p)
