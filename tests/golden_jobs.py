"""Golden jobs: a small fixed set of CLI jobs whose arrays must stay bit-identical to commit 4c4ae3c.

Not a test module. ``tests/make_golden.py`` runs these jobs against a checkout of 4c4ae3c and writes
``tests/data/golden_4c4ae3c.json``; ``tests/test_golden.py`` runs them against the current code and compares.

Each group is one ``python -m rovermarl.train -m ...`` invocation (one Hydra sweep) into ``<out>/<group>``.
A digest is kept for every array of every ``.npz`` / ``.npy`` file of every run dir
(``<job>/runs/seed_XXX/``): sha256 over the dtype string, the shape and the raw bytes of the C-contiguous
array. File bytes are never hashed (zip members carry timestamps). Digests are keyed
``<group>/<job dir>/<seed dir>/<file>/<array key>`` (``.npy`` files: array key ``array``); the group prefix is
needed because the shard job has the same overrides, hence the same job dir name, as a serial job.

One exception to bit-identity: the selectors' arm probabilities (array key ``probs``, EXP3) pass through numpy's
``np.exp``, whose float64 result is CPU-dispatched (numpy's own AVX-512 code on some chips, libm elsewhere; on
200,000 random arguments the two differ in about 4.6 % of values, in the last bit). For these arrays the golden
file also keeps the values (``tests/data/golden_4c4ae3c_probs.npz``), and the test accepts values within
``ULPS`` units in the last place of them. Every other array, including the arms chosen, stays bit-identical.

This module imports nothing from ``rovermarl``: it only starts subprocesses and reads files, so it can drive
any checkout (``cwd`` and ``PYTHONPATH`` pick the code).
"""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

COMMIT = "4c4ae3c"
GOLDEN = Path(__file__).resolve().parent / "data" / f"golden_{COMMIT}.json"
GOLDEN_VALUES = GOLDEN.with_name(f"golden_{COMMIT}_probs.npz")
CPU_DEPENDENT = ("probs",)  # array keys computed through np.exp, whose last bit depends on the CPU
ULPS = 4

# Small budgets: 300 generations in chunks of 128 (128 + 128 + 44), a checkpoint after every chunk, so chunk
# boundaries and checkpoint save/restore between chunks are on the path. Default recording (record=default).
BUDGET = ("generations=300", "seeds=2", "parallel.chunk=128", "checkpoint.every=128")
SERIAL = (*BUDGET, "parallel=serial")
NO_FIGURES = ("~hydra.callbacks.plot",)  # the end-of-sweep figures are not digested; they cost ~10 s per sweep

GROUPS: dict[str, tuple[str, ...]] = {
    "k_sweep": ("k=1,2,4,adaptive,ucb1", "setup=solo,duo", *SERIAL),
    "strict": ("selection=strict", "k=1,2", "setup=duo", *SERIAL),
    "homogeneous": ("team=homogeneous", "setup=solo,duo", *SERIAL),
    "trio": ("setup=trio", "k=1,adaptive", *SERIAL),
    # Same overrides as k_sweep's duo k=2 job, evaluated on 2 Ray IC-shard actors: must give the same arrays.
    "shards": ("k=2", "setup=duo", *BUDGET, "parallel=ray", "parallel.ic_shards=2", "ray.num_cpus=2"),
}

# The job dir names Hydra must produce (from the overrides that change results; sorted by key).
JOBS: dict[str, tuple[str, ...]] = {
    "k_sweep": tuple(f"generations=300,k={k},setup={s}" for k in ("1", "2", "4", "adaptive", "ucb1")
                     for s in ("solo", "duo")),
    "strict": tuple(f"generations=300,k={k},selection=strict,setup=duo" for k in ("1", "2")),
    "homogeneous": tuple(f"generations=300,setup={s},team=homogeneous" for s in ("solo", "duo")),
    "trio": tuple(f"generations=300,k={k},setup=trio" for k in ("1", "adaptive")),
    "shards": ("generations=300,k=2,setup=duo",),
}
SEED_DIRS = ("seed_000", "seed_001")


def command(group: str, out: Path) -> list[str]:
    """The command line of one group, writing its sweep into ``out / group``."""
    return [sys.executable, "-m", "rovermarl.train", "-m", *GROUPS[group], *NO_FIGURES,
            f"hydra.sweep.dir={Path(out) / group}"]


def run_all(out: Path, cwd: Path, pythonpath: str | None = None, parallel: int = 2,
            timeout: float = 600) -> dict[str, float]:
    """Run every group into ``out/<group>`` from ``cwd``, at most ``parallel`` invocations at a time.

    ``pythonpath``: put first on PYTHONPATH (selects the checkout to run). Raises RuntimeError naming the group
    and the tail of its stderr if an invocation fails. Returns each group's wall time in seconds.
    """
    env = dict(os.environ)
    if pythonpath is not None:
        env["PYTHONPATH"] = os.pathsep.join(p for p in (pythonpath, env.get("PYTHONPATH")) if p)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    order = ["shards", *(g for g in GROUPS if g != "shards")]  # the Ray start-up overlaps the serial groups
    pending, running, times = list(order), {}, {}
    deadline = time.monotonic() + timeout
    while pending or running:
        while pending and len(running) < parallel:
            g = pending.pop(0)
            log = open(out / f"{g}.log", "w+")  # noqa: SIM115 - closed when the process ends
            running[g] = (subprocess.Popen(command(g, out), cwd=cwd, env=env, stdout=log, stderr=subprocess.STDOUT),
                          log, time.monotonic())
        for g, (proc, log, t0) in list(running.items()):
            if proc.poll() is None:
                if time.monotonic() > deadline:
                    proc.kill()
                    proc.wait()
                else:
                    continue
            del running[g]
            times[g] = time.monotonic() - t0
            log.seek(0)
            text = log.read()
            log.close()
            if proc.returncode != 0:
                for p, lg, _ in running.values():
                    p.kill()
                    p.wait()
                    lg.close()
                raise RuntimeError(f"golden group {g!r} exited with {proc.returncode}: "
                                   f"{' '.join(command(g, out))}\n{text[-3000:]}")
        time.sleep(0.05)
    return times


def array_digest(a: np.ndarray) -> str:
    """sha256 over (dtype string, shape, raw bytes of the C-contiguous array)."""
    a = np.ascontiguousarray(a)
    h = hashlib.sha256()
    h.update(a.dtype.str.encode())
    h.update(b"\0")
    h.update(repr(tuple(int(n) for n in a.shape)).encode())
    h.update(b"\0")
    h.update(a.tobytes(order="C"))
    return h.hexdigest()


def digest_tree(out: Path) -> dict[str, str]:
    """Digest of every array of every .npz/.npy file in ``out/<group>/<job>/runs/seed_XXX/``."""
    digests = {}
    for run in sorted(Path(out).glob("*/*/runs/seed_*")):
        group, job = run.parent.parent.parent.name, run.parent.parent.name
        for f in sorted(run.iterdir()):
            prefix = f"{group}/{job}/{run.name}/{f.name}"
            if f.suffix == ".npz":
                with np.load(f, allow_pickle=False) as z:
                    for key in sorted(z.files):
                        digests[f"{prefix}/{key}"] = array_digest(z[key])
            elif f.suffix == ".npy":
                digests[f"{prefix}/array"] = array_digest(np.load(f, allow_pickle=False))
    return digests


def cpu_dependent_values(out: Path) -> dict[str, np.ndarray]:
    """The arrays named in ``CPU_DEPENDENT`` under ``out``, keyed as in :func:`digest_tree`."""
    values = {}
    for run in sorted(Path(out).glob("*/*/runs/seed_*")):
        group, job = run.parent.parent.parent.name, run.parent.parent.name
        for f in sorted(run.glob("*.npz")):
            with np.load(f, allow_pickle=False) as z:
                for key in sorted(set(z.files) & set(CPU_DEPENDENT)):
                    values[f"{group}/{job}/{run.name}/{f.name}/{key}"] = z[key]
    return values


def within_ulps(expected: np.ndarray, actual: np.ndarray, ulps: int = ULPS) -> bool:
    """Same dtype and shape, finite where expected is, and at most ``ulps`` float steps apart."""
    if expected.dtype != actual.dtype or expected.shape != actual.shape:
        return False
    if not np.array_equal(np.isfinite(expected), np.isfinite(actual)):
        return False
    spacing = np.spacing(np.maximum(np.abs(expected), np.abs(actual)))
    return bool(np.all(np.abs(expected - actual) <= ulps * spacing))


def job_dirs(out: Path) -> dict[str, list[str]]:
    """The job dirs each group's sweep produced (dirs holding ``runs/``)."""
    return {g: sorted(p.parent.name for p in (Path(out) / g).glob("*/runs")) for g in GROUPS}


def compare(expected: dict[str, str], actual: dict[str, str], expected_values: dict[str, np.ndarray] | None = None,
            actual_values: dict[str, np.ndarray] | None = None) -> str | None:
    """None if equal, else a message naming the first difference (missing/extra keys first, sorted).

    A key with an entry in ``expected_values`` passes if its digest matches or its values in ``actual_values``
    are within ``ULPS`` of the expected ones.
    """
    missing, extra = sorted(set(expected) - set(actual)), sorted(set(actual) - set(expected))
    if missing or extra:
        return (f"{len(missing)} digest keys missing, {len(extra)} unexpected; "
                f"first missing: {missing[:3]}, first unexpected: {extra[:3]}")
    expected_values, actual_values = expected_values or {}, actual_values or {}

    def differs(k: str) -> bool:
        if expected[k] == actual[k]:
            return False
        return not (k in expected_values and k in actual_values
                    and within_ulps(expected_values[k], actual_values[k]))

    for key in sorted(expected):
        if differs(key):
            n = sum(differs(k) for k in expected)
            return f"{n} of {len(expected)} arrays differ; first: {key} (golden {expected[key][:16]}..., " \
                   f"now {actual[key][:16]}...)"
    return None


def load_golden(path: Path = GOLDEN) -> dict:
    return json.loads(Path(path).read_text())


def load_golden_values(path: Path = GOLDEN_VALUES) -> dict[str, np.ndarray]:
    with np.load(path, allow_pickle=False) as z:
        return {k: z[k] for k in z.files}
