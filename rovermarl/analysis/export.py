"""Export the compact results of a sweep (``python -m rovermarl.analysis export SWEEP_DIR RESULTS_DIR``; the format
is in :mod:`rovermarl.analysis.results`). All or nothing: it writes into a hidden dir beside ``RESULTS_DIR`` and
moves it into place only when everything succeeded (:func:`staged`)."""

from __future__ import annotations

import contextlib
import os
import shutil
from pathlib import Path

import numpy as np
from omegaconf import OmegaConf

from rovermarl.analysis.curves import GRID_POINTS, Curves, change_points, log_grid, read_run_arrays
from rovermarl.analysis.rerun import mutated_rovers
from rovermarl.analysis.results import COUPLING_KINDS, ResultsError
from rovermarl.analysis.sweep import Job, fig6_job, find_jobs, labels
from rovermarl.record.outputs import INVOCATIONS, LAUNCH, atomic_open, write_json
from rovermarl.record.safe_read import RunSize, check_tree, load_npy, load_npz, read_json, read_jsonl
from rovermarl.runner.trust import check_targets


def coupling(curve, episodes: int) -> dict | None:
    """The phenotypic-coupling measure of one run, over its generations that mutated exactly one rover:
    for accepted updates that raised the score (``improved``), accepted ones that kept it (``neutral``) and
    rejected ones: how many there were, the mean share of episodes in which another rover changed its final POI
    (``share``), and the fraction of updates with at least one such episode (``any``). None without data."""
    if "switched" not in curve:
        return None
    acc, sw = curve["accepted"], curve["switched"].astype(np.float64)
    single = (curve["k"] == 1) & (sw >= 0)
    if not single.any():
        return None
    rose = curve["child_score"] > curve["score"][:-1]                   # than the parent's
    out = {}
    for kind, mask in zip(COUPLING_KINDS, (single & acc & rose, single & acc & ~rose, single & ~acc), strict=True):
        n = int(mask.sum())
        out[kind] = {"n": n, "share": float(sw[mask].mean() / episodes) if n else None,
                     "any": float((sw[mask] > 0).mean()) if n else None}
    return out


def compute_of(job: Job) -> dict:
    """Team evaluations and wall time of every launch of the job (``invocations.jsonl``, and the ``launch.json`` of
    a killed launch not relaunched since; else summary.json)."""
    log, killed = job.path / INVOCATIONS, job.path / LAUNCH
    launches = list(read_jsonl(log, "launch")) if log.is_file() else []   # each line checked: finite, bounded
    launches += [read_json(killed, kind="launch")] if killed.is_file() else []
    if not launches:                                                     # jobs run before the log existed
        launches = [read_json(job.path / "summary.json", kind="summary")]
    return {"launches": len(launches), "wall_time_s": sum(x.get("wall_time_s", 0.0) for x in launches),
            "team_evals": sum(x.get("team_evals", 0) for x in launches)}


def export_job(job: Job, label: str, out: Path, grid_points: int = GRID_POINTS, trust: bool = False) -> dict:
    """Write one job's compact results into ``out``; returns its summary. A world plug-in's job only with ``trust``
    (its world is built to size the run files)."""
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
    world = job.world(trust)
    if world is None:
        raise ResultsError(f"{job.path}: cannot build the world from its config")
    episodes = world.episodes
    couplings = {}
    for r in runs:
        c = coupling(read_run_arrays(r.path, RunSize.of(job.config, world)), episodes)
        if c is not None:
            couplings[str(r.seed)] = c
    summary = read_json(job.path / "summary.json", kind="summary") if job.finished else {}
    _same_generation(job, summary, runs)
    compute = compute_of(job)      # agent-steps: the team evaluations', plus those a learner took itself (PPO's)
    own = int(summary.get("own_agent_steps_per_generation", 0)) * curves.generations * len(runs)
    scored = compute["team_evals"] * world.episodes * world.steps * world.n_rovers
    compute |= {"own_agent_steps": own, "agent_steps": scored + own}
    summary.update({"label": label, "setup": job.setup, "generations": curves.generations,
                    "episodes": episodes, "source": job.name, "compute": compute})
    if couplings:
        summary["coupling"] = couplings
    if job.evals_per_generation != 1:                                # read back by Job.evals_per_generation
        summary["evals_per_generation"] = job.evals_per_generation
    out.mkdir(parents=True, exist_ok=True)
    with atomic_open(out / "curves.npz") as f:
        np.savez_compressed(f, **arrays)
    teams = final_teams(runs)
    if teams is not None:
        with atomic_open(out / "genomes.npz") as f:
            np.savez_compressed(f, **teams)
    with atomic_open(out / "config.yaml", "w") as f:
        f.write(OmegaConf.to_yaml(OmegaConf.create(job.config)))
    write_json(out / "summary.json", summary)
    return summary


def _same_generation(job: Job, summary: dict, runs) -> None:
    """:class:`ResultsError` unless the job's ``summary`` is of the runs read: the same seeds, each ending at the
    final score it records (a relaunch rewriting the job's runs pairs an old summary with new curves)."""
    final = summary.get("final_score")
    if not isinstance(final, dict):
        return
    seeds, present = sorted(int(s) for s in final), [r.seed for r in runs]
    if seeds != present:
        raise ResultsError(f"{job.path}: summary.json is of seeds {seeds[:8]}, the runs present {present[:8]}; a "
                           "relaunch may be writing the job: export it once that ends")
    for r in runs:
        if float(r.score[-1]) != final[str(r.seed)]:
            raise ResultsError(f"{job.path}: seed {r.seed} ends at {float(r.score[-1])!r} in its curve, "
                               f"{final[str(r.seed)]!r} in summary.json (not the same generation of the run); a "
                               "relaunch may be writing the job: export it once that ends")


def final_teams(runs) -> dict | None:
    """Every run's final team, for ``analysis verify`` to re-score: ``seed`` (R,) and ``genomes`` (R, N, P) float64;
    None unless every run wrote its ``genomes.npy``."""
    if not runs or not all(r.has("genomes.npy") for r in runs):
        return None
    genomes = [load_npy(r.path / "genomes.npy", RunSize().genomes()) for r in runs]   # header against file size
    if len({g.shape for g in genomes}) != 1:
        raise ResultsError(f"{runs[0].path.parent}: final teams of different shapes")
    return {"seed": np.array([r.seed for r in runs], dtype=np.int64),
            "genomes": np.stack(genomes).astype(np.float64)}


def _kept_compute(out: Path, replaced: set[str]) -> dict:
    """The compute of ``out``'s jobs that this export leaves in place (from its ``compute.json``): a study exported
    job by job, over several sweeps or sessions, keeps every job's compute."""
    try:
        jobs = read_json(out / "compute.json", kind="compute").get("jobs", {})
    except (OSError, ValueError, AttributeError):
        return {}
    return {name: c for name, c in jobs.items() if name not in replaced and (out / name / "summary.json").is_file()}


def export(sweep: Path, out: Path, generations: int | None = None, grid_points: int = GRID_POINTS,
           fig6: bool = True, log=print, trust: bool = False) -> dict:
    """Export every finished job of ``sweep`` (with ``generations`` generations, if given) into ``out``: its job
    dirs, ``compute.json`` and ``fig6.npz`` replace those of ``out``, whose other job dirs stay (exports add up).
    The Fig. 6 data re-runs one run from its job's config: only with the classes of rovermarl's config groups
    (:func:`~rovermarl.runner.trust.check_targets`, before anything is written), unless ``trust``. Nothing of
    ``out`` changes unless the whole export succeeds."""
    jobs, notes = find_jobs(sweep)
    jobs = [j for j in jobs if j.finished and (generations is None or len(j.runs[0].score) == generations + 1)]
    if not jobs:
        raise ResultsError(f"no finished job in {sweep}" + (f" with generations={generations}" if generations else ""))
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ResultsError(f"{out}: not a directory")
    check_tree(out)                                                     # its entries are replaced: no link in it
    rerun = fig6_job(jobs) if fig6 else None
    if rerun is not None and not trust:
        check_targets(rerun.config, str(rerun.path))
    totals = {"jobs": _kept_compute(out, {j.name for j in jobs})}
    named = {}
    for setup in dict.fromkeys(j.setup for j in jobs):                  # labels tell methods apart within a setup
        group = [j for j in jobs if j.setup == setup]
        named.update(zip((j.name for j in group), labels(group), strict=True))
    with staged(out) as stage:
        for job in jobs:
            label = named[job.name]
            summary = export_job(job, label, stage / job.name, grid_points, trust)
            totals["jobs"][job.name] = summary["compute"]
            log(f"exported {job.name} ({len(job.runs)} runs) as {label!r}")
        totals |= {key: sum(c.get(key, 0) for c in totals["jobs"].values())     # every job of out: they add up
                   for key in ("team_evals", "own_agent_steps", "agent_steps", "wall_time_s")}
        write_json(stage / "compute.json", totals)
        if rerun is not None:
            log(f"fig6: {export_fig6(rerun, stage / 'fig6.npz', trust=trust)}")
    for note in notes:
        log(f"note: {note}")
    return totals


@contextlib.contextmanager
def staged(out: Path):
    """A new hidden dir next to ``out`` (``.<name>.export-<pid>.tmp``) to write the export into. When the block
    succeeds its entries go into place: it becomes ``out`` if there is none, else each entry replaces its namesake
    in ``out`` (renamed aside, the new one renamed in, the old one removed) and the rest of ``out`` stays. When the
    block fails the dir is removed (with the parents of ``out`` it made) and ``out`` is as it was."""
    out = Path(out).resolve()
    made = [p for p in (out.parent, *out.parent.parents) if not p.exists()][::-1]
    out.parent.mkdir(parents=True, exist_ok=True)
    stage = out.parent / f".{out.name}.export-{os.getpid()}.tmp"
    _remove(stage)                               # a leftover of a killed export whose pid this process reuses
    try:
        stage.mkdir()
        yield stage
        _move_into(stage, out)
    except BaseException:
        _remove(stage)
        for parent in reversed(made):
            with contextlib.suppress(OSError):
                parent.rmdir()
        raise


def _move_into(stage: Path, out: Path) -> None:
    """Move the entries of ``stage`` into ``out`` (see :func:`staged`); on failure ``out`` is restored."""
    if not out.exists():
        try:
            os.rename(stage, out)
            return
        except OSError:
            if not out.is_dir():                 # else made meanwhile: merge into it
                raise
    moved: list[tuple[str, Path | None]] = []    # (entry, its old version set aside)
    try:
        for entry in sorted(p.name for p in stage.iterdir()):
            dest, aside = out / entry, None
            if dest.exists() or dest.is_symlink():
                aside = out / f".{entry}.old-{os.getpid()}.tmp"
                _remove(aside)
                os.rename(dest, aside)
            moved.append((entry, aside))
            os.rename(stage / entry, dest)
    except BaseException:
        for entry, aside in reversed(moved):     # put the new entries back into the stage, the old ones in place
            if not (stage / entry).exists() and ((out / entry).exists() or (out / entry).is_symlink()):
                os.rename(out / entry, stage / entry)
            if aside is not None:
                os.rename(aside, out / entry)
        raise
    for _, aside in moved:
        if aside is not None:
            _remove(aside)
    stage.rmdir()


def _remove(path: Path) -> None:
    """Remove a file, link or dir tree if it exists."""
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    else:
        with contextlib.suppress(FileNotFoundError):
            path.unlink()


# ---- Fig. 6 data ---------------------------------------------------------------------------------------------------
FIG6_LEVELS = (4.0 + 1 / 16, 5.0)  # the first update past the all-solo level 4, and the first to reach 5


def _crossings(generation: np.ndarray, score: np.ndarray, levels=FIG6_LEVELS) -> list[int]:
    """Indices of the behaviour entries where the score first reaches each level (the 'after' entry), in
    increasing order, each once (one update can cross several levels)."""
    hits = (np.flatnonzero((score[1:] >= level) & (score[:-1] < level)) for level in levels)
    return sorted({int(hit[0]) + 1 for hit in hits if hit.size})


def export_fig6(job: Job, path: Path, run_seed: int | None = None, levels=FIG6_LEVELS, trust: bool = False) -> dict:
    """The data of a Fig. 6-style figure for one run of ``job`` (default: the best final score, earliest first):
    its score change points, the occupancy of one episode over generations, and the team's trajectories just
    before and after the updates that first lift the score to each of ``levels`` (:data:`FIG6_LEVELS`), with the
    rover each update changed (found by re-running the run, which must reproduce the recorded scores)."""
    runs = [r for r in job.runs if r.has("behaviour.npz") and r.has("occupancy.npz")]
    if not runs:
        raise ResultsError(f"{job.path}: no run recorded behaviour.npz and occupancy.npz")
    curves = Curves.from_scores([r.seed for r in runs], [r.score for r in runs])
    if run_seed is None:                                               # the best final score, reached first
        run = runs[int(np.argmin(curves.first(max(r.score[-1] for r in runs))))]
    else:
        run = next((r for r in runs if r.seed == run_seed), None)
        if run is None:
            raise ResultsError(f"{job.path}: no recorded run with seed {run_seed}")
    b = load_npz(run.path / "behaviour.npz", job.size.behaviour(), ("generation", "score", "xy"), stored=True)
    generation, score, xy = b["generation"], b["score"], b["xy"]
    o = load_npz(run.path / "occupancy.npz", job.size.occupancy(), ("generation", "count"), stored=True)
    occ_generation, count = o["generation"], o["count"]
    after = _crossings(generation, score, levels)
    events = [(i - 1, i) for i in after]        # the 'before' entry is the parent team of the 'after' generation
    replayed = mutated_rovers(job.config, run.seed, [int(generation[i]) for _, i in events],  # in generation order
                              source=str(job.path), trust=trust)
    for (_, i), (_, parent_score, accepted) in zip(events, replayed, strict=True):
        if parent_score != score[i] or not accepted:
            raise ResultsError(f"{run.path}: re-running seed {run.seed} does not reproduce generation "
                               f"{int(generation[i])}")
    world = job.world(trust)
    returns = (count[-1] >= np.asarray(world.coupling)) @ np.asarray(world.value)   # (E,): show one ending best
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
              "event_mutated": np.array([m[0] if len(m) == 1 else -1 for m, _, _ in replayed], dtype=np.int64),
              "coupling": np.asarray(world.coupling), "value": np.asarray(world.value)}
    with atomic_open(path) as f:
        np.savez_compressed(f, **arrays)
    return {"job": job.name, "seed": run.seed, "episode": episode,
            "events": [[int(generation[a]), int(generation[b])] for a, b in events],
            "mutated_rover": arrays["event_mutated"].tolist()}
