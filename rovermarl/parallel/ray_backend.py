"""Seeds on Ray actors. One embedded Ray (or a joined cluster) serves every job of a multirun, and
the actor pool is reused across jobs. Only integers and plain config dicts cross to the workers."""

from __future__ import annotations

import logging
import os
import socket

import ray

from rovermarl.evolution import Run, evolve
from rovermarl.parallel import plain

_POOL: list = []


@ray.remote(num_cpus=1)
class SeedWorker:
    """Holds the runs it is advancing; each call advances one run by a chunk of generations."""

    def __init__(self):
        self.runs: dict[int, Run] = {}

    def advance(self, cfg: dict, seed: int, n: int):
        """Returns ``(seed, generations advanced, result or None)``; the result once the run is done."""
        run = self.runs.get(seed)
        if run is None:
            run = self.runs[seed] = Run(cfg, seed)
        before = run.generation
        evolve(run, n)
        if run.done:
            del self.runs[seed]
            return seed, run.generation - before, run.result()
        return seed, run.generation - before, None


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


def _workers(n: int) -> list:
    while len(_POOL) < n:
        _POOL.append(SeedWorker.remote())
    return _POOL[:n]


def run_ray(cfg, seeds, on_result, on_progress) -> None:
    ensure_ray(cfg.ray)
    n_workers = cfg.parallel.workers or max(1, int(ray.cluster_resources().get("CPU", 1)))
    workers = _workers(min(n_workers, len(seeds)))
    job_cfg = ray.put(plain(cfg))
    chunk = cfg.parallel.chunk
    queue = list(seeds)
    inflight = {}
    for w in workers:
        if queue:
            inflight[w.advance.remote(job_cfg, queue.pop(0), chunk)] = w
    while inflight:
        [ref], _ = ray.wait(list(inflight), num_returns=1)
        worker = inflight.pop(ref)
        seed, advanced, result = ray.get(ref)
        on_progress(advanced)
        if result is None:
            inflight[worker.advance.remote(job_cfg, seed, chunk)] = worker
            continue
        on_result(result)
        if queue:
            inflight[worker.advance.remote(job_cfg, queue.pop(0), chunk)] = worker
