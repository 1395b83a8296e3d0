"""Behaviour figures of one run (the paper's Fig. 6, from a sweep's recordings): the team's trajectories before and
after an accepted update, and how many rovers observe each POI over the generations."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from matplotlib.figure import Figure

from rovermarl.analysis.draw import line, new_figure, poi_handles, rover_handles, scene
from rovermarl.analysis.sweep import Job, RunCurve
from rovermarl.env import World
from rovermarl.palette import OCCUPANCY_CMAP
from rovermarl.record.safe_read import load_npz

UPDATE_EPISODES = 4


def pick_run(jobs: Sequence[Job], filename: str) -> tuple[Job, RunCurve] | None:
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


def fig_update(job: Job, run: RunCurve, world: World, at: int | None = None,
               n_episodes: int = UPDATE_EPISODES) -> tuple[Figure, dict] | None:
    """Fig. 6 bottom: the team's trajectories before (top row) and after (bottom row) one accepted update, in the
    ``n_episodes`` episodes whose final positions moved most. None if the run has no such update."""
    b = load_npz(run.path / "behaviour.npz", job.size.behaviour(), ("generation", "score", "xy"), stored=True)
    generation, score, xy = b["generation"], b["score"], b["xy"]
    i = pick_update(generation, score, at)
    if i is None:
        return None
    moved = np.linalg.norm(xy[i, :, -1] - xy[i - 1, :, -1], axis=-1).sum(axis=-1)
    episodes = np.sort(np.argsort(-moved, kind="stable")[: min(n_episodes, xy.shape[1])])
    lim = max(world.poi_distance + world.obs_radius, float(np.abs(xy[[i - 1, i]][:, episodes]).max())) + 0.5
    fig = new_figure(2.6 * len(episodes) + 0.4, 5.9)
    axes = fig.subplots(2, len(episodes), squeeze=False)
    for row, c in enumerate((i - 1, i)):
        returns = world.episode_return(np.asarray(xy[c, episodes], dtype=np.float64))   # in the run's reading
        for ax, e, ret in zip(axes[row], episodes, returns, strict=True):
            scene(ax, world, xy[c, e][None], lim, lw=1, ms=3)
            ax.set_title(f"episode {e}: return {ret:g}", fontsize=8)
        axes[row, 0].set_ylabel(f"{'before' if row == 0 else 'after'}: gen {generation[c]}\nscore {score[c]:.4g}")
    handles = poi_handles(world) + rover_handles(xy.shape[3])
    fig.legend(handles=handles, loc="outside lower center", ncol=len(handles), fontsize=8)
    fig.suptitle(f"{job.label}, {run.path.name}: update at generation {generation[i]}")
    info = {"methods": [job.label], "run": str(run.path), "episodes": episodes.tolist(),
            "generations": [int(generation[i - 1]), int(generation[i])],
            "scores": [float(score[i - 1]), float(score[i])]}
    return fig, info


def fig_occupancy(job: Job, run: RunCurve, world: World) -> tuple[Figure, dict]:
    """Fig. 6 top: the run's score, the mean number of rovers observing each POI at the end of an episode, and
    the fraction of episodes in which each POI is satisfied (enough rovers), over generations."""
    occ = load_npz(run.path / "occupancy.npz", job.size.occupancy(), ("generation", "count"), stored=True)
    generation, count = occ["generation"], occ["count"].astype(np.float64)
    last = max(len(run.score) - 1, int(generation[-1])) + 1
    edges = np.append(generation, last)
    poi_edges = np.arange(count.shape[2] + 1) - 0.5
    satisfied = (count >= np.asarray(world.coupling)).mean(axis=1)
    fig = new_figure(8.5, 7.5)
    axes = fig.subplots(3, 1, sharex=True, height_ratios=[1, 1.3, 1.3])
    line(axes[0], run.score, color="k", lw=1)
    axes[0].set(ylabel="score", title=f"{job.label}, {run.path.name}")
    for ax, image, what in ((axes[1], count.mean(axis=1), "mean rovers observing"),
                            (axes[2], satisfied, "fraction of episodes satisfied")):
        mesh = ax.pcolormesh(edges, poi_edges, image.T, vmin=0, vmax=max(1.0, image.max()), cmap=OCCUPANCY_CMAP)
        fig.colorbar(mesh, ax=ax, label=what)
        ax.set(ylabel="POI (coupling)", yticks=range(count.shape[2]))
        ax.set_yticklabels([f"{j} ({c})" for j, c in enumerate(world.coupling)], fontsize=7)
    axes[2].set(xlabel="generation", xlim=(0, last))
    return fig, {"methods": [job.label], "run": str(run.path), "entries": len(generation)}
