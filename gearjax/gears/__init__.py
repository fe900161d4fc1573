"""The gear pair: involute geometry, tooth modifications, the mesh of contact cells on the
base plane, the quasi-static contact (TE_S, NLTE; Velex & Ajmi Sections 2-3) and the ISO
6336-1 figures of the pair (c', c_gamma_alpha, n_E1, method-B K_v)."""

from .geometry import GearPair as GearPair
from .mesh import Cells as Cells
from .mesh import Mesh as Mesh
from .modifications import ToothModifications as ToothModifications
from .quasistatic import QuasiStatic as QuasiStatic
from .quasistatic import quasi_static as quasi_static
from .quasistatic import static_mesh_force as static_mesh_force
from .iso6336 import AccuracyData as AccuracyData
from .iso6336 import DynamicFactorB as DynamicFactorB
from .iso6336 import dynamic_factor as iso6336_dynamic_factor
