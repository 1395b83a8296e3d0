"""The first run says that it compiles, compiles once in the driver and reports rates without the compile; the
next run says nothing of it. python -m rovermarl.warmup compiles ahead. Cold caches: slow tests (-m slow)."""

import re

import pytest

from tests.conftest import run_cli

pytestmark = pytest.mark.slow


def test_a_cold_first_run_announces_the_compile_and_leaves_it_out_of_its_rate(tmp_path):
    env = {"NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    args = ("generations=300", "seeds=2", "parallel=serial", "record=off")
    first = run_cli(*args, f"hydra.run.dir={tmp_path / 'a'}", env=env, timeout=1200)
    assert first.returncode == 0, first.stderr[-2000:]
    assert "numba compiles the rover world's kernel (rollout, evaluate)" in first.stderr, first.stderr[-2000:]
    assert "CC-(1+1)-ES's compiled loop" in first.stderr and re.search(r"compiled in \d+ s", first.stderr)
    rate = float(re.search(r"\((\d+) team evals/s", first.stdout + first.stderr)[1])
    assert rate > 200                                          # the compile (a minute or more) is not in it
    second = run_cli(*args, f"hydra.run.dir={tmp_path / 'b'}", env=env, timeout=600)
    assert second.returncode == 0 and "compiles" not in second.stderr


def test_the_default_launch_on_ray_announces_the_compile_before_it(tmp_path):
    """Ray holds file descriptor 2 while it starts, beside the compile: the notice comes before, not into it."""
    run = run_cli("generations=20", "seeds=1", "record=off", f"hydra.run.dir={tmp_path / 'a'}",
                  env={"NUMBA_CACHE_DIR": str(tmp_path / "cache")}, timeout=1200)
    assert run.returncode == 0, run.stderr[-2000:]
    notice = run.stderr.find("numba compiles the rover world's kernel (rollout, evaluate)")
    assert 0 <= notice < run.stderr.find("compiled in "), run.stderr[-2000:]


def test_warmup_compiles_ahead(tmp_path):
    env = {"NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    warm = run_cli("setup=duo", module="rovermarl.warmup", env=env, timeout=1200)
    assert warm.returncode == 0 and "compiled and cached" in warm.stdout, warm.stderr[-2000:]
    run = run_cli("setup=duo", "generations=20", "seeds=1", "parallel=serial", f"hydra.run.dir={tmp_path / 'r'}",
                  env=env, timeout=600)
    assert run.returncode == 0 and "compiles" not in run.stderr, run.stderr[-2000:]


def test_the_python_api_says_once_that_it_compiles(tmp_path):
    """A user of World.evaluate, the vector env or the PettingZoo env does not wait in silence for numba."""
    import os
    import subprocess
    import sys

    code = ("import numpy as np; from rovermarl.env import make_world; from rovermarl.vector import VectorEnv; "
            "w = make_world('solo'); ic = w.initial_conditions(seed=0, n=w.episodes); "
            "t = np.zeros((w.n_rovers, w.n_params)); w.evaluate(t, ic); w.evaluate_many(t[None], ic); "
            "v = VectorEnv(num_envs=2, world=w); v.reset(seed=0); v.step(np.zeros((2, w.n_rovers, 2)))")
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"))
    said = []
    for _ in range(2):
        proc = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=1200)
        assert proc.returncode == 0, proc.stderr[-2000:]
        said.append(proc.stderr.count("numba compiles"))
    assert said == [1, 0]                                      # once when cold, never from the cache


def test_once_warmed_an_rl_job_is_cold_no_more(tmp_path):
    """A launch compiles ahead only what the job calls (Algorithm.kernel_calls): once it has, the next launch finds
    everything cached (an RL learner was warmed at every launch for a batch call it never makes: 3-25 min each)."""
    pytest.importorskip("torchrl")
    import os
    import subprocess
    import sys

    code = ("from rovermarl.config import compose_config; from rovermarl.runner.compile import cold, warm; "
            "cfg = compose_config('setup=solo', 'algorithm=mappo', 'budget.agent_steps=96000', 'record=off'); "
            "print('before', cold(cfg)); warm(cfg); print('after', cold(cfg))")
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"))
    proc = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=1200)
    assert proc.returncode == 0, proc.stderr[-2000:]
    before, after = proc.stdout.strip().splitlines()[-2:]
    assert "env_step" in before and after == "after {}", proc.stdout
