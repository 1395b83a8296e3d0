"""Runs on Ray: the backend :class:`Ray` (``parallel=ray``). One embedded Ray (or a joined cluster) serves every job
of a multirun, and one pool of :class:`ChunkWorker` actors (one CPU each) is reused by all its jobs. Only plain config
dicts, integer seeds and run states (arrays and numbers) cross to the workers; the driver writes every file."""

from __future__ import annotations

import contextlib
import logging
import os
import signal
import socket
import sys
import tempfile
import threading
import time
from dataclasses import dataclass
from functools import partial

import psutil
import ray

from rovermarl import errors
from rovermarl.parallel import Backend
from rovermarl.parallel.errors import BackendError

log = logging.getLogger("rovermarl")


@ray.remote(num_cpus=1)
class ChunkWorker:
    """Runs chunks with the chunk function it was started with, a pure function of its arguments. The actor keeps
    no run state, so when its process dies Ray restarts it and reruns the pending call (``parallel.retries``) with
    the same inputs and the same result. Actor calls skip the scheduler round trip that tasks pay."""

    def __init__(self, advance):
        self._advance = advance

    def advance(self, cfg: dict, seed: int, state: dict | None, n: int) -> dict:
        return self._advance(cfg, seed, state, n)


_POOL: list = []
_POOL_FN: list = []                                                  # the chunk function the pool's actors run


def release_pool() -> None:
    """Stop the pool's actors and free their CPUs (before IC-shard actors need them)."""
    for actor in _POOL:
        ray.kill(actor)
    forget_pool()


def forget_pool() -> None:
    """Drop the pool's actor handles (Ray is being shut down; a later Ray starts a new pool)."""
    _POOL.clear()
    _POOL_FN.clear()


def _workers(n: int, retries: int, advance) -> list:
    """``n`` actors of the pool running ``advance``, started on first use."""
    if _POOL_FN and _POOL_FN[0] is not advance:
        release_pool()
    _POOL_FN[:] = [advance]
    while len(_POOL) < n:
        _POOL.append(ChunkWorker.options(max_restarts=retries, max_task_retries=retries).remote(advance))
    return _POOL[:n]


def _watched(call):
    """``call()``, with Ray's own failures (not a chunk's exception) turned into one-line :class:`BackendError`."""
    try:
        return call()
    except (ray.exceptions.RayActorError, ray.exceptions.RaySystemError, ray.exceptions.WorkerCrashedError,
            ray.exceptions.ObjectLostError, ray.exceptions.GetTimeoutError, ConnectionError) as e:
        first = (str(e).strip().splitlines() or [""])[0][:200]
        raise BackendError(f"Ray failed: {type(e).__name__}: {first}") from None


def _alive(raylets: list) -> None:
    """:class:`BackendError` if Ray's GCS no longer answers or a raylet of this driver died (Ray itself would
    keep waiting, print its C++ logs and abort this process after 60 s)."""
    address = ray.get_runtime_context().gcs_address
    try:
        _probe(address, timeout=2.0)
    except ConnectionError as e:
        raise BackendError(f"Ray's GCS is gone: {e}") from None
    for p in raylets:
        if not p.is_running() or p.status() == "zombie":
            raise BackendError(f"Ray's raylet (PID {p.pid}) died")


def ensure_ray(ray_cfg) -> None:
    """Start an embedded local Ray, or join ``ray.address``, unless Ray already runs in this process."""
    if ray.is_initialized():
        return
    # Ray's C++ core copies its error lines to the driver's stderr; when Ray dies under a sweep they would come
    # before our one-line error. A user's own setting wins (README, "Configuration").
    os.environ.setdefault("RAY_BACKEND_LOG_LEVEL", "fatal")
    if ray_cfg.address:
        _probe(ray_cfg.address)
        where = {"address": ray_cfg.address}
    else:
        where = {"num_cpus": ray_cfg.num_cpus or os.cpu_count(), "include_dashboard": False}
    with _held_stderr(), _signals_noted() as seen:
        ray.init(**where, log_to_driver=False, logging_level=logging.ERROR)
    if signal.SIGTERM in seen:                      # Ray's start swallowed what its own SIGTERM handler raised
        raise SystemExit(signal.SIGTERM)
    if signal.SIGINT in seen:                       # or what the caller's SIGINT handler raised
        raise KeyboardInterrupt


@contextlib.contextmanager
def _signals_noted():
    """Yield a list that holds, after the block, the signal numbers delivered during it, as the C-level handler
    saw them (:func:`signal.set_wakeup_fd`), whatever became of the exception a Python handler raised: a SIGTERM
    during ``ray.init`` once ended a launch with exit 0, the signal lost (CI, 2026-12-07). Outside the main thread,
    where no handler runs, the list stays empty."""
    seen: list[int] = []
    if threading.current_thread() is not threading.main_thread():
        yield seen
        return
    r, w = socket.socketpair()
    r.setblocking(False)
    w.setblocking(False)
    previous = signal.set_wakeup_fd(w.fileno(), warn_on_full_buffer=False)
    try:
        yield seen
    finally:
        signal.set_wakeup_fd(previous)
        with contextlib.suppress(BlockingIOError):
            while data := r.recv(4096):
                seen.extend(data)
        r.close()
        w.close()


@contextlib.contextmanager
def _held_stderr():
    """Hold what is written to file descriptor 2 (Ray's C++ core announces its log level there as it starts) and
    show it only if the block fails (not when a signal cut it: the launch then ends in one line)."""
    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile() as held:
        os.dup2(held.fileno(), 2)
        try:
            yield
        except Exception:
            os.dup2(saved, 2)
            held.seek(0)
            sys.stderr.write(held.read().decode(errors="replace"))
            raise
        finally:
            os.dup2(saved, 2)
            os.close(saved)


PROBE_S = 5.0                        # seconds: a HOST:PORT that does not answer as Ray (gRPC) within this is refused
_HTTP2 = b"PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n" + bytes(3) + b"\x04" + bytes(5)   # client preface + empty SETTINGS


def _probe(address: str, timeout: float = PROBE_S) -> None:
    """Fail fast on a HOST:PORT that is not a Ray server (Ray itself waits for minutes, deaf to SIGTERM): Ray's GCS and
    its client server speak gRPC, so a connection that gets no HTTP/2 SETTINGS frame back within ``timeout`` seconds
    (refused, closed or silent) is refused. A signal during the wait ends it (the caller's handlers run)."""
    host, sep, port = address.removeprefix("ray://").rpartition(":")
    if not sep or not port.isdigit():
        return  # "auto" and other forms: let Ray resolve them
    try:
        with socket.create_connection((host, int(port)), timeout=timeout) as conn:
            conn.sendall(_HTTP2)
            head, deadline = b"", time.monotonic() + timeout
            while len(head) < 9:
                conn.settimeout(max(deadline - time.monotonic(), 0.001))
                chunk = conn.recv(9 - len(head))
                if not chunk:
                    raise ConnectionError("the connection was closed")
                head += chunk
    except TimeoutError:
        raise ConnectionError(f"nothing answers as Ray at {host}:{port} (no reply in {timeout:g} s)") from None
    except OSError as e:
        raise ConnectionError(f"nothing answers as Ray at {host}:{port} ({e.strerror or e})") from None
    if head[3] != 0x04:                                            # an HTTP/2 frame header: type at byte 3
        raise ConnectionError(f"nothing answers as Ray at {host}:{port} (not a gRPC server)")


@dataclass(frozen=True)
class Ray(Backend):
    """The runs on a pool of Ray actors (one CPU each), a chunk of generations per actor call; with ``ic_shards`` > 1
    one run at a time, each team evaluation's episodes split over that many actors (:mod:`rovermarl.parallel.shards`:
    heavy worlds only). The keys' defaults and meanings: ``conf/parallel/ray.yaml``."""

    workers: int | None
    retries: int
    ic_shards: int
    stall_timeout: float
    uses_ray = True

    def __post_init__(self):
        super().__post_init__()
        if self.workers is not None:
            errors.integer("workers", self.workers, 1)
        errors.integer("retries", self.retries, 0)
        errors.integer("ic_shards", self.ic_shards, 1)
        errors.number("stall_timeout", self.stall_timeout, 0, lo_open=True)

    @property
    def shards(self) -> int:
        return self.ic_shards

    def run(self, cfg, job: dict, records, on_chunk, advance) -> None:
        ensure_ray(cfg.ray)
        (_run_sharded if self.ic_shards > 1 else _run_pool)(self, job, records, on_chunk, advance)


def _run_sharded(par: Ray, job: dict, records, on_chunk, advance) -> None:
    """Advance the records one after another, each evaluation split over ``parallel.ic_shards`` actors."""
    from rovermarl.parallel.shards import ShardActor, ShardedEvaluation

    release_pool()                                                      # its actors hold the CPUs shards need
    actors = [ShardActor.remote(job) for _ in range(par.ic_shards)]
    evaluation = partial(ShardedEvaluation, actors)
    try:
        for rec in records:
            while not rec.done:
                on_chunk(rec, rec.add(advance(job, rec.seed, rec.state, par.chunk, evaluation)))
    finally:
        for a in actors:
            ray.kill(a)


def _run_pool(par: Ray, job: dict, records, on_chunk, advance) -> None:
    """Advance the records on the actor pool: one chunk per run in flight, at most one per actor."""
    cpus = max(1, int(ray.cluster_resources().get("CPU", 1)))
    slots = par.workers or cpus
    if slots > cpus:                     # an actor holds one CPU: the ones beyond Ray's CPUs would never start
        log.info("parallel.workers=%d is more than the %d CPUs of Ray: using %d workers", slots, cpus, cpus)
        slots = cpus
    queue = [rec for rec in records if not rec.done]
    free = _workers(min(slots, len(queue)), par.retries, advance)
    job_cfg, inflight, stall = ray.put(job), {}, float(par.stall_timeout)

    def submit(rec, worker):
        inflight[worker.advance.remote(job_cfg, rec.seed, rec.state, par.chunk)] = rec, worker

    while queue and free:
        submit(queue.pop(0), free.pop())
    last = probed = time.monotonic()
    raylets = [p for p in psutil.Process().children(recursive=True) if "raylet" in p.name()]   # an embedded Ray's
    with _continued() as resumed:
        while inflight:
            ready, _ = _watched(lambda: ray.wait(list(inflight), num_returns=1, timeout=0.5))
            if time.monotonic() - probed > 0.5:                        # Ray would wait, dump its logs, then abort
                _alive(raylets)
                probed = time.monotonic()
            last = max(last, resumed[0])                   # the time this launch was stopped is no stall
            if not ready:
                if time.monotonic() - last > stall:
                    raise BackendError(f"no chunk finished in {stall:g} s (parallel.stall_timeout): Ray is stuck "
                                       "or its processes died")
                continue
            last = time.monotonic()
            [ref] = ready
            rec, worker = inflight.pop(ref)
            on_chunk(rec, rec.add(_watched(lambda ref=ref: ray.get(ref))))
            if not rec.done:
                submit(rec, worker)
            elif queue:
                submit(queue.pop(0), worker)


@contextlib.contextmanager
def _continued():
    """A list whose one item is when this process last continued after being stopped (SIGCONT: after Ctrl-Z and
    ``fg``, or a scheduler's suspend and resume, as SLURM's ``scontrol suspend``); the stall timer starts again there.
    Only the main thread may set a handler: elsewhere the list stays ``[-inf]``."""
    resumed = [-float("inf")]
    if threading.current_thread() is not threading.main_thread():
        yield resumed
        return

    def note(*_):
        resumed[0] = time.monotonic()
    previous = signal.signal(signal.SIGCONT, note)
    try:
        yield resumed
    finally:
        signal.signal(signal.SIGCONT, previous)
