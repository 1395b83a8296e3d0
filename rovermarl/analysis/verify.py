"""Committed teams that re-score (issue 43): ``python -m rovermarl.analysis verify DIR``.

Every job of ``DIR`` with final teams is re-scored: a compact results dir's ``<job>/genomes.npz`` (seed (R,),
genomes (R, N, P) float64; written by ``analysis export`` and ``analysis heldout merge``), or a sweep's
``<job>/runs/seed_XXX/genomes.npy``. Each team is evaluated on its run's initial conditions and on its held-out
ones, and both scores must equal, bit for bit, what the job's ``summary.json`` (and, in a sweep, each run's
``run.json``) says. The world is rebuilt from the job's own config only with rovermarl's own classes
(:func:`~rovermarl.runner.trust.check_targets`): a results dir runs no code of its own.
"""

from __future__ import annotations

import json
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from omegaconf import OmegaConf

from rovermarl.analysis.results import ResultsError
from rovermarl.runner.chunk import build, heldout_score, to_plain, upgrade
from rovermarl.runner.trust import check_targets

TEAMS_LIMIT = 64 << 20    # bytes of a genomes.npz's arrays: 1000 runs of 4 x 2000 float64 parameters fit


@dataclass
class Checked:
    """One job's verdict: ``ok``, and one line saying what was compared (or the first difference)."""

    job: str
    ok: bool
    line: str


def _config(job: Path) -> dict:
    for path in (job / "config.yaml", job / ".hydra" / "config.yaml"):
        if path.is_file() and not path.is_symlink():
            cfg = upgrade(OmegaConf.load(path))
            check_targets(cfg, str(path))
            return to_plain(cfg)
    raise ResultsError(f"{job}: no config.yaml")


def _read_npz(path: Path, shape_of: dict) -> dict:
    """The arrays of ``path``, each checked against ``shape_of[name](shape)`` from its header before it is read; no
    member but those; at most :data:`TEAMS_LIMIT` bytes in all."""
    try:
        return _read_members(path, shape_of)
    except (OSError, ValueError, zipfile.BadZipFile) as e:
        raise ResultsError(f"{path}: unreadable ({e})") from None


def _read_members(path: Path, shape_of: dict) -> dict:
    with zipfile.ZipFile(path) as z:
        names = {i.filename.removesuffix(".npy"): i for i in z.infolist()}
        if set(names) != set(shape_of) or sum(i.file_size for i in names.values()) > TEAMS_LIMIT:
            raise ResultsError(f"{path}: members {sorted(names)} (want {sorted(shape_of)}, at most {TEAMS_LIMIT} B)")
        out = {}
        for name, info in names.items():
            with z.open(info) as f:
                header = {(1, 0): np.lib.format.read_array_header_1_0,
                          (2, 0): np.lib.format.read_array_header_2_0}.get(np.lib.format.read_magic(f))
                if header is None:
                    raise ResultsError(f"{path}: {name} is not a .npy array of format 1.0 or 2.0")
                shape, _, dtype = header(f)
                if not shape_of[name](shape, dtype):
                    raise ResultsError(f"{path}: {name} has shape {shape} and dtype {dtype}: not this job's")
                f.seek(0)
                out[name] = np.lib.format.read_array(f, allow_pickle=False)
    return out


def _teams(job: Path, world) -> dict[int, np.ndarray]:
    """Seed -> final team (N, P) of every run of ``job`` that kept one."""
    team_shape = (world.n_rovers, world.n_params)
    if (job / "genomes.npz").is_file():
        a = _read_npz(job / "genomes.npz", {
            "seed": lambda s, d: len(s) == 1 and d.kind == "i",
            "genomes": lambda s, d: s[1:] == team_shape and d == np.float64})
        if len(a["seed"]) != len(a["genomes"]):
            raise ResultsError(f"{job / 'genomes.npz'}: {len(a['seed'])} seeds, {len(a['genomes'])} teams")
        return {int(s): g for s, g in zip(a["seed"], a["genomes"], strict=True)}
    out = {}
    for path in sorted((job / "runs").glob("seed_*/genomes.npy")):
        g = np.load(path, mmap_mode="r", allow_pickle=False)
        if g.shape != team_shape:
            raise ResultsError(f"{path}: shape {g.shape}, want {team_shape}")
        out[int(path.parent.name.removeprefix("seed_"))] = np.array(g, dtype=np.float64)
    return out


def _recorded(job: Path, seed: int, summary: dict) -> tuple[float | None, float | None]:
    """(final, held-out) score of run ``seed`` as the job recorded it; a run's ``run.json`` must agree with the
    summary where both exist."""
    final, held = (summary.get(key, {}).get(str(seed)) for key in ("final_score", "heldout_score"))
    run_json = job / "runs" / f"seed_{seed:03d}" / "run.json"
    if run_json.is_file():
        run = json.loads(run_json.read_text())
        for key, value in (("final_score", final), ("heldout_score", held)):
            if value is not None and run.get(key) != value:
                raise ResultsError(f"{run_json}: {key} {run.get(key)} against {value} in summary.json")
        final, held = run.get("final_score", final), run.get("heldout_score", held)
    return final, held


def verify_job(job: Path) -> Checked:
    """Re-score every team of one job dir."""
    cfg = _config(job)
    parts = build(cfg)
    world = parts.world
    summary = json.loads((job / "summary.json").read_text())
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


def verify(path: Path) -> list[Checked]:
    """Every job of ``path`` (a results or sweep dir, or one job dir) that has final teams."""
    path = Path(path)
    if not path.is_dir():
        raise ResultsError(f"{path}: not a directory")
    jobs = [path] if (path / "summary.json").is_file() else sorted(p.parent for p in path.glob("*/summary.json"))
    jobs = [j for j in jobs if (j / "genomes.npz").is_file() or any((j / "runs").glob("seed_*/genomes.npy"))]
    if not jobs:
        raise ResultsError(f"{path}: no job with final teams (genomes.npz or runs/seed_*/genomes.npy)")
    return [verify_job(j) for j in jobs]
