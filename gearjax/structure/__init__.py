"""Structural finite elements of the geared system (everything but the pinion-gear element).

Shafts (Timoshenko beams), rigid discs, bearings, couplings and torsional springs
assembled into the constant matrices ``M`` and ``K`` of Eqs. (12)-(14) of Velex & Ajmi,
plus the modal tools (modal basis, modal damping, reduced models). The Baud & Velex test
rig of Section 6.1 is in :mod:`gearjax.rigs.baud_velex`. Node dof order:
``(u, v, w, phi, psi, theta)``; global index ``6 * node + dof``; SI units.
"""

from .assembly import ElementRecord as ElementRecord
from .assembly import Structure as Structure
from .assembly import StructureBuilder as StructureBuilder
from .assembly import StructureInputError as StructureInputError
from .beams import DOF_NAMES as DOF_NAMES
from .beams import DOFS_PER_NODE as DOFS_PER_NODE
from .beams import STEEL as STEEL
from .beams import ElementInputError as ElementInputError
from .beams import Material as Material
from .beams import bearing_stiffness as bearing_stiffness
from .beams import coupling_stiffness as coupling_stiffness
from .beams import disc_properties as disc_properties
from .beams import hollow_section as hollow_section
from .beams import rigid_disc as rigid_disc
from .beams import shear_coefficient_hutchinson as shear_coefficient_hutchinson
from .beams import timoshenko_element as timoshenko_element
from .beams import torsional_coupling as torsional_coupling
from .beams import torsional_spring_to_ground as torsional_spring_to_ground
from .modal import ModalBasis as ModalBasis
from .modal import ReducedModel as ReducedModel
from .modal import RigidBodyModeWarning as RigidBodyModeWarning
from .modal import modal_basis as modal_basis
from .modal import modal_damping_matrix as modal_damping_matrix
from .modal import reduced_model as reduced_model
