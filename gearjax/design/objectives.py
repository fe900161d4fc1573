"""Design objectives: quasi-static TE_S (:class:`QuasiStaticObjective`) and dynamic steady-state
metrics (:class:`DynamicObjective`) of a tip-relief design, their smooth maxima and
:func:`make_objective` (see :mod:`gearjax.design` for the objectives and the 3D model)."""

from __future__ import annotations

import dataclasses
import math
import time

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..dynamics.batching import on_cpu, over_speeds, sequential_for
from ..dynamics.sweep import Transient
from ..errors import DesignError
from ..gears.mesh import Mesh
from ..gears.quasistatic import quasi_static, static_mesh_force
from .orbits import OrbitSet
from .spaces import ReliefSpace

__all__ = ["OBJECTIVES", "DYNAMIC_OBJECTIVES", "DESIGN_MODELS", "DEFAULT_SHARPNESS", "DESIGN_INERTIAS", "design_inertias", "smooth_max", "Evaluation", "QuasiStaticObjective", "DynamicObjective", "make_objective", "default_torque_Nm"]


OBJECTIVES = ("peak-force", "dynamic-factor", "dte-ptp", "te-ptp", "te-rms")
DYNAMIC_OBJECTIVES = ("peak-force", "dynamic-factor", "dte-ptp")
DESIGN_MODELS = ("torsional", "3d")
DEFAULT_SHARPNESS = 200.0
MODELS_KEPT = 8  # earlier models of other structures a DynamicObjective may return to
DEFAULT_ROWS = 4  # rows of a batch before any (a map's chunks; the CLI's 4 starts)
DESIGN_INERTIAS = "bodies"  # solid cylinders at the pitch radii (:mod:`gearjax.design`)


def design_inertias(mesh: Mesh, inertias_kg_m2=DESIGN_INERTIAS) -> tuple:
    """(J1, J2) (kg m^2): ``"bodies"`` -> solid cylinders at the pitch radii with the face
    widths (:func:`gearjax.models.torsional.solid_cylinder_inertias`), else the two values
    given."""
    from ..models.torsional import solid_cylinder_inertias

    if isinstance(inertias_kg_m2, str):
        if inertias_kg_m2 != "bodies":
            raise DesignError("inertias_kg_m2", inertias_kg_m2, "'bodies' or (J1, J2) in kg m^2")
        return tuple(float(v) for v in solid_cylinder_inertias(mesh.pair))
    j = np.asarray(inertias_kg_m2, dtype=float)
    if j.shape != (2,) or not np.all(np.isfinite(j)) or np.any(j <= 0):
        raise DesignError("inertias_kg_m2", inertias_kg_m2, "need two finite values > 0 (kg m^2)")
    return (float(j[0]), float(j[1]))


def _orbit_solver(solver):
    """The one-speed solver of a dynamic objective: :class:`~gearjax.Auto` (None) is the
    transient at its ``rtol`` (an objective's models never start on their periodic orbit);
    a :class:`~gearjax.dynamics.solvers.AbstractOrbitSolver` as given. Raises
    :class:`DesignError` for a bad ``rtol`` or another solver."""
    from ..dynamics.solvers import AbstractOrbitSolver
    from ..dynamics.sweep import Auto, tolerance_options
    from ..errors import SimulationError

    solver = Auto() if solver is None else solver
    if isinstance(solver, Auto):
        try:
            return Transient(**tolerance_options(solver.rtol))
        except SimulationError as exc:
            raise DesignError("rtol", solver.rtol, "must lie in [1e-13, 1e-2]") from exc
    if not isinstance(solver, AbstractOrbitSolver):
        raise DesignError("solver", type(solver).__name__,
                          "a design objective differentiates one speed at a time: Auto(), "
                          "Transient(...) or Shooting(...)")
    return solver


def smooth_max(v, sharpness: float = DEFAULT_SHARPNESS, scale=1.0):
    """``scale * logsumexp(sharpness * v / scale) / sharpness`` over all entries of ``v``:
    a differentiable upper bound of ``max v``, exceeding it by at most ``scale ln(n) /
    sharpness``."""
    v = jnp.ravel(jnp.asarray(v))
    return scale * jax.scipy.special.logsumexp(sharpness * v / scale) / sharpness


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
    per_orbit : dynamic objectives over several orbit starts (:class:`OrbitSet`): the
        exact maximum over the speeds from each start, in the set's order; else None.
    """

    x: np.ndarray
    smooth: float
    exact: float
    grad: np.ndarray | None
    per_case: np.ndarray
    structure_ok: bool = True
    per_orbit: np.ndarray | None = None


def _value_and_jac(f, jac=jax.jacfwd):
    """``x -> (df/dx, (f, aux))`` for ``f(x) = (value, aux)``, one pass."""
    def g(x):
        v, aux = f(x)
        return v, (v, aux)

    return jac(g, has_aux=True)


def default_torque_Nm(pair, rig=None, what: str = "pinion_torque_Nm") -> float:
    """The pinion torque (N m) of an objective built without one: the ``rig``'s nominal
    torque, else the paper's 254.8 N m for the Baud-Velex pairs of Table 1 only.

    Raises
    ------
    DesignError
        for any other pair without a rig: another pair's torque is not the paper's (its
        static mesh force, dynamic factors and TE would all be those of 254.8 N m)."""
    if rig is not None:
        return float(rig.pinion_torque_Nm)
    from ..rigs.baud_velex import PINION_TORQUE_NM, baud_velex_pair

    if any(pair == baud_velex_pair(h) for h in (False, True)):
        return PINION_TORQUE_NM
    raise DesignError(what, None, "give the pinion torque (N m) or the rig: the paper's "
                                  "254.8 N m is the Baud-Velex pair's, not this pair's")


# ---------------------------------------------------------------------------- quasi-static
class QuasiStaticObjective:
    """TE_S fluctuation objective ``"te-ptp"`` or ``"te-rms"`` (m) on one mesh period.

    Parameters
    ----------
    mesh : the mesh (stiffness law, cells).
    space : the :class:`ReliefSpace`.
    torques_Nm : one or several pinion torques C_m0 (N m) (F_S = C_m0 / (Rb1 cos b_b));
        None (default): :func:`default_torque_Nm` (the rig's; the paper's only for its pair).
    kind : ``"te-ptp"`` or ``"te-rms"``. For te-rms the smoothed value (the one descended)
        is the mean square fluctuation over the loads divided by the scale (m): the RMS has
        a V-shaped (non-differentiable) minimum where the fluctuation vanishes, the mean
        square a smooth one; ``exact`` is the RMS (m).
    n_positions : angles per mesh period.
    sharpness : beta of the smooth maxima (:mod:`gearjax.design`); scale = mean static mesh
        deflection F_S / (k_m cos b_b) at the first torque, k_m the mean geometric
        mesh stiffness.
    model : ``"torsional"`` (default: TE_S of the rigid-body mesh, Eq. (17)) or ``"3d"``
        (TE_S = W^T X_S + NLTE of the 3D quasi-static solution of ``rig``, Eqs. (10),
        (25): shaft and bearing deflections included, the load applied at the rig's
        torque node and scaled linearly with the torque).
    rig : the :class:`gearjax.rigs.registry.Rig` of a 3D objective.
    """

    def __init__(self, mesh: Mesh, space: ReliefSpace, torques_Nm=None, kind: str = "te-rms",
                 n_positions: int = 256, sharpness: float = DEFAULT_SHARPNESS,
                 model: str = "torsional", rig=None):
        if torques_Nm is None:
            torques_Nm = default_torque_Nm(mesh.pair, rig, "torques_Nm")
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
            from ..rigs.factory import build_model

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
    formulation : ``"te"`` (Eq. (20) / (42) with the contact law, default),
        ``"reference"`` (Eq. (16) / (14)) or ``"perturbation"`` (Eq. (47a) / (48a)); see
        :mod:`gearjax.design`, "Formulation". The 3D perturbation formulation holds its
        splitting constant k_m at the build design.
    pinion_torque_Nm, inertias_kg_m2, damping_ratio : model data (defaults: the rig's
        torque, the paper's 254.8 N m for its own pair only, else required
        (:func:`default_torque_Nm`); :data:`DESIGN_INERTIAS` (the gear bodies, sdof only);
        0.03).
    nlte_reaction : ``"drive"`` (default, as every command and model) or ``"pinion"``
        (:mod:`gearjax.design`, "Inertias"; sdof only: the 3D model refuses it).
    max_frequency_hz : modal cut-off of the 3D model (Hz; None: all modes); default
        ``"auto"``: :func:`gearjax.models.geared3d.default_max_frequency_hz` of the highest
        speed (3 mesh harmonics x 1.5, at least 6 kHz: 16.8 kHz up to 900 rad/s on the
        Baud-Velex rig, whose mesh modes lie at 3.4-3.5 kHz).
    solver : the periodic solver of every speed, one that differentiates one speed at a time
        (:class:`~gearjax.dynamics.solvers.AbstractOrbitSolver`): :class:`~gearjax.Auto`
        (default; its ``rtol`` the requested relative accuracy of the metrics: the
        transient), :class:`~gearjax.Transient` (transient then measured periods; on the 3D
        model cut short by the periodic estimate after every period) or
        :class:`~gearjax.Shooting` (the periodic orbit by Newton; forward mode only). The
        transient is the default because it is far cheaper for equal values (see
        ``benchmarks/results/code_notes.md``, section gearjax.design.objectives).
    orbits : the starts of the steady state at every speed, an :class:`OrbitSet` or the
        tuple of its start names (default the quasi-static state alone, as a forward
        ``sweep``); several: the objective is the largest value over the orbits they reach
        (robust to a switch of the orbit a start lands on, :mod:`gearjax.design.orbits`).
    implicit : with :class:`~gearjax.Shooting`, differentiate the periodic orbit by the
        implicit function theorem (default; :func:`gearjax.design.orbits.
        implicit_steady_metrics`) rather than through the Newton iterations.
    sharpness : beta of the smooth maximum over speeds (:mod:`gearjax.design`).
    n_table : table knots per mesh period of the model.
    adjoint : diffrax adjoint for the gradient (default ``diffrax.ForwardMode()`` with
        ``jax.jacfwd``; a ``RecursiveCheckpointAdjoint`` uses ``jax.jacrev``, the transient
        only: the shooting is forward mode).

    Raises
    ------
    DesignError
        for a bad kind, model, solver, adjoint or speeds.
    """

    def __init__(self, mesh: Mesh, space: ReliefSpace, speeds_rad_s, kind: str = "peak-force", *,
                 model: str = "torsional", rig=None,
                 formulation: str = "te", pinion_torque_Nm: float | None = None,
                 inertias_kg_m2=DESIGN_INERTIAS, damping_ratio: float = 0.03,
                 nlte_reaction: str = "drive", max_frequency_hz: float | str | None = "auto",
                 solver=None, sharpness: float = DEFAULT_SHARPNESS, n_table: int = 256,
                 adjoint=None, orbits=("quasi-static",), implicit: bool = True):
        if kind not in DYNAMIC_OBJECTIVES:
            raise DesignError("objective", kind, f"dynamic objectives are {DYNAMIC_OBJECTIVES}")
        if model not in DESIGN_MODELS:
            raise DesignError("model", model, f"must be one of {DESIGN_MODELS}")
        if model == "3d" and rig is None:
            raise DesignError("rig", rig, "the 3D model needs a rig (gearjax.rigs.registry.get_rig)")
        if model == "3d" and nlte_reaction != "drive":
            from ..rigs.factory import NLTE_REACTION_3D

            raise DesignError("nlte_reaction", nlte_reaction, NLTE_REACTION_3D)
        solver = _orbit_solver(solver)
        if isinstance(adjoint, diffrax.RecursiveCheckpointAdjoint) and not isinstance(
                solver, Transient):
            raise DesignError("adjoint", type(adjoint).__name__,
                              "the shooting differentiates in forward mode only")
        speeds = np.atleast_1d(np.asarray(speeds_rad_s, dtype=float))
        if speeds.ndim != 1 or not np.all(np.isfinite(speeds)) or np.any(speeds <= 0):
            raise DesignError("speeds_rad_s", speeds.tolist(), "need finite pinion speeds > 0 (rad/s)")
        if pinion_torque_Nm is None:
            pinion_torque_Nm = default_torque_Nm(mesh.pair, rig)
        space = space.for_dynamics(mesh.pair)
        self.mesh, self.space, self.kind = mesh, space, kind
        self.pinion_torque_Nm = float(pinion_torque_Nm)
        self.speeds = speeds
        self.formulation = formulation
        self.model_type, self.rig, self.solver = model, rig, solver
        if model == "torsional":
            self.model_kwargs = dict(pinion_torque_Nm=float(pinion_torque_Nm),
                                     inertias_kg_m2=design_inertias(mesh, inertias_kg_m2),
                                     damping_ratio=float(damping_ratio), formulation=formulation,
                                     nlte_reaction=nlte_reaction, n_table=int(n_table))
        else:
            if max_frequency_hz == "auto":
                from ..models.geared3d import default_max_frequency_hz

                max_frequency_hz = default_max_frequency_hz(float(np.max(speeds)), mesh.pair.z1)
            self.model_kwargs = dict(pinion_torque_Nm=float(pinion_torque_Nm),
                                     damping_ratio=float(damping_ratio), formulation=formulation,
                                     max_frequency_hz=max_frequency_hz, n_table=int(n_table))
        self.sharpness = float(sharpness)
        self.adjoint = diffrax.ForwardMode() if adjoint is None else adjoint
        self.static_force_N = static_mesh_force(mesh.pair, pinion_torque_Nm)
        cos_bb = math.cos(mesh.pair.base_helix_angle_rad)
        self._x_ref_m = self.static_force_N / (float(mesh.mean_stiffness()) * cos_bb)
        self.scale = self._scales()[DYNAMIC_OBJECTIVES.index(kind)]
        self.orbits = orbits if isinstance(orbits, OrbitSet) else OrbitSet(tuple(orbits))
        self.model = None
        self._earlier: list = []  # models of other structures, newest first (_model_for)
        self._rows: list = []  # each row's current model (batch)
        self.n_builds = 0
        self.build_time_s = 0.0
        self._static = (space, tuple(float(v) for v in self._scales()), self.sharpness,
                        solver, self.orbits, bool(implicit))

    # model management
    def build(self, x, frozen: bool = False):
        """The model (:class:`~gearjax.models.torsional.TorsionalModel` or
        :class:`~gearjax.models.geared3d.Geared3DModel`) built at design ``x``;
        ``frozen`` drops the angle map (switching angles fixed at ``x``: forward values
        elsewhere are resolved to the table spacing, derivatives miss their motion)."""
        t0 = time.perf_counter()
        mods = self.space.mods(np.asarray(x, dtype=float))
        if self.model_type == "torsional":
            from ..models.torsional import TorsionalModel

            m = TorsionalModel.build(self.mesh, mods, moving_events=not frozen,
                                     **self.model_kwargs)
        else:
            from ..rigs.factory import build_model

            m = build_model(self.rig, mods, mesh=self.mesh, **self.model_kwargs)
            if frozen:
                fixed = eqx.tree_at(lambda j: (j.kinds, j.cells), m.jumps,
                                    (jnp.zeros_like(m.jumps.kinds), jnp.zeros_like(m.jumps.cells)))
                m = dataclasses.replace(m, jumps=fixed, table_codes=None, angle_map=None)
                m = m.with_modifications(m.mods)  # re-assembled without the angle map
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
            model = self._model_for(x, fresh=attempt == 1)
            xj = jnp.asarray(x)
            if grad:
                g, (sm, (ex, per, ok)) = _dyn_vjac(model, xj, speeds, self._static, self.adjoint)
                g = np.asarray(g)[k]
            else:
                sm, (ex, per, ok) = _dyn_values(model, xj, speeds, self._static)
                g = None
            if bool(ok) or attempt == 1:
                break
            self.model = None  # a failed integration: once more on a model built at x
        per = np.asarray(per)[k]
        per_orbit = per.max(axis=0) if per.ndim == 2 else None  # (speeds, starts)
        per = per.max(axis=1) if per.ndim == 2 else per
        return Evaluation(x, float(sm[k]), float(ex[k]), g, per, bool(ok), per_orbit)

    def _model_for(self, x, fresh: bool = False):
        """The current model if its discrete structure holds at ``x`` (switching events
        of the same kinds on the same cells), else an earlier model whose structure holds
        there (the last :data:`MODELS_KEPT` of other structures), else (or with ``fresh``)
        a model built at ``x``. Checked before integrating: the mapped model of another
        structure has an angle map that does not fit ``x``, and its integration can crawl
        to the step limit instead of failing.

        Why earlier models are kept: an optimiser's path comes back to a structure it has
        left, and a 3D build compiles the objective's programs again (its event angles are
        static; an sdof build compiles nothing: its events are padded arrays) (see
        ``benchmarks/results/code_notes.md``, section gearjax.design.objectives)."""
        xj = jnp.asarray(x)
        if self.model is not None and not bool(_structure_holds(self.model, xj, self.space)):
            self._earlier = [self.model] + self._earlier[:MODELS_KEPT - 1]
            self.model = None
        if self.model is None and not fresh:
            for i, m in enumerate(self._earlier):
                if bool(_structure_holds(m, xj, self.space)):
                    self.model = self._earlier.pop(i)
                    break
        if self.model is None:
            self.model = self.build(x)
        return self.model

    def rebuilt(self, x) -> Evaluation:
        """The objective at ``x`` on a model built at ``x``, as a forward sweep builds it
        (the current model, built at an earlier design and mapped to ``x``, is kept). The
        two differ by what the build fixes at its own design: the table knots (sdof te:
        1.5e-7), the perturbation formulation's ``k_m`` and, on the 3D model, probably
        the modal basis computed with the build design's mesh stiffness (not isolated):
        3D te objective (spur, 2 speeds, modes < 8.9 kHz) after 5 optimiser steps from
        (20 um, 0.40) to (17 um, 0.39): 3.1e-4 relative, the rebuilt value equal to
        ``gearjax sweep``'s to 1e-9."""
        x = self.space.check(x)
        if self._rows:  # the lockstep program, one row per start (no other compilation)
            m = self.build(x)
            xs = np.repeat(x[None], len(self._rows), axis=0)
            return _evaluations(xs, self._rows_call([m] * len(self._rows), xs), self._index,
                                False)[0]
        kept = self.model
        try:  # with the gradient: the optimiser's program (the value alone compiles another)
            self.model = self.build(x)
            return dataclasses.replace(self(x, grad=True), grad=None)
        finally:
            self.model = kept

    def all_metrics(self, x, grad: bool = True):
        """(smooth (3,), exact (3,), jacobian (3, size) or None) of peak-force,
        dynamic-factor and dte-ptp at ``x`` from one set of solves (same model)."""
        x = self.space.check(x)
        model = self._model_for(x)
        speeds = jnp.asarray(self.speeds)
        if grad:
            g, (sm, (ex, _, _)) = _dyn_vjac(model, jnp.asarray(x), speeds, self._static,
                                            self.adjoint)
            return np.asarray(sm), np.asarray(ex), np.asarray(g)
        sm, (ex, _, _) = _dyn_values(model, jnp.asarray(x), speeds, self._static)
        return np.asarray(sm), np.asarray(ex), None

    def grid(self, xs, reference_x=None) -> tuple[np.ndarray, np.ndarray]:
        """(smooth, exact) at every row of ``xs``. The torsional objective evaluates the
        objective itself at every design: on a CPU one design after the other (one
        design's speeds and orbit starts fill the cores, :func:`~gearjax.design.
        multi_start`), elsewhere by :meth:`batch` in calls of its row count (the values
        program of the optimiser's lockstep); the 3D objective, whose
        builds are slow, in one compiled call on a *frozen* model built at
        ``reference_x`` (default: the middle row): switching angles of other designs
        resolved to the table spacing (1/n_table of a mesh period). Rows whose
        integration failed are NaN."""
        xs = np.asarray(xs, dtype=float)
        k = self._index
        if self.model_type == "torsional":
            if on_cpu():
                evs = [self(x, grad=False) for x in xs]
            else:
                size = len(self._rows) or DEFAULT_ROWS
                pad = -(-xs.shape[0] // size) * size - xs.shape[0]
                rows = np.concatenate([xs, np.repeat(xs[-1:], pad, axis=0)])
                evs = []
                for i in range(0, rows.shape[0], size):
                    evs += self.batch(rows[i:i + size], grad=False)
                evs = evs[:xs.shape[0]]
            bad = np.array([not e.structure_ok for e in evs])
            sm = np.array([e.smooth for e in evs])
            ex = np.array([e.exact for e in evs])
            return np.where(bad, np.nan, sm), np.where(bad, np.nan, ex)
        ref = xs[len(xs) // 2] if reference_x is None else reference_x
        model = self.build(ref, frozen=True)
        sm, (ex, _, ok) = _dyn_grid(model, jnp.asarray(xs), jnp.asarray(self.speeds),
                                    self._static)
        bad = ~np.asarray(ok, dtype=bool)
        return (np.where(bad, np.nan, np.asarray(sm)[:, k]),
                np.where(bad, np.nan, np.asarray(ex)[:, k]))

    # lockstep evaluation of several designs (multi-start optimisation, maps)
    def batch(self, xs, grad: bool = True) -> list:
        """:class:`Evaluation` of every row of ``xs`` (n, size) from one compiled call:
        the rows' models (each row's current model while its structure holds, else one
        of the same structure built before, else one built at the row) stacked and the
        objective (and with ``grad`` its gradient) vmapped over them: one program for
        every call of ``n`` rows with gradients (an optimiser's starts in lockstep), one
        without (a map's grid in chunks, which would pay 2-3x its cost for tangents it
        drops). A row whose integration failed is evaluated once more on a model built
        at it."""
        xs = np.stack([self.space.check(x) for x in np.asarray(xs, dtype=float)])
        n = xs.shape[0]
        if len(self._rows) != n:
            self._rows = [None] * n
        fresh = np.zeros(n, bool)
        for attempt in range(2):
            models = [self._row_model(i, xs[i], bool(fresh[i])) for i in range(n)]
            out = self._rows_call(models, xs, grad)
            ok = np.asarray(out[1][1][2], dtype=bool)
            if ok.all() or attempt == 1:
                break
            fresh = ~ok
            for i in np.nonzero(fresh)[0]:
                self._rows[i] = None
        return _evaluations(xs, out, self._index, grad)

    def _rows_call(self, models, xs, grad: bool = True):
        """:func:`_dyn_rows` (``grad``) or :func:`_dyn_rows_values` of the rows' models
        at ``xs``, in the one layout ``(jacobian or None, (smooth, (exact, per, ok)))``."""
        dyn = [eqx.partition(m, eqx.is_array) for m in models]
        static = dyn[0][1]
        stacked = jax.tree.map(lambda *a: jnp.stack(a), *[d for d, _ in dyn])
        args = (stacked, static, jnp.asarray(xs), jnp.asarray(self.speeds), self._static)
        if grad:
            return _dyn_rows(*args, self.adjoint)
        return None, _dyn_rows_values(*args)

    def _row_model(self, i: int, x, fresh: bool):
        """Row ``i``'s model for the design ``x`` (:meth:`batch`; the pool of earlier
        models is shared with :meth:`_model_for`)."""
        xj = jnp.asarray(x)
        m = self._rows[i]
        if m is not None and not bool(_structure_holds(m, xj, self.space)):
            if not any(m is e for e in self._earlier):
                self._earlier = [m] + self._earlier[:MODELS_KEPT - 1]
            m = None
        if m is None and not fresh:
            m = next((e for e in self._earlier if bool(_structure_holds(e, xj, self.space))),
                     None)
        if m is None:
            m = self.build(x)
            self._earlier = [m] + self._earlier[:MODELS_KEPT - 1]
        self._rows[i] = m
        return m


def _evaluations(xs, out, k: int, grad: bool) -> list:
    """The :class:`Evaluation` of each row of a :func:`_dyn_rows` call."""
    g, (sm, (ex, per, ok)) = jax.device_get(out)  # g None without gradients
    evs = []
    for i in range(xs.shape[0]):
        p = np.asarray(per[i])[k]  # (speeds, starts)
        evs.append(Evaluation(xs[i], float(sm[i][k]), float(ex[i][k]),
                              np.asarray(g[i])[k] if grad else None, p.max(axis=1),
                              bool(ok[i]), p.max(axis=0)))
    return evs


def _model_values(m, speeds, static, adjoint=None):
    """Smooth and exact maxima over ``speeds`` (and the orbit set's starts) of (max F_D,
    max F_D / F_S, DTE ptp) of the model ``m``, the values per speed and start, and
    whether every solve succeeded on a model of the right structure."""
    _, scales, sharpness, solver, orbits, implicit = static
    res = over_speeds(lambda w: orbits.metrics(solver, m, w, adjoint, implicit), speeds,
                      sequential=sequential_for(m))
    per = jnp.stack([res.max_mesh_force_N, res.dynamic_factor, res.dte_ptp_m])  # (3, w, s)
    sm = jnp.stack([smooth_max(per[i], sharpness, scales[i]) for i in range(3)])
    ok = m.structure_ok & jnp.all(res.solver_ok)
    return sm, (jnp.max(per, axis=(1, 2)), per, ok)


def _dyn_values_impl(model, x, speeds, static, adjoint=None):
    """:func:`_model_values` of ``model`` mapped to the design ``x``."""
    return _model_values(model.with_modifications(static[0].mods(x)), speeds, static, adjoint)


_dyn_values = eqx.filter_jit(_dyn_values_impl)


@eqx.filter_jit
def _structure_holds(model, x, space):
    """Whether ``model`` mapped to design ``x`` keeps its build's discrete structure."""
    return model.with_modifications(space.mods(x)).structure_ok


@eqx.filter_jit
def _dyn_vjac(model, x, speeds, static, adjoint):
    reverse = isinstance(adjoint, diffrax.RecursiveCheckpointAdjoint)
    jac = jax.jacrev if reverse else jax.jacfwd
    return _value_and_jac(lambda y: _dyn_values_impl(model, y, speeds, static, adjoint), jac)(x)


@eqx.filter_jit
def _dyn_grid(model, xs, speeds, static):
    return over_speeds(lambda x: _dyn_values_impl(model, x, speeds, static), xs,
                       sequential=sequential_for(model))


@eqx.filter_jit
def _dyn_rows(stacked, static_model, xs, speeds, static, adjoint):
    """Value and forward-mode Jacobian of :func:`_dyn_values_impl` for every row: the
    stacked array parts of the rows' models (``static_model`` the static part they share)
    and designs ``xs``, vmapped."""
    def one(dyn, x):
        model = eqx.combine(dyn, static_model)
        return _value_and_jac(lambda y: _dyn_values_impl(model, y, speeds, static, adjoint))(x)

    return jax.vmap(one)(stacked, xs)


@eqx.filter_jit
def _dyn_rows_values(stacked, static_model, xs, speeds, static):
    """:func:`_dyn_rows` without the Jacobian (values alone, vmapped over the rows)."""
    def one(dyn, x):
        return _dyn_values_impl(eqx.combine(dyn, static_model), x, speeds, static)

    return jax.vmap(one)(stacked, xs)


def make_objective(kind: str, mesh: Mesh, space: ReliefSpace, *, speeds_rad_s=None,
                   torques_Nm=None, **kwargs):
    """The objective ``kind`` of :data:`OBJECTIVES` (dynamic ones need ``speeds_rad_s``);
    ``torques_Nm`` None: :func:`default_torque_Nm` (the ``rig`` keyword's torque)."""
    if kind not in OBJECTIVES:
        raise DesignError("objective", kind, f"must be one of {OBJECTIVES}")
    if torques_Nm is None:
        torques_Nm = default_torque_Nm(mesh.pair, kwargs.get("rig"), "torques_Nm")
    if kind in DYNAMIC_OBJECTIVES:
        if speeds_rad_s is None:
            raise DesignError("speeds_rad_s", None, f"objective {kind!r} needs a speed range")
        return DynamicObjective(mesh, space, speeds_rad_s, kind,
                                pinion_torque_Nm=float(np.atleast_1d(torques_Nm)[0]), **kwargs)
    return QuasiStaticObjective(mesh, space, torques_Nm, kind, **kwargs)
