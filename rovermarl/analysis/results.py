"""Compact results of a sweep, and reading them back: :func:`load`.

:mod:`rovermarl.analysis.export` writes them (``python -m rovermarl.analysis export SWEEP_DIR RESULTS_DIR``). A sweep
dir holds gigabytes (every generation of every run, trajectories, ``.rrd`` recordings); the compact results keep what
the claims and figures need, in a few MB, with the same job-dir layout::

    RESULTS_DIR/<job>/summary.json   the job's summary.json, plus label, setup, budget, coupling per run, compute
    RESULTS_DIR/<job>/config.yaml    the job's composed config
    RESULTS_DIR/<job>/curves.npz     seed (R,); generations (); grid (M,) log-spaced generations, score (R, M) there;
                                     the exact curves as change points: step_run (S,), step_generation (S,),
                                     step_score (S,) (lossless; few, as a parent score never falls);
                                     probs (R, M, K) float32 on the grid (bandit jobs only)
    RESULTS_DIR/fig6.npz             one duo k=1 run's Fig. 6 data (:func:`rovermarl.analysis.export.export_fig6`)
    RESULTS_DIR/compute.json         team evaluations, agent-steps (theirs, and a learner's own: PPO's training steps)
                                     and wall time of the whole sweep
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from omegaconf import DictConfig, OmegaConf

from rovermarl.analysis.curves import Curves, read_exported
from rovermarl.record.safe_read import check_tree, read_json, read_yaml

# summary["coupling"][seed][kind]: single-rover updates accepted with a higher score, with an equal one, rejected
COUPLING_KINDS = ("improved", "neutral", "rejected")


class ResultsError(Exception):
    """Input that cannot be exported or read as results; ``str(err)`` is one line."""


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

    def config(self) -> DictConfig:
        """The job's composed config (read safely: a regular file, no tag runs anything)."""
        return OmegaConf.create(read_yaml(self.path / "config.yaml", kind="config") or {})


def load(path: Path) -> list[Result]:
    """Every exported job under the results dir ``path`` (sorted by name)."""
    path = Path(path)
    if not path.is_dir():
        raise ResultsError(f"not a results directory: {path}")
    out = []
    try:
        check_tree(path)
        for curves_file in sorted(path.glob("*/curves.npz")):
            job_dir = curves_file.parent
            summary = read_json(job_dir / "summary.json", kind="summary")
            if not isinstance(summary, dict):
                raise ResultsError(f"{job_dir / 'summary.json'} is not a job summary")
            config = read_yaml(job_dir / "config.yaml", kind="config") if (job_dir / "config.yaml").exists() else {}
            generations = config.get("generations") if isinstance(config, dict) else None
            e = read_exported(job_dir, len(summary.get("seeds") or []) or None, generations)
            out.append(Result(job_dir.name, str(summary.get("label")), str(summary.get("setup")), summary, e.curves,
                              e.grid, e.probs, job_dir))
    except OSError as e:                                    # safe_read's Unsafe and Corrupt: one line
        raise ResultsError(str(e)) from None
    if not out:
        raise ResultsError(f"no exported job (*/curves.npz) in {path}; run `python -m rovermarl.analysis export`")
    return out


def load_study(results: Path, name: str) -> list[dict]:
    """The jobs of a study's compact numbers, ``RESULTS/<name>.json`` (the readings and baselines studies)."""
    path = Path(results) / f"{name}.json"
    try:
        return read_json(path)["jobs"]
    except (OSError, ValueError, KeyError, TypeError) as e:
        raise ResultsError(f"{path}: no {name} results ({type(e).__name__}); run `export` first") from None
