import os
import subprocess
import sys
from pathlib import Path

import pytest

from rovermarl.config import compose_config

ROOT = Path(__file__).resolve().parents[1]


make_cfg = compose_config


def run_cli(*args: str, module: str = "rovermarl.train", cwd: Path | None = None, env: dict | None = None,
            timeout: int = 300) -> subprocess.CompletedProcess:
    full_env = {**os.environ, **(env or {})}
    return subprocess.run([sys.executable, "-m", module, *args], cwd=cwd or ROOT, env=full_env,
                          capture_output=True, text=True, timeout=timeout)


@pytest.fixture(scope="session")
def ray_session():
    """One Ray instance for the whole test session: 2 CPUs, no dashboard."""
    import ray
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield ray
    ray.shutdown()
