"""The multi-rover world (SPEC sections 1-3, 5): rollouts and team evaluation, on a world made of parts.

A :class:`World` holds its parts, none calling another: ``params`` (:class:`~rovermarl.env.params.Params`),
``task`` (:class:`~rovermarl.env.task.Task`), ``starts`` (:class:`~rovermarl.env.starts.Starts`), ``kernel`` (the
:class:`~rovermarl.env.kernel.KernelWorld` record the compiled rollout reads) and ``compiled`` (the module of its
compiled functions); docs/ARCHITECTURE.md maps them and docs/WORLDS.md is a plug-in's contract. Building a World runs
a plug-in's trial (:mod:`rovermarl.env.trial`): a bad plug-in fails there, in one line.
"""

from __future__ import annotations

import math
import pkgutil
from collections.abc import Collection
from dataclasses import fields
from functools import cached_property
from typing import ClassVar

import numpy as np

from rovermarl import errors
from rovermarl.env import kernel
from rovermarl.env.kernel import record
from rovermarl.env.kernel.compose import kernel_module
from rovermarl.env.kernel.hooks import ROVERS, Hooks
from rovermarl.env.params import DTYPES, Params, keywords
from rovermarl.env.prepared import (
    NO_FINAL,
    Prepared,
    Rollout,
    final_in,
    genomes_in,
    score_teams,
    warn_insane,
    workers_in,
)
from rovermarl.env.starts import InitialConditions, Starts
from rovermarl.env.task import Task
from rovermarl.env.trial import State, check_params, check_sense, check_state, no_dataclass, plugin_homes, state_dims
from rovermarl.jit import name_compiled, say_if_cold

_NO_LAYOUT = np.empty((0, 0))

__all__ = ["DTYPES", "Rollout", "World", "world_class"]


class World:
    """One rover world. POI ``j`` sits at angle ``2*pi*j/P`` on a circle of radius ``poi_distance``.

    ``coupling[j]`` rovers within ``obs_radius`` of POI ``j`` at the last step earn ``value[j]`` (``reward="final"``;
    the other readings of :data:`~rovermarl.env.kernel.REWARDS` score every step, SPEC section 8).

    The world options of SPEC section 8 are parameters: ``reward`` (final | any_step | best_step | mean_step),
    ``speed`` (affine | clip) and ``poi_type`` (coupling | sign | value); the defaults are the SPEC reading.
    ``World(**keywords)`` builds its :attr:`params` from the keywords; ``World(params)`` takes them built.

    >>> make_world("duo", reward="any_step", speed="clip", poi_type="sign").poi_sensor_type.tolist()[:3]
    [1.0, -1.0, -1.0]
    """

    # ---- what a world plug-in may set (docs/WORLDS.md): these members, with the paper's values ------------------
    Params: ClassVar[type[Params]] = Params     # its configuration's class: a plug-in's own parameters subclass it
    hooks: ClassVar[Hooks] = ROVERS             # the compiled hooks of the world (rovermarl.env.kernel.hooks)
    state: ClassVar[tuple[State, ...]] = ()     # the per-episode state the hooks read and write (none: the paper's)
    layout_dim = 0      # K: numbers per episode that draw_layout adds to the initial conditions
    fixed_pois = True   # the POIs are poi_xy in every episode: the occupancy and C8 measures read them
                        # (the behaviour observer leaves those measures out of a world that sets False)

    def kernel_extra(self) -> tuple:
        """The plug-in's own arrays and numbers for its hooks (``KernelWorld.extra``), in the kernel's precision
        where they meet the rovers' state (``np.dtype(self.dtype)``). The paper's world: none."""
        return ()

    def draw_layout(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """(n, K): what the world draws per episode after the rovers' starts (``layout_dim`` K numbers each), from
        the initial conditions' generator."""
        return np.empty((n, self.layout_dim))

    def obs_blocks(self) -> list[tuple[str, np.ndarray, np.ndarray]]:
        """The observation's blocks in order: (name, low (size,), high (size,)). The paper's: 3 numbers per POI
        (distance / range, bearing / pi, type), then 2 per other rover; a plug-in appends its own sensors' blocks
        (and writes them after the paper's rows in its ``sense`` hook).

        >>> [(name, low.size) for name, low, high in make_world("solo").obs_blocks()]
        [('poi', 30), ('rover', 8)]
        """
        kinds = float(np.abs(self.task.sensor_type).max(initial=1.0))
        poi_high = np.tile([1.0, 1.0, kinds], self.n_pois)
        return [("poi", -poi_high, poi_high), ("rover", -np.ones(2 * self.n_rovers), np.ones(2 * self.n_rovers))]

    def poi_positions(self, layout: np.ndarray | None = None) -> np.ndarray:
        """(P, 2): the POIs of an episode whose layout is ``layout`` (K,); the paper's: fixed, ``poi_xy``."""
        return self.poi_xy

    def poi_track(self, layout: np.ndarray | None = None) -> np.ndarray | None:
        """(T+1, P, 2): an episode's POIs at each step, for a world whose POIs move; None: at :meth:`poi_positions`."""
        return None

    def draw(self, ax, layout: np.ndarray | None = None) -> None:
        """Draw what the plug-in adds to the world (obstacles, ...) on matplotlib axes, for an episode's ``layout``."""

    def log_static(self, rec, layout: np.ndarray | None = None) -> None:
        """Log what the plug-in adds to the world into the Rerun recording stream ``rec`` (under ``world/``)."""

    def team_return(self, xy: np.ndarray) -> np.ndarray:
        """Team return of positions xy (..., M, 2) -> (...,) (``Task.team_return``); a world whose reward needs an
        episode's layout raises."""
        return self.task.team_return(xy)

    @property
    def max_return(self) -> float:
        """The best team return an episode can give (``Task.max_return``): EXP3's reward scale, the figures' top."""
        return self.task.max_return

    # ---- the parts ---------------------------------------------------------------------------------------------
    def __init__(self, params: Params | None = None, /, **keywords):
        if params is None:
            params = self.Params(**keywords)                    # the parameters' checks, then the plug-in's own
        elif keywords or type(params) is not self.Params:
            raise TypeError(f"{type(self).__name__}(params) takes one {self.Params.__qualname__} and no keywords")
        object.__setattr__(self, "params", params)
        self.kernel                             # noqa: B018 -- built now: a bad plug-in fails here, in one line
        if self.hooks != ROVERS or self.state:           # a plug-in's hooks: one line naming its file if they fail
            with errors.plugin_errors(plugin_homes(self)):
                check_sense(self)
                check_state(self)                       # every hook tried once, the state guarded

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        check_params(cls)                       # its parameters are its Params' fields, else one line

    def __getattr__(self, name: str):
        """A parameter reads as an attribute: ``world.steps`` is ``world.params.steps``."""
        params = self.__dict__.get("params")
        if params is not None and name in params.__dataclass_fields__:
            return getattr(params, name)
        if hasattr(type(self), name):           # a property that raised AttributeError inside: that error, again
            return object.__getattribute__(self, name)
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")

    def __setattr__(self, name: str, value) -> None:
        raise AttributeError(f"a {type(self).__name__} is immutable: build another with other parameters")

    def __repr__(self) -> str:
        shown = ", ".join(f"{f.name}={getattr(self.params, f.name)!r}" for f in fields(self.params) if f.repr)
        return f"{type(self).__name__}({shown})"

    def __reduce__(self):
        return type(self), (self.params,)

    @cached_property
    def task(self) -> Task:
        return Task.of(self.coupling, self.value, self.poi_distance, self.poi_type, self.obs_radius, self.reward,
                       self.n_rovers)

    @cached_property
    def starts(self) -> Starts:
        """The initial conditions (the plug-in's ``draw_layout`` after the rovers' starts)."""
        return Starts(self.n_rovers, self.start_box, self.episodes, self.draw_layout)

    @cached_property
    def kernel(self) -> kernel.KernelWorld:
        """The world as the kernel reads it, passed whole (:func:`rovermarl.env.kernel.record.build`)."""
        return record.build(self.params, self.task, self.obs_blocks(), self.layout_dim, self.kernel_extra(),
                            state_dims(self))

    @property
    def poi_xy(self) -> np.ndarray:
        """(P, 2) float64: POI ``j`` at angle ``2*pi*j/P`` on the circle of radius ``poi_distance``."""
        return self.task.poi_xy

    @property
    def poi_sensor_type(self) -> np.ndarray:
        """(P,): the third sensor number of each POI in range (``env.poi_type``, ``Task.of``)."""
        return self.task.sensor_type.copy()

    @property
    def n_pois(self) -> int:
        return len(self.coupling)

    @cached_property
    def obs_dim(self) -> int:
        """D, the sum of the ``obs_blocks`` (38 for the paper's 10 POIs and 4 rovers)."""
        return sum(low.size for _, low, _ in self.obs_blocks())

    @property
    def w_max(self) -> float:
        return math.radians(self.w_max_deg)

    def initial_conditions(self, seed=0, n: int | None = None) -> InitialConditions:
        """``n`` (default ``episodes``) starts: ``Starts.initial_conditions``."""
        return self.starts.initial_conditions(seed, n)

    def run_ic(self, seed: int, generation: int = 0) -> InitialConditions:
        """The initial conditions run ``seed`` is scored on: ``Starts.run_ic``."""
        return self.starts.run_ic(seed, generation)

    def heldout_ic(self, seed: int, n: int = 256) -> InitialConditions:
        """Run ``seed``'s held-out initial conditions: ``Starts.heldout_ic``."""
        return self.starts.heldout_ic(seed, n)

    @cached_property
    def _float(self) -> type:
        return np.dtype(self.dtype).type        # env.dtype: the kernel's precision

    @cached_property
    def _team_shape(self) -> tuple[int, int]:
        return self.n_rovers, self.policy.n_params(self.obs_dim)

    @cached_property
    def compiled(self):
        """The module of the world's compiled functions: :mod:`~rovermarl.env.kernel.fused` for the paper's hooks,
        else one compiled around ``hooks`` (:mod:`~rovermarl.env.kernel.compose`)."""
        module = kernel_module(self.hooks, tuple(self.state))
        if module.__name__.startswith("rovermarl_world_"):             # the compile notice names the world
            name_compiled(module.__name__, f"{type(self).__name__}'s kernel from {type(self).__module__}")
        return module

    def kernel_for(self, layout: np.ndarray) -> kernel.KernelWorld:
        """:attr:`kernel` with the initial conditions' ``layout`` (E, K) (a world without one: :attr:`kernel`)."""
        return self.kernel._replace(layout=layout) if self.layout_dim else self.kernel

    @classmethod
    def from_config(cls, cfg, trust: bool | Collection[str] = False, cls_: type[World] | None = None) -> World:
        """Build from a composed config (or a plain dict) with ``setup``, ``env`` and ``policy`` sections
        (``params.keywords``): the class ``env._target_`` names, or ``cls_`` (a class the caller holds: ``make_world``).
        A plug-in only with ``trust`` (:func:`world_class`): the training path trusts the config it composed; a read
        path of results only with ``--trust-config``."""
        env = cfg["env"]
        cls = cls_ or world_class(env.get("_target_") if hasattr(env, "get") else None, trust)
        return cls(**keywords(cfg, cls))

    @property
    def n_params(self) -> int:
        """Genome length of one rover's policy (658 by default)."""
        return self._team_shape[1]

    # ---- sensing and reward -------------------------------------------------------------------
    def observe(self, xy: np.ndarray, heading: np.ndarray, layout: np.ndarray | None = None) -> np.ndarray:
        """Observations: xy (..., N, 2), heading (..., N) (a plug-in's layout (..., K)) -> (..., N, obs_dim) float64.
        The paper's world with libm's rounding (the rollout's within a few ulp); a plug-in's through its ``sense``,
        its state as the episode starts."""
        xy, heading, layout = self._batch(xy, heading, layout)
        out = np.empty(heading.shape + (self.obs_dim,))
        flat = xy.reshape(-1, self.n_rovers, 2), heading.reshape(-1, self.n_rovers)
        if self.hooks == ROVERS:
            kernel.sense_libm(*flat, self.poi_xy, self.task.sensor_type, float(self.sensor_range),
                              out.reshape(-1, self.n_rovers, self.obs_dim))
        else:
            k = self.kernel._replace(poi_xy=self.poi_xy, poi_type=self.task.sensor_type,
                                     sensor_range=float(self.sensor_range),
                                     layout=layout.reshape(flat[1].shape[0], self.layout_dim))
            self.compiled.observe(*flat, k, self.compiled.state_of(flat[0], k),
                                  out.reshape(-1, self.n_rovers, self.obs_dim))
        return out

    def episode_return(self, xy: np.ndarray, layout: np.ndarray | None = None) -> np.ndarray:
        """Episode returns under this world's reward hooks from trajectories xy (..., T+1, M, 2) (index 0 the start,
        unscored; a plug-in's layout (..., K)) -> (...,); the team's own trajectories give :meth:`returns`."""
        xy = np.asarray(xy, dtype=np.float64)
        if xy.ndim < 3 or xy.shape[-3] != self.steps + 1 or xy.shape[-1] != 2:
            raise ValueError(f"xy must have shape (..., {self.steps + 1}, M, 2), got {xy.shape}")
        flat = np.ascontiguousarray(xy.reshape(-1, *xy.shape[-3:]))
        lay = np.zeros(xy.shape[:-3] + (self.layout_dim,)) if layout is None else np.asarray(layout, np.float64)
        out = np.empty(flat.shape[0])
        k = self.kernel_for(np.ascontiguousarray(lay.reshape(flat.shape[0], self.layout_dim)))
        self.compiled.returns_of(flat, k, out)              # as the rollout's reward reads them
        return out.reshape(xy.shape[:-3])

    # ---- rollouts -----------------------------------------------------------------------------
    def prepare(self, ic) -> Prepared:
        """Initial conditions ``ic`` (:class:`InitialConditions`, or xy (E, N, 2), heading (E, N)) checked and in the
        kernel's precision once (:class:`~rovermarl.env.prepared.Prepared`: pass it wherever a method takes ``ic``;
        plain ``ic`` is prepared again on every call, a few microseconds). No episode, or nan or inf, is refused in
        one line (ValueError)."""
        if type(ic) is Prepared:
            return ic if ic.world is self else self.prepare(ic.ic)
        xy0, h0, layout = (a.copy() for a in self._batch(*ic))
        if h0.ndim != 2 or h0.shape[0] == 0:
            raise ValueError(f"initial conditions must hold E >= 1 episodes, xy (E, {self.n_rovers}, 2); got "
                             f"{xy0.shape}")
        if not (np.isfinite(xy0).all() and np.isfinite(h0).all()):
            e = int(np.flatnonzero(~(np.isfinite(xy0).all(axis=(1, 2)) & np.isfinite(h0).all(axis=1)))[0])
            raise ValueError(f"initial conditions must be finite numbers: episode {e}'s xy or heading holds nan or inf")
        f, k = self._float, self.kernel_for(layout)
        return Prepared(InitialConditions(xy0, h0, layout), xy0.astype(f), h0.astype(f), k, tuple(k), self)

    def rollout(self, genomes: np.ndarray, ic) -> Rollout:
        """Full trajectories of a team: genomes (N, P), ic (:class:`InitialConditions`, or xy (E, N, 2), heading
        (E, N), or :meth:`prepare`'s)."""
        p, genomes = self._prepared(ic), genomes_in(genomes, self._team_shape, "genomes")
        e = p.episodes
        traj = Rollout(np.empty((e, self.steps + 1, self.n_rovers, 2)),
                       np.empty((e, self.steps + 1, self.n_rovers)), np.empty(e), p.ic.layout.copy())
        args = (genomes.astype(self._float), p.xy, p.heading, p.kernel, traj.returns, traj.xy, traj.heading, NO_FINAL)
        say_if_cold(self.compiled.rollout, args, "the world's rollout")
        self.compiled.rollout(*args)
        return traj

    def returns(self, genomes: np.ndarray, ic, final_xy: np.ndarray | None = None) -> np.ndarray:
        """Per-episode team returns (E,) of a team genomes (N, P) from ic (or :meth:`prepare`'s); ``final_xy``
        (E, N, 2), a writeable C-ordered float64 array, if given, receives the rovers' final positions."""
        return self._one(genomes, ic, final_xy)[1]

    def evaluate(self, genomes: np.ndarray, ic, final_xy: np.ndarray | None = None) -> float:
        """Score F: the mean team return over the episodes of ``ic`` (SPEC section 5); see :meth:`returns`. With
        ``ic`` from :meth:`prepare`, as fast as the compiled rollout (``benchmarks/api.py``)."""
        return self._one(genomes, ic, final_xy)[0]

    def evaluate_many(self, teams: np.ndarray, ic, final_xy: np.ndarray | None = None,
                      workers: int | None = None) -> np.ndarray:
        """Scores (B,) of B teams (B, N, P) on the same ``ic``, each the float :meth:`evaluate` gives, bit for bit.
        Teams share each pass of the rollout's lanes, split over up to ``workers`` threads (None: every CPU this
        process may use; 1: this thread), up to B // 8 threads (``prepared.score_teams``). ``final_xy``
        (B, E, N, 2), as in :meth:`returns`."""
        teams = np.asarray(teams)
        if teams.ndim != 3 or teams.shape[1:] != (self.n_rovers, self.n_params):
            raise ValueError(f"teams must have shape (B, {self.n_rovers}, {self.n_params}), got {teams.shape}")
        p, workers = self._prepared(ic), workers_in(workers)
        b = teams.shape[0]
        flat = genomes_in(teams, teams.shape, "teams").reshape(b * self.n_rovers, self.n_params)
        if final_xy is not None:
            final_xy = final_in(final_xy, (b, *p.xy.shape)).reshape(b * p.episodes, self.n_rovers, 2)
        return score_teams(self, flat, p, final_xy, workers)[0]

    def homogeneous(self, genome: np.ndarray) -> np.ndarray:
        """The team (N, P) of N copies of one rover's genome (P,) (the paper's homogeneous control)."""
        genome = np.asarray(genome, dtype=np.float64)
        if genome.shape != (self.n_params,):
            raise ValueError(f"genome must have shape ({self.n_params},), got {genome.shape}")
        return np.ascontiguousarray(np.broadcast_to(genome, (self.n_rovers, self.n_params)))

    def kernel_args(self, ic) -> tuple:
        """``compiled.rollout``'s arguments after the genomes, for a compiled loop: xy (E, N, 2), heading (E, N)
        in ``env.dtype``, and the :class:`~rovermarl.env.kernel.KernelWorld` with their layout."""
        p = self._prepared(ic)
        return p.xy, p.heading, p.kernel

    def _prepared(self, ic) -> Prepared:
        return ic if type(ic) is Prepared and ic.world is self else self.prepare(ic)

    def _one(self, genomes, ic, final_xy):
        """(score, returns (E,)) of one team, with the least overhead (the genomes' check, one array, the call)."""
        p = ic if type(ic) is Prepared and ic.world is self else self.prepare(ic)
        g = genomes_in(genomes, self._team_shape, "genomes")
        final_xy = NO_FINAL if final_xy is None else final_in(final_xy, p.xy.shape)
        returns = np.empty(p.heading.shape[0])
        run = self.compiled.evaluate
        if not run.overloads:
            say_if_cold(run, (g, p.xy, p.heading, p.fields, returns, final_xy), "the world's rollout")
        f, sane = run(g, p.xy, p.heading, p.fields, returns, final_xy)
        if not sane:
            warn_insane(np.zeros(1, dtype=bool), returns[None])
        return f, returns

    def _batch(self, xy, heading, layout=None):
        """Checked, contiguous float64 (xy (..., N, 2), heading (..., N), layout (..., K)); no layout: K = 0 only."""
        xy = np.ascontiguousarray(xy, dtype=np.float64)
        heading = np.ascontiguousarray(heading, dtype=np.float64)
        if xy.shape[-2:] != (self.n_rovers, 2) or heading.shape != xy.shape[:-1]:
            raise ValueError(f"expected xy (..., {self.n_rovers}, 2) and heading (..., {self.n_rovers}), "
                             f"got {xy.shape} and {heading.shape}")
        if not self.layout_dim and (layout is None or layout.shape[-1] == 0):
            return xy, heading, _NO_LAYOUT                              # unread: the kernel's record has its own
        if layout is None:
            if self.layout_dim:
                raise ValueError(f"{type(self).__name__}'s initial conditions carry a layout (..., "
                                 f"{self.layout_dim}): pass all of World.initial_conditions, not only xy and heading")
            layout = np.empty(heading.shape[:-1] + (0,))
        layout = np.ascontiguousarray(layout, dtype=np.float64)
        if layout.shape != heading.shape[:-1] + (self.layout_dim,):
            raise ValueError(f"expected layout {heading.shape[:-1] + (self.layout_dim,)}, got {layout.shape}")
        return xy, heading, layout


OWN = (f"{__name__}.World", "rovermarl.env.World")          # env._target_ of rovermarl's own world


def world_class(target: str | None, trust: bool | Collection[str] = False) -> type[World]:
    """The class ``env._target_`` names: :class:`World` for None or its own path (:data:`OWN`); a plug-in's only
    with ``trust``: True (any), or a collection of the exact names allowed (those the current command line named).
    The name is checked as a string before anything is imported (importing a module runs its code, and ``python -m``
    puts the working directory, results and all, on ``sys.path``)."""
    if target is None or (isinstance(target, str) and target in OWN):
        return World
    if not isinstance(target, str):
        raise errors.ConfigError("env._target_", target, "must be a dotted class name (a string)")
    if not (trust is True or (trust and not isinstance(trust, (bool, str)) and target in trust)):
        raise errors.ConfigError("env._target_", target, "a world plug-in; a results directory may not run code: "
                                 "pass --trust-config if you trust it")
    try:
        cls = pkgutil.resolve_name(target)
    except Exception as e:                              # its own error, in one line (a plug-in refused when made)
        where = "; run from its module's folder or put that on PYTHONPATH" * (isinstance(e, ModuleNotFoundError)
                                                                              and target.startswith(f"{e.name}."))
        raise errors.ConfigError("env._target_", target, f"cannot be imported ({type(e).__name__}: "
                                 f"{' '.join(str(e).split())}){where}") from None
    if not (isinstance(cls, type) and issubclass(cls, World)):
        raise errors.ConfigError("env._target_", target, "must name a subclass of rovermarl.worlds.World")
    return no_dataclass(cls)
