"""The task of a world (SPEC sections 1-2): where the POIs are, what a rover's sensors say of them, the observation's
size, and what a set of positions earns. :class:`Task` is a base of :class:`~rovermarl.env.World`, computed from its
parameters (:class:`~rovermarl.env.params.Params`) when first read and kept (``functools.cached_property``: no
attribute is set on the frozen world by hand)."""

from __future__ import annotations

import math
from functools import cached_property

import numpy as np

from rovermarl.env import kernel


class Task:
    """The POIs and the reward of a world: ``self`` has the fields of :class:`~rovermarl.env.params.Params`."""

    @cached_property
    def poi_xy(self) -> np.ndarray:
        """(P, 2) float64: POI ``j`` at angle ``2*pi*j/P`` on the circle of radius ``poi_distance``."""
        angle = 2 * np.pi * np.arange(self.n_pois) / self.n_pois
        return np.ascontiguousarray(self.poi_distance * np.stack([np.cos(angle), np.sin(angle)], axis=1))

    @cached_property
    def _coupling(self) -> np.ndarray:
        return np.array(self.coupling, dtype=np.int64)

    @cached_property
    def _value(self) -> np.ndarray:
        return np.array(self.value, dtype=np.float64)

    @cached_property
    def _type(self) -> np.ndarray:
        c = self._coupling.astype(np.float64)
        return {"coupling": c - 1.0, "sign": np.where(c == 1, -1.0, 1.0), "value": self._value.copy()}[self.poi_type]

    @property
    def poi_sensor_type(self) -> np.ndarray:
        """(P,): the third sensor number of each POI in range (``env.poi_type``: ``c - 1``, the sign ``-1`` for
        ``c = 1`` and ``+1`` otherwise, or the POI's value)."""
        return self._type.copy()

    @property
    def n_pois(self) -> int:
        return len(self.coupling)

    @cached_property
    def obs_dim(self) -> int:
        """The sum of the world's ``obs_blocks``: 3 numbers per POI and 2 per rover (38 for 10 POIs and 4 rovers) in
        the paper's world."""
        return sum(low.size for _, low, _ in self.obs_blocks())

    @property
    def w_max(self) -> float:
        return math.radians(self.w_max_deg)

    @property
    def max_return(self) -> float:
        """Best achievable team return: a 0/1 knapsack of POIs with rover budget N (4 solo, 6 duo). Under
        ``reward="any_step"``, or where two POIs' observation discs overlap (e.g. ``poi_distance=9, obs_radius=3``:
        one rover can observe both), a rover may earn several POIs, so the bound is every POI's value."""
        d = np.linalg.norm(self.poi_xy[:, None] - self.poi_xy[None], axis=-1)[np.triu_indices(self.n_pois, 1)]
        overlap = bool((d < 2 * self.obs_radius).any())
        return kernel.max_return(kernel.REWARDS.index(self.reward), self.coupling, self.value, self.n_rovers, overlap)

    def team_return(self, xy: np.ndarray) -> np.ndarray:
        """Team return of one set of positions (SPEC section 1): xy (..., M, 2) -> (...,). It is the episode's
        return under ``reward="final"`` (xy after the last step); the per-step readings combine it over the steps
        (``World.episode_return``). ``M`` is any number of rovers: the team's N, or a counterfactual team (one rover
        removed, partners added: :mod:`rovermarl.algorithms.credit`).

        >>> w = make_world("duo")
        >>> w.team_return(np.array([[13.0, 0.0], [12.5, 0.5], [0.0, 0.0]])).item()    # M = 3: both on duo POI 0
        3.0
        """
        xy = np.ascontiguousarray(xy, dtype=np.float64)
        if xy.ndim < 2 or xy.shape[-1] != 2:
            raise ValueError(f"xy must have shape (..., M, 2), got {xy.shape}")
        out = np.empty(xy.shape[:-2])
        kernel.reward(xy.reshape(-1, *xy.shape[-2:]), self.poi_xy, self._coupling, self._value,
                      float(self.obs_radius), out.reshape(-1))
        return out
