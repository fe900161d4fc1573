"""Differentiable tip-relief design: objectives, gradients, an optax optimiser, Harris maps.

The design variables are the tip-relief amplitude ``P_c`` (m) and extent ``L_c`` (fraction
of the path of contact) of pinion and gear (paper Section 2.2.1, Fig. 4), shared by both
gears (``x = (P_c, L_c)``) or separate (``x = (P_c1, P_c2, L_c1, L_c2)``), with a linear or
parabolic shape (:class:`ReliefSpace`).

Objectives (:data:`OBJECTIVES`)
-------------------------------
* ``"te-ptp"`` / ``"te-rms"``: peak-to-peak / RMS fluctuation of the quasi-static
  transmission error under load TE_S (Eq. (10), unilateral contact of Eq. (17)) over one
  mesh period, at one or several pinion torques (several: RMS over the loads for te-rms,
  smooth maximum over the loads for te-ptp).
* ``"peak-force"``: the largest dynamic mesh force F_D (N, Eq. (22)/(24)) over a range of
  pinion speeds, from the sdof torsional model (Eqs. (16), (20), (47a)) or the 3D model
  (Eqs. (14), (42), (48a); section "3D model" below) at steady state.
* ``"dynamic-factor"``: the same divided by the static force F_S (Eq. (23)).
* ``"dte-ptp"``: the largest peak-to-peak dynamic transmission error (m) over the speeds.

Smooth maximum
--------------
The maximum over speeds (and over loads, and the extrema of TE_S over the mesh period for
te-ptp) is replaced by ``smax_beta(v) = scale * logsumexp(beta v / scale) / beta`` with
``beta = sharpness`` (default :data:`DEFAULT_SHARPNESS` = 200) and ``scale`` the natural
unit of the objective (F_S for forces, 1 for the dynamic factor, the mean static mesh
deflection for transmission errors), so that ``max v <= smax <= max v + scale ln(n) /
beta`` (at most 1.2 % of the unit for 12 speeds). The optimiser descends the smooth value;
every evaluation reports the exact maximum beside it (``exact``). The maximum over time
inside each steady-state period is the exact maximum of the sampled signal
(:func:`gearjax.dynamics.simulate.simulate`).

Gradients
---------
Forward mode through the whole chain (mesh cells -> quasi-static table -> diffrax solve
in ``diffrax.ForwardMode`` -> metric), ``jax.jacfwd`` over the 2-4 design variables. The
switching angles of the quasi-static solution move with the design; the torsional model
follows them with its angle map (see :mod:`gearjax.models.torsional`, "Derivatives with
respect to the design"), valid while the discrete structure of the quasi-static solution
is the one the model was built with: every evaluation checks it and :class:`DynamicObjective`
rebuilds the model (a recompilation) when it changes. ``benchmarks/bench_gradients.py``
compares forward mode with reverse mode (``diffrax.RecursiveCheckpointAdjoint``).

Bounds
------
The optimiser works on unconstrained variables ``u``: ``x = lo + (hi - lo) sigmoid(u)``
per variable, bounds ``[0, 40 um]`` for amplitudes and ``[0.02, 0.98]`` for extents by
default (:class:`ReliefSpace`), so every iterate respects them.

Inertias and the NLTE'' reaction (dynamic objectives)
----------------------------------------------------
The sdof design model uses the gear *bodies* (:data:`DESIGN_INERTIAS`: the torsional
model's default solid cylinders at the pitch radii, J1 = 4.48e-3, J2 = 4.76 kg m^2 for the
spur Baud-Velex pair, i.e. the annular bodies of the 3D rig, 4.0e-3 and 4.76, plus the
shaft core under the face width, 5e-4 and 1.3e-3) and puts the NLTE'' reaction torque on
the drive (``nlte_reaction="drive"``, kappa = 1, see :mod:`gearjax.models.torsional`).
Reason: the shafts are torsionally far softer than the mesh (pinion shaft to the motor
coupling G pi d^4 / 32 / L ~ 9e4 N m/rad; mesh k_m Rb1^2 = 7.4e8 x 0.0489^2 = 1.8e6
N m/rad), so at the mesh modes (3.4 kHz) the shafts, hubs and motor are decoupled from
the bodies (hub on the pinion shaft: ~500 Hz). Measured, short relief, zeta 0.03: the 3D
rig's mesh receptance |k_m C_vv - 1| peaks at 823.5 rad/s (modes 3373 / 3466 Hz with 29 /
21 % of the mesh strain energy); the sdof critical speed omega_n / z1 is 776 rad/s with
the bodies (820 with the bare annuli) against 406 rad/s with the shaft-line inertias
(1.8e-2, 4.80) used before (pinion body + shaft + motor-side hub). With the long relief
(NLTE'' != 0) the 3D rig gives dynamic factors 1.33/1.24/1.99/1.52 (perturbation) and
1.32/1.21/2.37/1.45 (reference) at 600/700/800/900 rad/s; the sdof with the bodies and
``"drive"`` 1.41/1.81/4.15/1.63 and 1.42/2.24/2.15/1.52, with the paper's Eq. (15)
(``"pinion"``, kappa = 30) 22/55/259/44 and 14/24/11/0 (teeth flying apart), with the
shaft-line inertias (kappa = 8.3) 6.2/5.3/4.9/4.7 and 5.4/3.7/3.6/3.6. Both are passable
(``inertias_kg_m2``, ``nlte_reaction``).

Formulation (dynamic objectives)
--------------------------------
Default perturbation (Eq. (47a): constant mean stiffness, linear, always stable, smooth
in the design). The te formulation (Eq. (20)) with the loaded stiffness of the long
relief is parametrically unstable around the main critical speed: Floquet spectral
radius (:func:`gearjax.dynamics.stability.spectral_radius`) up to 1.074, > 1 over 770-810 rad/s
(0.97-1.02 of its omega_n / z1 = 795 rad/s), dynamic factor 457 at 800 rad/s; the sdof
multipliers depend on Omega / omega_n and zeta only, so this holds for any inertias. The
reference formulation (Eq. (16)) is the physical check, but contact loss makes it
non-smooth in the design; the optimum is checked against it by forward sweeps
(``notebooks/tip_relief_design.ipynb``).

3D model
--------
``DynamicObjective(..., model="3d", rig=rig)`` drives the 3D model of a rig (Eqs. (14),
(42), (48a), modes below ``max_frequency_hz``, by default 4.5 mesh harmonics of the
highest speed, at least 6 kHz) at its periodic steady state
by shooting (:func:`gearjax.dynamics.steady.steady_state`: no transient, whose 61.8 rad/s
shaft-line mode would leave a residue larger than the design's effect). Its events (jumps
of ``k(theta)``, of NLTE', kinks of TE_S at the relief starts) follow the design through
the same angle map (:mod:`gearjax.models.geared3d`, "Derivatives with respect to the
design"), and ``prepare`` checks the discrete structure as the torsional model does
(rebuild when it changes). Exact derivatives in the te formulation; the perturbation
formulation holds its splitting constant ``k_m`` at the build design (the objective
jumps by a little when a rebuild changes it). Measured (spur, short relief, 300 and 500
rad/s, zeta 0.1, tight shooting tolerances): jacfwd against central differences of the
same objective 1e-5 (te) and 4e-6 (perturbation) for the peak force, dynamic factor and
DTE peak-to-peak; one value-and-gradient ~30-50 s on 2 loaded cores
(``tests/test_design.py``).

Bounds of linear reliefs
------------------------
The dynamic models refuse equal-slope linear reliefs whose flat overlap band exceeds a
base pitch (spur) or is not empty (helical) (:meth:`ToothModifications.check_against`):
dynamic objectives lower the extent bound of a linear :class:`ReliefSpace` below that
limit (:meth:`ReliefSpace.for_dynamics`: 0.786 for the Table 1 spur pair, 0.495 for the
helical pair), so that no optimiser step or map point reaches a refused design.
"""

from __future__ import annotations

import dataclasses
import math
import time

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optax

from .gears.mesh import Mesh
from .gears.modifications import ToothModifications, max_equal_slope_extent
from .gears.quasistatic import quasi_static, static_mesh_force
from .errors import DesignError

__all__ = [
    "OBJECTIVES",
    "DEFAULT_SHARPNESS",
    "DESIGN_INERTIAS",
    "design_inertias",
    "DesignError",
    "ReliefSpace",
    "smooth_max",
    "QuasiStaticObjective",
    "DynamicObjective",
    "Evaluation",
    "OptimisationResult",
    "optimise",
    "multi_start",
    "coarse_starts",
    "harris_map",
    "HarrisMap",
    "harris_curves",
    "plot_design_map",
    "plot_history",
    "plot_harris",
]

OBJECTIVES = ("peak-force", "dynamic-factor", "dte-ptp", "te-ptp", "te-rms")
DYNAMIC_OBJECTIVES = ("peak-force", "dynamic-factor", "dte-ptp")
DESIGN_MODELS = ("torsional", "3d")
DEFAULT_SHARPNESS = 200.0
DESIGN_INERTIAS = "bodies"  # solid cylinders at the pitch radii (module docstring)


def design_inertias(mesh: Mesh, inertias_kg_m2=DESIGN_INERTIAS) -> tuple:
    """(J1, J2) (kg m^2): ``"bodies"`` -> solid cylinders at the pitch radii with the face
    widths (:func:`gearjax.models.torsional.solid_cylinder_inertias`), else the two values
    given."""
    from .models.torsional import solid_cylinder_inertias

    if isinstance(inertias_kg_m2, str):
        if inertias_kg_m2 != "bodies":
            raise DesignError("inertias_kg_m2", inertias_kg_m2, "'bodies' or (J1, J2) in kg m^2")
        return tuple(float(v) for v in solid_cylinder_inertias(mesh.pair))
    j = np.asarray(inertias_kg_m2, dtype=float)
    if j.shape != (2,) or not np.all(np.isfinite(j)) or np.any(j <= 0):
        raise DesignError("inertias_kg_m2", inertias_kg_m2, "need two finite values > 0 (kg m^2)")
    return (float(j[0]), float(j[1]))


def smooth_max(v, sharpness: float = DEFAULT_SHARPNESS, scale=1.0):
    """``scale * logsumexp(sharpness * v / scale) / sharpness`` over all entries of ``v``:
    a differentiable upper bound of ``max v``, exceeding it by at most ``scale ln(n) /
    sharpness``."""
    v = jnp.ravel(jnp.asarray(v))
    return scale * jax.scipy.special.logsumexp(sharpness * v / scale) / sharpness


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


class Evaluation(eqx.Module):
    """One evaluation of an objective at a design.

    Attributes
    ----------
    x : the design (see :class:`ReliefSpace`).
    smooth : the smoothed objective (what the optimiser descends), SI units.
    exact : the exact maximum / value beside it.
    grad : d smooth / d x (same units over those of x), or None.
    per_case : the per-speed (dynamic) or per-load (quasi-static) values.
    structure_ok : the model's discrete structure matched (dynamic objectives), else True.
    """

    x: np.ndarray
    smooth: float
    exact: float
    grad: np.ndarray | None
    per_case: np.ndarray
    structure_ok: bool = True


def _value_and_jac(f, jac=jax.jacfwd):
    """``x -> (df/dx, (f, aux))`` for ``f(x) = (value, aux)``, one pass."""
    def g(x):
        v, aux = f(x)
        return v, (v, aux)

    return jac(g, has_aux=True)


# ---------------------------------------------------------------------------- quasi-static
class QuasiStaticObjective:
    """TE_S fluctuation objective ``"te-ptp"`` or ``"te-rms"`` (m) on one mesh period.

    Parameters
    ----------
    mesh : the mesh (stiffness law, cells).
    space : the :class:`ReliefSpace`.
    torques_Nm : one or several pinion torques C_m0 (N m) (F_S = C_m0 / (Rb1 cos b_b)).
    kind : ``"te-ptp"`` or ``"te-rms"``. For te-rms the smoothed value (the one descended)
        is the mean square fluctuation over the loads divided by the scale (m): the RMS has
        a V-shaped (non-differentiable) minimum where the fluctuation vanishes, the mean
        square a smooth one; ``exact`` is the RMS (m).
    n_positions : angles per mesh period.
    sharpness : beta of the smooth maxima (module docstring); scale = mean static mesh
        deflection F_S / (k_m cos b_b) at the first torque, k_m the mean geometric
        mesh stiffness.
    model : ``"torsional"`` (default: TE_S of the rigid-body mesh, Eq. (17)) or ``"3d"``
        (TE_S = W^T X_S + NLTE of the 3D quasi-static solution of ``rig``, Eqs. (10),
        (25): shaft and bearing deflections included, the load applied at the rig's
        torque node and scaled linearly with the torque).
    rig : the :class:`gearjax.rigs.registry.Rig` of a 3D objective.
    """

    def __init__(self, mesh: Mesh, space: ReliefSpace, torques_Nm=254.8, kind: str = "te-rms",
                 n_positions: int = 256, sharpness: float = DEFAULT_SHARPNESS,
                 model: str = "torsional", rig=None):
        if kind not in ("te-ptp", "te-rms"):
            raise DesignError("objective", kind, "quasi-static objectives are 'te-ptp', 'te-rms'")
        if model not in DESIGN_MODELS:
            raise DesignError("model", model, f"must be one of {DESIGN_MODELS}")
        if model == "3d" and rig is None:
            raise DesignError("rig", rig, "the 3D model needs a rig (gearjax.rigs.registry.get_rig)")
        torques = np.atleast_1d(np.asarray(torques_Nm, dtype=float))
        if torques.ndim != 1 or not np.all(np.isfinite(torques)) or np.any(torques <= 0):
            raise DesignError("torques_Nm", torques.tolist(), "need finite torques > 0 (N m)")
        if int(n_positions) < 16:
            raise DesignError("n_positions", n_positions, "need >= 16 angles per mesh period")
        self.mesh, self.space, self.kind = mesh, space, kind
        self.forces_N = np.array([static_mesh_force(mesh.pair, t) for t in torques])
        self.torques_Nm = torques
        self.theta = mesh.theta_grid(int(n_positions))
        self.sharpness = float(sharpness)
        cos_bb = math.cos(mesh.pair.base_helix_angle_rad)
        self.scale_m = float(self.forces_N[0] / (float(mesh.mean_stiffness()) * cos_bb))
        self.model_type, self.model3d = model, None
        if model == "3d":
            from .rigs.factory import build_model

            self.model3d = build_model(
                rig, None, mesh=mesh, pinion_torque_Nm=float(torques[0]),
                formulation="reference", max_frequency_hz=1000.0)  # quasi-static: no modes used
        self._value = eqx.filter_jit(self._values)
        self._vjac = eqx.filter_jit(_value_and_jac(self._values))
        self._grid = eqx.filter_jit(jax.vmap(self._values))

    def _values(self, x):
        mods = self.space.mods(x)
        beta, s = self.sharpness, self.scale_m

        def per_load(f):
            if self.model3d is None:
                te = quasi_static(self.mesh, mods, self.theta, f).te_s_m
            else:  # the 3D static load is linear in the torque (F_0 at the torque node)
                m, r = self.model3d, f / self.forces_N[0]
                m = eqx.tree_at(lambda m: (m.mods, m.cond.f_c, m.cond.c_w, m.cond.x0_local,
                                           m.pinion_torque_Nm),
                                m, (mods, m.cond.f_c * r, m.cond.c_w * r, m.cond.x0_local * r,
                                    m.pinion_torque_Nm * r))
                te = jax.vmap(lambda t: m.quasi_static(t).te_s_m)(jnp.asarray(self.theta))
            if self.kind == "te-rms":
                v = jnp.sqrt(jnp.mean((te - jnp.mean(te)) ** 2))
                return v, v
            smooth = smooth_max(te, beta, s) + smooth_max(-te, beta, s)
            return smooth, jnp.max(te) - jnp.min(te)

        sm, ex = jax.vmap(per_load)(jnp.asarray(self.forces_N))
        if self.kind == "te-rms":  # descend the mean square (smooth at a zero minimum)
            return jnp.mean(sm**2) / s, (jnp.sqrt(jnp.mean(ex**2)), ex)
        return smooth_max(sm, beta, s), (jnp.max(ex), ex)

    def __call__(self, x, grad: bool = True) -> Evaluation:
        x = self.space.check(x)
        if grad:
            g, (sm, (ex, per)) = self._vjac(jnp.asarray(x))
            return Evaluation(x, float(sm), float(ex), np.asarray(g), np.asarray(per))
        sm, (ex, per) = self._value(jnp.asarray(x))
        return Evaluation(x, float(sm), float(ex), None, np.asarray(per))

    def grid(self, xs) -> tuple[np.ndarray, np.ndarray]:
        """(smooth, exact) at every row of ``xs`` (n, size), one vmapped call."""
        sm, (ex, _) = self._grid(jnp.asarray(xs, dtype=float))
        return np.asarray(sm), np.asarray(ex)


# ---------------------------------------------------------------------------- dynamic
class DynamicObjective:
    """Dynamic objective over a speed range, sdof torsional or 3D model.

    Parameters
    ----------
    mesh : the mesh.
    space : the :class:`ReliefSpace`; linear reliefs get their extent bound lowered below
        the pair's equal-slope limit (:meth:`ReliefSpace.for_dynamics`), see :attr:`space`.
    speeds_rad_s : pinion speeds Omega1 (rad/s) over which the maximum is taken.
    kind : ``"peak-force"`` (N), ``"dynamic-factor"`` or ``"dte-ptp"`` (m).
    model : ``"torsional"`` (default; Eqs. (16), (20), (47a)) or ``"3d"`` (the 3D model of
        ``rig``, Eqs. (14), (42), (48a), reduced to the modes below ``max_frequency_hz``).
    rig : the :class:`gearjax.rigs.registry.Rig` of a 3D objective (structure, torque node,
        encoder position 1).
    formulation : ``"perturbation"`` (Eq. (47a) / (48a), default), ``"te"`` (Eq. (20) /
        (42)) or ``"reference"`` (Eq. (16) / (14)); see the module docstring,
        "Formulation". The 3D perturbation formulation holds its splitting constant k_m
        at the build design (module docstring, "3D model").
    pinion_torque_Nm, inertias_kg_m2, damping_ratio : model data (defaults: 254.8 N m,
        :data:`DESIGN_INERTIAS` (the gear bodies, sdof only), 0.03).
    nlte_reaction : ``"drive"`` (default) or ``"pinion"`` (module docstring, "Inertias";
        sdof only).
    max_frequency_hz : modal cut-off of the 3D model (Hz; None: all modes); default
        ``"auto"``: :func:`gearjax.models.geared3d.default_max_frequency_hz` of the highest
        speed (3 mesh harmonics x 1.5, at least 6 kHz: 16.8 kHz up to 900 rad/s on the
        Baud-Velex rig, whose mesh modes lie at 3.4-3.5 kHz).
    method : ``"transient"`` (:func:`gearjax.dynamics.simulate.simulate`, transient then measured
        periods; default for the sdof model) or ``"steady"`` (periodic steady state by
        shooting, :func:`gearjax.dynamics.steady.steady_state`; default for the 3D model, whose
        slow shaft-line modes would need long transients).
    sharpness : beta of the smooth maximum over speeds (module docstring).
    n_table : table knots per mesh period of the model.
    sim_kwargs : options of :func:`gearjax.dynamics.simulate.simulate` (or of
        :func:`gearjax.dynamics.steady.steady_state`) (static).
    adjoint : diffrax adjoint for the gradient (default ``diffrax.ForwardMode()`` with
        ``jax.jacfwd``; a ``RecursiveCheckpointAdjoint`` uses ``jax.jacrev``, transient
        method only: the shooting is forward mode).
    """

    def __init__(self, mesh: Mesh, space: ReliefSpace, speeds_rad_s, kind: str = "peak-force", *,
                 model: str = "torsional", rig=None,
                 formulation: str = "perturbation", pinion_torque_Nm: float = 254.8,
                 inertias_kg_m2=DESIGN_INERTIAS, damping_ratio: float = 0.03,
                 nlte_reaction: str = "drive", max_frequency_hz: float | str | None = "auto",
                 method: str | None = None,
                 sharpness: float = DEFAULT_SHARPNESS, n_table: int = 256,
                 sim_kwargs: dict | None = None, adjoint=None):
        if kind not in DYNAMIC_OBJECTIVES:
            raise DesignError("objective", kind, f"dynamic objectives are {DYNAMIC_OBJECTIVES}")
        if model not in DESIGN_MODELS:
            raise DesignError("model", model, f"must be one of {DESIGN_MODELS}")
        if model == "3d" and rig is None:
            raise DesignError("rig", rig, "the 3D model needs a rig (gearjax.rigs.registry.get_rig)")
        method = ("steady" if model == "3d" else "transient") if method is None else method
        if method not in ("transient", "steady"):
            raise DesignError("method", method, "must be 'transient' or 'steady'")
        if method == "steady" and isinstance(adjoint, diffrax.RecursiveCheckpointAdjoint):
            raise DesignError("adjoint", type(adjoint).__name__,
                              "the steady (shooting) method differentiates in forward mode only")
        speeds = np.atleast_1d(np.asarray(speeds_rad_s, dtype=float))
        if speeds.ndim != 1 or not np.all(np.isfinite(speeds)) or np.any(speeds <= 0):
            raise DesignError("speeds_rad_s", speeds.tolist(), "need finite pinion speeds > 0 (rad/s)")
        space = space.for_dynamics(mesh.pair)
        self.mesh, self.space, self.kind = mesh, space, kind
        self.speeds = speeds
        self.formulation = formulation
        self.model_type, self.rig, self.method = model, rig, method
        if model == "torsional":
            self.model_kwargs = dict(pinion_torque_Nm=float(pinion_torque_Nm),
                                     inertias_kg_m2=design_inertias(mesh, inertias_kg_m2),
                                     damping_ratio=float(damping_ratio), formulation=formulation,
                                     nlte_reaction=nlte_reaction, n_table=int(n_table))
        else:
            if max_frequency_hz == "auto":
                from .models.geared3d import default_max_frequency_hz

                max_frequency_hz = default_max_frequency_hz(float(np.max(speeds)), mesh.pair.z1)
            self.model_kwargs = dict(pinion_torque_Nm=float(pinion_torque_Nm),
                                     damping_ratio=float(damping_ratio), formulation=formulation,
                                     max_frequency_hz=max_frequency_hz, n_table=int(n_table))
        self.sharpness = float(sharpness)
        self.sim_kwargs = dict(sim_kwargs or {})
        self.adjoint = diffrax.ForwardMode() if adjoint is None else adjoint
        self.static_force_N = static_mesh_force(mesh.pair, pinion_torque_Nm)
        cos_bb = math.cos(mesh.pair.base_helix_angle_rad)
        self._x_ref_m = self.static_force_N / (float(mesh.mean_stiffness()) * cos_bb)
        self.scale = self._scales()[DYNAMIC_OBJECTIVES.index(kind)]
        self.model = None
        self.n_builds = 0
        self.build_time_s = 0.0
        self._static = (space, tuple(float(v) for v in self._scales()), self.sharpness,
                        tuple(sorted(self.sim_kwargs.items())), method)

    # model management
    def build(self, x, frozen: bool = False):
        """The model (:class:`~gearjax.models.torsional.TorsionalModel` or
        :class:`~gearjax.models.geared3d.Geared3DModel`) built at design ``x``;
        ``frozen`` drops the angle map (switching angles fixed at ``x``: forward values
        elsewhere are resolved to the table spacing, derivatives miss their motion)."""
        t0 = time.perf_counter()
        mods = self.space.mods(np.asarray(x, dtype=float))
        if self.model_type == "torsional":
            from .models.torsional import TorsionalModel

            m = TorsionalModel.build(self.mesh, mods, **self.model_kwargs)
            if frozen:
                m = dataclasses.replace(m, jump_kinds=(0,) * len(m.jump_kinds))
                m = m.with_modifications(m.mods)  # re-assembled without the angle map
        else:
            from .rigs.factory import build_model

            m = build_model(self.rig, mods, mesh=self.mesh, **self.model_kwargs)
            if frozen:
                m = dataclasses.replace(m, event_thetas=(), event_kinds=(), event_cells=(),
                                        table_codes=None)
        self.n_builds += 1
        self.build_time_s += time.perf_counter() - t0
        return m

    def _scales(self):
        """Units of the three dynamic metrics: F_S (N), 1, mean static deflection (m)."""
        return (self.static_force_N, 1.0, self._x_ref_m)

    @property
    def _index(self) -> int:
        return DYNAMIC_OBJECTIVES.index(self.kind)

    def __call__(self, x, grad: bool = True) -> Evaluation:
        """Evaluate at ``x`` (and its gradient), rebuilding the model when its structure
        does not match the design."""
        x = self.space.check(x)
        k = self._index
        speeds = jnp.asarray(self.speeds)
        for attempt in range(2):
            if self.model is None:
                self.model = self.build(x)
            xj = jnp.asarray(x)
            if grad:
                g, (sm, (ex, per, ok)) = _dyn_vjac(self.model, xj, speeds, self._static,
                                                   self.adjoint)
                g = np.asarray(g)[k]
            else:
                sm, (ex, per, ok) = _dyn_values(self.model, xj, speeds, self._static)
                g = None
            if bool(ok) or attempt == 1:
                break
            self.model = None  # structure changed: rebuild at x
        return Evaluation(x, float(sm[k]), float(ex[k]), g, np.asarray(per)[k], bool(ok))

    def all_metrics(self, x, grad: bool = True):
        """(smooth (3,), exact (3,), jacobian (3, size) or None) of peak-force,
        dynamic-factor and dte-ptp at ``x`` from one set of solves (same model)."""
        x = self.space.check(x)
        if self.model is None:
            self.model = self.build(x)
        speeds = jnp.asarray(self.speeds)
        if grad:
            g, (sm, (ex, _, _)) = _dyn_vjac(self.model, jnp.asarray(x), speeds, self._static,
                                            self.adjoint)
            return np.asarray(sm), np.asarray(ex), np.asarray(g)
        sm, (ex, _, _) = _dyn_values(self.model, jnp.asarray(x), speeds, self._static)
        return np.asarray(sm), np.asarray(ex), None

    def grid(self, xs, reference_x=None) -> tuple[np.ndarray, np.ndarray]:
        """(smooth, exact) at every row of ``xs`` in one vmapped call, with a *frozen*
        model built at ``reference_x`` (default: the middle row): switching angles of other
        designs are resolved to the table spacing (1/n_table of a mesh period), which is
        what a forward map needs (no derivatives)."""
        xs = np.asarray(xs, dtype=float)
        ref = xs[len(xs) // 2] if reference_x is None else reference_x
        model = self.build(ref, frozen=True)
        sm, (ex, _, _) = _dyn_grid(model, jnp.asarray(xs), jnp.asarray(self.speeds), self._static)
        return np.asarray(sm)[:, self._index], np.asarray(ex)[:, self._index]


def _dyn_values_impl(model, x, speeds, static, adjoint=None):
    """Smooth and exact maxima over ``speeds`` of (max F_D, max F_D / F_S, DTE ptp)."""
    from .dynamics.simulate import simulate

    space, scales, sharpness, sim_kw, method = static
    m = model.with_modifications(space.mods(x))
    kw = dict(sim_kw)
    if method == "steady":
        from .dynamics.steady import steady_state

        res = jax.vmap(lambda w: steady_state(m, w, **kw).result)(speeds)
    else:
        if adjoint is not None:
            kw["adjoint"] = adjoint
        res = jax.vmap(lambda w: simulate(m, w, **kw))(speeds)
    per = jnp.stack([res.max_mesh_force_N, res.dynamic_factor, res.dte_ptp_m])
    sm = jnp.stack([smooth_max(per[i], sharpness, scales[i]) for i in range(3)])
    ok = m.structure_ok & jnp.all(res.solver_ok)
    return sm, (jnp.max(per, axis=1), per, ok)


_dyn_values = eqx.filter_jit(_dyn_values_impl)


@eqx.filter_jit
def _dyn_vjac(model, x, speeds, static, adjoint):
    reverse = isinstance(adjoint, diffrax.RecursiveCheckpointAdjoint)
    jac = jax.jacrev if reverse else jax.jacfwd
    return _value_and_jac(lambda y: _dyn_values_impl(model, y, speeds, static, adjoint), jac)(x)


@eqx.filter_jit
def _dyn_grid(model, xs, speeds, static):
    return jax.vmap(lambda x: _dyn_values_impl(model, x, speeds, static))(xs)


def make_objective(kind: str, mesh: Mesh, space: ReliefSpace, *, speeds_rad_s=None,
                   torques_Nm=254.8, **kwargs):
    """The objective ``kind`` of :data:`OBJECTIVES` (dynamic ones need ``speeds_rad_s``)."""
    if kind not in OBJECTIVES:
        raise DesignError("objective", kind, f"must be one of {OBJECTIVES}")
    if kind in DYNAMIC_OBJECTIVES:
        if speeds_rad_s is None:
            raise DesignError("speeds_rad_s", None, f"objective {kind!r} needs a speed range")
        return DynamicObjective(mesh, space, speeds_rad_s, kind,
                                pinion_torque_Nm=float(np.atleast_1d(torques_Nm)[0]), **kwargs)
    return QuasiStaticObjective(mesh, space, torques_Nm, kind, **kwargs)


# ---------------------------------------------------------------------------- optimiser
@dataclasses.dataclass
class OptimisationResult:
    """Result of :func:`optimise`.

    Attributes
    ----------
    x, smooth, exact : the best design found and its smoothed / exact objective.
    x0, smooth0, exact0 : the starting design and its objective.
    history : list of dicts (iteration, x, smooth, exact, grad_norm_u, structure_ok).
    iterations : optimiser steps taken.
    stop_reason : ``"tolerance"``, ``"small-step"`` or ``"max-iter"``.
    wall_time_s : seconds spent.
    """

    x: np.ndarray
    smooth: float
    exact: float
    x0: np.ndarray
    smooth0: float
    exact0: float
    history: list
    iterations: int
    stop_reason: str
    wall_time_s: float

    def as_dict(self, space: ReliefSpace) -> dict:
        out = {n: float(v) for n, v in zip(space.names, self.x)}
        out.update({"objective_before": self.exact0, "objective_after": self.exact,
                    "smooth_before": self.smooth0, "smooth_after": self.smooth,
                    "start": {n: float(v) for n, v in zip(space.names, self.x0)},
                    "iterations": self.iterations, "stop_reason": self.stop_reason,
                    "wall_time_s": self.wall_time_s})
        return out


def optimise(objective, x0, *, learning_rate: float = 0.15, max_iter: int = 60,
             rtol: float = 1e-4, patience: int = 8, step_tol: float = 1e-4,
             callback=None) -> OptimisationResult:
    """Minimise ``objective`` (a :class:`QuasiStaticObjective` or :class:`DynamicObjective`)
    from ``x0`` with optax Adam on the unconstrained variables of its
    :class:`ReliefSpace` (bounds hold by construction), learning rate decayed by cosine
    to 5 % over ``max_iter``.

    Stopping rule: the best smoothed value has not improved by more than ``rtol``
    (relative) for ``patience`` iterations ("tolerance"), or the Adam step in ``u`` is
    below ``step_tol`` ("small-step"), or ``max_iter`` steps ("max-iter"). Returns the best
    iterate (by the smoothed value) with the history.
    """
    space = objective.space
    x0 = space.check(x0, "x0")
    t0 = time.perf_counter()
    sched = optax.cosine_decay_schedule(learning_rate, max(1, max_iter), alpha=0.05)
    opt = optax.adam(sched)
    u = jnp.asarray(space.to_unconstrained(x0))
    state = opt.init(u)
    hist = []
    best = None
    since = 0
    reason = "max-iter"
    first = None
    it = 0
    for it in range(max_iter + 1):
        x = np.asarray(space.from_unconstrained(u))
        x = np.clip(x, space.lower, space.upper)
        ev = objective(x, grad=True)
        if first is None:
            first = ev
        dxdu = np.asarray(jax.vmap(jax.grad(lambda v, i: space.from_unconstrained(v)[i],
                                            argnums=0), in_axes=(None, 0))(
            u, jnp.arange(space.size))).diagonal()
        g_u = ev.grad * dxdu
        hist.append({"iteration": it, "x": x.tolist(), "smooth": ev.smooth, "exact": ev.exact,
                     "grad_norm_u": float(np.linalg.norm(g_u)), "structure_ok": ev.structure_ok})
        if callback is not None:
            callback(hist[-1])
        if best is None or ev.smooth < best.smooth * (1 - rtol) - 1e-300:
            since = 0
        else:
            since += 1
        if best is None or ev.smooth < best.smooth:
            best = ev
        if since >= patience:
            reason = "tolerance"
            break
        if it == max_iter:
            break
        upd, state = opt.update(jnp.asarray(g_u), state, u)
        if float(jnp.max(jnp.abs(upd))) < step_tol:
            reason = "small-step"
            break
        u = optax.apply_updates(u, upd)
    return OptimisationResult(
        x=best.x, smooth=best.smooth, exact=best.exact, x0=x0, smooth0=first.smooth,
        exact0=first.exact, history=hist, iterations=it, stop_reason=reason,
        wall_time_s=time.perf_counter() - t0,
    )


def coarse_starts(space: ReliefSpace, n_per_axis: int = 2) -> np.ndarray:
    """Starting designs on a coarse grid inside the bounds (interior points at
    ``(i + 1) / (n + 1)`` of each range), shape ``(n_per_axis ** size, size)``."""
    lo, hi = space.lower, space.upper
    f = (np.arange(n_per_axis) + 1.0) / (n_per_axis + 1.0)
    axes = [lo[i] + (hi[i] - lo[i]) * f for i in range(space.size)]
    return np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, space.size)


def multi_start(objective, starts, **kwargs) -> tuple[OptimisationResult, list]:
    """:func:`optimise` from every row of ``starts``; returns (best by exact value, all)."""
    results = [optimise(objective, x0, **kwargs) for x0 in np.asarray(starts, dtype=float)]
    return min(results, key=lambda r: r.exact), results


# ---------------------------------------------------------------------------- Harris maps
@dataclasses.dataclass
class HarrisMap:
    """Objective over a grid of (amplitude, extent) of a shared relief.

    Attributes: ``amplitudes_m`` (na,), ``extents`` (ne,), ``smooth`` and ``exact``
    (na, ne), ``objective`` (name), ``wall_time_s``.
    """

    amplitudes_m: np.ndarray
    extents: np.ndarray
    smooth: np.ndarray
    exact: np.ndarray
    objective: str
    wall_time_s: float


def harris_map(objective, amplitudes_m, extents) -> HarrisMap:
    """The objective over the grid ``amplitudes_m x extents`` (shared relief), computed by
    the objective's vmapped ``grid`` in one call."""
    if objective.space.size != 2:
        raise DesignError("space", objective.space.names, "a Harris map needs a shared relief")
    a = np.asarray(amplitudes_m, dtype=float)
    e = np.asarray(extents, dtype=float)
    xs = np.stack(np.meshgrid(a, e, indexing="ij"), -1).reshape(-1, 2)
    for x in xs:
        objective.space.check(x, "grid point")
    t0 = time.perf_counter()
    sm, ex = objective.grid(xs)
    return HarrisMap(a, e, sm.reshape(a.size, e.size), ex.reshape(a.size, e.size),
                     objective.kind, time.perf_counter() - t0)


def harris_curves(mesh: Mesh, reliefs: dict, torques_Nm, n_positions: int = 256) -> dict:
    """Classic Harris plot data: TE_S peak-to-peak (m) against pinion torque for several
    reliefs (``{name: ToothModifications}``), vmapped over the torques for each relief.
    Returns ``{"torques_Nm": (n,), name: (n,) ...}``."""
    torques = np.asarray(torques_Nm, dtype=float)
    forces = jnp.asarray([static_mesh_force(mesh.pair, t) for t in torques])
    theta = mesh.theta_grid(int(n_positions))
    out = {"torques_Nm": torques}

    @eqx.filter_jit
    def ptp(mods):
        def one(f):
            te = quasi_static(mesh, mods, theta, f).te_s_m
            return jnp.max(te) - jnp.min(te)

        return jax.vmap(one)(forces)

    for name, mods in reliefs.items():
        out[name] = np.asarray(ptp(mods))
    return out


# ---------------------------------------------------------------------------- plots
def _pyplot():
    from .plotting import _pyplot as p

    return p()


_UNITS = {"peak-force": ("peak dynamic mesh force", 1e-3, "kN"),
          "dynamic-factor": ("peak dynamic factor", 1.0, "-"),
          "dte-ptp": ("peak DTE peak-to-peak", 1e6, "um"),
          "te-ptp": ("TE$_S$ peak-to-peak", 1e6, "um"),
          "te-rms": ("TE$_S$ RMS fluctuation", 1e6, "um")}


def plot_design_map(hmap: HarrisMap, path: str, results=(), marks: dict | None = None,
                    title: str = ""):
    """Contour map of the exact objective over (extent, amplitude) with optimiser paths
    (``results``: :class:`OptimisationResult` of a shared relief) and named points
    (``marks``: ``{label: (amplitude_m, extent)}``)."""
    plt = _pyplot()
    label, f, unit = _UNITS.get(hmap.objective, (hmap.objective, 1.0, ""))
    fig, ax = plt.subplots(figsize=(7, 5.5), constrained_layout=True)
    cs = ax.contourf(hmap.extents, hmap.amplitudes_m * 1e6, hmap.exact * f, levels=24,
                     cmap="viridis")
    fig.colorbar(cs, ax=ax, label=f"{label} [{unit}]")
    for k, r in enumerate(results):
        xs = np.array([h["x"] for h in r.history])
        ax.plot(xs[:, 1], xs[:, 0] * 1e6, "w.-", lw=1.0, ms=3,
                label="optimiser paths" if k == 0 else None)
        ax.plot(xs[-1, 1], xs[-1, 0] * 1e6, "r*", ms=10)
    for name, (a, e) in (marks or {}).items():
        ax.plot(e, a * 1e6, "o", mfc="none", mec="w", ms=9)
        ax.annotate(name, (e, a * 1e6), color="w", xytext=(5, 5), textcoords="offset points")
    ax.set_xlabel("relief extent L$_c$ [fraction of path of contact]")
    ax.set_ylabel("relief amplitude P$_c$ [um]")
    ax.set_title(title or f"Harris map: {label}")
    if results:
        ax.legend(loc="upper right")
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def plot_history(results, path: str, objective: str = "", title: str = ""):
    """Smoothed and exact objective against iteration for one or several runs."""
    plt = _pyplot()
    if isinstance(results, OptimisationResult):
        results = [results]
    label, f, unit = _UNITS.get(objective, (objective or "objective", 1.0, ""))
    fig, ax = plt.subplots(figsize=(7, 4.5), constrained_layout=True)
    for k, r in enumerate(results):
        it = [h["iteration"] for h in r.history]
        (ln,) = ax.plot(it, [h["exact"] * f for h in r.history], "-", lw=1.4,
                        label="exact" if k == 0 else None)
        ax.plot(it, [h["smooth"] * f for h in r.history], "--", lw=1.0, color=ln.get_color(),
                label="smoothed" if k == 0 else None)
    ax.set_xlabel("iteration")
    ax.set_ylabel(f"{label} [{unit}]")
    ax.grid(alpha=0.3)
    ax.legend()
    ax.set_title(title or "optimisation history")
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def plot_harris(curves: dict, path: str, title: str = ""):
    """Classic Harris plot: TE_S peak-to-peak (um) against pinion torque (N m)."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7, 4.5), constrained_layout=True)
    t = curves["torques_Nm"]
    for name, v in curves.items():
        if name != "torques_Nm":
            ax.plot(t, np.asarray(v) * 1e6, "-o", ms=3, label=name)
    ax.set_xlabel("pinion torque C$_{m0}$ [N m]")
    ax.set_ylabel("TE$_S$ peak-to-peak [um]")
    ax.grid(alpha=0.3)
    ax.legend()
    ax.set_title(title or "Harris plot")
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path
