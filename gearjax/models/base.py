"""What every solver may ask of a gear model: :class:`AbstractGearModel`.

A model is a complete pytree (born complete: every derived array is computed by its
builder or by :meth:`AbstractGearModel.with_modifications`, never patched afterwards), and
the solvers of :mod:`gearjax.dynamics` and :mod:`gearjax.design` use only what this class
declares. Concrete models (:class:`gearjax.models.torsional.TorsionalModel`, the 3D model)
are final subclasses.

Conventions (paper: Velex & Ajmi): the independent variable is the pinion angle
``theta = Omega1 t`` (rad), ``' = d/dtheta``; the *simulation angle* ``s`` equals ``theta``
at the build-time design and is mapped to it by :meth:`AbstractGearModel.angle` when the
switching angles move with the modifications. The state ``y`` is dimensionless (scaled by
the model). Speeds are the pinion speed ``Omega1`` (rad/s). SI units throughout.
"""

from __future__ import annotations

import abc
import math

import equinox as eqx
import jax
import jax.numpy as jnp

from ..errors import ModelError
from .formulations import FORMULATION_NAMES, AbstractFormulation, Reference, formulation_of
from ..excitation.jumps import JumpSet

__all__ = ["AbstractGearModel", "AbstractModalModel", "ModelOutputs", "FORMULATIONS",
           "LINEAR_FORMULATIONS", "AbstractWithoutContactLaw", "WithoutContactLaw",
           "ModalWithoutContactLaw", "without_contact_law", "modal_transient_start",
           "modal_periodic_estimate"]

# the names of the paper's three formulations (gearjax.models.formulations), and of the two
# linearised about the quasi-static contact (one build, one mesh term apart)
FORMULATIONS = FORMULATION_NAMES
LINEAR_FORMULATIONS = tuple(n for n in FORMULATION_NAMES if formulation_of(n).linear)


class ModelOutputs(eqx.Module):
    """Observables at one angle (all scalars).

    Attributes
    ----------
    mesh_force_N : dynamic normal mesh force F_D (N), Eqs. (22)/(24).
    dte_m : dynamic transmission error DTE = x + NLTE (m, transverse on the base plane).
    accel_m_s2 : acceleration observable (m/s^2), or None when the model has none
        (torsional model).
    """

    mesh_force_N: jax.Array
    dte_m: jax.Array
    accel_m_s2: jax.Array | None = None


class AbstractGearModel(eqx.Module):
    """The interface of a gear model to the solvers (transient, shooting, Floquet, sweep,
    design).

    Attributes
    ----------
    formulation : the :class:`~gearjax.models.formulations.AbstractFormulation`:
        :class:`~gearjax.models.formulations.Reference` (Eq. (14), sdof Eq. (16):
        unilateral contact on every cell, nonlinear),
        :class:`~gearjax.models.formulations.TransmissionError` (Eq. (42), sdof Eq. (20):
        affine in the state with the loaded quasi-static stiffness) or
        :class:`~gearjax.models.formulations.Perturbation` (Eq. (48a), sdof Eq. (47a):
        affine with the mean stiffness ``k_m``); ``.name`` is its word in results.
    period_rad : excitation period in theta (rad): one mesh period ``2 pi / z1`` or a
        multiple (pitch errors, eccentricity).
    jumps : :class:`~gearjax.excitation.jumps.JumpSet`, the sorted simulation angles in
        ``[0, period_rad)`` where the right-hand side jumps or kinks independently of
        speed (passed to the step-size controller), padded to a static bound: data, so
        that a design that moves them (or changes their count within the bound) is not a
        new program.
    damping_ratio : modal / mesh viscous damping ratio zeta (dimensionless).
    structure_ok : traced bool, the discrete structure of the quasi-static solution
        (active sets, NLTE cell, relief zones at every table knot) is the build one, so
        the angle map and the tables are valid for the current modifications.
    """

    formulation: eqx.AbstractVar[AbstractFormulation]
    period_rad: eqx.AbstractVar[float]
    jumps: eqx.AbstractVar[JumpSet]
    damping_ratio: eqx.AbstractVar[jax.Array]
    structure_ok: eqx.AbstractVar[jax.Array]

    # ------------------------------------------------------------------ constants
    @property
    def jump_thetas(self) -> tuple:
        """The valid angles of :attr:`jumps` (rad), a tuple (concrete models only)."""
        return self.jumps.angles()

    @property
    @abc.abstractmethod
    def mesh_period_rad(self) -> float:
        """One mesh period in theta, ``2 pi / z1`` (rad)."""

    @property
    @abc.abstractmethod
    def static_force_N(self):
        """Static normal mesh force ``F_S = C_m0 / (Rb1 cos b_b)`` (N), Section 3."""

    @property
    @abc.abstractmethod
    def state_size(self) -> int:
        """Number of components of the (scaled) state ``y``."""

    @abc.abstractmethod
    def with_modifications(self, mods) -> "AbstractGearModel":
        """A complete model with the tooth modifications ``mods``
        (:class:`gearjax.gears.modifications.ToothModifications`) and every derived array
        (tables, mean stiffness, scalings, angle map) recomputed from them. Traceable:
        jit/vmap/jacfwd through it differentiate the model in the design."""

    def require_structure(self) -> None:
        """Raise :class:`~gearjax.errors.ModelError` unless :attr:`structure_ok`: a model
        mapped by :meth:`with_modifications` to a design whose switching events differ
        from its build's (another count or order) has an angle map and tables that do not
        fit that design, and integrating it crawls to the step limit and returns NaN
        (sdof reference, zeta 0.03: minutes per speed). Host-level: the sweeps call it on
        their concrete model before compiling."""
        if not bool(jnp.all(jnp.asarray(self.structure_ok))):
            raise ModelError(
                "mods", "with_modifications(...)",
                "the design changes the model's switching events (count or order) from "
                "those of its build, so its angle map and tables do not fit it: build a "
                "model at this design (TorsionalModel.build / build_model) instead; a "
                "model refused at its own build design has switching events its build "
                "could not follow (a bug: please report it with the model's inputs; the 3D "
                "build_model(..., moving_events=False) builds it without moving events)")

    # ------------------------------------------------------------------ dynamics
    @abc.abstractmethod
    def angle(self, s):
        """``(theta, dtheta/ds)`` at the simulation angle ``s`` (rad); ``dtheta/ds`` is None
        when the map is the identity (no design-dependent switching angle)."""

    @abc.abstractmethod
    def initial_state(self, omega, theta0=0.0):
        """Scaled state at ``theta0`` on the quasi-static solution (dynamic part zero)."""

    @abc.abstractmethod
    def vector_field(self, s, y, omega, contact: bool = True):
        """``dy/ds`` of the equation of motion (Eq. (14)/(42)/(48a) or their sdof forms
        (16)/(20)/(47a)) at the simulation angle ``s`` for pinion speed ``omega`` (rad/s)."""

    @abc.abstractmethod
    def homogeneous_vector_field(self, theta, y, omega):
        """Linear homogeneous part of the equation of motion for the dynamic part of the
        state (for the Floquet analysis of :mod:`gearjax.dynamics.stability`)."""

    @abc.abstractmethod
    def outputs(self, theta, y, omega, contact: bool = True) -> ModelOutputs:
        """Mesh force F_D (N, Eqs. (22)/(24)), DTE (m) and, where the model has one, an
        acceleration (m/s^2) at the simulation angle ``theta`` (``contact=False``: te and
        perturbation without the contact law, as :meth:`vector_field`)."""

    @abc.abstractmethod
    def decay_rate_per_rad(self, omega):
        """Free-decay rate of the slowest relevant mode per radian of theta (sizes the
        automatic transient): ``zeta omega / Omega``."""

    @abc.abstractmethod
    def natural_frequency_rad_s(self):
        """Natural frequency (rad/s) of the mode that dominates the mesh deflection
        (sdof: ``omega_n = sqrt(k_m cos^2 b_b / m_eq)``)."""

    # ------------------------------------------------------------------ starts
    def transient_start(self, omega):
        """State at theta = 0 that a transient starts from. Default: the quasi-static
        state :meth:`initial_state`; modal models start their slow modes on the period
        mean (:func:`modal_transient_start`)."""
        return self.initial_state(omega)

    def deflected_start(self, omega, factor):
        """The quasi-static state at theta = 0 (:meth:`initial_state`) with its
        displacements scaled by ``factor`` and its velocities kept: ``factor = -1`` mirrors
        the static deflection of the mesh about zero (teeth apart by the static approach), a
        start from which a transient can reach a contact-losing orbit that coexists with
        the one reached from the quasi-static state (:class:`gearjax.design.OrbitSet`).
        Default: a state ``(displacements, velocities)`` in two halves, zero at zero
        deflection (the sdof model's ``(z / x_ref, z' / (r x_ref))``)."""
        y = self.initial_state(omega)
        half = y.shape[0] // 2
        return y.at[:half].multiply(factor)

    @property
    def periodic_start(self) -> bool:
        """True when :meth:`initial_state` is already the periodic steady state (then no
        transient needs integrating). Default False."""
        return False

    @property
    def mesh_level_contact(self) -> bool:
        """True when te/perturbation decide contact from the mesh force alone
        (:func:`gearjax.gears.contact.te_contact`), so that a linear orbit is the model's
        wherever its mesh force stays compressive (what the frequency-domain solver
        checks). False with the per-cell law (:attr:`gearjax.gears.contact.TEContactLaw.CELLS`:
        a cell may open while the mesh stays loaded). Default True."""
        return True

    @property
    def speed_scaled_state(self) -> bool:
        """True when the state is scaled by the pinion speed so that the homogeneous part
        of :meth:`vector_field` at speed ``Omega`` is ``Omega^-1`` times one
        speed-independent operator (the models' ``(z / x, z' / (r x))``, ``r = omega /
        Omega``: ``d/dtheta = Omega^-1 d/dt`` on the physical time scale): the
        frequency-domain solver then decomposes the operator once per model, not once
        per speed (:mod:`gearjax.dynamics.harmonic_split`, which checks it at every
        speed). Default False."""
        return False

    def compiled_form(self) -> "AbstractGearModel":
        """The model as a compiled sweep program receives it
        (:func:`gearjax.dynamics.sweep.sweep`): models whose equations differ only in
        array data get the same static fields here, so that one compilation serves them
        all (the 3D te and perturbation formulations). Default: the model itself."""
        return self

    def harmonic_state(self, omega, theta0=0.0):
        """Periodic steady state at ``theta0`` solved in the frequency domain, for models
        whose :attr:`periodic_start` is True; the default has none."""
        raise ModelError("harmonic_state", type(self).__name__,
                         "this model has no frequency-domain periodic state")


class AbstractModalModel(AbstractGearModel):
    """A model whose state is modal coordinates (r modal displacements, then r scaled modal
    velocities) of a linear structure: the 3D model. Declares what the transient solver
    uses to cut a transient short and to judge what is left of it, which only a modal
    state gives (:func:`gearjax.dynamics.simulate.simulate`,
    :mod:`gearjax.dynamics.periodicity`)."""

    @abc.abstractmethod
    def transient_amplitudes(self, dy, omega):
        """Bounds of the free response still in a transient, from ``dy = y(theta + P) -
        y(theta)`` (state change over one excitation period ``P`` at one phase; zero on the
        periodic orbit): ``(mesh force (N), DTE (m), acceleration (m/s^2))``, used by
        :func:`gearjax.dynamics.simulate.simulate` for ``convergence``
        (:func:`modal_transient_amplitudes`)."""

    @abc.abstractmethod
    def periodic_estimate(self, y_start, y_end, omega, slow_only: bool = False):
        """Estimate of the periodic state at the end of one excitation period of a
        transient, from its start ``y_start`` and end ``y_end`` (a quasi-Newton step on
        the periodicity residual, used by :func:`gearjax.dynamics.simulate.simulate` to cut
        the transient short); ``slow_only``: correct only the modes well below the
        excitation frequency, which respond to its period mean
        (:func:`modal_periodic_estimate`)."""


class AbstractWithoutContactLaw(AbstractGearModel):
    """The te or perturbation model ``model`` with its equations exactly as printed,
    Eqs. (20)/(42) and (47a)/(48a): linear in the state, without the contact law of
    :func:`gearjax.gears.contact.te_contact`, so the mesh force may turn tensile.

    The solver interface is the wrapped model's (model-specific attributes: ``.model``),
    except :meth:`vector_field` and :meth:`outputs`, which always call the model's with
    ``contact=False`` (their ``contact`` argument is there for the interface and ignored).
    Use it to compare with a linear frequency-domain solution or to watch a parametric
    instability grow (the contact law bounds both); a physical response needs the contact
    law. The five solver attributes are copied from ``model`` at construction (equinox
    abstract variables must be fields), so wrap the model after changing it.
    :func:`without_contact_law` wraps any model (:class:`WithoutContactLaw`, or
    :class:`ModalWithoutContactLaw` keeping a modal model's capabilities).
    """

    model: AbstractGearModel
    formulation: AbstractFormulation
    period_rad: float
    jumps: JumpSet
    damping_ratio: jax.Array
    structure_ok: jax.Array

    def __init__(self, model: AbstractGearModel):
        if isinstance(model.formulation, Reference):
            raise ModelError("formulation", "reference", "the reference formulation's contact "
                             "is per cell and always on; WithoutContactLaw is for te/perturbation")
        self.model = model
        self.formulation, self.period_rad = model.formulation, model.period_rad
        self.jumps, self.damping_ratio = model.jumps, model.damping_ratio
        self.structure_ok = model.structure_ok

    @property
    def mesh_period_rad(self):
        return self.model.mesh_period_rad

    @property
    def static_force_N(self):
        return self.model.static_force_N

    @property
    def state_size(self):
        return self.model.state_size

    @property
    def periodic_start(self):
        return self.model.periodic_start

    @property
    def speed_scaled_state(self):
        return self.model.speed_scaled_state


    def with_modifications(self, mods):
        return without_contact_law(self.model.with_modifications(mods))

    def angle(self, s):
        return self.model.angle(s)

    def initial_state(self, omega, theta0=0.0):
        return self.model.initial_state(omega, theta0)

    def vector_field(self, s, y, omega, contact: bool = False):
        """The model's ``dy/ds`` with ``contact=False``."""
        return self.model.vector_field(s, y, omega, contact=False)

    def homogeneous_vector_field(self, theta, y, omega):
        return self.model.homogeneous_vector_field(theta, y, omega)

    def outputs(self, theta, y, omega, contact: bool = False) -> ModelOutputs:
        """The model's outputs with ``contact=False`` (the linear mesh force, N)."""
        return self.model.outputs(theta, y, omega, contact=False)

    def decay_rate_per_rad(self, omega):
        return self.model.decay_rate_per_rad(omega)

    def natural_frequency_rad_s(self):
        return self.model.natural_frequency_rad_s()

    def transient_start(self, omega):
        return self.model.transient_start(omega)

    def deflected_start(self, omega, factor):
        return self.model.deflected_start(omega, factor)

    def harmonic_state(self, omega, theta0=0.0):
        return self.model.harmonic_state(omega, theta0)


class WithoutContactLaw(AbstractWithoutContactLaw):
    """:class:`AbstractWithoutContactLaw` of a model without a modal state (the sdof model)."""


class ModalWithoutContactLaw(AbstractWithoutContactLaw, AbstractModalModel):
    """:class:`AbstractWithoutContactLaw` of a :class:`AbstractModalModel` (the 3D model),
    keeping its transient extrapolation."""

    def transient_amplitudes(self, dy, omega):
        return self.model.transient_amplitudes(dy, omega)

    def periodic_estimate(self, y_start, y_end, omega, slow_only: bool = False):
        return self.model.periodic_estimate(y_start, y_end, omega, slow_only)


def without_contact_law(model: AbstractGearModel) -> AbstractWithoutContactLaw:
    """``model`` (te or perturbation) without the contact law: :class:`ModalWithoutContactLaw`
    for a modal model, else :class:`WithoutContactLaw`. Raises
    :class:`~gearjax.errors.ModelError` for the reference formulation."""
    if isinstance(model, AbstractModalModel):
        return ModalWithoutContactLaw(model)
    return WithoutContactLaw(model)


def modal_transient_start(model: AbstractGearModel, omega, omega_r, n_average: int = 64):
    """Transient start of a modal model (state: r modal displacements then r scaled modal
    velocities; ``omega_r`` (r,) modal frequencies, rad/s).

    Each mode starts between the quasi-static state at 0, right for modes far above the
    first excitation frequency ``nu_1 = 2 pi Omega / P``, and its mean over one period
    (velocity ~0), right for modes far below it (they respond to the mean only)::

        y_i = mean_i + g_i (y_qs,i(0) - mean_i),   g_i = w_i^4 / (w_i^4 + nu_1^4).

    Measurements: ``benchmarks/results/model_notes.md`` (dynamics/simulate.py).
    """
    y_qs = model.initial_state(omega)
    if y_qs.ndim != 1 or y_qs.shape[0] != 2 * omega_r.shape[0]:
        return y_qs
    period = float(model.period_rad)
    thetas = (jnp.arange(n_average) + 0.5) * (period / n_average)
    mean = jnp.mean(jax.vmap(lambda t: model.initial_state(omega, t))(thetas), axis=0)
    nu1 = 2.0 * math.pi / period * omega
    w4 = jnp.asarray(omega_r) ** 4
    g = w4 / (w4 + nu1**4)
    g = jnp.concatenate([g, g])
    return mean + g * (y_qs - mean)


def free_decay(omega_n, zeta, period_s):
    """``(|mu|, arg mu)`` of the multiplier ``mu = exp((-zeta + i sqrt(1 - zeta^2)) omega_n
    period_s)`` of a free mode of natural frequency ``omega_n`` (rad/s) and damping ratio
    ``zeta`` over ``period_s`` seconds."""
    arg = omega_n * period_s
    return jnp.exp(-zeta * arg), arg * jnp.sqrt(jnp.clip(1.0 - zeta**2, 0.0, 1.0))


def free_decay_per_period(omega_n, zeta, period_s):
    """``(|mu|, |1 - mu|)`` of :func:`free_decay`'s multiplier per period."""
    decay, wd = free_decay(omega_n, zeta, period_s)
    return decay, jnp.sqrt((1.0 - decay * jnp.cos(wd)) ** 2 + (decay * jnp.sin(wd)) ** 2)


def modal_transient_amplitudes(dy, omega, period_rad: float, omega_r, damping_ratio, scale,
                               force_per_coord, dte_per_coord, accel_per_coord):
    """Free response left in a modal state (:meth:`AbstractGearModel.transient_amplitudes`):
    state ``y = (z / a, z' / (omega_j a))`` per mode ``j`` (``omega_r`` (r,) rad/s, ``a``
    the length ``scale``, ``'`` the time derivative), ``dy`` its change over one period
    ``P`` (``period_rad / omega`` s). A free mode decays by the multiplier ``mu_j =
    exp((-zeta + i sqrt(1 - zeta^2)) omega_j P)`` per period, so what is left of it after
    the period is ``|mu_j| / |1 - mu_j|`` times its change over the period (its amplitude
    ``a |(dy_j, dy_r+j)|``). The outputs sum every mode's share (``force_per_coord`` N,
    ``dte_per_coord`` m and ``accel_per_coord`` m/s^2 per unit modal displacement, the
    latter times ``omega_j^2``; None: no acceleration output), over the modes whose
    remainder exceeds their change (``|mu_j| > |1 - mu_j|``; the change of the others is
    in the extrema's change that ``simulate`` takes as well). Per mode, not the slowest
    mode's factor on every change: integration noise of the fast modes is not amplified
    by a slow mode's ``1 / |1 - mu|`` (~15-500 on the 3D rig)."""
    om = jnp.asarray(omega_r)
    r = om.shape[0]
    zeta = jnp.clip(jnp.asarray(damping_ratio), 0.0, 1.0)
    decay, gap = free_decay_per_period(om, zeta, period_rad / omega)
    # only the modes whose remainder exceeds their change (|mu| > |1 - mu|): the others'
    # change shows in the extrema's change itself, and their state change is mostly
    # integration noise, which omega_j^2 would blow up in the acceleration (25 kHz static
    # corrections at 20 rad/s: 6e-3 of the acceleration's peak-to-peak)
    weight = decay / jnp.clip(gap, 1e-12, None)
    amp = scale * jnp.sqrt(dy[:r] ** 2 + dy[r:2 * r] ** 2) * jnp.where(weight > 1.0, weight, 0.0)
    acc = None if accel_per_coord is None else jnp.sum(jnp.abs(accel_per_coord) * om**2 * amp)
    return (jnp.sum(jnp.abs(force_per_coord) * amp), jnp.sum(jnp.abs(dte_per_coord) * amp), acc)


def modal_periodic_estimate(y_start, y_end, omega, period_rad: float, omega_r, damping_ratio,
                            min_gap: float = 1e-3, slow_only: bool = False):
    """Periodic state of a modal model estimated from one period of its transient
    (:meth:`AbstractGearModel.periodic_estimate`; state ``y = (z / a, z' / (omega_j a))`` per
    mode ``j``, ``omega_r`` (r,) rad/s, as in :func:`modal_transient_amplitudes`).

    Shooting with the free-decay monodromy as the Jacobian: over one period ``P``
    (``period_rad / omega`` s) the free response of mode ``j`` in its scaled coordinates
    ``u = (x, x' / omega_j)``, ``u' = omega_j [[0, 1], [-1, -2 zeta]] u``, is mapped by
    ``M_j = exp(omega_j P [[0, 1], [-1, -2 zeta]]) = e^(-zeta w) (cos(w_d) I + sin(w_d) /
    sqrt(1 - zeta^2) [[zeta, 1], [-1, -zeta]])`` (``w = omega_j P``, ``w_d = w sqrt(1 -
    zeta^2)``). With ``y = p + e`` (periodic part ``p``, transient ``e``), the change over the
    period is ``dy = (M - I) e_start``, so what is left at the end is ``e_end = M (M -
    I)^-1 dy`` and ``p = y_end - e_end``: exact for uncoupled linear modes, a Newton step
    with an approximate Jacobian where the time-varying mesh stiffness or the contact law
    couples them (iterated by ``simulate``, which checks that the residual falls). Modes
    whose ``|1 - mu_j| = sqrt(det(M_j - I))`` is below ``min_gap`` (barely damped at a
    multiple of the excitation frequency) keep ``y_end``.

    ``slow_only``: only the modes that turn by at most a quarter of a cycle per period
    (``omega_j P <= pi / 2``) are corrected. Such a mode sees the excitation as a fast
    oscillation and responds to its period mean, which the contact state changes little,
    so its free-decay monodromy stays a good Jacobian where the mesh modes' does not
    (contact loss near a resonance); it is also the mode that makes a plain transient long
    (the 3D rig's 9.8 Hz mode: ``|mu| = 0.99943`` per mesh period at 780 rad/s and zeta
    0.03)."""
    om = jnp.asarray(omega_r)
    r = om.shape[0]
    zeta = jnp.clip(jnp.asarray(damping_ratio), 0.0, 1.0 - 1e-12)
    e, wd = free_decay(om, zeta, period_rad / omega)
    c, sn = e * jnp.cos(wd), e * jnp.sin(wd) / jnp.sqrt(1.0 - zeta**2)
    m11, m12, m21, m22 = c + zeta * sn, sn, -sn, c - zeta * sn
    a11, a22 = m11 - 1.0, m22 - 1.0
    det = a11 * a22 - m12 * m21  # = |1 - mu|^2
    use = det > min_gap**2
    if slow_only:
        use = use & (om * (period_rad / omega) <= 0.5 * jnp.pi)
    det = jnp.where(use, det, 1.0)
    d = y_end - y_start
    dx, dv = d[:r], d[r:2 * r]
    ex, ev = (a22 * dx - m12 * dv) / det, (a11 * dv - m21 * dx) / det  # (M - I)^-1 dy
    left = jnp.concatenate([jnp.where(use, m11 * ex + m12 * ev, 0.0),
                            jnp.where(use, m21 * ex + m22 * ev, 0.0)])
    return y_end.at[: 2 * r].add(-left)
