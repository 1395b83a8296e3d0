import os
import subprocess
import sys
from pathlib import Path

import pytest
from hydra import compose, initialize_config_dir
from hydra.core.global_hydra import GlobalHydra

from rovermarl.config import quote_numeric_options
from rovermarl.env.world import CONF_DIR

ROOT = Path(__file__).resolve().parents[1]


def make_cfg(*overrides: str):
    """Compose the job config as the CLI would (numeric group options quoted)."""
    GlobalHydra.instance().clear()
    with initialize_config_dir(str(CONF_DIR), version_base="1.3"):
        return compose("config", overrides=quote_numeric_options(list(overrides)))


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
