"""Where the independent runs of a job execute: in this process (``parallel=serial``) or on Ray actors."""

from __future__ import annotations

from collections.abc import Callable

from omegaconf import DictConfig, OmegaConf

from rovermarl.evolution import Run, evolve


def run_seeds(cfg: DictConfig, seeds: list[int], on_result: Callable[[dict], None],
              on_progress: Callable[[int], None] = lambda n: None) -> None:
    """Run one CC-(1+1)-ES run per seed; ``on_result(result)`` is called as each run finishes,
    ``on_progress(n)`` after every ``parallel.chunk`` generations of any run."""
    if cfg.parallel.backend == "serial":
        run_serial(cfg, seeds, on_result, on_progress)
    else:
        from rovermarl.parallel.ray_backend import run_ray
        run_ray(cfg, seeds, on_result, on_progress)


def run_serial(cfg, seeds, on_result, on_progress) -> None:
    for seed in seeds:
        run = Run(cfg, seed)
        while not run.done:
            before = run.generation
            evolve(run, cfg.parallel.chunk)
            on_progress(run.generation - before)
        on_result(run.result())


def plain(cfg: DictConfig) -> dict:
    """The job config as plain containers (what crosses to workers), without Hydra's own node."""
    out = OmegaConf.to_container(cfg, resolve=True)
    out.pop("hydra", None)
    return out
