"""What a world plug-in may override: :class:`Scenario`, the base of :class:`~rovermarl.env.World`.

The paper's world is the first scenario and overrides nothing. A plug-in is a subclass of ``World`` in a module of its
own plus a yaml in the ``env`` group whose ``_target_`` names it (``examples/obstacles``, ``examples/random_pois``;
``docs/ARCHITECTURE.md``, "Adding a world"). Its fields are its parameters (keys of its yaml); ``hooks`` names its
compiled hooks (:mod:`rovermarl.env.kernel.hooks`); each method below may be called alone, e.g.
``make_world("solo").obs_blocks()``.
"""

from __future__ import annotations

from typing import ClassVar, NamedTuple

import numpy as np

from rovermarl import errors
from rovermarl.env.kernel.checks import input_rows

PER = ("rover", "episode")


class State(NamedTuple):
    """One array of a world's per-episode state (``World.state``): ``per`` "rover" gives it shape (N*E, width) (row
    ``q = i*E + e``), "episode" (E, width); ``width`` an integer or the name of a World attribute (``"n_pois"``);
    ``dtype`` "float" (the kernel's precision, ``env.dtype``), "float64", "float32", "int64" or "bool"."""

    name: str
    per: str
    width: int | str = 1
    dtype: str = "float"


class Scenario:
    """The plug-in methods of a world, with the paper's world's behaviour. ``self`` is a
    :class:`~rovermarl.env.World` (its fields ``n_rovers``, ``poi_xy``, ``dtype``, ... are set)."""

    layout_dim = 0      # K: numbers per episode that draw_layout adds to the initial conditions
    fixed_pois = True   # the POIs are World.poi_xy in every episode: the occupancy and C8 measures read them
                        # (the behaviour observer leaves those measures out of a world that sets False)
    state: ClassVar[tuple[State, ...]] = ()   # the per-episode state the hooks read and write (none: the paper's)

    def check(self) -> None:
        """Check the plug-in's own fields (raise ``errors.ConfigError``: one line naming key, value and what is
        allowed); called before the kernel record is built."""

    def check_sense(self) -> None:
        """Run the hook ``sense`` once (seed 0's first start) and check that it fills exactly the rows that
        :meth:`obs_blocks` declares; else one line saying both."""
        p = self.prepare(self.initial_conditions(seed=0, n=1))
        extra = 8
        filled = self.compiled.sensed_rows(p.xy, p.heading, p.kernel, self.compiled.state_of(p.xy, p.kernel), extra)
        d = self.obs_dim
        if not filled[:d].all() or filled[d:].any():
            wrote = int(np.flatnonzero(filled).max(initial=-1)) + 1
            blocks = ", ".join(f"{name} {low.size}" for name, low, _ in self.obs_blocks())
            raise errors.ConfigError(f"{type(self).__name__}.sense", wrote, f"rows filled, but obs_blocks declares "
                                     f"{d} ({blocks}): sense must fill each of them and no more"
                                     + ("" if filled[d:].any() or not filled[:d].any() else
                                        f"; rows left unfilled: {np.flatnonzero(~filled[:d]).tolist()[:8]}"))

    def check_state(self) -> None:
        """A trial run of every hook on seed 0's first two starts (random actions, ``steps`` steps, in the order of
        the rollout) with guard cells beside and below every array of :attr:`state`, checked after each hook: a hook
        that writes outside its declared width ends in one line naming the state and the hook (and one that raises
        or does not compile fails here, when the world is built). 0.6-3 ms per build once compiled; its compile
        about a quarter of the rollout's (``docs/WORLDS.md``)."""
        p = self.prepare(self.initial_conditions(seed=0, n=2))
        n_ep, n = p.heading.shape
        f = p.xy.dtype
        x, y, heading = (np.ascontiguousarray(a.T.ravel()) for a in (p.xy[:, :, 0], p.xy[:, :, 1], p.heading))
        sin_h, cos_h = np.sin(heading), np.cos(heading)
        a0, a1 = np.random.default_rng(0).uniform(-1.0, 1.0, (2, n * n_ep)).astype(f)
        guarded = []                                     # (entry, width, buffer (rows + R, width + G), its view)
        for entry, width in zip(self.state, self.state_dims(), strict=True):
            rows = n * n_ep if entry.per == "rover" else n_ep
            dtype = f if entry.dtype == "float" else np.dtype(entry.dtype)
            buf = np.empty((2 * rows + 8, 2 * int(width) + 8), dtype=dtype)
            buf.view(np.uint8)[:] = 0xA5                 # a byte pattern no hook writes by chance
            buf[:rows, :width] = 0                       # the state itself: zeros, as fresh memory mostly is
            guarded.append((entry, int(width), buf, buf[:rows, :width]))
        s = tuple(view for _, _, _, view in guarded)
        obs, xy, returns = np.zeros(self.obs_dim * n * n_ep, dtype=f), np.empty((n_ep, n, 2)), np.empty(n_ep)
        acc = self.compiled.env_start(p.kernel, n_ep)

        def call(hook: int, name: str) -> bool:
            before = [buf.view(np.uint8).copy() for _, _, buf, _ in guarded]
            out = self.compiled.trial(hook, x, y, heading, sin_h, cos_h, a0, a1, n, p.kernel, s, obs, xy, acc,
                                      returns)
            for (entry, width, buf, view), old in zip(guarded, before, strict=True):
                changed = buf.view(np.uint8) != old
                changed[:view.shape[0], :width * buf.itemsize] = False           # inside the declared state
                if changed.any():
                    r, c = np.argwhere(changed)[0]
                    fn = getattr(self.hooks, name).py_func
                    raise errors.PluginError(
                        f"{type(self).__name__}'s hook {name} ({fn.__code__.co_filename}) writes outside its "
                        f"state {entry.name!r} ({entry.per}, width {width}, so (rows, {width})): at row {r}, column "
                        f"{c // buf.itemsize}; write only columns 0..{width - 1} of rows 0..{view.shape[0] - 1}, "
                        f"or declare it wider")
            return out

        call(0, "begin")
        each_step = call(4, "stepwise")
        for _ in range(self.steps):
            call(1, "sense")
            call(2, "move")
            call(3, "tick")
            if each_step:
                call(5, "score_step")
        xy[:] = np.stack([x.reshape(n, n_ep).T, y.reshape(n, n_ep).T], axis=-1)
        call(6, "score_end")

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

    def input_rows(self) -> np.ndarray:
        """(N, D) int64: each rover's observation rows that may be nonzero, increasing, then -1 (what the MLP reads,
        ``KernelWorld.rows``). From :meth:`obs_blocks`: of the paper's blocks (first, ``poi`` and ``rover``) those
        ``checks.input_rows`` keeps, then every row of the plug-in's own blocks. A plug-in whose ``sense`` fills the
        paper's rows otherwise overrides this (reading a row of zeros costs time, never a result).

        >>> from rovermarl.env import make_world
        >>> make_world("solo").input_rows()[0, :4].tolist()        # POI 0's type row (type 0) is left out
        [0, 1, 3, 4]
        """
        blocks = self.obs_blocks()
        n, d = self.n_rovers, sum(low.size for _, low, _ in blocks)
        paper = [("poi", 3 * self.n_pois), ("rover", 2 * self.n_rovers)]
        out = np.full((n, d), -1, dtype=np.int64)
        if [(name, low.size) for name, low, _ in blocks[:2]] != paper:
            out[:] = np.arange(d)
            return out
        base, k0 = input_rows(n, self._type), sum(size for _, size in paper)
        for i in range(n):
            mine = np.concatenate([base[i][base[i] >= 0], np.arange(k0, d)])
            out[i, :mine.size] = mine
        return out

    def state_dims(self) -> np.ndarray:
        """(S,) int64: the width of each array of :attr:`state`, checked (one line naming the entry)."""
        dims = []
        for k, entry in enumerate(self.state):
            where = f"{type(self).__name__}.state[{k}] ({getattr(entry, 'name', entry)!r})"
            if not isinstance(entry, State):
                raise errors.ConfigError(where, entry, "must be a rovermarl.env.State(name, per, width, dtype)")
            errors.choice(f"{where}.per", entry.per, PER)
            errors.choice(f"{where}.dtype", entry.dtype, ("float", "float64", "float32", "int64", "bool"))
            width = getattr(self, entry.width) if isinstance(entry.width, str) else entry.width
            dims.append(errors.integer(f"{where}.width", width, 0))
        return np.array(dims, dtype=np.int64)

    def poi_positions(self, layout: np.ndarray | None = None) -> np.ndarray:
        """(P, 2): the POIs of an episode whose layout is ``layout`` (K,); the paper's: fixed, ``poi_xy``."""
        return self.poi_xy

    def poi_track(self, layout: np.ndarray | None = None) -> np.ndarray | None:
        """(T+1, P, 2): where the POIs of an episode (``layout`` (K,)) are at each step, for a world whose POIs
        move (the recording draws them there); None: they stay at :meth:`poi_positions` (the paper's)."""
        return None

    def draw(self, ax, layout: np.ndarray | None = None) -> None:
        """Draw what the plug-in adds to the world (obstacles, ...) on matplotlib axes, for an episode's ``layout``."""

    def log_static(self, rec, layout: np.ndarray | None = None) -> None:
        """Log what the plug-in adds to the world into the Rerun recording stream ``rec`` (under ``world/``)."""
