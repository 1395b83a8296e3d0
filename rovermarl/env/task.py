"""The task of a world (SPEC sections 1-2, 8): where the POIs are, what the sensors say of them, and what a set of
positions earns. :class:`Task` is a part a :class:`~rovermarl.env.World` holds (``World.task``), built from the
parameters it is given (:meth:`Task.of`) and reading nothing else."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rovermarl.env import kernel


@dataclass(frozen=True, eq=False)
class Task:
    """The POIs and the scoring of positions. P POIs: ``poi_xy`` (P, 2) float64, ``coupling`` (P,) int64, ``value``
    (P,) float64, ``sensor_type`` (P,) float64 (the sensors' third number per POI, ``env.poi_type``); ``obs_radius``;
    ``reward`` (``env.reward``); ``n_rovers`` N."""

    poi_xy: np.ndarray
    coupling: np.ndarray
    value: np.ndarray
    sensor_type: np.ndarray
    obs_radius: float
    reward: str
    n_rovers: int

    @classmethod
    def of(cls, coupling, value, poi_distance: float, poi_type: str, obs_radius: float, reward: str,
           n_rovers: int) -> Task:
        """POI ``j`` at angle ``2*pi*j/P`` on the circle of radius ``poi_distance``; its sensor type ``c - 1``
        (``poi_type="coupling"``), the sign ``-1`` for ``c = 1`` and ``+1`` otherwise (``"sign"``), or its value."""
        c, v = np.array(coupling, dtype=np.int64), np.array(value, dtype=np.float64)
        angle = 2 * np.pi * np.arange(c.size) / c.size
        xy = np.ascontiguousarray(poi_distance * np.stack([np.cos(angle), np.sin(angle)], axis=1))
        cf = c.astype(np.float64)
        sensor = {"coupling": cf - 1.0, "sign": np.where(c == 1, -1.0, 1.0), "value": v.copy()}[poi_type]
        return cls(xy, c, v, sensor, obs_radius, reward, n_rovers)

    @property
    def max_return(self) -> float:
        """Best achievable team return: a 0/1 knapsack of POIs with rover budget N (4 solo, 6 duo). Under
        ``reward="any_step"``, or where two POIs' observation discs overlap (e.g. ``poi_distance=9, obs_radius=3``:
        one rover can observe both), a rover may earn several POIs, so the bound is every POI's value."""
        p = self.poi_xy.shape[0]
        d = np.linalg.norm(self.poi_xy[:, None] - self.poi_xy[None], axis=-1)[np.triu_indices(p, 1)]
        overlap = bool((d < 2 * self.obs_radius).any())
        return kernel.max_return(kernel.REWARDS.index(self.reward), self.coupling.tolist(), self.value.tolist(),
                                 self.n_rovers, overlap)

    def team_return(self, xy: np.ndarray) -> np.ndarray:
        """Team return of one set of positions (SPEC section 1): xy (..., M, 2) -> (...,), ``M`` rovers (the team's
        N, or a counterfactual team: :mod:`rovermarl.algorithms.credit`). The episode's return under
        ``reward="final"``; the per-step readings combine it over the steps (``World.episode_return``).

        >>> w = make_world("duo")
        >>> w.team_return(np.array([[13.0, 0.0], [12.5, 0.5], [0.0, 0.0]])).item()    # M = 3: both on duo POI 0
        3.0
        """
        xy = np.ascontiguousarray(xy, dtype=np.float64)
        if xy.ndim < 2 or xy.shape[-1] != 2:
            raise ValueError(f"xy must have shape (..., M, 2), got {xy.shape}")
        out = np.empty(xy.shape[:-2])
        kernel.reward(xy.reshape(-1, *xy.shape[-2:]), self.poi_xy, self.coupling, self.value,
                      float(self.obs_radius), out.reshape(-1))
        return out
