import functools
import importlib.util
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rovermarl.config import compose_config

ROOT = Path(__file__).resolve().parents[1]


make_cfg = compose_config


def start_until_checkpoint(argv: list[str], sweep: Path, timeout: float = 240) -> subprocess.Popen:
    """Start ``argv`` (a train command into ``sweep``) in a session of its own, and return it once a run of the sweep
    has written its first checkpoint; fails if it ended before."""
    import time
    proc = subprocess.Popen(argv, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    deadline = time.monotonic() + timeout
    while not list(sweep.glob("*/runs/*/checkpoint.bin")) and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)
    assert proc.poll() is None, "the sweep ended before its first checkpoint"
    return proc


def run_cli(*args: str, module: str = "rovermarl.train", cwd: Path | None = None, env: dict | None = None,
            timeout: int = 300) -> subprocess.CompletedProcess:
    full_env = {**os.environ, **(env or {})}
    return subprocess.run([sys.executable, "-m", module, *args], cwd=cwd or ROOT, env=full_env,
                          capture_output=True, text=True, timeout=timeout)


@functools.cache
def study_module(name: str):
    """The module ``studies/<name>/report.py`` (studies/ is no installed package: loaded by its path)."""
    spec = importlib.util.spec_from_file_location(f"studies_{name}_report", ROOT / "studies" / name / "report.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module                      # (dataclasses look their module up there)
    spec.loader.exec_module(module)
    return module


def run_study(name: str, *args: str, cwd: Path | None = None, env: dict | None = None,
              timeout: int = 300) -> subprocess.CompletedProcess:
    """``python studies/<name>/report.py ARGS``, as a user runs it."""
    return subprocess.run([sys.executable, str(ROOT / "studies" / name / "report.py"), *args], cwd=cwd or ROOT,
                          env={**os.environ, **(env or {})}, capture_output=True, text=True, timeout=timeout)


@pytest.fixture(scope="session")
def ray_session():
    """One Ray instance for the whole test session: 2 CPUs, no dashboard."""
    import ray
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield ray
    ray.shutdown()


def sweep_curves(sweep: Path) -> dict:
    """Every run's curve.npz of a sweep: {"<job>/runs/seed_XXX/curve.npz": {key: array}}."""
    out = {}
    for path in sorted(Path(sweep).glob("*/runs/seed_*/curve.npz")):
        with np.load(path) as z:
            out[path.relative_to(sweep).as_posix()] = {k: z[k] for k in z.files}
    return out


def assert_same_curves(got: dict, want: dict) -> None:
    """Two :func:`sweep_curves` results hold the same runs with bit-identical arrays."""
    assert got.keys() == want.keys() and want
    for key in want:
        for name in want[key]:
            np.testing.assert_array_equal(got[key][name], want[key][name], err_msg=f"{key}:{name}")
