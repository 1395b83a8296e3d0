"""Everything a world plug-in imports, from one module: ``from rovermarl.worlds import ...`` (``docs/WORLDS.md``).

- the base class and its declarations: :class:`World`, :class:`State`, :class:`InitialConditions`, :func:`make_world`;
- the hooks: :class:`Hooks` (each field defaults to the paper's hook), ``ROVERS`` (the paper's), ``rover_hooks``
  (the module of the paper's hooks, to call one from yours);
- the decorator and options every hook takes: ``njit`` (numba's, with rovermarl's cache stamps) and ``FAST``;
- kernel helpers the example worlds call: ``like`` (a constant in a value's dtype), ``bearing``, ``reading``,
  ``sense_flat``, ``sense_rovers``, ``move_flat`` (the paper's rules and stages in the flat layout), ``sense_at``,
  ``reward_at``, ``final_only``, ``no_acc``, ``no_step`` (the paper's sensing and reward with POIs per episode);
- the one-line errors a world's ``check`` raises: ``errors`` (``errors.number``, ``errors.integer``), ``ConfigError``.

Nothing else of ``rovermarl.env`` is the plug-ins' to import: ``tests/test_world_plugins.py`` checks the example
worlds import only this module.
"""

from rovermarl import errors
from rovermarl.env import InitialConditions, State, World, make_world
from rovermarl.env.kernel import hooks as rover_hooks
from rovermarl.env.kernel.episode_pois import final_only, no_acc, no_step, reward_at, sense_at
from rovermarl.env.kernel.hooks import ROVERS, Hooks
from rovermarl.env.kernel.math import FAST, like
from rovermarl.env.kernel.rules import bearing, reading
from rovermarl.env.kernel.stages import move_flat, sense_flat, sense_rovers
from rovermarl.errors import ConfigError
from rovermarl.jit import njit

__all__ = ["FAST", "ROVERS", "ConfigError", "Hooks", "InitialConditions", "State", "World", "bearing", "errors",
           "final_only", "like", "make_world", "move_flat", "njit", "no_acc", "no_step", "reading", "reward_at",
           "rover_hooks", "sense_at", "sense_flat", "sense_rovers"]
