"""One chunk of one run: advance run ``seed`` of a config from a state by n generations (any algorithm).

A run is a pure function of ``(config, seed)`` (its named random streams: :mod:`rovermarl.env.streams`), so
:func:`advance` rebuilds it from its compact state and Ray can rerun a chunk on another worker after a crash with the
same numbers. Teams are scored as the ``evaluation`` section says (``fresh_ic``: SPEC section 8) by the evaluation
passed in (local by default, IC shards from :mod:`rovermarl.parallel`).
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass

import numpy as np
from omegaconf import DictConfig, OmegaConf

from rovermarl import errors
from rovermarl.algorithms.base import Algorithm, Evaluator, KernelInputs, Measured, build_operator
from rovermarl.env import Rollout, World
from rovermarl.env.streams import RunStreams
from rovermarl.record.events import BehaviourObserver
from rovermarl.resources import CONF_DIR, packaged

EvaluationFactory = Callable[..., Evaluator]   # (world, ic, keep_final, fresh_seed) -> Evaluator
EVALUATION = packaged("config.yaml")["evaluation"]   # its defaults, also for configs from before the section


@dataclass(frozen=True, eq=False)
class Parts:
    """What every run of a config is built from (:func:`build`)."""

    world: World
    algorithm: Algorithm
    record: dict
    evaluation: dict


def build(cfg) -> Parts:
    """World and algorithm of a composed config (a ``DictConfig`` or plain dict); bad values raise ConfigError."""
    cfg = upgrade(cfg if isinstance(cfg, DictConfig) else OmegaConf.create(cfg))
    world = World.from_config(cfg, trust=True)   # composed from the command line (or checked: check_targets)
    try:
        algorithm = build_operator(cfg.get("algorithm"), "algorithm", world=world)
    except errors.ConfigError as e:                  # keys of the groups an algorithm reads are named as they are
        head = e.key.split(".")[1] if e.key.startswith("algorithm.") else ""
        raise (errors.ConfigError(e.key.partition(".")[2], e.value, e.requirement) if head in cfg else e) from None
    if not isinstance(algorithm, Algorithm):
        raise errors.ConfigError("algorithm._target_", cfg.algorithm._target_,
                                 "must name a subclass of rovermarl.algorithms.Algorithm")
    record = OmegaConf.to_container(cfg.record, resolve=True) if "record" in cfg else {}
    return Parts(world, algorithm, record, _evaluation(cfg.get("evaluation"), algorithm))


@dataclass(frozen=True)
class EvaluationConfig:
    """The ``evaluation`` section: how a team is scored (defaults and meanings: ``conf/config.yaml``)."""

    fresh_ic: bool
    heldout: int

    def __post_init__(self):
        errors.flag("fresh_ic", self.fresh_ic)
        errors.integer("heldout", self.heldout, 1, 1_000_000)


def _evaluation(node, algorithm: Algorithm) -> dict:
    """The ``evaluation`` section, checked, with its defaults filled in (a config from before the section)."""
    given = OmegaConf.to_container(node, resolve=True) if OmegaConf.is_config(node) else dict(node or {})
    out = errors.build("evaluation", EvaluationConfig, {**EVALUATION, **given})
    if out.fresh_ic and not algorithm.fresh_ic:
        raise errors.ConfigError("evaluation.fresh_ic", True, f"the algorithm {type(algorithm).__name__} does not "
                                 "draw fresh initial conditions (Algorithm.fresh_ic is false)")
    return asdict(out)


def upgrade(cfg: DictConfig) -> DictConfig:
    """A config written by rovermarl before the ``algorithm`` group (up to commit 4c4ae3c), as it reads today: its
    operators' targets moved from ``rovermarl.evolution`` to ``rovermarl.algorithms.operators``, and CC-(1+1)-ES
    was the only algorithm. Other configs are returned as they are."""
    if "algorithm" in cfg or "k" not in cfg:
        return cfg
    cfg = cfg.copy()
    for group in ("k", "selection", "team", "mutation"):
        target = OmegaConf.select(cfg, f"{group}._target_")
        if isinstance(target, str) and target.startswith("rovermarl.evolution."):
            cfg[group]["_target_"] = target.replace("rovermarl.evolution.", "rovermarl.algorithms.operators.", 1)
    cfg.algorithm = OmegaConf.load(CONF_DIR / "algorithm" / "cc11es.yaml")
    return cfg


_CACHE: dict[str, Parts] = {}                         # per process: the built parts of each config


def parts(cfg: dict) -> Parts:
    """:func:`build` of a plain config, cached per process (a job and its chunks build once)."""
    key = json.dumps(cfg, sort_keys=True, default=str)
    if key not in _CACHE:
        if len(_CACHE) > 16:
            _CACHE.clear()
        _CACHE[key] = build(cfg)
    return _CACHE[key]


class Evaluation(Evaluator):
    """The :class:`~rovermarl.algorithms.base.Evaluator` of a run in this process, on its initial conditions ``ic``
    (prepared once: a call checks only the genomes); with ``keep_final`` the final positions (E, N, 2) go to the
    buffer :attr:`final_xy`; ``fresh_seed`` is the run's seed under ``evaluation.fresh_ic`` (else None)."""

    def __init__(self, world: World, ic: tuple, keep_final: bool = True, fresh_seed: int | None = None):
        self.world, self.ic, self.seed = world, ic, fresh_seed
        self.prepared = world.prepare(ic)
        self.fresh = fresh_seed is not None
        self.final_xy = np.empty(ic[0].shape) if keep_final else None
        self.calls = 0

    def draw(self, generation: int) -> None:
        if not self.fresh:
            super().draw(generation)
        self.ic = self.world.run_ic(self.seed, generation)
        self.prepared = self.world.prepare(self.ic)

    def score(self, genomes: np.ndarray) -> float:
        self.calls += 1
        return self.world.evaluate(genomes, self.prepared)

    def measure(self, genomes: np.ndarray) -> Measured:
        self.calls += 1
        score = self.world.evaluate(genomes, self.prepared, self.final_xy)
        return Measured(score, None if self.final_xy is None else self.final_xy.copy())

    def measure_many(self, teams: np.ndarray) -> list[Measured]:
        """What :meth:`measure` gives for each of B teams (B, N, P), bit for bit, from one ``World.evaluate_many``
        call in this thread (a run's process already has its core)."""
        self.calls += len(teams)
        final = None if self.final_xy is None else np.empty((len(teams), *self.final_xy.shape))
        scores = self.world.evaluate_many(teams, self.prepared, final, workers=1)
        return [Measured(float(f), None if final is None else final[b]) for b, f in enumerate(scores)]

    def kernel_inputs(self) -> KernelInputs:
        return KernelInputs(self.world, self.ic, self.final_xy)

    def rollout(self, genomes: np.ndarray) -> Rollout:
        self.calls += 1
        return self.world.rollout(genomes, self.ic)


class Run:
    """One run in this process. ``Run(cfg, seed)`` starts it (evaluating the initial team); ``state=`` continues
    from :meth:`state`, bit-identical to a run that never stopped.

    >>> run = Run(compose_config("k=adaptive", "generations=50"), seed=0)   # doctest: +SKIP
    >>> arrays = run.advance(50)          # score (50,), k (50,), probs (50, 4), ...
    """

    def __init__(self, cfg, seed: int, state: dict | None = None, evaluation: EvaluationFactory = Evaluation):
        plain = cfg if isinstance(cfg, dict) else to_plain(cfg)
        self.parts = p = parts(plain)
        self.seed, self.generations = int(seed), int(plain["generations"])
        streams = RunStreams(self.seed)                                   # the run's random streams, named
        self.ic = p.world.run_ic(self.seed)
        fresh = p.evaluation["fresh_ic"]
        record = {**p.record, "occupancy": False} if fresh else p.record  # positions on other ICs: not comparable
        self.observer = BehaviourObserver(p.world, self.ic, record, changes=not fresh)
        self.evaluate = evaluation(p.world, self.ic, self.observer.needs_final, self.seed if fresh else None)
        if state is None:
            self.generation = 0
            self.algo_state, initial = p.algorithm.init(streams, self.evaluate)
            self.initial_score = initial.score
            self.observer.start(self.team, initial.score, initial.final_xy)
        else:
            self.generation = int(state["generation"])
            self.algo_state = p.algorithm.state_type.from_dict(state["algorithm"])
            self.initial_score = None
            self.observer.load_state_dict(state["observer"], self.team, self.score)

    @property
    def team(self) -> np.ndarray:
        """The current team's genomes (N, P)."""
        return self.parts.algorithm.team(self.algo_state)

    @property
    def score(self) -> float:
        return self.parts.algorithm.score(self.algo_state)

    @property
    def done(self) -> bool:
        return self.generation >= self.generations

    def advance(self, n: int) -> dict[str, np.ndarray]:
        """Up to ``n`` more generations (never past the budget); returns their arrays (score and the algorithm's
        declared series)."""
        n = max(0, min(n, self.generations - self.generation))
        self.algo_state, arrays = self.parts.algorithm.advance(self.algo_state, self.generation, n, self.evaluate,
                                                               self.observer)
        self.generation += n
        if self.done:
            self.observer.finish(self.generation, self.team, self.score)
        return arrays

    def heldout_score(self) -> float:
        """The current team's score on the run's ``evaluation.heldout`` held-out initial conditions."""
        return heldout_score(self.parts, self.seed, self.team)

    def state(self) -> dict:
        """What the next generation depends on (plain arrays, numbers and dicts)."""
        return {"generation": self.generation, "algorithm": self.algo_state.as_dict(),
                "observer": self.observer.state_dict()}


def advance(cfg: dict, seed: int, state: dict | None, n: int, evaluation: EvaluationFactory = Evaluation) -> dict:
    """The chunk function: advance run ``seed`` of plain config ``cfg`` by up to ``n`` generations from ``state``
    (None: from its start).

    Returns ``seed``, ``start``, ``stop``, the new ``state``, ``score`` (stop - start,), ``series`` (the algorithm's
    arrays of those generations), ``events`` (the observer's, per result file), ``evaluations`` (team evaluations),
    ``cpu_s`` (the chunk's CPU-seconds); when starting also ``initial_score`` and the initial conditions ``ic_xy``
    (E, N, 2), ``ic_heading`` (E, N); when done the final team ``genomes`` and its ``heldout_score``.
    """
    cpu = time.process_time()
    run = Run(cfg, seed, state, evaluation)
    start = run.generation
    arrays = run.advance(n)
    chunk = {"seed": run.seed, "start": start, "stop": run.generation, "state": run.state(),
             "score": arrays.pop("score"), "series": arrays, "events": run.observer.drain(),
             "evaluations": run.evaluate.calls}
    if state is None:
        chunk.update(initial_score=run.initial_score, ic_xy=run.ic[0], ic_heading=run.ic[1])
        if run.ic[2].shape[-1]:                                     # a world plug-in's layout
            chunk.update(ic_layout=run.ic[2])
    if run.done:
        chunk.update(genomes=run.team, heldout_score=run.heldout_score())
    chunk["cpu_s"] = time.process_time() - cpu                          # this process's CPU time for the chunk
    return chunk


def heldout_score(p: Parts, seed: int, team: np.ndarray) -> float:
    """F of team genomes (N, P) on the ``evaluation.heldout`` held-out initial conditions of run ``seed``
    (:meth:`World.heldout_ic <rovermarl.env.World.heldout_ic>`), in the world's reading."""
    return p.world.evaluate(team, p.world.heldout_ic(seed, p.evaluation["heldout"]))


def to_plain(cfg: DictConfig) -> dict:
    """A composed config as plain containers (what crosses to workers), without Hydra's node, nor the ``budget``
    section while it sets nothing (``agent_steps: null``), so a config reads as it did before the section existed."""
    out = OmegaConf.to_container(cfg, resolve=True)
    out.pop("hydra", None)
    if isinstance(out.get("budget"), dict) and out["budget"].get("agent_steps") is None:
        del out["budget"]
    return out
