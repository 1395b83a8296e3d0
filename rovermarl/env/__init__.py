"""Rover world: geometry (``world``), starts and initial conditions (``starts``), what a world plug-in overrides
(``scenario``), the compiled kernel in stages and hooks (``kernel``), and the SPEC in plain numpy (``reference``, the
tests' oracle)."""

from rovermarl.env.make import make_world
from rovermarl.env.scenario import State
from rovermarl.env.starts import InitialConditions
from rovermarl.env.world import Rollout, World

__all__ = ["InitialConditions", "Rollout", "State", "World", "make_world"]
