"""Result files of a job, written atomically (temp file in the same directory, then rename).

Job dir layout::

    summary.json
    runs/seed_XXX/curve.npz               score (G+1), k (G), accepted (G), child_score (G), probs (G, K)
    runs/seed_XXX/genomes.npy             final team genomes (N, P)
    runs/seed_XXX/initial_conditions.npz  xy (E, N, 2), heading (E, N)
"""

from __future__ import annotations

import contextlib
import json
import os
import tempfile
from pathlib import Path

import numpy as np

CURVE_KEYS = ("score", "k", "accepted", "child_score", "probs")


@contextlib.contextmanager
def atomic_open(path: Path, mode: str = "wb"):
    """Open a temp file next to ``path``; rename it onto ``path`` only if the block succeeds."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, mode) as f:
            yield f
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def run_dir(job_dir: Path, seed: int) -> Path:
    return Path(job_dir) / "runs" / f"seed_{seed:03d}"


def save_run(job_dir: Path, result: dict) -> Path:
    """Write one finished run's files; returns its directory."""
    out = run_dir(job_dir, result["seed"])
    with atomic_open(out / "curve.npz") as f:
        np.savez(f, **{k: result[k] for k in CURVE_KEYS if k in result})
    with atomic_open(out / "genomes.npy") as f:
        np.save(f, result["genomes"])
    with atomic_open(out / "initial_conditions.npz") as f:
        np.savez(f, xy=result["ic_xy"], heading=result["ic_heading"])
    return out


def first_reaching(score: np.ndarray, level: float) -> int | None:
    """First generation g with score[g] >= level (score[0] is the initial team), or None."""
    hits = np.flatnonzero(score >= level)
    return int(hits[0]) if hits.size else None


def summarize(choices: dict, seeds: list[int], results: dict[int, dict], levels, wall_time_s: float,
              team_evals: int) -> dict:
    """The job's summary: config choices, per-seed final scores and first generations reaching each level."""
    final = {str(s): float(results[s]["score"][-1]) for s in seeds}
    return {
        "choices": choices,
        "seeds": list(seeds),
        "final_score": final,
        "median_final_score": float(np.median(list(final.values()))),
        "first_generation_reaching": {
            str(lv): {str(s): first_reaching(results[s]["score"], lv) for s in seeds} for lv in levels},
        "wall_time_s": wall_time_s,
        "team_evals": team_evals,
        "team_evals_per_s": team_evals / wall_time_s if wall_time_s > 0 else None,
    }


def write_json(path: Path, obj: dict) -> None:
    with atomic_open(path, "w") as f:
        json.dump(obj, f, indent=2)
        f.write("\n")
