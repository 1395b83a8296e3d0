"""Every figure of a sweep, a job dir or exported results: ``python -m rovermarl.plot`` and the end-of-sweep callback.

:func:`plot_sweep` writes ``figures/<kind>_<setup>.<format>``: ``curves``, ``soft_vs_strict``, ``bandit``, ``update``
and ``occupancy`` (docs/GUIDE.md, Figures); from exported results also ``fig6_duo`` and ``switched_k1``
(:mod:`rovermarl.analysis.fig6`); and ``index.json``: every figure with its files, methods and panel count, the jobs
read and the notes. Medians and thresholds use the full curves; lines are drawn with at most
:data:`~rovermarl.analysis.draw.MAX_POINTS` points. Figures are written atomically.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path

from matplotlib.figure import Figure

from rovermarl.analysis.behaviour_figures import fig_occupancy, fig_update, pick_run, pick_update
from rovermarl.analysis.curve_figures import XLABEL, fig_bandit, fig_curves, fig_soft_vs_strict
from rovermarl.analysis.draw import save
from rovermarl.analysis.fig6 import fig_fig6, fig_switched
from rovermarl.analysis.levels import threshold_for
from rovermarl.analysis.results import load
from rovermarl.analysis.stamp import FORMATS, inputs_stamp, options
from rovermarl.analysis.sweep import (
    Job,
    RunCurve,
    SweepError,
    check_dir,
    fig6_job,
    find_jobs,
    load_job,
    soft_strict_pairs,
)
from rovermarl.record.outputs import write_json
from rovermarl.record.safe_read import RunSize, load_npz, refuse_odd


def _load_update_run(path: Path, update_gen: int | None, notes: list[str]) -> tuple[Job, RunCurve]:
    """The job and run of ``--update-run``, checked (with ``--update-gen``) before anything is drawn."""
    path = Path(path)
    if not (path / "curve.npz").is_file():
        raise SweepError(f"--update-run {path}: not a run dir (no curve.npz)")
    if not (path / "behaviour.npz").is_file():
        raise SweepError(f"--update-run {path}: no behaviour.npz (this run recorded no trajectories)")
    try:
        b = load_npz(path / "behaviour.npz", RunSize().behaviour(), ("generation", "score", "xy"), stored=True)
        generation, score = b["generation"], b["score"]
    except Exception as e:
        raise SweepError(f"--update-run {path}: unreadable behaviour.npz ({type(e).__name__})") from None
    if update_gen is not None and pick_update(generation, score, update_gen) is None:
        shown = ", ".join(map(str, generation[1:11])) + (", ..." if len(generation) > 11 else "")
        raise SweepError(f"--update-gen {update_gen}: not a logged behaviour generation of {path} "
                         f"(logged after the first: {shown or 'none'})")
    job = load_job(path.parent.parent, notes)
    run = next((r for r in job.runs if r.path.resolve() == path.resolve()), None) if job else None
    if run is None:
        raise SweepError(f"--update-run {path}: unreadable run")
    return job, run


def _behaviour_figures(setup: str, group: Sequence[Job], chosen: tuple[Job, RunCurve] | None, update_gen: int | None,
                       notes: list[str], trust: bool = False) -> list[tuple[str, tuple[Figure, dict]]]:
    """The update and occupancy figures of one setup: from the chosen run, else from the best run that recorded
    the data; a note instead of a figure when there is none."""
    out = []
    for kind, filename in (("update", "behaviour.npz"), ("occupancy", "occupancy.npz")):
        own = chosen is not None and chosen[0].setup == setup and chosen[1].has(filename)
        picked = chosen if own else pick_run(group, filename)
        world = picked[0].world(trust) if picked else None
        if picked is None or world is None:
            why = ("no run recorded" if picked is None else "cannot build the world of" if trust
                   else "cannot build (a world plug-in? --trust-config) the world of")
            notes.append(f"{setup}: {why} {filename}; no {kind} figure")
            continue
        try:
            drawn = (fig_occupancy(*picked, world) if kind == "occupancy" else
                     fig_update(*picked, world, at=update_gen if own else None))
        except Exception as e:  # a corrupt or half-written file costs this figure only
            notes.append(f"{picked[1].path}: unreadable {filename} ({type(e).__name__}); no {kind} figure")
            continue
        if drawn is None and own and update_gen is not None:
            raise SweepError(f"--update-gen {update_gen}: not a logged behaviour generation (after the first) of "
                             f"{picked[1].path}")
        if drawn is None:
            notes.append(f"{setup}: the score never rose in {picked[1].path}; no update figure")
        else:
            out.append((kind, drawn))
    return out


def _fig6(path: Path, jobs: Sequence[Job], xscale: str, notes: list[str]) -> tuple[Figure, dict] | None:
    """Fig. 6 from the exported ``fig6.npz``, drawn in the world of the job it comes from; None with a note if that
    job or its world is missing."""
    job = fig6_job(jobs)
    world = job.world() if job is not None else None
    if world is None:
        notes.append(f"{path}: no duo k=1 job whose world it shows; no fig6 figure")
        return None
    try:
        return fig_fig6(path, job, world, xscale)
    except (ValueError, OSError) as e:                                  # OSError: safe_read's Corrupt
        notes.append(f"{e}; no fig6 figure")
        return None


def plot_sweep(path: Path, out: Path | None = None, thresholds: dict[str, float] | None = None,
               formats: Sequence[str] = FORMATS, update_run: Path | None = None, update_gen: int | None = None,
               log=None, xscale: str = "linear", x: str = "auto", trust: bool = False,
               only: Sequence[Path] | None = None) -> dict:
    """Draw every figure of the sweep, job or results dir ``path`` into ``out`` (default ``path/figures``); returns
    the index (also written as ``index.json``); :class:`SweepError` on unusable input.

    ``xscale="log"``: generations on a log axis (0 included). ``x``: the score curves' x-axis, ``generation``,
    ``evals`` or ``auto`` (:func:`~rovermarl.analysis.curve_figures.x_axis`). ``trust``: build world plug-ins the
    jobs' configs name (their modules run code; the end-of-sweep callback trusts its own jobs, ``only`` those it ran).
    """
    path = check_dir(path)
    out = Path(out) if out is not None else path / "figures"
    try:
        refuse_odd(out, "figures dir")                                   # a linked figures dir: written elsewhere
        stamp = inputs_stamp(path, out, **options(thresholds, formats, update_run, update_gen, xscale, x, trust))
    except OSError as e:
        raise SweepError(str(e)) from None
    jobs, notes = find_jobs(path, only)
    chosen = _load_update_run(update_run, update_gen, notes) if update_run is not None else None
    figures: list[dict] = []

    def emit(kind: str, setup: str, drawn) -> None:
        if drawn is None:
            return
        fig, info = drawn
        name = kind + "_" + re.sub(r"[^\w.-]+", "_", setup)
        if xscale == "log":
            for ax in fig.axes:
                if ax.get_xlabel() in XLABEL.values() or ax.get_shared_x_axes().get_siblings(ax) != [ax]:
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
        emit("curves", setup, fig_curves(setup, [j for j in group if id(j) not in paired], threshold, x))
        if pairs:
            emit("soft_vs_strict", setup, fig_soft_vs_strict(setup, pairs, threshold))
        if bandits := [j for j in group if j.bandit]:
            emit("bandit", setup, fig_bandit(setup, bandits))
        for kind, drawn in _behaviour_figures(setup, group, chosen, update_gen, notes, trust):
            emit(kind, setup, drawn)

    if (path / "fig6.npz").is_file():                                   # exported results: C8 figures
        emit("fig6", "duo", _fig6(path / "fig6.npz", jobs, "symlog" if xscale == "log" else "linear", notes))
        emit("switched", "k1", fig_switched(load(path)))

    if log is not None:
        for note in notes:
            log.info("note: %s", note)
    index = {"source": str(path), "formats": list(formats), "figures": figures, "notes": notes, "inputs": stamp,
             "jobs": [{"dir": j.name, "setup": j.setup, "label": j.label,
                       "runs": len(j.runs), "finished": j.finished, "bandit": j.bandit} for j in jobs]}
    write_json(out / "index.json", index)
    return index
