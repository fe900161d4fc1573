"""Differentiable tip-relief design: objectives, gradients, an optax optimiser, Harris maps.

The design variables are the tip-relief amplitude ``P_c`` (m) and extent ``L_c`` (fraction
of the path of contact) of pinion and gear (paper Section 2.2.1, Fig. 4), shared
(``x = (P_c, L_c)``) or separate (``x = (P_c1, P_c2, L_c1, L_c2)``), linear or parabolic
(:class:`ReliefSpace`). The optimiser works on unconstrained ``u``,
``x = lo + (hi - lo) sigmoid(u)``, so every iterate respects the bounds; dynamic objectives
lower the extent bound of a linear relief below the pair's equal-slope limit
(:meth:`ReliefSpace.for_dynamics`), so no step reaches a design the models refuse.

Objectives (:data:`OBJECTIVES`): ``"te-ptp"`` / ``"te-rms"``, the peak-to-peak / RMS
fluctuation (m) of the quasi-static transmission error TE_S (Eqs. (10), (17)) over a mesh
period at one or several pinion torques; ``"peak-force"``, the largest dynamic mesh force
F_D (N, Eqs. (22)/(24)) over a range of pinion speeds at steady state, from the sdof
torsional model (Eqs. (16), (20), (47a)) or the 3D model of a rig (Eqs. (14), (42), (48a));
``"dynamic-factor"``, the same over the static force F_S (Eq. (23)); ``"dte-ptp"``, the
largest peak-to-peak dynamic transmission error (m).

Smooth maximum: maxima over speeds, loads (and the TE_S extrema of te-ptp) are
:func:`smooth_max` with ``beta = sharpness`` (:data:`DEFAULT_SHARPNESS`) and ``scale`` the
objective's unit (F_S, 1, or the mean static mesh deflection), so ``max v <= smax <= max v
+ scale ln(n) / beta``; every evaluation reports the exact maximum beside it.

Gradients: forward mode (``jax.jacfwd``, ``diffrax.ForwardMode``) through mesh cells,
quasi-static table, solve and metric; the switching angles follow the design through the
models' angle map (:mod:`gearjax.excitation.events`), valid while the quasi-static
structure is the build one, which :class:`DynamicObjective` checks at every evaluation
(rebuilding the model, which compiles nothing for the sdof model). Shooting orbits are
differentiated implicitly (:mod:`gearjax.design.orbits`); an :class:`OrbitSet` of starts
takes the largest value over the orbits they reach. With contact loss the objective is
continuous with kinks; between them it is the orbit's derivative (no saltation).

Inertias (:data:`DESIGN_INERTIAS`): the sdof model uses the gear bodies (solid cylinders at
the pitch radii) and puts the NLTE'' reaction on the drive (``kappa = 1``), because the
shafts are torsionally far softer than the mesh and decouple from the bodies at the mesh
modes. Formulation: te (Eq. (20) / (42)) with the contact law of Section 6.2
(:func:`gearjax.gears.contact.te_contact`) by default, bounded through contact loss; without
it the linear te equation can be parametrically unstable near the main critical speed.
The 3D perturbation formulation holds its splitting constant ``k_m`` at the build design.
Measurements behind these choices: ``benchmarks/results/code_notes.md``, gearjax.design.
"""

from ..errors import DesignError as DesignError
from .maps import HarrisMap as HarrisMap
from .maps import MapPatch as MapPatch
from .maps import harris_curves as harris_curves
from .maps import harris_map as harris_map
from .objectives import DEFAULT_SHARPNESS as DEFAULT_SHARPNESS
from .objectives import DESIGN_INERTIAS as DESIGN_INERTIAS
from .objectives import DESIGN_MODELS as DESIGN_MODELS
from .objectives import DYNAMIC_OBJECTIVES as DYNAMIC_OBJECTIVES
from .objectives import OBJECTIVES as OBJECTIVES
from .objectives import DynamicObjective as DynamicObjective
from .objectives import Evaluation as Evaluation
from .objectives import QuasiStaticObjective as QuasiStaticObjective
from .objectives import design_inertias as design_inertias
from .objectives import make_objective as make_objective
from .objectives import smooth_max as smooth_max
from .orbits import ORBIT_STARTS as ORBIT_STARTS
from .orbits import OrbitSet as OrbitSet
from .orbits import implicit_steady_metrics as implicit_steady_metrics
from .optimise import OptimisationResult as OptimisationResult
from .optimise import coarse_starts as coarse_starts
from .optimise import multi_start as multi_start
from .optimise import optimise as optimise
from .optimise import optimise_lockstep as optimise_lockstep
from .spaces import ReliefSpace as ReliefSpace

__all__ = [
    "OBJECTIVES",
    "DEFAULT_SHARPNESS",
    "DESIGN_INERTIAS",
    "DESIGN_MODELS",
    "design_inertias",
    "DesignError",
    "ReliefSpace",
    "smooth_max",
    "QuasiStaticObjective",
    "DynamicObjective",
    "Evaluation",
    "make_objective",
    "OptimisationResult",
    "optimise",
    "optimise_lockstep",
    "multi_start",
    "coarse_starts",
    "harris_map",
    "HarrisMap",
    "MapPatch",
    "ORBIT_STARTS",
    "OrbitSet",
    "implicit_steady_metrics",
    "harris_curves",
]
