"""The gear pair: involute geometry, tooth modifications, the mesh of contact cells on the
base plane and the quasi-static contact (TE_S, NLTE). Velex & Ajmi Sections 2-3."""

from .geometry import GearPair as GearPair
from .mesh import Cells as Cells
from .mesh import Mesh as Mesh
from .modifications import ToothModifications as ToothModifications
from .quasistatic import QuasiStatic as QuasiStatic
from .quasistatic import quasi_static as quasi_static
from .quasistatic import static_mesh_force as static_mesh_force
