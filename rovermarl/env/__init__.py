"""Rover world: geometry, initial conditions, compiled rollout kernel and reward."""

from rovermarl.env.world import InitialConditions, Rollout, World, make_world

__all__ = ["InitialConditions", "Rollout", "World", "make_world"]
