"""The algorithm plug-in contract (docs/ARCHITECTURE.md, "Plug-in points").

An algorithm is one class plus one yaml in ``conf/algorithm/``, built as ``instantiate(cfg.algorithm, world=world)``.
It holds no run state: :meth:`Algorithm.init` creates the run's state, a dataclass subclass of :class:`RunState`
named by :attr:`Algorithm.state_type` (fields: arrays, numbers, strings, None, plain dicts of those such as RNG
states), and :meth:`Algorithm.advance` threads it through, so the runner can checkpoint it, ship it to another
process and resume bit-identically. Randomness comes only from the run's named streams (:class:`RunStreams`).
It asks the evaluation only what :class:`Evaluator` declares and tells the behaviour observer what
:class:`Observer` declares. The public methods check and normalise; subclasses implement ``_init``, ``_advance``
and ``_team``. Per-generation arrays are declared in :attr:`Algorithm.series` (checkpoints, ``curve.npz``, the
Rerun recording and the figures follow it); ``score`` (G+1,) belongs to every run and is kept by the runner.

Example (a run of 3 generations, in the runner's words)::

    world = make_world("solo")
    algo = instantiate(cfg.algorithm, world=world)      # e.g. CC11ES
    evaluate = Evaluation(world, world.run_ic(7))       # run 7's initial conditions
    state, f0 = algo.init(RunStreams(7), evaluate)
    state, arrays = algo.advance(state, 0, 3, evaluate, NullObserver())
    arrays["score"].shape, arrays["k"].shape            # ((3,), (3,))
"""

from __future__ import annotations

import sys
from abc import ABC, abstractmethod
from dataclasses import MISSING, dataclass, fields
from typing import ClassVar, NamedTuple, Protocol

import numpy as np

from rovermarl import errors
from rovermarl.env import InitialConditions, Rollout, World
from rovermarl.env.streams import RunStreams


class Measured(NamedTuple):
    """A team's score F with what its evaluation measured: ``final_xy`` (E, N, 2), the rovers' final positions, or
    None when the run keeps none (no observer reads them)."""

    score: float
    final_xy: np.ndarray | None


class KernelInputs(NamedTuple):
    """What a compiled generation loop needs to evaluate teams itself as the evaluation does: the world, the initial
    conditions and the buffer (E, N, 2) for final positions (None: none kept)."""

    world: World
    ic: InitialConditions
    final_xy: np.ndarray | None


class Evaluator(ABC):
    """What an algorithm may ask of the evaluation of its teams (genomes (N, P)), on the run's initial conditions.
    ``fresh`` is true under ``evaluation.fresh_ic``: an algorithm with ``fresh_ic = True`` calls :meth:`draw` once
    per generation and scores every team it compares there. ``calls`` counts the team evaluations made (one per
    team scored, measured or rolled out; a compiled loop adds its own)."""

    fresh: bool = False
    calls: int = 0

    @abstractmethod
    def measure(self, genomes: np.ndarray) -> Measured:
        """The team's score F with its final positions (what the observer reads)."""

    def score(self, genomes: np.ndarray) -> float:
        """The team's score F."""
        return self.measure(genomes).score

    def measure_many(self, teams: np.ndarray) -> list[Measured]:
        """:meth:`measure` of each of B teams (B, N, P), in order (an evaluation may score them in one call)."""
        return [self.measure(team) for team in teams]

    @abstractmethod
    def rollout(self, genomes: np.ndarray) -> Rollout:
        """One team evaluation with its whole trajectories (xy (E, T+1, N, 2), heading (E, T+1, N), returns (E,)):
        what a learner that credits rovers by counterfactuals needs."""

    def draw(self, generation: int) -> None:
        """Score on the initial conditions of ``generation`` from now on (only when :attr:`fresh`)."""
        raise AlgorithmError(f"{type(self).__name__} draws no fresh initial conditions (evaluation.fresh_ic is off)")

    def kernel_inputs(self) -> KernelInputs | None:
        """The inputs of a compiled loop that evaluates teams itself, or None where teams are not scored in this
        process on fixed initial conditions (then no compiled loop applies)."""
        return None


@dataclass(frozen=True)
class Series:
    """One per-generation array of a run: ``name`` -> (G, *shape) of ``dtype``; ``fill`` marks generations not
    computed, ``columns`` names a vector's entries (e.g. one per bandit arm), logged under ``<entity>/<column>``
    (``entity``: where the Rerun recording logs it, default ``metrics/<name>``)."""

    name: str
    dtype: str
    shape: tuple[int, ...] = ()
    fill: float = 0
    doc: str = ""
    columns: tuple[str, ...] = ()
    entity: str = ""

    def empty(self, generations: int) -> np.ndarray:
        return np.full((generations, *self.shape), self.fill, dtype=self.dtype)

    @property
    def path(self) -> str:
        """The Rerun entity path."""
        return self.entity or f"metrics/{self.name}"


class Observer(Protocol):
    """What an algorithm tells the behaviour observer (:mod:`rovermarl.record.events`) inside its loop; ``final_xy``
    (E, N, 2) is what :meth:`Evaluator.measure` returned for that team (None: none kept; an observer that measures
    positions refuses None in one line)."""

    def evaluated(self, mutated: np.ndarray, final_xy: np.ndarray | None) -> int:
        """A team that changed the rovers ``mutated`` (N,) bool of the parent team was evaluated, its rovers ending
        at ``final_xy``; returns the number of episodes in which another rover ends at another POI than under the
        parent team (-1: not measured)."""

    def accepted(self, generation: int, genomes: np.ndarray, score: float, score_changed: bool,
                 final_xy: np.ndarray | None) -> None:
        """The team genomes (N, P), evaluated as ``score`` with its rovers ending at ``final_xy``, became the parent
        team at ``generation``."""

    def switch_inputs(self) -> tuple | None:
        """What :meth:`evaluated` compares, for a compiled loop that measures it itself: ``(parent_poi (E, N),
        poi_xy (P, 2), radius)``, or None when nothing is measured."""


class NullObserver:
    """An observer that measures nothing (``evaluated`` returns -1)."""

    def evaluated(self, mutated: np.ndarray, final_xy: np.ndarray | None) -> int:
        return -1

    def switch_inputs(self) -> None:
        return None

    def accepted(self, generation: int, genomes: np.ndarray, score: float, score_changed: bool,
                 final_xy: np.ndarray | None) -> None:
        pass


# Names a run's arrays already use (curve.npz, the runner's record, the observer's files): no series may take them.
RESERVED = frozenset({"score", "seed", "genomes", "ic_xy", "ic_heading", "ic_layout", "heldout_score", "initial_score"})
RESERVED_PREFIXES = ("behaviour_", "occupancy_")

LOOPS = ("auto", "python", "compiled")   # algorithm.loop: which generation loop runs (an algorithm with one)


def python_loop(loop: str, what: str) -> str:
    """``algorithm.loop`` of an algorithm with no compiled loop (``what``, e.g. "the CCEA"): auto or python."""
    if errors.choice("loop", loop, LOOPS) == "compiled":
        raise errors.ConfigError("loop", loop, f"{what} has no compiled generation loop (auto and python run its "
                                 "Python one)")
    return loop


@dataclass(kw_only=True)
class RunState:
    """A run's state: what :meth:`Algorithm.init` returns and :meth:`Algorithm.advance` threads through. An algorithm
    declares its own as a dataclass subclass (``@dataclass(kw_only=True)``) and names it :attr:`Algorithm.state_type`;
    ``score`` is the score of the run's team (:meth:`Algorithm.score`)."""

    score: float

    def as_dict(self) -> dict:
        """The fields by name (not copied): the form a checkpoint and a chunk hold."""
        return {f.name: getattr(self, f.name) for f in fields(self)}

    @classmethod
    def from_dict(cls, d: dict) -> RunState:
        """The state of :meth:`as_dict` ``d``; ValueError (one line) if its keys are not this type's fields."""
        names = {f.name for f in fields(cls)}
        needed = {f.name for f in fields(cls) if f.default is MISSING and f.default_factory is MISSING}
        extra, missing = sorted(set(d) - names), sorted(needed - set(d))
        wrong = [w for w in (extra and f"has no field {', '.join(extra)}", missing and f"lacks {', '.join(missing)}")
                 if w]
        if wrong:
            raise ValueError(f"a {cls.__qualname__} has fields {', '.join(sorted(names))}; this state "
                             + "; ".join(wrong))
        return cls(**d)


class AlgorithmError(Exception):
    """A run cannot continue because of a plug-in's behaviour; the message is one line naming the plug-in."""


class Algorithm:
    """Base class of a learner over a team of N rovers, each with a genome of P parameters.

    Subclasses set :attr:`series` (in ``__init__`` if it depends on the config). One that honours
    ``evaluation.fresh_ic`` (calls :meth:`Evaluator.draw` each generation, re-scores the parents there) sets
    :attr:`fresh_ic`; the runner refuses ``evaluation.fresh_ic=true`` for the others. :attr:`kernel_calls` names the
    world kernel's other functions it calls (``evaluate_many``; ``observe`` and ``env_step`` through
    :class:`~rovermarl.vector.VectorEnv`), so that a launch compiles them ahead (:mod:`rovermarl.runner.compile`).
    """

    state_type: ClassVar[type[RunState]] = RunState   # the run state's declared type (a subclass names its own)
    series: tuple[Series, ...] = ()
    fresh_ic: bool = False
    kernel_calls: ClassVar[tuple[str, ...]] = ()    # the world kernel's functions it calls besides rollout and evaluate
    final_team: str = "best"      # the run's team: the best kept so far (elitist), or "last": the last iterate

    def __init__(self, world):
        self.world = world

    def init(self, streams: RunStreams, evaluate: Evaluator) -> tuple[RunState, Measured]:
        """A fresh run's state and its initial team's score with its final positions (``_init`` may return the
        :class:`Measured` ``evaluate`` gave, or a float: then no positions). ``streams`` are the run's named random
        streams (its ``algorithm``, ``mutation`` and ``selector`` ones are the algorithm's)."""
        state, score = self._init(streams, evaluate)
        return self._declared(state, "_init"), score if isinstance(score, Measured) else Measured(float(score), None)

    def advance(self, state: RunState, generation: int, n: int, evaluate: Evaluator,
                observer: Observer) -> tuple[RunState, dict[str, np.ndarray]]:
        """Advance ``state`` (at ``generation``) by ``n`` generations: the new state and the arrays of those
        generations, ``score`` (n,) after each one and every declared :attr:`series` (n, *shape)."""
        state, arrays = self._advance(self._declared(state, "advance's argument"), generation, n, evaluate,
                                      observer)
        self._declared(state, "_advance")
        missing = {"score", *(s.name for s in self.series)} - set(arrays)
        if missing:
            raise AlgorithmError(f"{type(self).__name__}.advance returned no {', '.join(sorted(missing))}")
        return state, arrays

    def _declared(self, state, where: str) -> RunState:
        """``state`` if it is of :attr:`state_type`, else :class:`AlgorithmError` naming ``where`` it came from."""
        if not isinstance(state, self.state_type):
            raise AlgorithmError(f"{type(self).__name__}.{where} gave a {type(state).__name__}, not its declared "
                                 f"state type {self.state_type.__qualname__} (Algorithm.state_type)")
        return state

    def team(self, state: RunState) -> np.ndarray:
        """The team of ``state`` as the world sees it: genomes (N, P)."""
        return self._team(state)

    def score(self, state: RunState) -> float:
        """The score of :meth:`team`."""
        return float(state.score)

    def check_series(self) -> None:
        """Raise :class:`~rovermarl.errors.ConfigError` (one line) if a declared series takes a name the run's files
        already use (:data:`RESERVED`), or two series share a name."""
        names = [s.name for s in self.series]
        for name in names:
            if name in RESERVED or name.startswith(RESERVED_PREFIXES) or names.count(name) > 1:
                raise errors.ConfigError("algorithm.series", name, f"{type(self).__name__} declares a series "
                                         "under a name that is taken (" + ", ".join(sorted(RESERVED)) +
                                         ", behaviour_*, occupancy_*, or another series)")

    def kernel_functions(self, kernel) -> list:
        """The functions of the world kernel ``kernel`` (``World.compiled``) that :attr:`kernel_calls` names, or
        :class:`~rovermarl.errors.ConfigError` (one line naming this class's file) for a name the kernel lacks."""
        for name in self.kernel_calls:
            if not callable(getattr(kernel, name, None)):
                home = getattr(sys.modules.get(type(self).__module__), "__file__", type(self).__module__)
                raise errors.ConfigError("algorithm.kernel_calls", name, f"{type(self).__name__} ({home}) names no "
                                         f"function of the world kernel {kernel.__name__}")
        return [getattr(kernel, name) for name in self.kernel_calls]

    def check_run(self, fresh_ic: bool, local: bool) -> None:
        """Refuse (:class:`~rovermarl.errors.ConfigError`, one line) a run this algorithm cannot honour as
        configured: under ``evaluation.fresh_ic`` (``fresh_ic``), or with teams scored in other processes (``local``
        false: ``parallel.ic_shards`` > 1). The runner calls it before any work and reports a key of the algorithm's
        own (``loop``) under ``algorithm.``, a dotted one (``parallel.ic_shards``) as it is."""

    def evaluations_per_generation(self, fresh_ic: bool = False) -> float:
        """Team evaluations one generation costs (``fresh_ic``: under ``evaluation.fresh_ic``): what the runner's
        time estimate and the comparisons at equal evaluations assume. Override it when it is not 1."""
        return 1.0

    def agent_steps_per_generation(self, fresh_ic: bool = False) -> int:
        """Agent-steps (one rover, one time step) one generation costs: the budget unit every learner shares
        (``budget.agent_steps``). A team evaluation is ``episodes x steps x n_rovers`` agent-steps (960 for 4 rovers
        at 16 x 15); a learner that steps the environment itself (PPO) overrides this."""
        w = self.world
        return int(round(self.evaluations_per_generation(fresh_ic) * w.episodes * w.steps * w.n_rovers))

    def own_agent_steps_per_generation(self, fresh_ic: bool = False) -> int:
        """Agent-steps one generation takes outside the team evaluations it asks of the :class:`Evaluator`: 0, or a
        learner's own training steps (PPO's). A study's ``compute.json`` adds them to the evaluations'."""
        return 0

    def _init(self, streams: RunStreams, evaluate: Evaluator):
        raise NotImplementedError

    def _advance(self, state, generation, n, evaluate, observer):
        raise NotImplementedError

    def _team(self, state):
        raise NotImplementedError


BIT_GENERATORS = {c.__name__: c for c in (np.random.PCG64, np.random.PCG64DXSM, np.random.Philox, np.random.SFC64,
                                          np.random.MT19937)}   # numpy's, by the name their state carries


def generator(state: dict) -> np.random.Generator:
    """A generator continuing from a bit-generator ``state`` (how a run's RNG streams live in its state). The name
    in ``state`` only picks from :data:`BIT_GENERATORS`: a name from a file is never looked up as a function."""
    name = state.get("bit_generator") if isinstance(state, dict) else None
    if not isinstance(name, str) or name not in BIT_GENERATORS:
        raise ValueError(f"bit generator {str(name)[:40]!r} is not one of numpy's ({', '.join(BIT_GENERATORS)})")
    bit = BIT_GENERATORS[name]()
    bit.state = state
    return np.random.Generator(bit)


def init_range(low, high) -> tuple[float, float]:
    """The initial genomes' range (``policy.init_low``, ``policy.init_high``), checked: numbers, low below high."""
    low, high = errors.number("policy.init_low", low), errors.number("policy.init_high", high)
    if high <= low:
        raise errors.ConfigError("policy.init_high", high, f"must be greater than policy.init_low={low}")
    return low, high


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
