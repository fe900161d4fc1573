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
the drive (``nlte_reaction="drive"``, kappa = 1, the default of every model and command,
see :mod:`gearjax.models.torsional`).
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
Default te (Eq. (20) / (42)) with the contact law of Section 6.2
(:func:`gearjax.gears.contact.te_contact`): the closest of the TE-based formulations to the
reference, and bounded through contact loss. Without the contact law the linear te
equation of the long relief was parametrically unstable around the main critical speed
(Floquet radius up to 1.074 over 770-810 rad/s, dynamic factor 457 at 800 rad/s), and the
optimiser chased that non-physical resonance. The reference formulation (Eq. (16), cell by
cell contact) and the perturbation formulation (Eq. (47a), constant k_m) are options; the
optimum of any of them is checked by forward sweeps of the reference
(``notebooks/tip_relief_design.ipynb``).

Kinks: with contact loss the objective is continuous but has kinks in the design where a
contact-loss interval appears or vanishes at the speed and instant of the maximum (the
mesh force touches zero tangentially), where the speed or instant of the maximum switches
(a smooth maximum over speeds removes the first; the second stays), and where the discrete
quasi-static structure changes (rebuild, :class:`DynamicObjective`). Between them the
forward-mode derivative through the integrator's steps is the derivative of the orbit
(the vector field is continuous across contact loss, so no saltation term is missing):
``tests/test_design.py`` checks it against central differences at a speed with contact
loss.

3D model
--------
``DynamicObjective(..., model="3d", rig=rig)`` drives the 3D model of a rig (Eqs. (14),
(42), (48a), modes below ``max_frequency_hz``, by default 4.5 mesh harmonics of the
highest speed, at least 6 kHz) at its periodic steady state, by default
(``method="auto"``) through the accelerated transient of
:func:`gearjax.dynamics.simulate.simulate` (its periodic estimate after every period
removes the 61.8 rad/s shaft-line mode that a plain transient would leave as a residue
larger than the design's effect), or by shooting (``method="steady"``,
:func:`gearjax.dynamics.steady.steady_state`). Its events (jumps
of ``k(theta)``, of NLTE', kinks of TE_S at the relief starts) follow the design through
the same angle map (:mod:`gearjax.models.geared3d`, "Derivatives with respect to the
design"), and ``prepare`` checks the discrete structure as the torsional model does
(rebuild when it changes). Exact derivatives in the te formulation; the perturbation
formulation holds its splitting constant ``k_m`` at the build design (the objective
jumps by a little when a rebuild changes it). Measured (spur, short relief, 300 and 500
rad/s, zeta 0.1, modes < 3 kHz; ``tests/test_design.py``): jacfwd against central
differences of the same objective 1.2e-5 (te) and 4.6e-6 (perturbation) by the
transient at rtol 1e-10, 1e-5 and 4e-6 by shooting at 1e-11, for the peak force,
dynamic factor and DTE peak-to-peak; the two methods' maxima 2.8e-9 apart. Cost (2
speeds 330/480 rad/s, modes < 8.9 kHz, default tolerances, 2-core CPU): value and
gradient 1.0 s by the transient after a ~30 s first call, 48 s + 164 s by shooting
(``benchmarks/bench_gradients.py --model 3d``).

Bounds of linear reliefs
------------------------
The dynamic models refuse equal-slope linear reliefs whose flat overlap band exceeds a
base pitch (spur) or is not empty (helical) (:meth:`ToothModifications.check_against`):
dynamic objectives lower the extent bound of a linear :class:`ReliefSpace` below that
limit (:meth:`ReliefSpace.for_dynamics`: 0.786 for the Table 1 spur pair, 0.495 for the
helical pair), so that no optimiser step or map point reaches a refused design.
"""

from ..errors import DesignError as DesignError
from .maps import HarrisMap as HarrisMap
from .maps import harris_curves as harris_curves
from .maps import harris_map as harris_map
from .objectives import DEFAULT_SHARPNESS as DEFAULT_SHARPNESS
from .objectives import DESIGN_INERTIAS as DESIGN_INERTIAS
from .objectives import DESIGN_METHODS as DESIGN_METHODS
from .objectives import DESIGN_MODELS as DESIGN_MODELS
from .objectives import DYNAMIC_OBJECTIVES as DYNAMIC_OBJECTIVES
from .objectives import OBJECTIVES as OBJECTIVES
from .objectives import DynamicObjective as DynamicObjective
from .objectives import Evaluation as Evaluation
from .objectives import QuasiStaticObjective as QuasiStaticObjective
from .objectives import design_inertias as design_inertias
from .objectives import make_objective as make_objective
from .objectives import method_tolerances as method_tolerances
from .objectives import smooth_max as smooth_max
from .optimise import OptimisationResult as OptimisationResult
from .optimise import coarse_starts as coarse_starts
from .optimise import multi_start as multi_start
from .optimise import optimise as optimise
from .spaces import ReliefSpace as ReliefSpace

__all__ = [
    "OBJECTIVES",
    "DEFAULT_SHARPNESS",
    "DESIGN_INERTIAS",
    "DESIGN_METHODS",
    "DESIGN_MODELS",
    "design_inertias",
    "method_tolerances",
    "DesignError",
    "ReliefSpace",
    "smooth_max",
    "QuasiStaticObjective",
    "DynamicObjective",
    "Evaluation",
    "make_objective",
    "OptimisationResult",
    "optimise",
    "multi_start",
    "coarse_starts",
    "harris_map",
    "HarrisMap",
    "harris_curves",
]
