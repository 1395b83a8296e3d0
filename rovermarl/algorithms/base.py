"""The algorithm plug-in contract.

An algorithm is one class plus one yaml in ``conf/algorithm/``. Hydra builds it from its config node with the
world as a keyword (``instantiate(cfg.algorithm, world=world)``). It holds no run state: a run's state is an
explicit plain dict (arrays, numbers, nested dicts, RNG states) that :meth:`Algorithm.init` creates and
:meth:`Algorithm.advance` threads through, so the runner can checkpoint it, ship it to another process and resume
bit-identically. Randomness comes only from the ``SeedSequence`` the runner hands to :meth:`Algorithm.init`.

The public methods check and normalise; subclasses implement the private ``_init``, ``_advance`` and ``_team``
(evosax's ``ask``/``tell`` over ``_ask``/``_tell``).

Per-generation arrays are declared, not hand-listed elsewhere: :attr:`Algorithm.series` names each one (dtype,
per-generation shape, the value of generations not computed). Checkpoints, ``curve.npz``, the Rerun recording and
the figures follow the declaration. The team score after each generation, ``score`` (G+1,), belongs to every run
and is kept by the runner.

Example (a run of 3 generations, in the runner's words)::

    world = make_world("solo")
    algo = instantiate(cfg.algorithm, world=world)      # e.g. CC11ES
    seeds = np.random.SeedSequence(7)
    ic = world.initial_conditions(seeds.spawn(1)[0])    # the runner's stream 0: initial conditions
    evaluate = Evaluation(world, ic)
    state, f0 = algo.init(seeds, evaluate)
    state, arrays = algo.advance(state, 0, 3, evaluate, NullObserver())
    arrays["score"].shape, arrays["k"].shape            # ((3,), (3,))
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from rovermarl import errors
from rovermarl.env.evaluated import Evaluated

Evaluate = Callable[[np.ndarray], Evaluated]   # team genomes (N, P) -> score F on the run's initial conditions
# The runner's Evaluate also has ``fresh`` (bool) and ``draw(generation)``: under ``evaluation.fresh_ic`` an
# algorithm with ``fresh_ic = True`` calls ``draw(g)`` once per generation g and scores every team it compares on
# that set (a plain callable has no ``fresh``: read it with ``getattr(evaluate, "fresh", False)``).


@dataclass(frozen=True)
class Series:
    """One per-generation array of a run: ``name`` -> (G, *shape) of ``dtype``.

    ``fill`` marks generations not computed. ``columns`` names the entries of a vector series (e.g. one per bandit
    arm); ``entity`` is where the Rerun recording logs it (default ``metrics/<name>``, a vector's entries under
    ``<entity>/<column>``).
    """

    name: str
    dtype: str
    shape: tuple[int, ...] = ()
    fill: float = 0
    doc: str = ""
    columns: tuple[str, ...] = ()
    entity: str = ""

    def empty(self, generations: int) -> np.ndarray:
        """(generations, *shape) filled with :attr:`fill`."""
        return np.full((generations, *self.shape), self.fill, dtype=self.dtype)

    @property
    def path(self) -> str:
        """The Rerun entity path."""
        return self.entity or f"metrics/{self.name}"


class Observer(Protocol):
    """What an algorithm tells the behaviour observer (see :mod:`rovermarl.record.events`) inside its loop.

    ``score`` is what ``evaluate`` returned for that team (an :class:`Evaluated`: the observer reads its final
    positions there), not a float made of it; a float is refused in one line when the observer measures positions.
    """

    def evaluated(self, mutated: np.ndarray, score: Evaluated) -> int:
        """A team that changed the rovers ``mutated`` (N,) bool of the parent team was evaluated (``score``); returns
        the number of episodes in which another rover ends at another POI than under the parent team (-1: not
        measured)."""

    def accepted(self, generation: int, genomes: np.ndarray, score: Evaluated, score_changed: bool) -> None:
        """The team genomes (N, P), evaluated as ``score``, became the parent team at ``generation``."""


class NullObserver:
    """An observer that measures nothing (``evaluated`` returns -1)."""

    def evaluated(self, mutated: np.ndarray, score: Evaluated) -> int:
        return -1

    def switch_inputs(self) -> None:
        """Nothing to compare (see :meth:`BehaviourObserver.switch_inputs
        <rovermarl.record.events.BehaviourObserver.switch_inputs>`)."""
        return None

    def accepted(self, generation: int, genomes: np.ndarray, score: float, score_changed: bool) -> None:
        pass


# Names a run's arrays already use (curve.npz, the runner's record, the observer's files): no series may take them.
RESERVED = frozenset({"score", "seed", "genomes", "ic_xy", "ic_heading", "ic_layout", "heldout_score", "initial_score"})
RESERVED_PREFIXES = ("behaviour_", "occupancy_")


class AlgorithmError(Exception):
    """A run cannot continue because of a plug-in's behaviour; the message is one line naming the plug-in."""


class Algorithm:
    """Base class of a learner over a team of N rovers, each with a genome of P parameters.

    Subclasses set :attr:`series` (in ``__init__`` if it depends on the config) and implement ``_init``,
    ``_advance`` and ``_team``. One that honours ``evaluation.fresh_ic`` (``evaluate.fresh``: call
    ``evaluate.draw(g)`` each generation, re-score the parents there) sets :attr:`fresh_ic`; the runner refuses
    ``evaluation.fresh_ic=true`` for the others.
    """

    series: tuple[Series, ...] = ()
    fresh_ic: bool = False

    def __init__(self, world):
        self.world = world

    # ---- public API ------------------------------------------------------------------------------------------
    def init(self, seeds: np.random.SeedSequence, evaluate: Evaluate) -> tuple[dict, float]:
        """A fresh run's state and its initial team's score. ``seeds`` is the run's ``SeedSequence`` after the
        runner took its own streams; spawn the algorithm's streams from it."""
        state, score = self._init(seeds, evaluate)
        return state, score if isinstance(score, Evaluated) else float(score)

    def advance(self, state: dict, generation: int, n: int, evaluate: Evaluate,
                observer: Observer) -> tuple[dict, dict[str, np.ndarray]]:
        """Advance ``state`` (at ``generation``) by ``n`` generations.

        Returns the new state and the arrays of those generations: ``score`` (n,) after each one, and every
        declared :attr:`series` (n, *shape).
        """
        state, arrays = self._advance(state, generation, n, evaluate, observer)
        missing = {"score", *(s.name for s in self.series)} - set(arrays)
        if missing:
            raise AlgorithmError(f"{type(self).__name__}.advance returned no {', '.join(sorted(missing))}")
        return state, arrays

    def team(self, state: dict) -> np.ndarray:
        """The team of ``state`` as the world sees it: genomes (N, P)."""
        return self._team(state)

    def score(self, state: dict) -> float:
        """The score of :meth:`team`."""
        return float(state["score"])

    def check_series(self) -> None:
        """Raise :class:`~rovermarl.errors.ConfigError` (one line) if a declared series takes a name the run's files
        already use (:data:`RESERVED`), or two series share a name."""
        names = [s.name for s in self.series]
        for name in names:
            if name in RESERVED or name.startswith(RESERVED_PREFIXES) or names.count(name) > 1:
                raise errors.ConfigError("algorithm.series", name, f"{type(self).__name__} declares a series "
                                         "under a name that is taken (" + ", ".join(sorted(RESERVED)) +
                                         ", behaviour_*, occupancy_*, or another series)")

    def evaluations_per_generation(self, fresh_ic: bool = False) -> float:
        """Team evaluations one generation costs (``fresh_ic``: under ``evaluation.fresh_ic``): what the runner's
        time estimate and the comparisons at equal evaluations assume. Override it when it is not 1."""
        return 1.0

    # ---- to implement ----------------------------------------------------------------------------------------
    def _init(self, seeds, evaluate):
        raise NotImplementedError

    def _advance(self, state, generation, n, evaluate, observer):
        raise NotImplementedError

    def _team(self, state):
        raise NotImplementedError


BIT_GENERATORS = {c.__name__: c for c in (np.random.PCG64, np.random.PCG64DXSM, np.random.Philox, np.random.SFC64,
                                          np.random.MT19937)}   # numpy's, by the name their state carries


def generator(state: dict) -> np.random.Generator:
    """A generator continuing from a bit-generator ``state`` (of one of numpy's :data:`BIT_GENERATORS`): how a
    run's RNG streams live in its plain-dict state. The name in ``state`` only picks from those classes: a name
    from a file is never looked up as a function."""
    name = state.get("bit_generator") if isinstance(state, dict) else None
    if not isinstance(name, str) or name not in BIT_GENERATORS:
        raise ValueError(f"bit generator {str(name)[:40]!r} is not one of numpy's ({', '.join(BIT_GENERATORS)})")
    bit = BIT_GENERATORS[name]()
    bit.state = state
    return np.random.Generator(bit)


def build_operator(node, group: str, **context):
    """Instantiate config ``node`` of ``group`` (``_target_`` plus keywords, and ``context`` such as N); bad values
    raise :class:`~rovermarl.errors.ConfigError` with the key under ``group`` (``gamma`` -> ``k.gamma``)."""
    from hydra.errors import InstantiationException
    from hydra.utils import instantiate
    from omegaconf import DictConfig, OmegaConf

    if isinstance(node, dict):
        node = OmegaConf.create(node)
    if not isinstance(node, DictConfig) or "_target_" not in node:
        raise errors.ConfigError(group, None if node is None else OmegaConf.to_container(node),
                                 "must be a config with a _target_ (pick an option of the group)")
    try:                               # partial, then called: context objects (the World) stay as they are
        factory = instantiate(node, _partial_=True)
    except InstantiationException as e:
        raise _config_error(e.__cause__ or e, group, node) from None
    try:
        return factory(**context)
    except (errors.ConfigError, TypeError) as e:
        raise _config_error(e, group, node) from None


def _config_error(cause: BaseException, group: str, node) -> errors.ConfigError:
    if isinstance(cause, errors.ConfigError):
        return cause.under(group)
    if isinstance(cause, TypeError):
        return errors.ConfigError(group, node._target_, f"bad keys: {cause}")
    return errors.ConfigError(f"{group}._target_", node._target_,
                              "cannot be imported or called: " + " ".join(str(cause).split()))
