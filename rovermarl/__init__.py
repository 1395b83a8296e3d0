"""rovermarl: cooperative co-evolution (CC-(1+1)-ES with fixed or adaptive k) for multi-rover teams."""

from rovermarl.env import Rollout, World, make_world

__all__ = ["Rollout", "World", "make_world"]
__version__ = "0.1.0"
