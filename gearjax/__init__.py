"""gearjax: a differentiable gear-dynamics engine on JAX.

Implements Velex & Ajmi, "On the modelling of excitations in geared systems by
transmission errors" (J. Sound Vib.): mesh model, quasi-static and no-load transmission
errors, and the dynamic formulations Eqs. (14), (42), (48a). SI units throughout
(m, N, kg, s, rad). Float64 is enabled on import.
"""

import jax

jax.config.update("jax_enable_x64", True)

from .geometry import GearPair as GearPair
from .geometry import GeometryError as GeometryError
from .geometry import baud_velex_pair as baud_velex_pair
from .mesh import Cells as Cells
from .mesh import Mesh as Mesh
from .modifications import ModificationError as ModificationError
from .modifications import ToothModifications as ToothModifications
from .modifications import fig5_pitch_errors as fig5_pitch_errors
from .modifications import table1_relief as table1_relief
from .quasistatic import QuasiStatic as QuasiStatic
from .quasistatic import contact_gaps as contact_gaps
from .quasistatic import quasi_static as quasi_static
from .quasistatic import solve_unilateral as solve_unilateral
from .quasistatic import static_mesh_force as static_mesh_force
from .rigfile import load_rig as load_rig
from .rigs import Rig as Rig
from .rigs import RigError as RigError
from .rigs import get_rig as get_rig
from .models.torsional import ModelError as ModelError
from .models.torsional import TorsionalModel as TorsionalModel
from .models.geared3d import Geared3DModel as Geared3DModel
from .simulate import SimulationError as SimulationError
from .simulate import SimulationResult as SimulationResult
from .sweep import SweepResult as SweepResult
from .stability import floquet_multipliers as floquet_multipliers
from .stability import spectral_radius as spectral_radius
from .steady import steady_state as steady_state
from .steady import steady_sweep as steady_sweep

# the functions simulate() and sweep() stay in their modules (gearjax.simulate.simulate,
# gearjax.sweep.sweep): re-exporting them here would shadow the submodules of the same name

__version__ = "0.1.0"
