"""Phenotypic coupling figures (claim C8), from exported results (:mod:`rovermarl.analysis.results`).

- ``fig6``: the paper's Fig. 6 for one duo k=1 run: its score; which POIs its rovers observe at the end of one
  episode over the generations (red: one rover, blue: two); the team's trajectories in every episode just
  before and after the single-rover updates that first lift the score past 4 (a duo POI observed in one more
  episode) and to 5 (see :data:`rovermarl.analysis.export.FIG6_LEVELS`).
- ``switched``: over runs, the share of episodes in which a rover that was not mutated ends at another POI, for
  accepted updates that raised the score, accepted ones that kept it, and rejected ones.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from rovermarl.analysis.draw import new_figure, rover_handles, scene
from rovermarl.analysis.results import COUPLING_KINDS, Result
from rovermarl.analysis.sweep import Job
from rovermarl.env import World
from rovermarl.palette import OCCUPANCY
from rovermarl.record.safe_read import ANY, Spec, load_npz

FIG6_BYTES = 64 << 20     # the arrays of a fig6.npz at most (a legitimate one holds well under 1 MB)

KIND_LABELS = dict(zip(COUPLING_KINDS, ("accepted,\nscore rose", "accepted,\nscore equal", "rejected"), strict=True))


def fig_fig6(path: Path, job: Job, world: World, xscale: str = "linear") -> tuple[Figure, dict]:
    """Fig. 6 from ``fig6.npz``, a run of ``job`` in ``world``; returns (figure, info)."""
    d = load_npz(path, {ANY: tuple(Spec((None,) * n, most=1 << 16) for n in range(7))}, max_bytes=FIG6_BYTES)
    if tuple(d["coupling"].tolist()) != world.coupling:
        raise ValueError(f"{path}: its POI couplings differ from the world of {job.name}")
    events = len(d["event_generation"])
    cols = max(2 * events, 4)
    fig = new_figure(2.6 * cols + 0.6, 9.5)
    grid = fig.add_gridspec(3, cols, height_ratios=[1, 1.1, 1.6])
    ax_score = fig.add_subplot(grid[0, :])
    ax_occ = fig.add_subplot(grid[1, :], sharex=ax_score)
    last = int(d["generations"])
    g, v = d["step_generation"], d["step_score"]
    ax_score.step(np.append(g, last), np.append(v, v[-1]), where="post", color="k", lw=1.2)
    ax_score.set(ylabel="score", title=f"{job.setup}, {job.label}, seed {int(d['seed'])}: score, and the POIs observed "
                                       f"at the end of episode {int(d['episode'])}")
    # occupancy of one episode: a bar per POI, coloured by how many rovers observe it
    gens = np.append(d["occupancy_generation"], last)
    occ = d["occupancy"]                                                  # (M, P)
    for j in range(occ.shape[1]):
        shown = [(occ[:, j] == n, colour) for n, colour in OCCUPANCY.items()] + [(occ[:, j] > max(OCCUPANCY), "k")]
        for on, colour in shown:
            spans = [(gens[i], gens[i + 1] - gens[i]) for i in np.flatnonzero(on)]
            ax_occ.broken_barh(spans, (j - 0.4, 0.8), color=colour)
    ax_occ.set(ylabel="POI (coupling)", xlabel="generation", yticks=range(occ.shape[1]),
               ylim=(-0.6, occ.shape[1] - 0.4))
    ax_occ.set_yticklabels([f"{j} ({c})" for j, c in enumerate(d["coupling"])], fontsize=7)
    ax_occ.legend(handles=[Line2D([], [], color=c, lw=6, label=f"{n} rover{'s' * (n > 1)}")
                           for n, c in OCCUPANCY.items()], fontsize=8, loc="upper left")
    for ax in (ax_score, ax_occ):
        ax.set_xscale(xscale, **({"linthresh": 1} if xscale == "symlog" else {}))
        ax.set_xlim(0, last)
        for (_, after), name in zip(d["event_generation"], "ab", strict=False):
            ax.axvline(after, color="0.4", ls=":", lw=1)
            if ax is ax_score:
                ax.annotate(f"({name})", (after, v.max()), fontsize=9, ha="right", va="top")
    # trajectories before and after each event, all episodes overlaid
    xy = d["event_xy"]                                                    # (events, 2, E, T+1, N, 2)
    lim = world.poi_distance + world.obs_radius + 1.0
    for ev in range(events):
        for side in range(2):
            ax = fig.add_subplot(grid[2, 2 * ev + side])
            scene(ax, world, xy[ev, side], lim, lw=0.6, ms=1.5, alpha=0.6)
            mutated = int(d["event_mutated"][ev])
            what = "before" if side == 0 else f"after rover {mutated}'s update" if mutated >= 0 else "after"
            ax.set_title(f"({'ab'[ev]}) {what}\ngen {int(d['event_generation'][ev, side])}, "
                         f"score {float(d['event_score'][ev, side]):.4g}", fontsize=8)
    fig.legend(handles=rover_handles(xy.shape[4]), loc="outside lower center", ncol=xy.shape[4], fontsize=8)
    info = {"methods": [job.label], "seed": int(d["seed"]), "episode": int(d["episode"]),
            "events": d["event_generation"].tolist(), "mutated_rover": d["event_mutated"].tolist()}
    return fig, info


def fig_switched(results: Sequence[Result]) -> tuple[Figure, dict] | None:
    """Box plots over runs of the C8 share per update kind, one panel per k=1 job; None without coupling data."""
    jobs = [r for r in results if r.summary.get("coupling") and r.label.startswith("k=1")]
    if not jobs:
        return None
    jobs.sort(key=lambda r: (r.setup != "solo", r.label))
    fig = new_figure(3.3 * len(jobs) + 0.6, 3.8)
    axes = fig.subplots(1, len(jobs), squeeze=False, sharey=True)[0]
    for ax, r in zip(axes, jobs, strict=True):
        data = [[c[k]["share"] for c in r.summary["coupling"].values() if c[k]["n"]] for k in KIND_LABELS]
        ax.boxplot([x if x else [np.nan] for x in data], showfliers=False)
        for i, x in enumerate(data):
            jitter = np.linspace(-0.12, 0.12, len(x)) if len(x) > 1 else np.zeros(len(x))
            ax.plot(np.full(len(x), i + 1.0) + jitter, x, ".", color=f"C{i}", alpha=0.7)
        ax.set_xticks(range(1, len(KIND_LABELS) + 1), list(KIND_LABELS.values()), fontsize=8)
        ax.set_title(f"{r.setup} {r.label}: {len(r.summary['coupling'])} runs", fontsize=9)
        ax.set_ylim(0, 1)
    axes[0].set_ylabel("share of episodes where another\nrover's final POI changed")
    fig.suptitle("Single-rover updates change what the other rovers observe (one dot per run)")
    return fig, {"methods": [f"{r.setup} {r.label}" for r in jobs]}
