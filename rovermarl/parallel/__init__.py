"""Where the independent runs of a job execute: in this process (``parallel=serial``) or on Ray actors.

Both go through :func:`advance`: a run moves forward in chunks of ``parallel.chunk`` generations, each
chunk starting from the compact state the previous one returned. A chunk is therefore a pure function of
``(config, seed, state)``: Ray can retry it on another worker after a crash and get the same numbers.
"""

from __future__ import annotations

import copy
import dataclasses
import json
import os
from collections.abc import Callable

import numpy as np
from omegaconf import DictConfig, OmegaConf

from rovermarl.evolution import Run, build, evolve
from rovermarl.record.checkpoint import RunRecord

OnChunk = Callable[[RunRecord, int], None]
_PARTS: dict[str, object] = {}                                      # per process: built parts of each config


def advance(cfg: dict, seed: int, state: dict | None, n: int, evaluator=None) -> dict:
    """Advance run ``seed`` by up to ``n`` generations from ``state`` (None: from its start).

    ``evaluator(run)``, if given, returns the team-evaluation function to use instead of local evaluation.

    Returns the chunk: ``start``, ``stop``, the history of generations [start, stop), the events logged
    in them, the new ``state``; plus ``initial_score`` and the initial conditions when starting, and the
    final ``genomes`` when the run is done.
    """
    run = Run(cfg, seed, parts=_parts(cfg), state=state)
    if evaluator is not None:
        run.evaluate = evaluator(run)
    start = run.generation
    events = run.recorder.drain() if state is None else None          # generation 0's events
    evolve(run, n)
    chunk = {"seed": run.seed, "start": start, "stop": run.generation, "state": run.state(),
             **run.history.arrays(start, run.generation), **run.recorder.drain()}
    if events is not None:
        chunk = {**chunk, **_prepend(events, chunk), "initial_score": run.history.score[0],
                 "ic_xy": run.ic[0], "ic_heading": run.ic[1]}
    if run.done:
        chunk["genomes"] = run.parents_genomes
    if os.environ.get("ROVERMARL_WORK_LOG"):                         # benchmarks/soak.py counts executed work
        with open(os.environ["ROVERMARL_WORK_LOG"], "a") as f:
            f.write(f"{seed} {start} {run.generation}\n")
    return chunk


def _prepend(first: dict, chunk: dict) -> dict:
    return {key: np.concatenate([first[key], chunk[key]]) for key in first}


def _parts(cfg: dict):
    """Built world and operators for ``cfg``, cached per process; every run gets a fresh selector."""
    key = json.dumps(cfg, sort_keys=True, default=str)
    if key not in _PARTS:
        if len(_PARTS) > 16:
            _PARTS.clear()
        _PARTS[key] = build(cfg)
    parts = _PARTS[key]
    return dataclasses.replace(parts, selector=copy.deepcopy(parts.selector))


def run_records(cfg: DictConfig, records: list[RunRecord], on_chunk: OnChunk) -> None:
    """Advance every record to its end; ``on_chunk(record, advanced)`` runs in this process after each chunk."""
    if cfg.parallel.backend == "serial":
        run_serial(cfg, records, on_chunk)
    elif cfg.parallel.get("ic_shards", 1) > 1:
        from rovermarl.parallel.shards import run_sharded
        run_sharded(cfg, records, on_chunk)
    else:
        from rovermarl.parallel.ray_backend import run_ray
        run_ray(cfg, records, on_chunk)


def run_serial(cfg, records, on_chunk) -> None:
    job = plain(cfg)
    for rec in records:
        while not rec.done:
            on_chunk(rec, rec.add(advance(job, rec.seed, rec.state, cfg.parallel.chunk)))


def plain(cfg: DictConfig) -> dict:
    """The job config as plain containers (what crosses to workers), without Hydra's own node."""
    out = OmegaConf.to_container(cfg, resolve=True)
    out.pop("hydra", None)
    return out
