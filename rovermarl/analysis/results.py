"""Compact results of a sweep: ``python -m rovermarl.analysis export SWEEP_DIR RESULTS_DIR``.

A sweep dir holds gigabytes (every generation of every run, trajectories, ``.rrd`` recordings). The compact
results keep what the claims and figures need, in a few MB, with the same job-dir layout::

    RESULTS_DIR/<job>/summary.json   the job's summary.json, plus label, setup, budget, coupling per run, compute
    RESULTS_DIR/<job>/config.yaml    the job's composed config
    RESULTS_DIR/<job>/curves.npz     seed (R,); generations (); grid (M,) log-spaced generations, score (R, M) there;
                                     the exact curves as change points: step_run (S,), step_generation (S,),
                                     step_score (S,) (a parent score never falls, so these few points are lossless);
                                     probs (R, M, K) float32 on the grid (bandit jobs only)
    RESULTS_DIR/fig6.npz             one duo k=1 run's data for the Fig. 6-style figure (see :func:`export_fig6`)
    RESULTS_DIR/compute.json         team evaluations, agent-steps and wall time of the whole sweep

:func:`load` reads a results dir (or a sweep dir) back as :class:`Curves` per job.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from omegaconf import OmegaConf

from rovermarl.analysis.figures import Job, find_jobs, labels
from rovermarl.record.outputs import atomic_open, write_json

GRID_POINTS = 400
COUPLING_KINDS = ("improved", "neutral", "rejected")  # accepted with a higher score, accepted with an equal one


class ResultsError(Exception):
    """Input that cannot be exported; ``str(err)`` is one line."""


def log_grid(generations: int, points: int = GRID_POINTS) -> np.ndarray:
    """Generations 0 and about ``points`` log-spaced ones in [1, generations] (ints, both ends included)."""
    top = max(int(generations), 1)
    return np.unique(np.concatenate([[0], np.round(np.logspace(0, math.log10(top), points)).astype(np.int64)]))


def change_points(score: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(generations, values) where the curve score (G+1,) takes a new value, generation 0 first."""
    g = np.concatenate([[0], np.flatnonzero(np.diff(score) != 0) + 1])
    return g, score[g]


@dataclass
class Curves:
    """Every run's exact score curve of one job, from change points."""

    seeds: np.ndarray            # (R,)
    generations: int             # G
    step_run: np.ndarray         # (S,) run index of each change point
    step_generation: np.ndarray  # (S,)
    step_score: np.ndarray       # (S,)

    @classmethod
    def from_scores(cls, seeds, scores: list[np.ndarray]) -> Curves:
        parts = [change_points(s) for s in scores]
        return cls(np.asarray(seeds), len(scores[0]) - 1,
                   np.concatenate([np.full(len(g), i) for i, (g, _) in enumerate(parts)]),
                   np.concatenate([g for g, _ in parts]), np.concatenate([v for _, v in parts]))

    def run(self, i: int) -> tuple[np.ndarray, np.ndarray]:
        m = self.step_run == i
        return self.step_generation[m], self.step_score[m]

    def at(self, generations) -> np.ndarray:
        """Scores at the given generations: (R, len(generations))."""
        generations = np.atleast_1d(np.asarray(generations))
        out = np.empty((len(self.seeds), len(generations)))
        for i in range(len(self.seeds)):
            g, v = self.run(i)
            out[i] = v[np.searchsorted(g, generations, side="right") - 1]
        return out

    def full(self, i: int) -> np.ndarray:
        """Run ``i``'s score after every generation: (G+1,)."""
        g, v = self.run(i)
        return np.repeat(v, np.diff(np.append(g, self.generations + 1)))

    def first(self, level: float) -> np.ndarray:
        """First generation each run reaches ``level``: (R,) float, ``inf`` for never."""
        out = np.full(len(self.seeds), np.inf)
        for i in range(len(self.seeds)):
            g, v = self.run(i)
            hit = np.flatnonzero(v >= level - 1e-9)
            if hit.size:
                out[i] = g[hit[0]]
        return out


# ---- export ------------------------------------------------------------------------------------------------------
def coupling(curve, episodes: int) -> dict | None:
    """The phenotypic-coupling measure of one run, over its generations that mutated exactly one rover:
    for accepted updates that raised the score (``improved``), accepted ones that kept it (``neutral``) and
    rejected ones: how many there were, the mean share of episodes in which another rover changed its final POI
    (``share``), and the fraction of updates with at least one such episode (``any``). None without data."""
    if "switched" not in curve:
        return None
    k, acc, sw = curve["k"], curve["accepted"], curve["switched"].astype(np.float64)
    parent_before = curve["score"][:-1]
    single = (k == 1) & (sw >= 0)
    if not single.any():
        return None
    rose = curve["child_score"] > parent_before
    out = {}
    for kind, mask in (("improved", single & acc & rose), ("neutral", single & acc & ~rose),
                       ("rejected", single & ~acc)):
        n = int(mask.sum())
        out[kind] = {"n": n, "share": float(sw[mask].mean() / episodes) if n else None,
                     "any": float((sw[mask] > 0).mean()) if n else None}
    return out


def _compute(job: Job) -> dict:
    """Team evaluations and wall time of every launch of the job (``invocations.jsonl``; else summary.json)."""
    log = job.path / "invocations.jsonl"
    launches = [json.loads(x) for x in log.read_text().splitlines() if x.strip()] if log.is_file() else []
    if not launches:                                                     # jobs run before the log existed
        summary = json.loads((job.path / "summary.json").read_text())
        launches = [{"wall_time_s": summary.get("wall_time_s", 0.0), "team_evals": summary.get("team_evals", 0)}]
    return {"launches": len(launches), "wall_time_s": sum(x["wall_time_s"] for x in launches),
            "team_evals": sum(x["team_evals"] for x in launches)}


def export_job(job: Job, label: str, out: Path, grid_points: int = GRID_POINTS) -> dict:
    """Write one job's compact results into ``out``; returns its summary."""
    runs = sorted(job.runs, key=lambda r: r.seed)
    lengths = {len(r.score) for r in runs}
    if len(lengths) != 1:
        raise ResultsError(f"{job.path}: runs of different lengths {sorted(lengths)}; finish the job first")
    curves = Curves.from_scores([r.seed for r in runs], [r.score for r in runs])
    grid = log_grid(curves.generations, grid_points)
    arrays = {"seed": curves.seeds, "generations": np.int64(curves.generations), "grid": grid,
              "score": curves.at(grid), "step_run": curves.step_run.astype(np.int32),
              "step_generation": curves.step_generation, "step_score": curves.step_score}
    if job.bandit:
        arrays["probs"] = np.stack([r.probs[np.minimum(grid, len(r.probs) - 1)] for r in runs]).astype(np.float32)
    world = job.world()
    if world is None:
        raise ResultsError(f"{job.path}: cannot build the world from its config")
    episodes = world.episodes
    couplings = {}
    for r in runs:
        with np.load(r.path / "curve.npz") as z:
            c = coupling({key: z[key] for key in z.files}, episodes)
        if c is not None:
            couplings[str(r.seed)] = c
    summary = json.loads((job.path / "summary.json").read_text()) if job.finished else {}
    compute = _compute(job)
    compute["agent_steps"] = compute["team_evals"] * world.episodes * world.steps * world.n_rovers
    summary.update({"label": label, "setup": job.setup, "generations": curves.generations,
                    "episodes": episodes, "source": job.name, "compute": compute})
    if couplings:
        summary["coupling"] = couplings
    out.mkdir(parents=True, exist_ok=True)
    with atomic_open(out / "curves.npz") as f:
        np.savez_compressed(f, **arrays)
    with atomic_open(out / "config.yaml", "w") as f:
        f.write(OmegaConf.to_yaml(OmegaConf.create(job.config)))
    write_json(out / "summary.json", summary)
    return summary


def export(sweep: Path, out: Path, generations: int | None = None, grid_points: int = GRID_POINTS,
           fig6: bool = True, log=print) -> dict:
    """Export every finished job of ``sweep`` (with ``generations`` generations, if given) into ``out``."""
    jobs, notes = find_jobs(sweep)
    jobs = [j for j in jobs if j.finished and (generations is None or len(j.runs[0].score) == generations + 1)]
    if not jobs:
        raise ResultsError(f"no finished job in {sweep}" + (f" with generations={generations}" if generations else ""))
    out = Path(out)
    totals = {"jobs": {}, "team_evals": 0, "agent_steps": 0, "wall_time_s": 0.0}
    named = {}
    for setup in dict.fromkeys(j.setup for j in jobs):                  # labels tell methods apart within a setup
        group = [j for j in jobs if j.setup == setup]
        named.update(zip((j.name for j in group), labels(group), strict=True))
    for job in jobs:
        label = named[job.name]
        summary = export_job(job, label, out / job.name, grid_points)
        totals["jobs"][job.name] = summary["compute"]
        totals["team_evals"] += summary["compute"]["team_evals"]
        totals["wall_time_s"] += summary["compute"]["wall_time_s"]
        totals["agent_steps"] += summary["compute"]["agent_steps"]
        log(f"exported {job.name} ({len(job.runs)} runs) as {label!r}")
    write_json(out / "compute.json", totals)
    if fig6:
        duo_k1 = [j for j in jobs if j.setup == "duo" and j.label == "k=1"]
        if duo_k1:
            info = export_fig6(duo_k1[0], out / "fig6.npz")
            log(f"fig6: {info}")
    for note in notes:
        log(f"note: {note}")
    return totals


# ---- Fig. 6 --------------------------------------------------------------------------------------------------------
FIG6_LEVELS = (4.0 + 1 / 16, 5.0)  # the first update past the all-solo level 4, and the first to reach 5


def _crossings(generation: np.ndarray, score: np.ndarray, levels=FIG6_LEVELS) -> list[int]:
    """Indices of the behaviour entries where the score first reaches each level (the 'after' entry), in
    increasing order, each once (one update can cross several levels)."""
    out = set()
    for level in levels:
        hit = np.flatnonzero((score[1:] >= level) & (score[:-1] < level))
        if hit.size:
            out.add(int(hit[0]) + 1)
    return sorted(out)


def export_fig6(job: Job, path: Path, run_seed: int | None = None, levels=FIG6_LEVELS) -> dict:
    """The data of a Fig. 6-style figure for one run of ``job`` (default: the best final score, earliest first):
    its score change points, the occupancy of one episode over generations, and the team's trajectories just
    before and after the updates that first lift the score to each of ``levels`` (by default: past 4, the
    all-solo level, in one more episode; and to 5, a duo POI in every episode), with the rover each update changed
    (found by re-running the run, which must reproduce the recorded scores)."""
    from rovermarl.evolution import Run, evolve

    runs = [r for r in job.runs if (r.path / "behaviour.npz").is_file() and (r.path / "occupancy.npz").is_file()]
    if not runs:
        raise ResultsError(f"{job.path}: no run recorded behaviour.npz and occupancy.npz")
    curves = Curves.from_scores([r.seed for r in runs], [r.score for r in runs])
    if run_seed is None:
        best = max(r.score[-1] for r in runs)
        first = curves.first(best)
        run = runs[int(np.argmin(first))]
    else:
        run = next((r for r in runs if r.seed == run_seed), None)
        if run is None:
            raise ResultsError(f"{job.path}: no recorded run with seed {run_seed}")
    with np.load(run.path / "behaviour.npz") as b:
        generation, score, xy = b["generation"], b["score"], b["xy"]
    with np.load(run.path / "occupancy.npz") as o:
        occ_generation, count = o["generation"], o["count"]
    after = _crossings(generation, score, levels)
    events = [(i - 1, i) for i in after]        # the 'before' entry is the parent team of the 'after' generation
    replay, mutated = Run(OmegaConf.create(job.config), run.seed), []
    for _, i in events:                                                  # events come in generation order
        g = int(generation[i])
        evolve(replay, g - 1 - replay.generation)
        parents = replay.parents_genomes.copy()
        evolve(replay, 1)
        if replay.f_parent != score[i] or not replay.history.accepted[g - 1]:
            raise ResultsError(f"{run.path}: re-running seed {run.seed} does not reproduce generation {g}")
        mutated.append(np.flatnonzero((replay.parents_genomes != parents).any(axis=1)).astype(np.int64))
    final_count = count[-1]                                              # (E, P): pick an episode that ends best
    world = job.world()
    returns = (final_count >= np.asarray(world.coupling)) @ np.asarray(world.value)
    best_eps = np.flatnonzero(returns == returns.max())
    changes = [(np.diff(count[:, e], axis=0) != 0).any(axis=1).sum() for e in best_eps]
    episode = int(best_eps[int(np.argmax(changes))])
    idx = [i for pair in events for i in pair]
    steps = change_points(run.score)
    arrays = {"seed": np.int64(run.seed), "generations": np.int64(len(run.score) - 1),
              "step_generation": steps[0], "step_score": steps[1],
              "episode": np.int64(episode), "occupancy_generation": occ_generation,
              "occupancy": count[:, episode], "event_generation": generation[idx].reshape(-1, 2),
              "event_score": score[idx].reshape(-1, 2), "event_xy": xy[idx].reshape(len(events), 2, *xy.shape[1:]),
              "event_mutated": np.array([m[0] if len(m) == 1 else -1 for m in mutated], dtype=np.int64),
              "coupling": np.asarray(world.coupling), "value": np.asarray(world.value)}
    with atomic_open(path) as f:
        np.savez_compressed(f, **arrays)
    return {"job": job.name, "seed": run.seed, "episode": episode,
            "events": [[int(generation[a]), int(generation[b])] for a, b in events],
            "mutated_rover": arrays["event_mutated"].tolist()}


# ---- reading results back ----------------------------------------------------------------------------------------
@dataclass
class Result:
    """One exported job."""

    name: str
    label: str
    setup: str
    summary: dict
    curves: Curves
    grid: np.ndarray
    probs: np.ndarray | None
    path: Path


def load(path: Path) -> list[Result]:
    """Every exported job under the results dir ``path`` (sorted by name)."""
    path = Path(path)
    if not path.is_dir():
        raise ResultsError(f"not a results directory: {path}")
    out = []
    for curves_file in sorted(path.glob("*/curves.npz")):
        summary = json.loads((curves_file.parent / "summary.json").read_text())
        with np.load(curves_file) as z:
            curves = Curves(z["seed"], int(z["generations"]), z["step_run"], z["step_generation"], z["step_score"])
            probs = z["probs"] if "probs" in z.files else None
            grid = z["grid"]
        out.append(Result(curves_file.parent.name, summary["label"], summary["setup"], summary, curves, grid, probs,
                          curves_file.parent))
    if not out:
        raise ResultsError(f"no exported job (*/curves.npz) in {path}; run `python -m rovermarl.analysis export`")
    return out
