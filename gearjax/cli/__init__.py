"""The ``gearjax`` command line: argument parsing and formatting only."""

from .main import main as main
