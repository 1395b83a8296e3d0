"""Paper-style figures (Figs. 4-8) from a finished or partly finished sweep.

A sweep dir holds job dirs, each with ``summary.json``, ``.hydra/`` and ``runs/seed_XXX/curve.npz`` (plus, when
recorded, ``behaviour.npz`` and ``occupancy.npz``). :func:`plot_sweep` writes into ``figures/``:

- ``curves_<setup>``: top, the median score of every method; bottom, every run's curve, one panel per method, with
  dotted lines where 1/4, 1/2 and 3/4 of the runs first reach the threshold (Figs. 4, 5, 8); strict jobs with a
  soft counterpart are left to ``soft_vs_strict``;
- ``soft_vs_strict_<setup>``: medians with soft (solid) and strict (dashed) selection; strict runs below (Fig. 7);
- ``bandit_<setup>``: the bandit's mean probability of each k over generations, one panel per adaptive job;
- ``update_<setup>``: one run's trajectories before and after an accepted update that raised the score (Fig. 6);
- ``occupancy_<setup>``: that run's score and how many rovers observe each POI over generations (Fig. 6);
- ``index.json``: every figure with its files, methods and panel count, the jobs read and the notes.

Figures are bare :class:`~matplotlib.figure.Figure` objects on the Agg canvas (no pyplot state), written atomically.
Medians and thresholds use the full curves; lines are drawn with at most :data:`MAX_POINTS` points.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Circle, Patch
from omegaconf import OmegaConf

from rovermarl.record.outputs import atomic_open, first_reaching, write_json

DEFAULT_THRESHOLDS = {"solo": 4.0, "duo": 5.0, "trio": 5.0}
QUARTILES = (0.25, 0.5, 0.75)
MAX_POINTS = 2000
FORMATS = ("png", "pdf")
UPDATE_EPISODES = 4
_NOT_METHOD = ("parallel", "ray", "hydra", "setup", "record", "checkpoint", "resume")  # never tell methods apart
_SETUP_ORDER = {"solo": 0, "duo": 1, "trio": 2}  # the paper's Setup 1 and 2 first
_POI_COLOUR = {1: "tab:olive", 2: "tab:purple"}


class PlotError(Exception):
    """Input that cannot be plotted; ``str(err)`` is one line."""


# ---- reading a sweep ---------------------------------------------------------------------------------------------
@dataclass
class Run:
    path: Path
    seed: int
    score: np.ndarray  # (G+1,) parent score after each generation
    probs: np.ndarray | None  # (G, K) bandit arm probabilities, None for fixed k
    probs_x: np.ndarray | None = None  # generations of the rows of probs (exported results), None: 0..G-1

    def has(self, name: str) -> bool:
        return (self.path / name).is_file()


@dataclass
class Job:
    path: Path
    choices: dict  # config group -> option name
    config: dict  # composed config (plain, unresolved)
    overrides: list[str]  # command-line overrides, quotes removed
    runs: list[Run]
    finished: bool  # summary.json present

    @property
    def name(self) -> str:
        return self.path.name

    @property
    def setup(self) -> str:
        return str(self.choices.get("setup") or (self.config.get("setup") or {}).get("name") or "default")

    @property
    def strict(self) -> bool:
        selection = self.config.get("selection") or {}
        return bool(selection.get("strict", self.choices.get("selection") == "strict"))

    @property
    def bandit(self) -> bool:
        return any(r.probs is not None for r in self.runs)

    @property
    def homogeneous(self) -> bool:
        target = str((self.config.get("team") or {}).get("_target_", ""))
        return self.choices.get("team") == "homogeneous" or target.endswith("HomogeneousTeam")

    @property
    def k_name(self) -> str:
        """``k=2`` for a fixed k, else the k option name (``adaptive``)."""
        option = self.choices.get("k")
        k_cfg = self.config.get("k") or {}
        if option is None:
            option = k_cfg.get("value") if "value" in k_cfg else str(k_cfg.get("_target_", "k")).rsplit(".")[-1]
        return f"k={option}" if re.fullmatch(r"\d+", str(option)) else str(option)

    @property
    def base_label(self) -> str:
        return "homogeneous" if self.homogeneous else self.k_name

    @property
    def label(self) -> str:
        """The method on its own: ``base_label``, plus `` strict`` for strict selection."""
        return self.base_label + (" strict" if self.strict else "")

    def sort_key(self) -> tuple:
        k = self.k_name
        kind = 1 if self.homogeneous else 0 if k.startswith("k=") else 2
        value = int(k[2:]) if kind == 0 else 0
        return _SETUP_ORDER.get(self.setup, 2), self.setup, kind, value, k, self.strict, self.name

    def keyed_overrides(self) -> set[str]:
        """``key=value`` items that may tell this job from another of the same setup."""
        items = set(self.overrides) | {f"{g}={o}" for g, o in self.choices.items()}
        return {i for i in items if i.split("=", 1)[0].split(".")[0].lstrip("+~") not in _NOT_METHOD}

    def arms(self, n_arms: int) -> list[int]:
        k_cfg, env = self.config.get("k") or {}, self.config.get("env") or {}
        arms = k_cfg.get("arms") or list(range(1, int(env.get("n_rovers", n_arms)) + 1))
        return [int(a) for a in arms] if len(arms) == n_arms else list(range(1, n_arms + 1))

    def world(self):
        """The job's :class:`~rovermarl.env.World` from its config, or None if it cannot be built."""
        from rovermarl.env import World, make_world
        for build in (lambda: World.from_config(OmegaConf.create(self.config)), lambda: make_world(self.setup)):
            try:
                return build()
            except Exception:  # an odd config only costs the trajectory figures
                pass
        return None


def _read_yaml(path: Path):
    try:
        return OmegaConf.to_container(OmegaConf.load(path), resolve=False) if path.is_file() else None
    except Exception:  # a broken yaml is treated as missing
        return None


def _read_json(path: Path) -> dict | None:
    try:
        return json.loads(path.read_text()) if path.is_file() else None
    except (OSError, ValueError):
        return None


def load_run(run_dir: Path) -> Run:
    with np.load(run_dir / "curve.npz") as curve:
        score = np.asarray(curve["score"], dtype=np.float64)
        probs = np.asarray(curve["probs"], dtype=np.float64) if "probs" in curve.files else None
    match = re.search(r"(\d+)$", run_dir.name)
    return Run(run_dir, int(match[1]) if match else -1, score, probs)


def _exported_runs(path: Path) -> list[Run]:
    """The runs of an exported job dir (see :mod:`rovermarl.analysis.results`): exact curves, probs on the grid."""
    from rovermarl.analysis.results import Curves
    with np.load(path / "curves.npz") as z:
        curves = Curves(z["seed"], int(z["generations"]), z["step_run"], z["step_generation"], z["step_score"])
        probs, grid = (z["probs"], z["grid"]) if "probs" in z.files else (None, None)
    return [Run(path, int(seed), curves.full(i), None if probs is None else probs[i].astype(np.float64), grid)
            for i, seed in enumerate(curves.seeds)]


def load_job(path: Path, notes: list[str]) -> Job | None:
    """Read one job dir (finished or not, or exported); None, with a note, if it has no readable run."""
    summary = _read_json(path / "summary.json")
    if (path / "curves.npz").is_file():
        return Job(path, dict(summary.get("choices") or {}), _read_yaml(path / "config.yaml") or {}, [],
                   _exported_runs(path), True)
    hydra_dir = path / ".hydra"
    choices = dict((summary or {}).get("choices") or {})
    if not choices:
        runtime = ((_read_yaml(hydra_dir / "hydra.yaml") or {}).get("hydra") or {}).get("runtime") or {}
        choices = {g: o for g, o in (runtime.get("choices") or {}).items() if "/" not in g and o is not None}
    overrides = [str(o).replace("'", "").replace('"', "") for o in _read_yaml(hydra_dir / "overrides.yaml") or []]
    runs = []
    for run_dir in sorted((path / "runs").glob("seed_*")):
        if not (run_dir / "curve.npz").is_file():
            continue
        try:
            runs.append(load_run(run_dir))
        except Exception as e:  # a half-written or corrupt file skips that run only
            notes.append(f"{run_dir}: unreadable curve.npz ({type(e).__name__}); run skipped")
    if not runs:
        notes.append(f"{path.name}: no finished run yet; job skipped")
        return None
    config = _read_yaml(hydra_dir / "config.yaml") or _read_yaml(path / "config.yaml") or {}  # CLI, or library use
    job = Job(path, choices, config, overrides, runs, summary is not None)
    expected = len((summary or {}).get("seeds") or []) or job.config.get("seeds")
    if not job.finished or (expected and len(runs) < expected):
        state = "finished" if job.finished else "unfinished"
        notes.append(f"{path.name}: {state}; plotting the {len(runs)} of {expected or '?'} runs present")
    return job


def find_jobs(path: Path) -> tuple[list[Job], list[str]]:
    """All job dirs under ``path`` (a sweep dir or one job dir), sorted by setup then method; plus notes."""
    path = Path(path)
    if not path.exists():
        raise PlotError(f"no such directory: {path}")
    if not path.is_dir():
        raise PlotError(f"not a directory: {path}")
    if not any(path.iterdir()):
        raise PlotError(f"empty directory: {path}")
    dirs = {p.parent for p in path.rglob("summary.json")}
    dirs |= {p.parent.parent.parent for p in path.rglob("runs/seed_*/curve.npz")}
    if not dirs:
        raise PlotError(f"no job under {path} (no summary.json, runs/seed_*/curve.npz or exported curves.npz)")
    notes: list[str] = []
    jobs = [job for d in sorted(dirs) if (job := load_job(d, notes)) is not None]
    if not jobs:
        raise PlotError(f"no readable run under {path} ({len(dirs)} job dirs, none with a runs/seed_*/curve.npz)")
    return sorted(jobs, key=Job.sort_key), notes


def labels(jobs: Sequence[Job]) -> list[str]:
    """Unique method labels: ``k=1``, ``homogeneous``, ``adaptive``; `` strict`` when soft and strict are mixed,
    then the distinguishing overrides (or the job dir) when two jobs would still share a label."""
    mixed = len({j.strict for j in jobs}) > 1
    out = [j.base_label + (" strict" if mixed and j.strict else "") for j in jobs]
    for label in set(out):
        same = [i for i, lab in enumerate(out) if lab == label]
        if len(same) > 1:
            keyed = [jobs[i].keyed_overrides() for i in same]
            common = set.intersection(*keyed)
            for i, items in zip(same, keyed, strict=True):
                extra = sorted(items - common - {f"selection={'strict' if jobs[i].strict else 'soft'}"})
                out[i] = f"{label} ({', '.join(extra)})" if extra else label
    if len(set(out)) < len(out):
        out = [f"{lab} [{j.name}]" if out.count(lab) > 1 else lab for lab, j in zip(out, jobs, strict=True)]
    return out


def soft_strict_pairs(jobs: Sequence[Job]) -> list[tuple[Job, Job]]:
    """(soft, strict) jobs that differ only in selection."""
    def key(job: Job) -> frozenset:
        return frozenset(i for i in job.keyed_overrides() if not i.startswith("selection"))
    soft = {key(j): j for j in jobs if not j.strict}
    return [(soft[key(j)], j) for j in jobs if j.strict and key(j) in soft]


# ---- curves ------------------------------------------------------------------------------------------------------
def downsample(y: np.ndarray, max_points: int = MAX_POINTS) -> tuple[np.ndarray, np.ndarray]:
    """(x, y[x]) with at most ``max_points`` points: exact for step curves with few steps, else evenly spaced."""
    y = np.asarray(y)
    n = len(y)
    if n <= max_points:
        return np.arange(n), y
    steps = np.flatnonzero(np.diff(y) != 0)
    if 2 * steps.size + 2 <= max_points:
        x = np.unique(np.concatenate([[0, n - 1], steps, steps + 1]))
    else:
        x = np.unique(np.linspace(0, n - 1, max_points).round().astype(np.int64))
    return x, y[x]


def median_curve(scores: Sequence[np.ndarray]) -> np.ndarray:
    """Median over runs at each generation; runs shorter than the longest count only where they exist."""
    stack = np.full((len(scores), max(len(s) for s in scores)), np.nan)
    for row, s in zip(stack, scores, strict=True):
        row[: len(s)] = s
    return np.nanmedian(stack, axis=0)


def quartile_generations(scores: Sequence[np.ndarray], level: float,
                         quartiles: Iterable[float] = QUARTILES) -> list[int | None]:
    """For each q, the generation at which ``ceil(q * n)`` of the ``n`` runs have reached ``level`` (None: never)."""
    first = sorted(g for s in scores if (g := first_reaching(s, level)) is not None)
    out = []
    for q in quartiles:
        m = max(1, math.ceil(q * len(scores) - 1e-9))
        out.append(first[m - 1] if m <= len(first) else None)
    return out


def _plot(ax, y, x=None, **kw):
    """Plot y (G,) against 0..G-1 (downsampled), or against the given x (M,) as is."""
    if x is None:
        x, y = downsample(y)
    ax.plot(x, y, **kw)


def _new_figure(width: float, height: float) -> Figure:
    fig = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _panels(n: int, top_height: float = 1.4, max_cols: int = 4) -> tuple[Figure, object, list]:
    """A figure with a wide top axis and ``n`` panels below it (rows of at most ``max_cols``, shared y)."""
    cols = max(1, min(n, max_cols))
    rows = math.ceil(n / cols)
    fig = _new_figure(3.2 * cols + 0.6, 2.9 * top_height + 2.5 * rows)
    grid = fig.add_gridspec(1 + rows, cols, height_ratios=[top_height] + [1] * rows)
    top = fig.add_subplot(grid[0, :])
    bottom: list = []
    for i in range(n):
        bottom.append(fig.add_subplot(grid[1 + i // cols, i % cols], sharey=bottom[0] if bottom else None))
    return fig, top, bottom


def _runs_panel(ax, job: Job, label: str, colour: str, threshold: float | None) -> list[int | None]:
    """Every run's curve of ``job``; dotted lines (thin, bold, thin) at the quartile generations."""
    scores = [r.score for r in job.runs]
    for s in scores:
        _plot(ax, s, color=colour, lw=0.7, alpha=0.6)
    ax.set_title(f"{label}: {len(scores)} runs" + ("" if job.finished else " (unfinished)"), fontsize=9)
    ax.set_xlabel("generation")
    if threshold is None:
        return []
    quart = quartile_generations(scores, threshold)
    for g, lw in zip(quart, (0.8, 2.0, 0.8), strict=True):
        if g is not None:
            ax.axvline(g, color="k", ls=":", lw=lw)
    ax.axhline(threshold, color="0.5", lw=0.5, ls="--")
    return quart


def _top(ax, title: str) -> None:
    ax.set(title=title, xlabel="generation", ylabel="median score")
    ax.legend(fontsize=8, loc="lower right")


def fig_curves(setup: str, jobs: Sequence[Job], threshold: float | None) -> tuple[Figure, dict]:
    """Figs. 4/5/8: medians on top (fixed-k methods faded when a bandit is present), runs below."""
    labs = labels(jobs)
    fig, top, bottom = _panels(len(jobs))
    fade = any(j.bandit for j in jobs)
    quart = {}
    for i, (job, lab, ax) in enumerate(zip(jobs, labs, bottom, strict=True)):
        colour = f"C{i % 10}"
        _plot(top, median_curve([r.score for r in job.runs]), color=colour, label=lab,
              alpha=1.0 if job.bandit or not fade else 0.35, lw=1.5)
        quart[lab] = _runs_panel(ax, job, lab, colour, threshold)
    bottom[0].set_ylabel("score")
    note = f"; dotted: 1/4, 1/2, 3/4 of runs reach {threshold:g}" if threshold is not None else ""
    _top(top, f"{setup}: median score{note}")
    return fig, {"methods": labs, "threshold": threshold, "quartile_generations": quart}


def fig_soft_vs_strict(setup: str, pairs: Sequence[tuple[Job, Job]], threshold: float | None) -> tuple[Figure, dict]:
    """Fig. 7: soft (solid) and strict (dashed) medians on top; the strict runs below, one panel per method."""
    fig, top, bottom = _panels(len(pairs))
    methods = labels([job for pair in pairs for job in pair])
    quart = {}
    for i, ((soft, strict), ax) in enumerate(zip(pairs, bottom, strict=True)):
        colour = f"C{i % 10}"
        for job, name, ls in ((soft, methods[2 * i], "-"), (strict, methods[2 * i + 1], "--")):
            _plot(top, median_curve([r.score for r in job.runs]), color=colour, ls=ls, label=name, lw=1.5)
        quart[methods[2 * i + 1]] = _runs_panel(ax, strict, methods[2 * i + 1], colour, threshold)
    bottom[0].set_ylabel("score")
    _top(top, f"{setup}: soft (solid) vs strict (dashed) selection")
    return fig, {"methods": methods, "threshold": threshold, "quartile_generations": quart}


def fig_bandit(setup: str, jobs: Sequence[Job]) -> tuple[Figure, dict]:
    """The bandit's probability of each k over generations (mean over seeds), one panel per adaptive job."""
    fig = _new_figure(3.6 * len(jobs) + 0.6, 3.4)
    axes = fig.subplots(1, len(jobs), squeeze=False, sharey=True)[0]
    labs = labels(jobs)
    for job, lab, ax in zip(jobs, labs, axes, strict=True):
        probs = [r.probs for r in job.runs if r.probs is not None]
        length = min(len(p) for p in probs)
        mean = np.mean([p[:length] for p in probs], axis=0)
        x = job.runs[0].probs_x
        for a, arm in enumerate(job.arms(mean.shape[1])):
            _plot(ax, mean[:, a], x=None if x is None else x[:length], color=f"C{a % 10}", label=f"k={arm}")
        ax.set(title=f"{lab}: mean over {len(probs)} runs", xlabel="generation", ylim=(0, 1))
        ax.legend(fontsize=8, loc="upper right")
    axes[0].set_ylabel("probability of choosing k")
    fig.suptitle(f"{setup}: bandit arm probabilities")
    return fig, {"methods": labs}


# ---- behaviour: trajectories and POI occupancy ----------------------------------------------------------------
def pick_run(jobs: Sequence[Job], filename: str) -> tuple[Job, Run] | None:
    """The run with the best final score among those that recorded ``filename`` (first job wins ties)."""
    found = [(j, r) for j in jobs for r in j.runs if r.has(filename)]
    return max(found, key=lambda jr: jr[1].score[-1]) if found else None


def pick_update(generation: np.ndarray, score: np.ndarray, at: int | None = None) -> int | None:
    """Index ``i`` of the behaviour entry shown 'after' (``i - 1`` is 'before'): the entry at generation ``at``,
    or by default the last whose score rose (the update that made the final team). None if there is none."""
    if at is not None:
        hit = np.flatnonzero(generation == at)
        return int(hit[0]) if hit.size and hit[0] > 0 else None
    rose = np.flatnonzero(np.diff(score) > 0)
    return int(rose[-1]) + 1 if rose.size else None


def _scene(ax, world, xy: np.ndarray, lim: float) -> None:
    """POIs (circles of the observation radius, coloured by coupling) and rover trajectories xy (T+1, N, 2)."""
    for (px, py), c in zip(world.poi_xy, world.coupling, strict=True):
        colour = _POI_COLOUR.get(c, "tab:brown")
        ax.add_patch(Circle((px, py), world.obs_radius, fc=colour, ec=colour, alpha=0.3))
    for i in range(xy.shape[1]):
        ax.plot(xy[:, i, 0], xy[:, i, 1], color=f"C{i % 10}", lw=1)
        ax.plot(xy[-1, i, 0], xy[-1, i, 1], "o", color=f"C{i % 10}", ms=3)
    ax.set(xlim=(-lim, lim), ylim=(-lim, lim), aspect="equal", xticks=[], yticks=[])


def fig_update(job: Job, run: Run, world, at: int | None = None,
               n_episodes: int = UPDATE_EPISODES) -> tuple[Figure, dict] | None:
    """Fig. 6 bottom: the team's trajectories before (top row) and after (bottom row) one accepted update, in the
    ``n_episodes`` episodes whose final positions moved most. None if the run has no such update."""
    with np.load(run.path / "behaviour.npz") as b:
        generation, score, xy = b["generation"], b["score"], b["xy"]
    i = pick_update(generation, score, at)
    if i is None:
        return None
    moved = np.linalg.norm(xy[i, :, -1] - xy[i - 1, :, -1], axis=-1).sum(axis=-1)
    episodes = np.sort(np.argsort(-moved, kind="stable")[: min(n_episodes, xy.shape[1])])
    lim = max(world.poi_distance + world.obs_radius, float(np.abs(xy[[i - 1, i]][:, episodes]).max())) + 0.5
    fig = _new_figure(2.6 * len(episodes) + 0.4, 5.9)
    axes = fig.subplots(2, len(episodes), squeeze=False)
    for row, c in enumerate((i - 1, i)):
        returns = world.team_return(np.asarray(xy[c, episodes, -1], dtype=np.float64))
        for ax, e, ret in zip(axes[row], episodes, returns, strict=True):
            _scene(ax, world, xy[c, e], lim)
            ax.set_title(f"episode {e}: return {ret:g}", fontsize=8)
        axes[row, 0].set_ylabel(f"{'before' if row == 0 else 'after'}: gen {generation[c]}\nscore {score[c]:.4g}")
    handles = [Patch(color=col, alpha=0.3, label=f"POI c={c}") for c, col in _POI_COLOUR.items()
               if c in world.coupling] + [Line2D([], [], color=f"C{r}", label=f"rover {r}")
                                           for r in range(xy.shape[3])]
    fig.legend(handles=handles, loc="outside lower center", ncol=len(handles), fontsize=8)
    fig.suptitle(f"{job.label}, {run.path.name}: update at generation {generation[i]}")
    info = {"methods": [job.label], "run": str(run.path), "episodes": episodes.tolist(),
            "generations": [int(generation[i - 1]), int(generation[i])],
            "scores": [float(score[i - 1]), float(score[i])]}
    return fig, info


def fig_occupancy(job: Job, run: Run, world) -> tuple[Figure, dict]:
    """Fig. 6 top: the run's score, the mean number of rovers observing each POI at the end of an episode, and
    the fraction of episodes in which each POI is satisfied (enough rovers), over generations."""
    with np.load(run.path / "occupancy.npz") as occ:
        generation, count = occ["generation"], occ["count"].astype(np.float64)
    last = max(len(run.score) - 1, int(generation[-1])) + 1
    edges = np.append(generation, last)
    poi_edges = np.arange(count.shape[2] + 1) - 0.5
    satisfied = (count >= np.asarray(world.coupling)).mean(axis=1)
    fig = _new_figure(8.5, 7.5)
    axes = fig.subplots(3, 1, sharex=True, height_ratios=[1, 1.3, 1.3])
    _plot(axes[0], run.score, color="k", lw=1)
    axes[0].set(ylabel="score", title=f"{job.label}, {run.path.name}")
    for ax, image, what in ((axes[1], count.mean(axis=1), "mean rovers observing"),
                            (axes[2], satisfied, "fraction of episodes satisfied")):
        mesh = ax.pcolormesh(edges, poi_edges, image.T, vmin=0, vmax=max(1.0, image.max()), cmap="viridis")
        fig.colorbar(mesh, ax=ax, label=what)
        ax.set(ylabel="POI (coupling)", yticks=range(count.shape[2]))
        ax.set_yticklabels([f"{j} ({c})" for j, c in enumerate(world.coupling)], fontsize=7)
    axes[2].set(xlabel="generation", xlim=(0, last))
    return fig, {"methods": [job.label], "run": str(run.path), "entries": len(generation)}


# ---- the whole sweep ---------------------------------------------------------------------------------------------
def save(fig: Figure, out: Path, name: str, formats: Sequence[str]) -> list[str]:
    """Write ``fig`` as ``out/name.<fmt>`` for each format, atomically; returns the file names."""
    files = []
    for fmt in formats:
        with atomic_open(Path(out) / f"{name}.{fmt}", "wb") as f:
            fig.savefig(f, format=fmt, dpi=150)
        files.append(f"{name}.{fmt}")
    return files


def threshold_for(setup: str, thresholds: dict[str, float] | None) -> float | None:
    """A setup's threshold: its own from ``thresholds``, else ``thresholds['*']``, else the default, else None."""
    thresholds = thresholds or {}
    return thresholds.get(setup, thresholds.get("*", DEFAULT_THRESHOLDS.get(setup)))


def _load_update_run(path: Path, update_gen: int | None, notes: list[str]) -> tuple[Job, Run]:
    """The job and run of ``--update-run``, checked (with ``--update-gen``) before anything is drawn."""
    path = Path(path)
    if not (path / "curve.npz").is_file():
        raise PlotError(f"--update-run {path}: not a run dir (no curve.npz)")
    if not (path / "behaviour.npz").is_file():
        raise PlotError(f"--update-run {path}: no behaviour.npz (this run recorded no trajectories)")
    try:
        with np.load(path / "behaviour.npz") as b:
            generation, score = b["generation"], b["score"]
    except Exception as e:
        raise PlotError(f"--update-run {path}: unreadable behaviour.npz ({type(e).__name__})") from None
    if update_gen is not None and pick_update(generation, score, update_gen) is None:
        shown = ", ".join(map(str, generation[1:11])) + (", ..." if len(generation) > 11 else "")
        raise PlotError(f"--update-gen {update_gen}: not a logged behaviour generation of {path} "
                        f"(logged after the first: {shown or 'none'})")
    job = load_job(path.parent.parent, notes)
    run = next((r for r in job.runs if r.path.resolve() == path.resolve()), None) if job else None
    if run is None:
        raise PlotError(f"--update-run {path}: unreadable run")
    return job, run


def _behaviour_figures(setup: str, group: Sequence[Job], chosen: tuple[Job, Run] | None, update_gen: int | None,
                       notes: list[str]) -> list[tuple[str, tuple[Figure, dict]]]:
    """The update and occupancy figures of one setup: from the chosen run, else from the best run that recorded
    the data; a note instead of a figure when there is none."""
    out = []
    for kind, filename in (("update", "behaviour.npz"), ("occupancy", "occupancy.npz")):
        own = chosen is not None and chosen[0].setup == setup and chosen[1].has(filename)
        picked = chosen if own else pick_run(group, filename)
        world = picked[0].world() if picked else None
        if picked is None or world is None:
            why = "no run recorded" if picked is None else "cannot build the world of"
            notes.append(f"{setup}: {why} {filename}; no {kind} figure")
            continue
        try:
            drawn = (fig_occupancy(*picked, world) if kind == "occupancy" else
                     fig_update(*picked, world, at=update_gen if own else None))
        except Exception as e:  # a corrupt or half-written file costs this figure only
            notes.append(f"{picked[1].path}: unreadable {filename} ({type(e).__name__}); no {kind} figure")
            continue
        if drawn is None and own and update_gen is not None:
            raise PlotError(f"--update-gen {update_gen}: not a logged behaviour generation (after the first) of "
                            f"{picked[1].path}")
        if drawn is None:
            notes.append(f"{setup}: the score never rose in {picked[1].path}; no update figure")
        else:
            out.append((kind, drawn))
    return out


def plot_sweep(path: Path, out: Path | None = None, thresholds: dict[str, float] | None = None,
               formats: Sequence[str] = FORMATS, update_run: Path | None = None, update_gen: int | None = None,
               log=None, xscale: str = "linear") -> dict:
    """Draw every figure of the sweep (or job) dir ``path`` into ``out`` (default ``path/figures``).

    ``path`` may also be a results dir of :mod:`rovermarl.analysis.results`; it adds the Fig. 6 and C8
    figures of :mod:`rovermarl.analysis.fig6`. ``xscale="log"`` puts generations on a log axis (0 included).

    Returns the index (also written as ``index.json``). Raises :class:`PlotError` on unusable input.
    """
    path = Path(path)
    jobs, notes = find_jobs(path)
    out = Path(out) if out is not None else path / "figures"
    chosen = _load_update_run(update_run, update_gen, notes) if update_run is not None else None
    figures: list[dict] = []

    def emit(kind: str, setup: str, drawn) -> None:
        if drawn is None:
            return
        fig, info = drawn
        name = kind + "_" + re.sub(r"[^\w.-]+", "_", setup)
        if xscale == "log":
            for ax in fig.axes:
                if ax.get_xlabel() == "generation" or ax.get_shared_x_axes().get_siblings(ax) != [ax]:
                    ax.set_xscale("symlog", linthresh=1)
                    ax.set_xlim(left=0)
        panels = sum(1 for ax in fig.axes if not hasattr(ax, "_colorbar"))
        figures.append({"name": name, "kind": kind, "setup": setup, "files": save(fig, out, name, formats),
                        "axes": len(fig.axes), "panels": panels, **info})

    for setup in dict.fromkeys(j.setup for j in jobs):
        group = [j for j in jobs if j.setup == setup]
        threshold = threshold_for(setup, thresholds)
        if threshold is None:
            notes.append(f"{setup}: no threshold (pass --threshold {setup}=VALUE); no quartile lines")
        pairs = soft_strict_pairs(group)
        paired = {id(strict) for _, strict in pairs}                   # drawn in soft_vs_strict instead
        emit("curves", setup, fig_curves(setup, [j for j in group if id(j) not in paired], threshold))
        if pairs:
            emit("soft_vs_strict", setup, fig_soft_vs_strict(setup, pairs, threshold))
        if bandits := [j for j in group if j.bandit]:
            emit("bandit", setup, fig_bandit(setup, bandits))
        for kind, drawn in _behaviour_figures(setup, group, chosen, update_gen, notes):
            emit(kind, setup, drawn)

    if (path / "fig6.npz").is_file():                                   # exported results: C8 figures
        from rovermarl.analysis.fig6 import fig_fig6, fig_switched
        from rovermarl.analysis.results import load
        emit("fig6", "duo", fig_fig6(path / "fig6.npz", "symlog" if xscale == "log" else "linear"))
        emit("switched", "k1", fig_switched(load(path)))

    if log is not None:
        for note in notes:
            log.info("note: %s", note)
    index = {"source": str(path), "formats": list(formats), "figures": figures, "notes": notes,
             "jobs": [{"dir": j.name, "setup": j.setup, "label": j.label,
                       "runs": len(j.runs), "finished": j.finished, "bandit": j.bandit} for j in jobs]}
    write_json(out / "index.json", index)
    return index
