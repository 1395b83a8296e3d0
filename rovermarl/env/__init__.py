"""Rover world: geometry and initial conditions (``world``), the compiled kernel in stages (``kernel``),
and the SPEC in plain numpy (``reference``, the tests' oracle)."""

from rovermarl.env.world import InitialConditions, Rollout, World, make_world

__all__ = ["InitialConditions", "Rollout", "World", "make_world"]
