"""Where the independent runs of a job execute: in this process (``parallel=serial``), on a pool of Ray actors, or
one after another with each evaluation split over Ray actors (``parallel.ic_shards``).

This package only dispatches chunks. The chunk function ``advance(cfg, seed, state, n, evaluation=...)`` (see
:func:`rovermarl.runner.chunk.advance`) is passed in; each backend calls it, and ``on_chunk(record, advanced)``
runs in this process after each chunk. A record (:class:`rovermarl.record.checkpoint.RunRecord`) has ``seed``,
``state``, ``done`` and ``add(chunk) -> generations advanced``.
"""

from __future__ import annotations

from collections.abc import Callable

from omegaconf import DictConfig

from rovermarl.parallel.errors import BackendError

__all__ = ["BackendError", "run_records", "run_serial"]
OnChunk = Callable[[object, int], None]


def run_records(cfg: DictConfig, job: dict, records: list, on_chunk: OnChunk, advance: Callable) -> None:
    """Advance every record to its end with ``advance`` on the backend of ``cfg.parallel``; ``job`` is the plain
    config the chunks get."""
    if cfg.parallel.backend == "serial":
        run_serial(cfg, job, records, on_chunk, advance)
    elif cfg.parallel.get("ic_shards", 1) > 1:
        from rovermarl.parallel.shards import run_sharded
        run_sharded(cfg, job, records, on_chunk, advance)
    else:
        from rovermarl.parallel.ray_backend import run_ray
        run_ray(cfg, job, records, on_chunk, advance)


def run_serial(cfg, job: dict, records: list, on_chunk: OnChunk, advance: Callable) -> None:
    for rec in records:
        while not rec.done:
            on_chunk(rec, rec.add(advance(job, rec.seed, rec.state, cfg.parallel.chunk)))
