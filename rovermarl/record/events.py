"""Behaviour events of one run, captured inside the generation loop (cheaply: only on accepted teams); what each
means is in docs/GUIDE.md (``behaviour.npz``, ``occupancy.npz``, ``switched`` of ``curve.npz``).

- occupancy ``count`` (E, P) int8: rovers observing each POI at the end of each episode, at generation 0 and
  whenever an accepted team changes it (each entry holds until the next);
- switched: per generation, the number of episodes (int16) in which a rover this generation did not mutate ends
  observing another POI (or none instead of one, or the reverse) than in the parent team (the paper's Section 5.3); -1
  when every rover was mutated (k = N, homogeneous team) or occupancy is off;
- behaviour ``xy`` (E, T+1, N, 2) float32: the parent team's trajectories at generation 0, at each accepted score
  change (and the generation before it if the team changed since the last entry: each change has its exact before
  and after) and at the last generation. Under ``evaluation.fresh_ic`` each score comes from new initial
  conditions, so only generation 0 and the last (``changes=False``), and no occupancy or switched.
"""

from __future__ import annotations

import numpy as np

from rovermarl.algorithms.base import AlgorithmError
from rovermarl.env.kernel import observers, poi_of, switched
from rovermarl.jit import njit

FILES = ("behaviour", "occupancy")   # the result files of :meth:`BehaviourObserver.drain`


class BehaviourObserver:
    """Measures a run's behaviour from the evaluations its algorithm makes (see the module doc).

    Built on the world, the run's initial conditions ``ic`` and the ``record`` switches (``occupancy``,
    ``behaviour``; on if absent). :meth:`evaluated` and :meth:`accepted` are told a team's final positions (E, N, 2)
    as its evaluation measured them (:meth:`Evaluator.measure <rovermarl.algorithms.base.Evaluator.measure>`).
    """

    def __init__(self, world, ic, cfg, changes: bool = True):
        self.world, self.ic, self.changes = world, ic, changes
        self.occupancy_on = bool(cfg.get("occupancy", True)) and world.fixed_pois   # they read World.poi_xy
        self.behaviour_on = bool(cfg.get("behaviour", True))
        shape = ic[0].shape                                            # (E, N, 2)
        self.parent_xy = np.empty(shape) if self.occupancy_on else None
        self.parent_poi = np.empty(shape[:2], dtype=np.int16)            # POI each rover observes at the end, -1: none
        self._radius = float(world.obs_radius)
        self.count = None
        self.last_behaviour = -1
        self.moved = False                                             # parent changed since the last behaviour entry
        self.parents, self.parent_score = None, None                   # the current parent team: (N, P), its score
        self._behaviour: list[tuple[int, float, np.ndarray]] = []
        self._occupancy: list[tuple[int, np.ndarray]] = []

    @property
    def needs_final(self) -> bool:
        """Whether the evaluation must keep final positions for this observer."""
        return self.occupancy_on

    def occupancy(self, final_xy: np.ndarray) -> np.ndarray:
        """:func:`occupancy` in this observer's world."""
        return occupancy(self.world, final_xy)

    def observed(self, final_xy: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """The POI each rover observes at the end: final_xy (E, N, 2) -> (E, N) int16, lowest index within
        ``obs_radius``, -1 for none."""
        out = np.empty(final_xy.shape[:2], dtype=np.int16) if out is None else out
        _observed(final_xy, self.world.poi_xy, self._radius, out)
        return out

    def evaluated(self, mutated: np.ndarray, final_xy: np.ndarray | None) -> int:
        """Episodes in which a rover outside ``mutated`` (N,) bool ends at another POI, its team's rovers ending at
        ``final_xy`` (E, N, 2), than under the parents; -1 if every rover was mutated or occupancy is off."""
        if not self.occupancy_on:
            return -1
        return switched(self._final_xy(final_xy), self.world.poi_xy, self._radius, self.parent_poi, mutated)

    @staticmethod
    def _final_xy(final_xy: np.ndarray | None) -> np.ndarray:
        if final_xy is None:
            raise AlgorithmError("the behaviour observer was told of a team without its final positions: pass on "
                                 "the final_xy of evaluate.measure(genomes)")
        return final_xy

    def switch_inputs(self) -> tuple | None:
        """What :meth:`evaluated` compares, for a compiled loop that calls :func:`~rovermarl.env.kernel.switched`
        itself: ``(parent_poi (E, N), poi_xy, radius)``, or None when nothing is measured."""
        return (self.parent_poi, self.world.poi_xy, self._radius) if self.occupancy_on else None

    def start(self, genomes: np.ndarray, score: float, final_xy: np.ndarray | None) -> None:
        """Generation 0: the initial team (genomes (N, P)) was just evaluated (``score``, ``final_xy`` (E, N, 2))."""
        self.accepted(0, genomes, score, True, final_xy)

    def accepted(self, generation: int, genomes: np.ndarray, score: float, score_changed: bool,
                 final_xy: np.ndarray | None) -> None:
        """The team genomes (N, P), evaluated as ``score`` with its rovers ending at ``final_xy`` (E, N, 2), became
        the parent at ``generation``."""
        if self.occupancy_on:
            self.parent_xy[...] = self._final_xy(final_xy)
            self.observed(self.parent_xy, self.parent_poi)
            count = self.occupancy(self.parent_xy)
            if self.count is None or not np.array_equal(count, self.count):
                self.count = count
                self._occupancy.append((generation, count))
        if self.behaviour_on and (self.changes or generation == 0):
            if score_changed:
                if self.moved:                                          # the exact team before this update
                    self._log_behaviour(generation - 1, self.parents, self.parent_score)
                self._log_behaviour(generation, genomes, score)
            else:
                self.moved = True
            self.parents, self.parent_score = genomes, score

    def finish(self, generation: int, genomes: np.ndarray, score: float) -> None:
        """The run ended at ``generation``: log the final team's trajectories (once)."""
        if self.behaviour_on and self.last_behaviour != generation:
            self._log_behaviour(generation, genomes, score)

    def _log_behaviour(self, generation, genomes, score):
        self._behaviour.append((generation, score, self.world.rollout(genomes, self.ic).xy.astype(np.float32)))
        self.last_behaviour, self.moved = generation, False

    def state_dict(self) -> dict:
        return {"parent_xy": None if self.parent_xy is None else self.parent_xy.copy(),
                "last_behaviour": self.last_behaviour, "moved": self.moved}

    def load_state_dict(self, state: dict, genomes: np.ndarray, score: float) -> None:
        """Restore after :meth:`state_dict`; ``genomes`` (N, P) and ``score`` are the current parent team's."""
        self.parents, self.parent_score = genomes, score
        self.last_behaviour, self.moved = int(state["last_behaviour"]), bool(state["moved"])
        if self.occupancy_on and state["parent_xy"] is not None:
            self.parent_xy = np.array(state["parent_xy"], dtype=np.float64)
            self.count = self.occupancy(self.parent_xy)
            self.observed(self.parent_xy, self.parent_poi)
        self._behaviour.clear()
        self._occupancy.clear()

    def drain(self) -> dict[str, dict[str, np.ndarray]]:
        """Events logged since the last drain, as arrays per result file (see module doc); clears them."""
        e, n = self.ic[1].shape
        steps, p = self.world.steps, self.world.n_pois
        b, o = self._behaviour, self._occupancy
        out = {"behaviour": {"generation": np.array([x[0] for x in b], dtype=np.int64),
                             "score": np.array([x[1] for x in b], dtype=np.float64),
                             "xy": np.array([x[2] for x in b], dtype=np.float32).reshape(len(b), e, steps + 1, n, 2)},
               "occupancy": {"generation": np.array([x[0] for x in o], dtype=np.int64),
                             "count": np.array([x[1] for x in o], dtype=np.int8).reshape(len(o), e, p)}}
        b.clear()
        o.clear()
        return out


def occupancy(world, final_xy: np.ndarray) -> np.ndarray:
    """Rovers within ``obs_radius`` of each POI: final_xy (E, N, 2) -> (E, P) int8 (same test as the reward)."""
    out = np.zeros((final_xy.shape[0], world.n_pois), dtype=np.int8)
    observers(final_xy, world.poi_xy, float(world.obs_radius), out)
    return out


@njit(cache=True)
def _observed(final_xy, poi_xy, radius, out):
    """out[e, i] = the POI rover i of episode e observes at the end, -1 for none: out (E, N)."""
    for e in range(final_xy.shape[0]):
        for i in range(final_xy.shape[1]):
            out[e, i] = poi_of(final_xy[e, i, 0], final_xy[e, i, 1], poi_xy, radius)
