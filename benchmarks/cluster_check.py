"""Check that a sweep on a real Ray cluster gives exactly the numbers of a local run.

Starts a Ray head (``ray start --head``) and a second worker node on this machine, one CPU each, with
their own temp dir and a fresh token; runs a small sweep with ``ray.address=127.0.0.1:PORT``, the same
sweep with ``parallel=serial``; compares every array of every run; checks that tasks ran on both nodes;
and stops exactly the processes it started. It never runs ``ray stop``, which would stop every Ray on
the machine. Prints one JSON line; exits 1 if anything differs or a process of the cluster survives.

    python benchmarks/cluster_check.py [--generations 200] [--seeds 3] [--keep]

``tests/test_cluster.py`` runs the same check through :func:`local_cluster` and :func:`compare`.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import re
import secrets
import shutil
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import psutil

ROOT = Path(__file__).resolve().parents[1]


def ray_cli() -> str | None:
    """The ``ray`` executable of this interpreter's environment (else the one on PATH)."""
    here = Path(sys.executable).with_name("ray")
    return str(here) if here.exists() else shutil.which("ray")


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("", 0))
        return s.getsockname()[1]


def cluster_env(token: str) -> dict[str, str]:
    """The environment of every node and driver: token auth on, this cluster's token, no inherited address."""
    env = {k: v for k, v in os.environ.items() if k not in ("RAY_ADDRESS", "RAY_AUTH_TOKEN_PATH")}
    return {**env, "RAY_AUTH_MODE": "token", "RAY_AUTH_TOKEN": token}


def processes(temp_dir: str) -> list[psutil.Process]:
    """The live processes of the cluster in ``temp_dir``: every process whose command line names it
    (GCS, raylets, monitors, dashboard) and all their descendants (agents and workers rename themselves
    ``ray::...``, so only their parent gives them away)."""
    found: dict[int, psutil.Process] = {}
    for p in psutil.process_iter(["cmdline"]):
        args = p.info["cmdline"] or []
        if p.pid != os.getpid() and any(a.endswith(temp_dir) or temp_dir + "/" in a for a in args):
            found[p.pid] = p
            with contextlib.suppress(psutil.Error):
                found.update((c.pid, c) for c in p.children(recursive=True))
    return list(found.values())


def _name(p: psutil.Process) -> str:
    try:
        return p.name()
    except psutil.Error:
        return ""


def stop(temp_dir: str, timeout: float = 10.0) -> list[str]:
    """Terminate the cluster in ``temp_dir`` in ``ray stop``'s order: raylets (their agents and workers
    follow them), then the rest, then the GCS, each SIGTERM then SIGKILL after ``timeout`` s (the GCS and
    the autoscaler monitor ignore SIGTERM while raylets are still up). Returns the survivors (should be
    none), as ``pid command`` strings."""
    stages = (lambda n: n == "raylet", lambda n: n != "gcs_server", lambda n: True)
    for _ in range(2):  # a raylet may still spawn a worker while it goes down: look again
        for stage in stages:
            procs = [p for p in processes(temp_dir) if stage(_name(p))]
            for p in procs:
                with contextlib.suppress(psutil.Error):
                    p.terminate()
            _, alive = psutil.wait_procs(procs, timeout=timeout)
            for p in alive:
                with contextlib.suppress(psutil.Error):
                    p.kill()
            psutil.wait_procs(alive, timeout=5)
        if not processes(temp_dir):
            break
    left = []
    for p in processes(temp_dir):
        with contextlib.suppress(psutil.Error):
            left.append(f"{p.pid} {' '.join(p.cmdline())[:120]}")
    return left


@contextlib.contextmanager
def local_cluster(nodes: int = 2, cpus: int = 1, keep: bool = False,
                  timeout: float = 120) -> Iterator[tuple[str, dict, str]]:
    """A Ray cluster of ``nodes`` nodes on this machine (head + workers), ``cpus`` CPUs each, token auth on.

    Yields ``(address, env, temp_dir)``: ``env`` is what a driver needs to join ``address`` (HOST:PORT).
    On exit, stops exactly this cluster's processes, raises if any survives, and removes ``temp_dir``
    (unless ``keep``). The temp dir is short on purpose: Ray's socket paths live under it.
    """
    ray = ray_cli()
    if ray is None:
        raise FileNotFoundError("no `ray` executable next to this Python or on PATH")
    temp_dir = tempfile.mkdtemp(prefix="rmc_", dir="/tmp")
    env = cluster_env(secrets.token_hex(32))
    port = free_port()
    address = f"127.0.0.1:{port}"
    common = [f"--num-cpus={cpus}", f"--temp-dir={temp_dir}", "--disable-usage-stats",
              "--min-worker-port=0", "--max-worker-port=0"]  # random worker ports: no clash between nodes
    cmds = [[ray, "start", "--head", f"--port={port}", "--include-dashboard=false", *common]]
    cmds += [[ray, "start", f"--address={address}", *common]] * (nodes - 1)
    try:
        for cmd in cmds:
            r = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=timeout)
            if r.returncode:
                raise RuntimeError(f"{' '.join(cmd[1:3])} failed ({r.returncode}):\n{r.stdout}\n{r.stderr}")
        yield address, env, temp_dir
    finally:
        left = stop(temp_dir)
        if not keep and not left:
            shutil.rmtree(temp_dir, ignore_errors=True)
    if left:
        raise RuntimeError(f"Ray processes of {temp_dir} survived:\n" + "\n".join(left))


def nodes_that_ran(temp_dir: str, marker: str = ":actor_name:ChunkWorker") -> set[str]:
    """Ids of the nodes whose workers ran rovermarl's chunk actor, from the worker logs (Ray marks each
    task or actor in them: ``:task_name:<task>`` or ``:actor_name:<class>``)."""
    nodes = set()
    for logs in Path(temp_dir).glob("session_*/logs"):
        if logs.parent.is_symlink():
            continue  # session_latest
        for out in logs.glob("worker-*.out"):
            if marker not in out.read_text(errors="replace"):
                continue
            _, worker_id, _, pid = out.stem.split("-")  # worker-<worker id>-<job id>-<pid>
            for log in logs.glob(f"python-core-worker-{worker_id}_{pid}.log"):
                nodes.update(re.findall(r"node_id=([0-9a-f]+)", log.read_text(errors="replace"))[:1])
    return nodes


def sweep(out: Path, overrides: list[str], env: dict | None = None, cwd: Path = ROOT, timeout: float = 300) -> None:
    """``python -m rovermarl.train -m OVERRIDES hydra.sweep.dir=OUT``; raises with its stderr on failure."""
    cmd = [sys.executable, "-m", "rovermarl.train", "-m", *overrides, f"hydra.sweep.dir={out}"]
    r = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)
    if r.returncode:
        raise RuntimeError(f"{' '.join(cmd[3:])} failed ({r.returncode}):\n{r.stderr[-3000:]}")


def compare(local: Path, cluster: Path) -> int:
    """Assert both sweep dirs hold the same jobs and runs, with equal final scores and equal arrays in
    every ``.npz``/``.npy`` of every run (``curve.npz`` and ``genomes.npy`` at least). Returns the number
    of arrays compared."""
    jobs = sorted(p.name for p in local.iterdir() if (p / "runs").is_dir())
    assert jobs, f"no jobs in {local}"
    assert jobs == sorted(p.name for p in cluster.iterdir() if (p / "runs").is_dir()), (local, cluster)
    n = 0
    for job in jobs:
        a, b = (json.loads((d / job / "summary.json").read_text()) for d in (local, cluster))
        assert a["final_score"] == b["final_score"], (job, a["final_score"], b["final_score"])
        runs = sorted(p.name for p in (local / job / "runs").iterdir())
        assert runs == sorted(p.name for p in (cluster / job / "runs").iterdir()), job
        for run in runs:
            files = sorted(p.name for p in (local / job / "runs" / run).iterdir() if p.suffix in (".npz", ".npy"))
            assert {"curve.npz", "genomes.npy"} <= set(files), (job, run, files)
            for name in files:
                x, y = (np.load(d / job / "runs" / run / name) for d in (local, cluster))
                pairs = [(k, x[k], y[k]) for k in x.files] if name.endswith(".npz") else [("", x, y)]
                if name.endswith(".npz"):
                    assert x.files == y.files, (job, run, name)
                for key, u, v in pairs:
                    np.testing.assert_array_equal(u, v, err_msg=f"{job}/{run}/{name}:{key}")
                    n += 1
    return n


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--generations", type=int, default=200)
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--keep", action="store_true", help="keep the cluster's temp dir (logs) and the sweeps")
    args = ap.parse_args()
    overrides = ["k=1,adaptive", "setup=duo", f"generations={args.generations}", f"seeds={args.seeds}",
                 "parallel.chunk=50"]
    out = Path(tempfile.mkdtemp(prefix="cluster_check_"))
    times = {}
    try:
        t = time.perf_counter()
        with local_cluster(keep=args.keep) as (address, env, temp_dir):
            times["start_s"] = time.perf_counter() - t
            t = time.perf_counter()
            sweep(out / "cluster", [*overrides, f"ray.address={address}"], env)
            times["cluster_sweep_s"] = time.perf_counter() - t
            nodes = nodes_that_ran(temp_dir)
            t = time.perf_counter()
        times["stop_s"] = time.perf_counter() - t
        t = time.perf_counter()
        sweep(out / "local", [*overrides, "parallel=serial"])
        times["local_sweep_s"] = time.perf_counter() - t
        arrays = compare(out / "local", out / "cluster")
        assert len(nodes) == 2, f"tasks ran on {len(nodes)} node(s), expected 2"
    except (AssertionError, RuntimeError) as e:
        print(f"cluster_check: FAILED: {e}", file=sys.stderr)
        return 1
    finally:
        if not args.keep:
            shutil.rmtree(out, ignore_errors=True)
    print(json.dumps({"ok": True, "address": address, "nodes_used": len(nodes), "arrays_equal": arrays,
                      **{k: round(v, 1) for k, v in times.items()}, **({"kept": str(out)} if args.keep else {})}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
