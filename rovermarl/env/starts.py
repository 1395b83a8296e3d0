"""Where the rovers start: each rover's start square and heading sector, a run's initial conditions (SPEC section 5)
and its held-out ones. :class:`Starts` is a part a :class:`~rovermarl.env.World` holds (``World.starts``)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from rovermarl.env.streams import RunStreams


class InitialConditions(NamedTuple):
    """E episodes' starts: xy (E, N, 2), heading (E, N), and layout (E, K): what else a world draws per episode
    (``World.draw_layout``; K = 0 for the paper's world). Any (xy, heading) pair is read with an empty layout."""

    xy: np.ndarray
    heading: np.ndarray
    layout: np.ndarray


@dataclass(frozen=True)
class Starts:
    """The initial conditions of N = ``n_rovers`` rovers in ``start_box`` squares, ``episodes`` E by default;
    ``draw_layout(rng, n) -> (n, K)`` draws what else a world draws per episode, after the starts
    (``World.draw_layout``)."""

    n_rovers: int
    start_box: float
    episodes: int
    draw_layout: Callable[[np.random.Generator, int], np.ndarray]

    @property
    def start_rotation(self) -> np.ndarray:
        """(N,): rover ``i``'s start square is ``[0, start_box]^2`` turned by this angle about the origin, so that
        its diagonal bisects heading sector ``i`` (for N = 4: the square of quadrant ``i``)."""
        return (np.arange(self.n_rovers) + 0.5) * (2 * np.pi / self.n_rovers) - np.pi / 4

    @property
    def start_squares(self) -> np.ndarray:
        """(N, 5, 2): the corners of each rover's start square, as a closed outline."""
        unit = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0, 0]], dtype=np.float64) * self.start_box
        return self._turn(np.broadcast_to(unit, (self.n_rovers, 5, 2)).transpose(1, 0, 2)).transpose(1, 0, 2)

    def _turn(self, xy: np.ndarray) -> np.ndarray:
        """Points of quadrant-0 squares into each rover's square: xy (..., N, 2). For N = 4 the turns are exact
        sign flips (SPEC's quadrants: 0: x, y >= 0; 1: x <= 0, y >= 0; 2: x, y <= 0; 3: x >= 0, y <= 0)."""
        if self.n_rovers == 4:
            return xy * np.array([[1.0, 1.0], [-1.0, 1.0], [-1.0, -1.0], [1.0, -1.0]])
        c, s = np.cos(self.start_rotation), np.sin(self.start_rotation)
        return np.stack([xy[..., 0] * c - xy[..., 1] * s, xy[..., 0] * s + xy[..., 1] * c], axis=-1)

    def initial_conditions(self, seed=0, n: int | None = None) -> InitialConditions:
        """Draw ``n`` (default ``episodes``) starts: xy (n, N, 2), heading (n, N).

        Rover ``i`` starts uniformly in its ``start_box`` square (:attr:`start_rotation`; quadrant ``i`` for N = 4),
        heading uniform in its sector ``[2 pi i/N, 2 pi (i+1)/N]``. ``seed`` is an int, a ``SeedSequence`` or a
        ``Generator``.
        """
        rng = np.random.default_rng(seed)
        n = self.episodes if n is None else n
        xy = self._turn(rng.uniform(0.0, self.start_box, size=(n, self.n_rovers, 2)))
        sector = 2 * np.pi / self.n_rovers
        low = sector * np.arange(self.n_rovers)
        heading = low + rng.uniform(0.0, sector, size=(n, self.n_rovers))
        layout = np.ascontiguousarray(self.draw_layout(rng, n), dtype=np.float64)     # after the starts
        return InitialConditions(np.ascontiguousarray(xy), np.ascontiguousarray(heading), layout)

    def run_ic(self, seed: int, generation: int = 0) -> InitialConditions:
        """The initial conditions run ``seed`` is scored on (SPEC section 5); under ``evaluation.fresh_ic`` generation
        ``g >= 1`` draws its own set (its streams: :mod:`rovermarl.env.streams`).

        >>> w = make_world("solo")
        >>> [a.shape for a in w.run_ic(3)], bool((w.run_ic(3, 1)[0] != w.run_ic(3)[0]).all())
        ([(16, 4, 2), (16, 4)], True)
        """
        return self.initial_conditions(RunStreams(int(seed)).initial_conditions(generation))

    def heldout_ic(self, seed: int, n: int = 256) -> InitialConditions:
        """``n`` initial conditions of run ``seed`` that its algorithm never sees, from a stream of their own
        (:mod:`rovermarl.env.streams`): the held-out score's."""
        return self.initial_conditions(RunStreams(int(seed)).heldout, n=n)
