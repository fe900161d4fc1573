"""Test-only models written independently of gearjax (shared by several test files)."""

from __future__ import annotations

import math

import numpy as np

import equinox as eqx
import jax.numpy as jnp

from gearjax.excitation.jumps import JumpSet
from gearjax.models.base import AbstractGearModel, ModelOutputs
from gearjax.models.formulations import AbstractFormulation, formulation_of


class HarmonicOscillator(AbstractGearModel):
    """m x_tt + c x_t + k x = k a cos(n theta), theta = Omega t: a 'mesh' whose TE_S is a
    pure harmonic and whose stiffness is constant. State (x, x') with ' = d/dtheta,
    starting at x = a. ``forced=False`` drops the right-hand side: with damping_ratio 0
    the free vibration from x = a, energy k a^2 / 2 exactly conserved."""

    mass: float
    stiffness: float
    damping_ratio: float
    amplitude: float
    order: int = eqx.field(static=True)
    formulation: AbstractFormulation = eqx.field(static=True)
    jumps: JumpSet
    forced: bool = eqx.field(static=True)
    structure_ok: bool = eqx.field(static=True)
    period_rad: float = eqx.field(static=True)

    def __init__(self, mass, stiffness, damping_ratio, amplitude, order,
                 formulation="perturbation", jump_thetas=(), forced=True):
        self.mass, self.stiffness = mass, stiffness
        self.damping_ratio, self.amplitude, self.order = damping_ratio, amplitude, order
        self.formulation, self.forced = formulation_of(formulation), forced
        self.structure_ok = True
        self.period_rad = 2 * math.pi / order
        self.jumps = JumpSet.from_angles(jump_thetas, self.period_rad)

    @property
    def mesh_period_rad(self):
        return self.period_rad

    @property
    def static_force_N(self):
        return 100.0 * self.stiffness * self.amplitude  # never a "contact loss"

    @property
    def omega_n(self):
        return math.sqrt(self.stiffness / self.mass)

    def _te_s(self, theta):
        return self.amplitude * jnp.cos(self.order * theta) if self.forced else 0.0

    @property
    def state_size(self):
        return 2

    def with_modifications(self, mods):
        return self

    def angle(self, s):
        return s, None

    def natural_frequency_rad_s(self):
        return self.omega_n

    def homogeneous_vector_field(self, theta, y, omega):
        c = 2 * self.damping_ratio * math.sqrt(self.stiffness * self.mass)
        return jnp.stack([y[1], (-self.stiffness * y[0] - omega * c * y[1]) / (omega**2 * self.mass)])

    def initial_state(self, omega, theta0=0.0):
        return jnp.stack([jnp.asarray(self.amplitude), jnp.zeros(())])

    def vector_field(self, theta, y, omega, contact: bool = True):  # linear: no contact law
        c = 2 * self.damping_ratio * math.sqrt(self.stiffness * self.mass)
        f = self.stiffness * (self._te_s(theta) - y[0])
        return jnp.stack([y[1], (f - omega * c * y[1]) / (omega**2 * self.mass)])

    def outputs(self, theta, y, omega, contact: bool = True):
        x_s = self._te_s(theta)
        return ModelOutputs(mesh_force_N=self.static_force_N + self.stiffness * (y[0] - x_s),
                            dte_m=y[0])

    def decay_rate_per_rad(self, omega):
        return self.damping_ratio * self.omega_n / omega


# ---------------------------------------------------------------------------------------
# Kahraman & Singh (1991): a gear pair with backlash and a time-varying mesh stiffness,
# integrated by SciPy with the contact switches located as events (no gearjax inside)
class KahramanSingh:
    """The dimensionless single-degree-of-freedom gear pair of Kahraman & Singh (1991,
    J. Sound Vib. 146(1)) in the form of gearjax issue 49::

        x'' + 2 zeta x' + K(tau) g(x) = F_m + sum_j F_te,j (j W)^2 cos(j W tau)
        K(tau) = 1 - sum_j a_j cos(j W tau)
        g(x) = x (x > 0),  0 (-b <= x <= 0),  x + b (x < -b)

    (``'`` = d/dtau, ``tau = omega_n t``, ``W`` the mesh frequency over omega_n; the forcing
    is ``-e''`` of the no-load transmission error ``e = sum_j F_te,j cos(j W tau)``).

    Integrated by ``scipy.integrate.solve_ivp`` (DOP853) one contact regime at a time:
    within a regime (drive flanks, free flight, back flanks) the right-hand side is smooth
    and linear, and the switches ``x = 0`` and ``x = -b`` are located as terminal events
    and the integration restarted from them in the new regime, so the solution is as
    accurate as the tolerance on every smooth piece."""

    def __init__(self, zeta=0.05, b=1.0, f_m=0.1, f_te=(0.01, 0.004, 0.002),
                 k_var=(0.2, 0.1, 0.05), rtol=1e-11, atol=1e-13):
        self.zeta, self.b, self.f_m = zeta, b, f_m
        self.f_te, self.k_var = tuple(f_te), tuple(k_var)
        self.rtol, self.atol = rtol, atol

    # ------------------------------------------------------------------ the equation
    def stiffness(self, tau, w):
        return 1.0 - sum(a * np.cos((j + 1) * w * tau) for j, a in enumerate(self.k_var))

    def te(self, tau, w):
        """e(tau) = sum_j F_te,j cos(j W tau)."""
        return sum(f * np.cos((j + 1) * w * tau) for j, f in enumerate(self.f_te))

    def forcing(self, tau, w):
        return self.f_m + sum(f * ((j + 1) * w) ** 2 * np.cos((j + 1) * w * tau)
                              for j, f in enumerate(self.f_te))

    def g(self, x):
        return np.where(x > 0, x, np.where(x < -self.b, x + self.b, 0.0))

    def force(self, tau, x, w):
        """The dimensionless mesh force K(tau) g(x) (> 0 drive, < 0 back flanks)."""
        return self.stiffness(tau, w) * self.g(x)

    def _rhs(self, regime, w):
        off = {1: 0.0, 0: None, -1: self.b}[regime]

        def f(tau, y):
            el = 0.0 if off is None else self.stiffness(tau, w) * (y[0] + off)
            return [y[1], self.forcing(tau, w) - 2.0 * self.zeta * y[1] - el]

        return f

    def regime_of(self, x, v):
        """1 drive, 0 free flight, -1 back flanks; on a switch the one the velocity enters."""
        if x > 0 or (x == 0 and v > 0):
            return 1
        if x < -self.b or (x == -self.b and v < 0):
            return -1
        return 0

    def _events(self, regime):
        def at(level, direction):
            def e(tau, y):
                return y[0] - level
            e.terminal, e.direction = True, direction
            return e
        if regime == 1:
            return [at(0.0, -1)]
        if regime == -1:
            return [at(-self.b, 1)]
        return [at(0.0, 1), at(-self.b, -1)]

    def integrate(self, w, y0, tau0, tau1, dense=False):
        """From ``y0`` at ``tau0`` to ``tau1``: (y(tau1), switch times, regimes visited,
        pieces) with ``pieces`` the (tau_a, tau_b, regime, dense output) of every smooth
        piece when ``dense``."""
        from scipy.integrate import solve_ivp

        tau, y = float(tau0), np.asarray(y0, dtype=float)
        regime = self.regime_of(*y)
        switches, visited, pieces = [], {regime}, []
        while tau < tau1:
            sol = solve_ivp(self._rhs(regime, w), (tau, tau1), y, method="DOP853",
                            rtol=self.rtol, atol=self.atol, events=self._events(regime),
                            dense_output=dense)
            if not sol.success:
                raise RuntimeError(sol.message)
            if dense:
                pieces.append((tau, float(sol.t[-1]), regime, sol.sol))
            tau, y = float(sol.t[-1]), sol.y[:, -1].copy()
            if sol.status == 1:  # a switch: the new regime from the velocity
                level = 0.0 if (regime == 1 or (regime == 0 and y[1] > 0)) else -self.b
                y[0] = level
                switches.append(tau)
                regime = (1 if y[1] > 0 else 0) if level == 0.0 else (0 if y[1] > 0 else -1)
                visited.add(regime)
        return y, switches, visited, pieces

    def measure(self, w, y0, n_periods=2, samples=400):
        """Extremes of the mesh force over ``n_periods`` excitation periods from ``y0`` at
        tau = 0: ``dict(f_max, f_min, x_max, x_min, regimes, y_end)``, each extremum
        sampled on every smooth piece and refined on its dense output (bounded Brent)."""
        from scipy.optimize import minimize_scalar

        period = 2.0 * np.pi / w
        y_end, _, visited, pieces = self.integrate(w, y0, 0.0, n_periods * period, dense=True)
        best = {}
        for a, b, reg, sol in pieces:
            t = np.linspace(a, b, max(8, int(samples * (b - a) / period)))
            x = sol(t)[0]
            f = self.force(t, x, w)
            for key, vals, sign in (("f_max", f, 1), ("f_min", f, -1), ("x_max", x, 1),
                                    ("x_min", x, -1)):
                i = int(np.argmax(sign * vals))
                lo, hi = t[max(i - 1, 0)], t[min(i + 1, t.size - 1)]
                func = ((lambda s: -sign * float(self.force(s, sol(s)[0], w)))
                        if key[0] == "f" else (lambda s: -sign * float(sol(s)[0])))
                v = sign * vals[i]
                if hi > lo:
                    r = minimize_scalar(func, bounds=(lo, hi), method="bounded",
                                        options={"xatol": 1e-12 * period})
                    v = max(v, -r.fun)
                best[key] = max(best.get(key, -np.inf), v)
        out = {k: (v if k.endswith("max") else -v) for k, v in best.items()}
        out["regimes"] = visited
        out["y_end"] = y_end
        return out

    def transient_periods(self, w, decay=1e-7):
        """Excitation periods for a free response to decay by ``decay`` (rate zeta)."""
        return int(np.ceil(np.log(1.0 / decay) / (self.zeta * 2.0 * np.pi / w)))

    def sweep(self, ws, y0, settle=2.0):
        """Brute-force transient sweep over ``ws`` in the given order (a slow run-up or
        run-down): at each speed ``settle`` times :meth:`transient_periods` periods from the
        previous speed's end state, then :meth:`measure` over two periods. Returns a list of
        dicts (with ``w``)."""
        out, y = [], np.asarray(y0, dtype=float)
        for w in ws:
            n = int(settle * self.transient_periods(w))
            y, _, _, _ = self.integrate(w, y, 0.0, n * 2.0 * np.pi / w)
            m = self.measure(w, y)
            m["w"] = float(w)
            out.append(m)
            y = m["y_end"]
        return out


def impact_regime(regimes) -> str:
    """"none", "single" or "double" from the contact regimes an orbit visits (1 drive,
    0 free flight, -1 back flanks)."""
    return "double" if -1 in regimes else ("single" if 0 in regimes else "none")


# the gear pair of the Kahraman & Singh case (gearjax issue 49): m = 0.23 kg, k_m = 3.8e8
# N/m, clearance 0.1 mm (the length of one dimensionless unit of x), z1 = 16
KS_MASS_KG, KS_STIFFNESS_N_PER_M, KS_LENGTH_M, KS_Z1 = 0.23, 3.8e8, 1e-4, 16


def ks_te_file(path, ks: KahramanSingh, n_rows: int = 512) -> None:
    """Write the TE file (``gearjax --te-file`` format) of the Kahraman & Singh case with
    ``n_rows`` rows per mesh period (and the closing row): NLTE = e (the no-load TE, m),
    the loaded stiffness k_m K, and TE_S = e + F_S / k (the static approach of a linear
    mesh of no-load position e), F_S = F_m k_m L."""
    u = np.arange(n_rows + 1) / n_rows
    tau_w = 2.0 * np.pi * u  # W tau over one mesh period
    e = KS_LENGTH_M * sum(f * np.cos((j + 1) * tau_w) for j, f in enumerate(ks.f_te))
    k = KS_STIFFNESS_N_PER_M * (1.0 - sum(a * np.cos((j + 1) * tau_w)
                                          for j, a in enumerate(ks.k_var)))
    f_s = ks.f_m * KS_STIFFNESS_N_PER_M * KS_LENGTH_M
    with open(path, "w") as fh:
        fh.write("# Kahraman & Singh (1991) case of gearjax issue 49 (tests/oscillators.py)\n")
        fh.write("mesh_cycle_fraction,te_s_m,nlte_m,mesh_stiffness_N_per_m\n")
        for row in zip(u, e + f_s / k, e, k):
            fh.write(",".join(repr(float(v)) for v in row) + "\n")


def ks_gear_model(ks: KahramanSingh, te_path, formulation: str = "te", backlash=True):
    """The gearjax sdof model of the case through the one builder: a 16-tooth spur pair
    with the TE file of :func:`ks_te_file`, inertias ``J_i = 2 m Rb_i^2`` (so ``m_eq = m``),
    the torque of ``F_S = F_m k_m L``, damping ``zeta`` and backlash ``b L``."""
    from gearjax.excitation.te_file import read_te_csv
    from gearjax.gears.geometry import GearPair
    from gearjax.rigs.factory import build_model
    from gearjax.rigs.rig import Rig

    pair = GearPair(normal_module_m=3e-3, z1=KS_Z1, z2=2 * KS_Z1, profile_shift1=0.2,
                    profile_shift2=-0.2)
    rb1, rb2 = pair.base_radii_m
    f_s = ks.f_m * KS_STIFFNESS_N_PER_M * KS_LENGTH_M
    rig = Rig(name="kahraman-singh", pair=pair, pinion_torque_Nm=f_s * rb1,
              pinion_pitch_errors_m=np.zeros(KS_Z1), description="Kahraman & Singh (1991) case",
              backlash_m=ks.b * KS_LENGTH_M if backlash else None)
    te = read_te_csv(te_path, pair.mesh_period_rad)
    return build_model(rig, None, model="torsional", formulation=formulation, te_table=te,
                       damping_ratio=ks.zeta,
                       inertias_kg_m2=(2 * KS_MASS_KG * rb1**2, 2 * KS_MASS_KG * rb2**2))


def ks_speed_rad_s(model, w):
    """Pinion speed (rad/s) of the dimensionless mesh frequency W: ``z1 Omega = W omega_n``."""
    return np.asarray(w) * float(model.omega_n) / KS_Z1


def ks_state(ks: KahramanSingh, model, xv):
    """gearjax's scaled state at theta = 0 of the KS state ``(x, x')`` at tau = 0 (phase
    0): ``z = L (x + e(0))`` (the substitution of NLTE''; ``e'(0) = 0``), ``y = (z / x_ref,
    (dz/dt) / (omega_n x_ref))``, ``dz/dt = L omega_n x'``."""
    scale = KS_LENGTH_M / float(model.x_ref)
    return np.array([(xv[0] + sum(ks.f_te)) * scale, xv[1] * scale])


def ks_unstate(ks: KahramanSingh, model, y):
    """The inverse of :func:`ks_state`."""
    scale = float(model.x_ref) / KS_LENGTH_M
    return np.array([y[0] * scale - sum(ks.f_te), y[1] * scale])


@eqx.filter_jit
def _settle_measure(m, omega, y0, n):
    """gearjax at one speed from ``y0``: ``n`` excitation periods of transient (the
    model's integrator and step-size controller), then simulate's metrics from the end."""
    import diffrax
    from gearjax.dynamics.integrate import integrate, jump_controller
    from gearjax.dynamics.simulate import default_solver, simulate

    solver, rtol, atol = default_solver(m.formulation)
    sol = integrate(lambda t, y, a: m.vector_field(t, y, a), solver,
                    jump_controller(m, rtol, atol), 0.0, n * m.period_rad, y0, omega,
                    saveat=diffrax.SaveAt(t1=True), max_steps=1_000_000)
    y = sol.ys[-1]
    return y, simulate(m, omega, n_transient_periods=0, y0=y)


def ks_gearjax_sweep(ks: KahramanSingh, model, ws, xv0, settle=2.0):
    """gearjax's brute-force transient sweep over the dimensionless speeds ``ws`` in the
    given order, as :meth:`KahramanSingh.sweep` (same transient length, started from the KS
    state ``xv0`` at the first speed, each next speed from the previous end state): the
    transient by :func:`gearjax.dynamics.integrate.integrate` under the model's step-size
    controller, then :func:`gearjax.dynamics.simulate.simulate` from its end state. Returns
    a list of dicts ``w, f_max, f_min`` (mesh force over ``k_m L``), ``contact_loss``,
    ``back_contact``, ``converged``."""
    f_ref = KS_STIFFNESS_N_PER_M * KS_LENGTH_M
    y, out = jnp.asarray(ks_state(ks, model, xv0)), []
    for w in ws:
        n = jnp.asarray(float(int(settle * ks.transient_periods(w))))  # data: one compilation
        y, r = _settle_measure(model, jnp.asarray(float(ks_speed_rad_s(model, w))), y, n)
        out.append(dict(w=float(w), f_max=float(r.max_mesh_force_N) / f_ref,
                        f_min=float(r.min_mesh_force_N) / f_ref,
                        contact_loss=bool(r.contact_loss), back_contact=bool(r.back_contact),
                        converged=bool(r.converged)))
    return out


def plain_period_map(model, omega, y0, rtol, atol, max_steps):
    """y(P) from y(0) = y0 over one excitation period by a plain diffrax Dopri5 solve under
    a plain PID controller (the model's jump angles, read on the host, as ``jump_ts``):
    independent of gearjax's integrator, step-size controller and variational equations."""
    p = float(model.period_rad)
    jumps = np.asarray(model.jump_thetas, dtype=float)
    return _plain_period_map(model, omega, y0, jnp.asarray(jumps[(jumps > 0) & (jumps < p)]),
                             rtol, atol, max_steps)


@eqx.filter_jit
def _plain_period_map(model, omega, y0, jumps, rtol, atol, max_steps):
    import diffrax

    sol = diffrax.diffeqsolve(
        diffrax.ODETerm(lambda t, y, a: model.vector_field(t, y, a)), diffrax.Dopri5(),
        t0=0.0, t1=float(model.period_rad), dt0=None, y0=jnp.asarray(y0),
        args=jnp.asarray(omega),
        stepsize_controller=diffrax.PIDController(rtol=rtol, atol=atol, jump_ts=jumps),
        max_steps=max_steps)
    return sol.ys[-1]
