"""gearjax: a differentiable gear-dynamics engine on JAX.

Implements Velex & Ajmi, "On the modelling of excitations in geared systems by
transmission errors" (J. Sound Vib.): mesh model, quasi-static and no-load transmission
errors, and the dynamic formulations Eqs. (14), (42), (48a). SI units throughout
(m, N, kg, s, rad).

Importing gearjax enables float64 (``jax_enable_x64``), which its solvers require, and
does nothing else to the process: XLA flags, devices, caches and progress printing are
the host layer's (:mod:`gearjax.runtime`; :func:`gearjax.runtime.configure`).
"""

import jax

jax.config.update("jax_enable_x64", True)

from .errors import DesignError as DesignError
from .errors import GearjaxError as GearjaxError
from .errors import GeometryError as GeometryError
from .errors import ModelError as ModelError
from .errors import ModificationError as ModificationError
from .errors import RigError as RigError
from .errors import SimulationError as SimulationError
from .gears.geometry import GearPair as GearPair
from .gears.mesh import Cells as Cells
from .gears.mesh import Mesh as Mesh
from .gears.modifications import ToothModifications as ToothModifications
from .gears.quasistatic import QuasiStatic as QuasiStatic
from .gears.quasistatic import contact_gaps as contact_gaps
from .gears.quasistatic import quasi_static as quasi_static
from .gears.contact import solve_unilateral as solve_unilateral
from .gears.contact import TEContactLaw as TEContactLaw
from .gears.quasistatic import static_mesh_force as static_mesh_force
from .rigs.rigfile import load_rig as load_rig
from .rigs.rig import Rig as Rig
from .rigs.registry import get_rig as get_rig
from .rigs.baud_velex import baud_velex_pair as baud_velex_pair
from .rigs.baud_velex import fig5_pitch_errors as fig5_pitch_errors
from .rigs.baud_velex import table1_relief as table1_relief
from .rigs.factory import build_model as build_model
from .models.torsional import TorsionalModel as TorsionalModel
from .models.geared3d import Geared3DModel as Geared3DModel
from .dynamics.simulate import SimulationResult as SimulationResult
from .dynamics.results import SweepResult as SweepResult
from .dynamics.stability import floquet_multipliers as floquet_multipliers
from .dynamics.stability import spectral_radius as spectral_radius
from .dynamics.steady import steady_state as steady_state
from .dynamics.steady import steady_sweep as steady_sweep
from .dynamics.continuation import continuation_sweep as continuation_sweep
from .dynamics.refine import Refinement as Refinement
from .dynamics.refine import propose_speeds as propose_speeds
from .dynamics.refine import refine as refine
from .dynamics.refine import refine_common as refine_common
from .dynamics.arclength import Arclength as Arclength
from .dynamics.arclength import trace_speed as trace_speed
from .dynamics.bifurcation import Bifurcation as Bifurcation
from .dynamics.bifurcation import Jump as Jump
from .dynamics.bifurcation import TracedBranches as TracedBranches

from .dynamics.simulate import simulate as simulate
from .dynamics.sweep import sweep as sweep
from .dynamics.solvers import AbstractPeriodicSolver as AbstractPeriodicSolver
from .dynamics.solvers import Fallback as Fallback
from .dynamics.sweep import Auto as Auto
from .dynamics.sweep import Transient as Transient
from .dynamics.steady import Shooting as Shooting
from .dynamics.harmonic_sweep import HarmonicBalance as HarmonicBalance
from .dynamics.orbit import RESULTS as RESULTS
from .dynamics.orbit import Orbit as Orbit
from .dynamics.orbit import measure as measure
from .dynamics.progress import AbstractProgressMeter as AbstractProgressMeter
from .dynamics.progress import NoProgressMeter as NoProgressMeter
from . import runtime as runtime
from .runtime.progress import TextProgressMeter as TextProgressMeter

__version__ = "0.1.0"
