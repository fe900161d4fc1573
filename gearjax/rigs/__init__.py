"""Test rigs: the :class:`Rig` record, the registry of built-in rigs, the Baud & Velex rig
of Section 6.1 (all its data), TOML rig files, the one model factory, the rig figures of
``gearjax info`` (with ISO 6336-1 method B), the Campbell diagram and the ROSS bridge."""

from .baud_velex import baud_velex_pair as baud_velex_pair
from .baud_velex import baud_velex_rig as baud_velex_rig
from .baud_velex import fig5_pitch_errors as fig5_pitch_errors
from .baud_velex import table1_relief as table1_relief
from .factory import build_model as build_model
from .registry import Rig as Rig
from .registry import RigError as RigError
from .registry import get_rig as get_rig
from .rigfile import load_rig as load_rig
from .campbell import Campbell as Campbell
from .campbell import campbell as campbell
from .iso_figures import rig_dynamic_factor as rig_dynamic_factor
