"""Test rigs: the registry of built-in rigs, the Baud & Velex rig of Section 6.1, TOML rig
files, the ROSS bridge."""

from .registry import Rig as Rig
from .registry import RigError as RigError
from .registry import get_rig as get_rig
from .rigfile import load_rig as load_rig
