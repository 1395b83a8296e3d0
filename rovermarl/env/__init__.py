"""Rover world: the World (``world``) and its parts (``params``, ``task``, ``starts``, the kernel record), a plug-in's
build-time trial (``trial``), and the compiled kernel in stages and hooks (``kernel``). A world plug-in imports
:mod:`rovermarl.worlds`."""

from rovermarl.env.make import make_world
from rovermarl.env.starts import InitialConditions
from rovermarl.env.trial import State
from rovermarl.env.world import Rollout, World

__all__ = ["InitialConditions", "Rollout", "State", "World", "make_world"]
