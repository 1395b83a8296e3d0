"""What a world plug-in may override: :class:`Scenario`, the base of :class:`~rovermarl.env.World`.

The paper's world is the first scenario and overrides nothing. A plug-in is a subclass of ``World`` in a module of its
own plus a yaml in the ``env`` group whose ``_target_`` names it (``examples/obstacles``, ``examples/random_pois``;
``docs/ARCHITECTURE.md``, "Adding a world"). Its fields are its parameters (keys of its yaml); ``hooks`` names its
compiled hooks (:mod:`rovermarl.env.kernel.hooks`); each method below may be called alone, e.g.
``make_world("solo").obs_blocks()``.
"""

from __future__ import annotations

import numpy as np


class Scenario:
    """The plug-in methods of a world, with the paper's world's behaviour. ``self`` is a
    :class:`~rovermarl.env.World` (its fields ``n_rovers``, ``poi_xy``, ``dtype``, ... are set)."""

    layout_dim = 0      # K: numbers per episode that draw_layout adds to the initial conditions
    fixed_pois = True   # the POIs are World.poi_xy in every episode: the occupancy and C8 measures read them
                        # (the behaviour observer leaves those measures out of a world that sets False)

    def check(self) -> None:
        """Check the plug-in's own fields (raise ``errors.ConfigError``: one line naming key, value and what is
        allowed); called before the kernel record is built."""

    def kernel_extra(self) -> tuple:
        """The plug-in's own arrays and numbers for its hooks (``KernelWorld.extra``), in the kernel's precision
        where they meet the rovers' state (``np.dtype(self.dtype)``). The paper's world: none.

        >>> from rovermarl.env import make_world
        >>> make_world("solo").kernel_extra()
        ()
        """
        return ()

    def draw_layout(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """(n, K): what the world draws per episode after the rovers' starts (``layout_dim`` K numbers each), from
        the initial conditions' generator."""
        return np.empty((n, self.layout_dim))

    def obs_blocks(self) -> list[tuple[str, np.ndarray, np.ndarray]]:
        """The observation's blocks in order: (name, low (size,), high (size,)). The paper's: 3 numbers per POI
        (distance / range, bearing / pi, type), then 2 per other rover; a plug-in appends its own sensors' blocks
        (and writes them after the paper's rows in its ``sense`` hook).

        >>> from rovermarl.env import make_world
        >>> [(name, low.size) for name, low, high in make_world("solo").obs_blocks()]
        [('poi', 30), ('rover', 8)]
        """
        kinds = float(np.abs(self.poi_sensor_type).max(initial=1.0))
        poi_high = np.tile([1.0, 1.0, kinds], self.n_pois)
        return [("poi", -poi_high, poi_high), ("rover", -np.ones(2 * self.n_rovers), np.ones(2 * self.n_rovers))]

    def poi_positions(self, layout: np.ndarray | None = None) -> np.ndarray:
        """(P, 2): the POIs of an episode whose layout is ``layout`` (K,); the paper's: fixed, ``poi_xy``."""
        return self.poi_xy

    def draw(self, ax, layout: np.ndarray | None = None) -> None:
        """Draw what the plug-in adds to the world (obstacles, ...) on matplotlib axes, for an episode's ``layout``."""

    def log_static(self, rec, layout: np.ndarray | None = None) -> None:
        """Log what the plug-in adds to the world into the Rerun recording stream ``rec`` (under ``world/``)."""
