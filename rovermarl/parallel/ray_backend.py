"""Runs as Ray tasks. One embedded Ray (or a joined cluster) serves every job of a multirun. Only plain
config dicts, integer seeds and run states (arrays and numbers) cross to the workers; the driver writes
every file."""

from __future__ import annotations

import logging
import os
import socket

import ray

from rovermarl.parallel import advance, plain


@ray.remote(num_cpus=1, retry_exceptions=False)
def advance_task(cfg: dict, seed: int, state: dict | None, n: int) -> dict:
    """:func:`rovermarl.parallel.advance` as a Ray task. If its worker process dies, Ray reruns it
    (``parallel.retries`` times) from the same inputs, so the chunk's numbers do not change."""
    return advance(cfg, seed, state, n)


def ensure_ray(ray_cfg) -> None:
    """Start an embedded local Ray, or join ``ray.address``, unless Ray already runs in this process."""
    if ray.is_initialized():
        return
    common = {"log_to_driver": False, "logging_level": logging.ERROR}
    if ray_cfg.address:
        _probe(ray_cfg.address)
        ray.init(address=ray_cfg.address, **common)
    else:
        ray.init(num_cpus=ray_cfg.num_cpus or os.cpu_count(), include_dashboard=False, **common)


def _probe(address: str, timeout: float = 5.0) -> None:
    """Fail fast on a HOST:PORT nobody listens on (Ray itself retries for minutes)."""
    host, sep, port = address.removeprefix("ray://").rpartition(":")
    if not sep or not port.isdigit():
        return  # "auto" and other forms: let Ray resolve them
    try:
        socket.create_connection((host, int(port)), timeout=timeout).close()
    except OSError as e:
        raise ConnectionError(f"nothing answers at {host}:{port} ({e.strerror or e})") from None


def run_ray(cfg, records, on_chunk) -> None:
    """Advance the records on Ray, one chunk task per run in flight, at most one per worker slot."""
    ensure_ray(cfg.ray)
    slots = cfg.parallel.workers or max(1, int(ray.cluster_resources().get("CPU", 1)))
    job_cfg = ray.put(plain(cfg))
    chunk = cfg.parallel.chunk
    task = advance_task.options(max_retries=cfg.parallel.retries)
    queue = [rec for rec in records if not rec.done]
    inflight = {}

    def submit(rec):
        inflight[task.remote(job_cfg, rec.seed, rec.state, chunk)] = rec

    while queue and len(inflight) < slots:
        submit(queue.pop(0))
    while inflight:
        [ref], _ = ray.wait(list(inflight), num_returns=1)
        rec = inflight.pop(ref)
        on_chunk(rec, rec.add(ray.get(ref)))
        if not rec.done:
            submit(rec)
        elif queue:
            submit(queue.pop(0))
