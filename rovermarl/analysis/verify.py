"""Committed teams that re-score (issue 43): ``python -m rovermarl.analysis verify DIR``.

Every final team of ``DIR`` (a results dir's ``<job>/genomes.npz``: seed (R,), genomes (R, N, P) float64; a sweep's
``<job>/runs/seed_XXX/genomes.npy``) is evaluated on its run's initial conditions and its held-out ones; both scores
must equal, bit for bit, what the job's ``summary.json`` (and a run's ``run.json``) says. The world is built only
from rovermarl's own classes (:func:`~rovermarl.runner.trust.check_targets`) unless ``--trust-config`` (a world
plug-in's job, e.g. ``results/learners``' random_pois ones, run from the repository root).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from omegaconf import OmegaConf

from rovermarl.analysis.results import ResultsError
from rovermarl.analysis.sweep import RUN_DIR
from rovermarl.record.safe_read import Spec, check_tree, load_npy, load_npz, read_json, read_yaml
from rovermarl.runner.chunk import build, heldout_score, to_plain, upgrade
from rovermarl.runner.trust import check_targets

RUNS = 100_000            # runs a job's genomes.npz may hold


@dataclass
class Checked:
    """One job's verdict: ``ok``, and one line saying what was compared (or the first difference)."""

    job: str
    ok: bool
    line: str
    refused: bool = False              # its files or config were refused: not re-scored


def _config(job: Path, trust: bool = False) -> dict:
    for path in (job / "config.yaml", job / ".hydra" / "config.yaml"):
        if path.is_file():
            cfg = upgrade(OmegaConf.create(read_yaml(path, kind="config")))
            if not trust:
                check_targets(cfg, str(path))
            return to_plain(cfg)
    raise ResultsError(f"{job}: no config.yaml")


def _teams(job: Path, world) -> dict[int, np.ndarray]:
    """Seed -> final team (N, P) of every run of ``job`` that kept one; each file's header checked before it is read
    (:mod:`rovermarl.record.safe_read`)."""
    n, p = world.n_rovers, world.n_params
    if (job / "genomes.npz").is_file():
        a = load_npz(job / "genomes.npz", {"seed": Spec((None,), "i", RUNS), "genomes": Spec((None, n, p), "f", RUNS)},
                     required=("seed", "genomes"))
        if len(a["seed"]) != len(a["genomes"]):
            raise ResultsError(f"{job / 'genomes.npz'}: {len(a['seed'])} seeds, {len(a['genomes'])} teams")
        return {int(s): np.asarray(g, dtype=np.float64) for s, g in zip(a["seed"], a["genomes"], strict=True)}
    return {int(path.parent.name.removeprefix("seed_")): np.asarray(load_npy(path, Spec((n, p), "f")), np.float64)
            for path in sorted((job / "runs").glob("seed_*/genomes.npy")) if RUN_DIR.fullmatch(path.parent.name)}


def _recorded(job: Path, seed: int, summary: dict) -> tuple[float | None, float | None]:
    """(final, held-out) score of run ``seed`` as the job recorded it; a run's ``run.json`` must agree with the
    summary where both exist."""
    final, held = (summary.get(key, {}).get(str(seed)) for key in ("final_score", "heldout_score"))
    run_json = job / "runs" / f"seed_{seed:03d}" / "run.json"
    if run_json.is_file():
        run = read_json(run_json, kind="run")
        for key, value in (("final_score", final), ("heldout_score", held)):
            if value is not None and run.get(key) != value:
                raise ResultsError(f"{run_json}: {key} {run.get(key)} against {value} in summary.json")
        final, held = run.get("final_score", final), run.get("heldout_score", held)
    return final, held


def verify_job(job: Path, trust: bool = False) -> Checked:
    """Re-score every team of one job dir (``trust``: build the classes its config names, a plug-in's included)."""
    cfg = _config(job, trust)
    parts = build(cfg)
    world = parts.world
    summary = read_json(job / "summary.json", kind="summary")
    teams = _teams(job, world)
    if not teams:
        return Checked(job.name, False, "no final teams")
    fresh, generations = parts.evaluation["fresh_ic"], int(cfg["generations"])
    heldouts = 0
    for seed, team in sorted(teams.items()):
        final, held = _recorded(job, seed, summary)
        if final is None:
            return Checked(job.name, False, f"seed {seed}: no recorded final score")
        got = world.evaluate(team, world.run_ic(seed, generations if fresh else 0))
        if got != final:
            return Checked(job.name, False, f"seed {seed}: final score {got!r} re-scored, {final!r} recorded")
        if held is not None:
            got = heldout_score(parts, seed, team)
            if got != held:
                return Checked(job.name, False, f"seed {seed}: held-out score {got!r} re-scored, {held!r} recorded")
            heldouts += 1
    missing = sorted(set(map(int, summary.get("final_score", {}))) - set(teams))
    if missing:
        return Checked(job.name, False, f"runs {missing} have no final team")
    return Checked(job.name, True, f"{len(teams)} teams re-score: final scores {len(teams)}/{len(teams)}, "
                                   f"held-out {heldouts}/{len(teams)} equal")


def verify(path: Path, trust: bool = False) -> list[Checked]:
    """Every job of ``path`` (a results or sweep dir, or one job dir) that has final teams (``trust``: as in
    :func:`verify_job`)."""
    path = Path(path)
    if not path.is_dir():
        raise ResultsError(f"{path}: not a directory")
    check_tree(path)                     # no link, FIFO or device anywhere under it: nothing is followed
    jobs = [path] if (path / "summary.json").is_file() else sorted(p.parent for p in path.glob("*/summary.json"))
    jobs = [j for j in jobs if (j / "genomes.npz").is_file() or any(
        RUN_DIR.fullmatch(g.parent.name) for g in (j / "runs").glob("seed_*/genomes.npy"))]   # seed_XXX.<hash>: aside
    if not jobs:
        raise ResultsError(f"{path}: no job with final teams (genomes.npz or runs/seed_*/genomes.npy)")
    checked = []
    for job in jobs:                     # a job whose file (safe_read) or config (ConfigError) is refused: its one line
        try:
            checked.append(verify_job(job, trust))
        except (ResultsError, ValueError, OSError) as e:
            checked.append(Checked(job.name, False, str(e), refused=True))
    return checked
