"""Score curves: the one reader of a sweep run's ``curve.npz`` (the parent score after every generation (G+1,); a
bandit's arm probabilities (G, K)) and of an exported job's ``curves.npz`` (:mod:`rovermarl.analysis.results`)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rovermarl.record.safe_read import FREE, RunSize, Spec, load_npz

GRID_POINTS = 400
EXPORTED_BYTES = 256 << 20      # an exported job's curves at most (results/paper's largest holds under 1 MB)


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


@dataclass
class Exported:
    """The content of an exported job's ``curves.npz``."""

    curves: Curves
    grid: np.ndarray            # (M,) log-spaced generations
    probs: np.ndarray | None    # (R, M, K) float32 bandit arm probabilities on the grid, None for fixed k


def read_exported(job_dir: Path, seeds: int | None = None, generations: int | None = None) -> Exported:
    """Read ``job_dir/curves.npz`` of an exported job (of ``seeds`` runs of ``generations``, when known: each
    member's size is checked against them before it is read, :mod:`rovermarl.record.safe_read`)."""
    r = seeds if isinstance(seeds, int) and 0 < seeds <= 1 << 16 else None
    g = generations if isinstance(generations, int) and 0 <= generations <= 10**10 else None
    steps = FREE if r is None or g is None else min(r * (g + 1), FREE)
    wide = GRID_POINTS + 1 if r is not None else 4096                  # the grid's points (and R when unknown)
    z = load_npz(Path(job_dir) / "curves.npz", {
        "seed": Spec((r,), "iu", 1 << 16), "generations": Spec((), "iu"), "step_run": Spec((None,), "iu", steps),
        "step_generation": Spec((None,), "iu", steps), "step_score": Spec((None,), "f", steps),
        "grid": Spec((None,), "iu", GRID_POINTS + 1), "score": Spec((r, None), "f", wide),
        "probs": Spec((r, None, None), "f", wide)},
        required=("seed", "generations", "step_run", "step_generation", "step_score", "grid"), max_bytes=EXPORTED_BYTES)
    curves = Curves(z["seed"], int(z["generations"]), z["step_run"], z["step_generation"], z["step_score"])
    return Exported(curves, z["grid"], z.get("probs"))


def read_run_curve(run_dir: Path, size: RunSize | None = None) -> tuple[np.ndarray, np.ndarray | None]:
    """(score (G+1,), probs (G, K) or None for fixed k) of a sweep's run dir, as float64 (``size``: what the run's
    config implies, checked before anything is read)."""
    curve = read_run_arrays(run_dir, size)
    probs = np.asarray(curve["probs"], dtype=np.float64) if "probs" in curve else None
    return np.asarray(curve["score"], dtype=np.float64), probs


def read_run_arrays(run_dir: Path, size: RunSize | None = None) -> dict[str, np.ndarray]:
    """Every array of a sweep's run ``curve.npz`` (score, k, accepted, child_score, and what else was recorded),
    each checked against ``size`` (:class:`~rovermarl.record.safe_read.RunSize`) before it is read."""
    return load_npz(Path(run_dir) / "curve.npz", (size or RunSize()).curve(), required=("score",), stored=True)
