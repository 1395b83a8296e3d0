"""Score figures of a sweep: the runs' curves with quartile lines (the paper's Figs. 4, 5, 8), soft against strict
selection (Fig. 7), and the bandit's arm probabilities."""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import numpy as np
from matplotlib.figure import Figure

from rovermarl.analysis.draw import downsample, line, new_figure, panels
from rovermarl.analysis.levels import QUARTILES, quartile_times
from rovermarl.analysis.sweep import Job, labels
from rovermarl.record.outputs import first_reaching


def median_curve(scores: Sequence[np.ndarray]) -> np.ndarray:
    """Median over runs at each generation; runs shorter than the longest count only where they exist."""
    stack = np.full((len(scores), max(len(s) for s in scores)), np.nan)
    for row, s in zip(stack, scores, strict=True):
        row[: len(s)] = s
    return np.nanmedian(stack, axis=0)


def quartile_generations(scores: Sequence[np.ndarray], level: float,
                         quartiles: Iterable[float] = QUARTILES) -> list[int | None]:
    """For each q, the generation at which ``ceil(q * n)`` of the ``n`` runs have reached ``level`` (None: never);
    the rule is :func:`~rovermarl.analysis.levels.quartile_times`."""
    first = [np.inf if (g := first_reaching(s, level)) is None else g for s in scores]
    return [None if np.isinf(t) else int(t) for t in quartile_times(first, quartiles)]


XLABEL = {"generation": "generation", "evals": "team evaluations"}


def x_axis(jobs: Sequence[Job], x: str = "auto") -> str:
    """``generation`` or ``evals``; ``auto``: team evaluations when the jobs spend different numbers per generation
    (CC-(1+1)-ES against the CCEA), so that equal budgets line up."""
    if x != "auto":
        return x
    return "evals" if len({j.evals_per_generation for j in jobs}) > 1 else "generation"


def _curve(ax, job: Job, y: np.ndarray, x: str, **kw) -> None:
    """y (G+1,) of ``job`` against generations or team evaluations (downsampled)."""
    g, y = downsample(y)
    line(ax, y, x=g if x == "generation" else job.evals(g), **kw)


def _at(job: Job, generation: float, x: str) -> float:
    return generation if x == "generation" else float(job.evals(generation))


def _runs_panel(ax, job: Job, label: str, colour: str, threshold: float | None,
                x: str = "generation") -> list[int | None]:
    """Every run's curve of ``job``; dotted lines (thin, bold, thin) at the quartile generations (drawn at their
    team evaluations when ``x="evals"``)."""
    scores = [r.score for r in job.runs]
    for s in scores:
        _curve(ax, job, s, x, color=colour, lw=0.7, alpha=0.6)
    ax.set_title(f"{label}: {len(scores)} runs" + ("" if job.finished else " (unfinished)"), fontsize=9)
    ax.set_xlabel(XLABEL[x])
    if threshold is None:
        return []
    quart = quartile_generations(scores, threshold)
    for g, lw in zip(quart, (0.8, 2.0, 0.8), strict=True):
        if g is not None:
            ax.axvline(_at(job, g, x), color="k", ls=":", lw=lw)
    ax.axhline(threshold, color="0.5", lw=0.5, ls="--")
    return quart


def _top(ax, title: str, x: str = "generation") -> None:
    ax.set(title=title, xlabel=XLABEL[x], ylabel="median score")
    ax.legend(fontsize=8, loc="lower right")


def fig_curves(setup: str, jobs: Sequence[Job], threshold: float | None, x: str = "auto") -> tuple[Figure, dict]:
    """Figs. 4/5/8: medians on top (fixed-k methods faded when a bandit is present), with a diamond at the last
    generation for the median held-out score of the final teams (jobs that recorded one); runs below. ``x``:
    ``generation``, ``evals`` (team evaluations) or ``auto`` (:func:`x_axis`)."""
    labs, x = labels(jobs), x_axis(jobs, x)
    fig, top, bottom = panels(len(jobs))
    fade = any(j.bandit for j in jobs)
    quart, held = {}, {}
    for i, (job, lab, ax) in enumerate(zip(jobs, labs, bottom, strict=True)):
        colour = f"C{i % 10}"
        median = median_curve([r.score for r in job.runs])
        _curve(top, job, median, x, color=colour, label=lab, alpha=1.0 if job.bandit or not fade else 0.35, lw=1.5)
        held[lab] = job.heldout()
        if held[lab] is not None:
            top.plot([_at(job, len(median) - 1, x)], [held[lab]], marker="D", ms=5, color=colour, ls="none",
                     clip_on=False)
        quart[lab] = _runs_panel(ax, job, lab, colour, threshold, x)
    bottom[0].set_ylabel("score")
    note = f"; dotted: 1/4, 1/2, 3/4 of runs reach {threshold:g}" if threshold is not None else ""
    note += "; diamonds: median held-out score" if any(v is not None for v in held.values()) else ""
    _top(top, f"{setup}: median score{note}", x)
    return fig, {"methods": labs, "threshold": threshold, "quartile_generations": quart,
                 "median_heldout_score": held, "x": x}


def fig_soft_vs_strict(setup: str, pairs: Sequence[tuple[Job, Job]], threshold: float | None) -> tuple[Figure, dict]:
    """Fig. 7: soft (solid) and strict (dashed) medians on top; the strict runs below, one panel per method."""
    fig, top, bottom = panels(len(pairs))
    methods = labels([job for pair in pairs for job in pair])
    quart = {}
    for i, ((soft, strict), ax) in enumerate(zip(pairs, bottom, strict=True)):
        colour = f"C{i % 10}"
        for job, name, ls in ((soft, methods[2 * i], "-"), (strict, methods[2 * i + 1], "--")):
            line(top, median_curve([r.score for r in job.runs]), color=colour, ls=ls, label=name, lw=1.5)
        quart[methods[2 * i + 1]] = _runs_panel(ax, strict, methods[2 * i + 1], colour, threshold)
    bottom[0].set_ylabel("score")
    _top(top, f"{setup}: soft (solid) vs strict (dashed) selection")
    return fig, {"methods": methods, "threshold": threshold, "quartile_generations": quart}


def fig_bandit(setup: str, jobs: Sequence[Job]) -> tuple[Figure, dict]:
    """The bandit's probability of each k over generations (mean over seeds), one panel per adaptive job."""
    fig = new_figure(3.6 * len(jobs) + 0.6, 3.4)
    axes = fig.subplots(1, len(jobs), squeeze=False, sharey=True)[0]
    labs = labels(jobs)
    for job, lab, ax in zip(jobs, labs, axes, strict=True):
        probs = [r.probs for r in job.runs if r.probs is not None]
        length = min(len(p) for p in probs)
        mean = np.mean([p[:length] for p in probs], axis=0)
        x = job.runs[0].probs_x
        for a, arm in enumerate(job.arms(mean.shape[1])):
            line(ax, mean[:, a], x=None if x is None else x[:length], color=f"C{a % 10}", label=f"k={arm}")
        ax.set(title=f"{lab}: mean over {len(probs)} runs", xlabel="generation", ylim=(0, 1))
        ax.legend(fontsize=8, loc="upper right")
    axes[0].set_ylabel("probability of choosing k")
    fig.suptitle(f"{setup}: bandit arm probabilities")
    return fig, {"methods": labs}
