"""CC-(1+1)-ES (SPEC section 6): one independent run, and the generation loop that advances it."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from hydra.errors import InstantiationException
from hydra.utils import instantiate
from omegaconf import DictConfig, OmegaConf

from rovermarl import errors
from rovermarl.env import World
from rovermarl.record.events import Recorder


@dataclass
class Parts:
    """Everything a run is built from: the world and the operators of its config groups."""

    world: World
    team: object
    mutation: object
    selection: object
    selector: object


def build(cfg) -> Parts:
    """Instantiate world and operators from a composed config; bad values raise ConfigError."""
    cfg = cfg if isinstance(cfg, DictConfig) else OmegaConf.create(cfg)
    world = World.from_config(cfg)
    low = errors.number("policy.init_low", cfg.policy.init_low)
    high = errors.number("policy.init_high", cfg.policy.init_high)
    if high <= low:
        raise errors.ConfigError("policy.init_high", high, f"must be greater than policy.init_low={low}")
    n = world.n_rovers
    return Parts(world=world,
                 team=_instantiate(cfg, "team", n_agents=n),
                 mutation=_instantiate(cfg, "mutation"),
                 selection=_instantiate(cfg, "selection"),
                 selector=_instantiate(cfg, "k", n_agents=n, f_max=world.max_return))


def _instantiate(cfg, group: str, **context):
    node = cfg.get(group)
    if not isinstance(node, DictConfig) or "_target_" not in node:
        raise errors.ConfigError(group, None if node is None else OmegaConf.to_container(node),
                                 "must be a config with a _target_ (pick an option of the group)")
    try:
        return instantiate(node, **context)
    except InstantiationException as e:
        cause = e.__cause__
        if isinstance(cause, errors.ConfigError):
            raise cause.under(group) from None
        if isinstance(cause, TypeError):
            raise errors.ConfigError(group, node._target_, f"bad keys: {cause}") from None
        raise errors.ConfigError(f"{group}._target_", node._target_,
                                 "cannot be imported or called: " + " ".join(str(cause or e).split())) from None


class History:
    """Per-generation record of a run of G generations.

    score (G+1,): parent score after each generation (score[0]: initial team); child_score (G,);
    k (G,); accepted (G,); switched (G,) int16, episodes in which an unmutated rover changed its final POI
    (see :mod:`rovermarl.record.events`); probs (G, K) for selectors with probabilities, else None.
    """

    def __init__(self, generations: int, selector):
        self.score = np.full(generations + 1, np.nan)
        self.child_score = np.full(generations, np.nan)
        self.k = np.zeros(generations, dtype=np.int16)
        self.accepted = np.zeros(generations, dtype=bool)
        self.switched = np.full(generations, -1, dtype=np.int16)
        probs = selector.probs
        self.probs = None if probs is None else np.full((generations, len(probs)), np.nan)

    def arrays(self, start: int = 0, stop: int | None = None) -> dict[str, np.ndarray]:
        """Generations [start, stop): per-generation arrays, and ``score`` after each of them."""
        stop = len(self.k) if stop is None else stop
        out = {"score": self.score[start + 1:stop + 1], "k": self.k[start:stop], "accepted": self.accepted[start:stop],
               "switched": self.switched[start:stop], "child_score": self.child_score[start:stop]}
        if self.probs is not None:
            out["probs"] = self.probs[start:stop]
        return out


class Run:
    """One independent run from one integer seed.

    The seed's ``SeedSequence`` spawns four independent streams: initial conditions, initial genomes,
    mutation (which rovers, which changes) and selector. :meth:`state` captures everything the next
    generation depends on; ``Run(cfg, seed, state=...)`` continues from it, bit-identical to a run that
    never stopped.
    """

    def __init__(self, cfg, seed: int, parts: Parts | None = None, state: dict | None = None):
        self.seed = int(seed)
        self.parts = p = parts or build(cfg)
        cfg = OmegaConf.to_container(cfg, resolve=True) if OmegaConf.is_config(cfg) else cfg  # plain: cheap access
        s_ic, s_init, s_mut, s_sel = np.random.SeedSequence(self.seed).spawn(4)
        self.ic = p.world.initial_conditions(np.random.default_rng(s_ic))
        self.rng_mut = np.random.default_rng(s_mut)
        self.rng_sel = np.random.default_rng(s_sel)
        self.recorder = Recorder(p.world, self.ic, cfg.get("record") or {})
        self.evaluate = self.local_evaluate
        self.parents = p.team.init(p.world.n_params, cfg["policy"]["init_low"], cfg["policy"]["init_high"],
                                   np.random.default_rng(s_init))
        self.generations = int(cfg["generations"])
        self.generation = 0
        self.history = History(self.generations, p.selector)
        if state is not None:                                            # resume: no initial evaluation
            self.load(state)
            return
        self.f_parent = self.evaluate(p.team.genomes(self.parents))
        self.history.score[0] = self.f_parent
        self.recorder.start(self.parents_genomes, self.f_parent)

    def local_evaluate(self, genomes: np.ndarray) -> float:
        """Score of a team genomes (N, P) on this run's initial conditions, in this process."""
        return self.parts.world.evaluate(genomes, self.ic, self.recorder.child_xy)

    @property
    def parents_genomes(self) -> np.ndarray:
        return self.parts.team.genomes(self.parents)

    @property
    def done(self) -> bool:
        return self.generation >= self.generations

    def state(self) -> dict:
        """What the next generation depends on (plain arrays, ints, floats and dicts)."""
        return {"generation": self.generation, "parents": self.parents.copy(), "f_parent": self.f_parent,
                "rng_mut": self.rng_mut.bit_generator.state, "rng_sel": self.rng_sel.bit_generator.state,
                "selector": self.parts.selector.state_dict(), "recorder": self.recorder.state_dict()}

    def load(self, state: dict) -> None:
        """Continue from a :meth:`state` of the same config and seed."""
        self.generation = int(state["generation"])
        self.parents = np.array(state["parents"], dtype=np.float64)
        self.f_parent = float(state["f_parent"])
        self.rng_mut.bit_generator.state = state["rng_mut"]
        self.rng_sel.bit_generator.state = state["rng_sel"]
        self.parts.selector.load_state_dict(state["selector"])
        self.recorder.load_state_dict(state["recorder"], self.parents_genomes, self.f_parent)

    def result(self) -> dict:
        """Plain arrays of the run (safe to send between processes)."""
        return {"seed": self.seed, "generation": self.generation, "initial_score": self.history.score[0],
                **self.history.arrays(), "genomes": self.parents_genomes, "ic_xy": self.ic[0], "ic_heading": self.ic[1],
                **self.recorder.drain()}


def evolve(run: Run, generations: int) -> None:
    """Advance ``run`` by up to ``generations`` generations of CC-(1+1)-ES."""
    team, mutate, accept, selector = run.parts.team, run.parts.mutation, run.parts.selection, run.parts.selector
    h = run.history
    for g in range(run.generation, min(run.generation + generations, run.generations)):
        if h.probs is not None:
            h.probs[g] = selector.probs                                  # before this generation's choice
        k = selector.choose(run.rng_sel)                                 # 1. choose k
        chosen = team.pick(k, run.rng_mut)                               # 2. k distinct rovers
        children = team.mutate(run.parents, chosen, mutate, run.rng_mut)  # 3. mutate them
        genomes = team.genomes(children)                                 # (N, P): the team the world sees
        f_child = run.evaluate(genomes)                                  # 4. evaluate the team
        h.switched[g] = run.recorder.switched(team.mutated(chosen))      #    did unmutated rovers switch POI?
        accepted = accept(f_child, run.f_parent)                         # 5. all k children or none
        selector.update(k, f_child, run.f_parent)                        # 6. reward the selector
        if accepted:                                                     # 7. record behaviour changes
            run.recorder.accepted(g + 1, genomes, f_child, f_child != run.f_parent)
            run.parents, run.f_parent = children, f_child
        h.k[g], h.accepted[g], h.child_score[g], h.score[g + 1] = k, accepted, f_child, run.f_parent
        run.generation = g + 1
    if run.done:
        run.recorder.finish(run.generation, run.parents_genomes, run.f_parent)
