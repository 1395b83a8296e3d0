"""One Hydra job: run its seeds (serially or on Ray), write every run's files and the job summary."""

from __future__ import annotations

import logging
import time
from pathlib import Path

from omegaconf import DictConfig
from tqdm.auto import tqdm

from rovermarl.config import validate
from rovermarl.parallel import run_seeds
from rovermarl.record.outputs import save_run, summarize, write_json

log = logging.getLogger("rovermarl")
GROUPS = ("setup", "env", "policy", "mutation", "selection", "k", "team", "parallel")


def run_job(cfg: DictConfig, job_dir: Path, name: str = "job", choices: dict | None = None) -> dict:
    """Run ``cfg.seeds`` independent runs into ``job_dir``; returns the summary (also summary.json)."""
    validate(cfg)
    seeds = [cfg.seed + i for i in range(cfg.seeds)]
    results: dict[int, dict] = {}
    t0 = time.perf_counter()
    with tqdm(total=len(seeds) * cfg.generations, desc=name, unit="gen", disable=None, leave=False,
              dynamic_ncols=True) as bar:
        def on_result(result: dict) -> None:
            save_run(job_dir, result)
            results[result["seed"]] = result
            bar.set_postfix_str(f"runs {len(results)}/{len(seeds)}")

        run_seeds(cfg, seeds, on_result, bar.update)
    wall = time.perf_counter() - t0
    summary = summarize(choices or {}, seeds, results, list(cfg.levels), wall,
                        team_evals=len(seeds) * (cfg.generations + 1))
    write_json(Path(job_dir) / "summary.json", summary)
    log.info("%s: median final score %.4g over %d seeds, %.1f s (%.0f team evals/s)", name,
             summary["median_final_score"], len(seeds), wall, summary["team_evals_per_s"])
    return summary
