"""PPO with parameter sharing from stable-baselines3 (the [rl] extra): the VecEnv view, the algorithm plug-in's
resume, its team (the deterministic policy as a genome) and its held-out score. Skipped where torch is absent."""

import numpy as np
import pytest

pytest.importorskip("torch", reason="the [rl] extra (torch, stable-baselines3) is not installed")
pytest.importorskip("stable_baselines3", reason="the [rl] extra (torch, stable-baselines3) is not installed")

import torch  # noqa: E402

from rovermarl.config import compose_config  # noqa: E402
from rovermarl.env import make_world  # noqa: E402
from rovermarl.runner.chunk import advance, parts, to_plain  # noqa: E402
from rovermarl.runner.validate import validate  # noqa: E402
from rovermarl.sb3 import VecEnv  # noqa: E402
from rovermarl.vector import DEFAULTS  # noqa: E402
from tests.conftest import make_cfg  # noqa: E402

pytestmark = pytest.mark.slow                    # .ci/run's slow part, after pip install -e ".[rl]"

SMALL = ("algorithm=ppo", "+algorithm.num_envs=16", "+algorithm.batch_size=240", "+algorithm.n_epochs=2", "record=off")


def test_the_vecenv_view_flattens_agents_and_keeps_the_defaults():
    env = VecEnv()
    assert env.num_envs == DEFAULTS["num_envs"] * 4 and env.observation_space.shape == (39,)
    env.seed(3)
    obs = env.reset()
    assert obs.shape == (env.num_envs, 39)
    for _ in range(15):
        env.step_async(np.zeros((env.num_envs, 2)))
        obs, rew, done, infos = env.step_wait()
    assert done.all() and "terminal_observation" in infos[0] and rew.shape == (env.num_envs,)


def test_ppo_resumes_bit_identically_and_its_team_is_its_deterministic_policy():
    plain = to_plain(make_cfg(*SMALL, "setup=solo", "generations=4"))
    whole = advance(plain, 1, None, 4)
    first = advance(plain, 1, None, 2)
    rest = advance(plain, 1, first["state"], 4)
    assert np.array_equal(np.concatenate([first["score"], rest["score"]]), whole["score"])
    got, want = rest["state"]["algorithm"], whole["state"]["algorithm"]
    for name in want["params"]:
        assert np.array_equal(got["params"][name], want["params"][name]), name
    assert not np.array_equal(first["state"]["algorithm"]["params"]["log_std"], want["params"]["log_std"])
    algo = parts(plain).algorithm
    model = algo._model()
    algo._load(model, algo.state_type.from_dict(want))
    world = make_world("solo")
    obs = np.random.default_rng(0).uniform(0, 1, (8, world.obs_dim + 1)).astype(np.float32)   # sensors, t / T
    mean = model.policy.predict(obs, deterministic=True)[0]
    genome, obs = whole["genomes"][0], obs[:, :-1]                  # the actor reads the sensors only
    assert np.allclose(mean, np.clip(np.tanh(np.tanh(obs @ genome[:38 * 16].reshape(38, 16)
                                                     + genome[608:624]) @ genome[624:656].reshape(16, 2)
                                             + genome[656:]), -1, 1), atol=1e-5)
    assert whole["heldout_score"] == world.evaluate(whole["genomes"], world.heldout_ic(1, 256))


@pytest.mark.parametrize("regime", [("evaluation.fresh_ic=false", "+algorithm.final_team=best"),
                                    ("evaluation.fresh_ic=true", "+algorithm.final_team=best"),
                                    ("evaluation.fresh_ic=true",)], ids=["fixed-best", "fresh-best", "fresh-last"])
def test_ppo_regimes_resume_bit_identically_and_run_twice_the_same(regime):
    plain = to_plain(make_cfg(*SMALL, "setup=solo", "generations=4", *regime))
    whole, again = advance(plain, 2, None, 4), advance(plain, 2, None, 4)
    assert np.array_equal(whole["score"], again["score"])               # run twice: the same numbers
    assert np.array_equal(whole["genomes"], again["genomes"])
    first = advance(plain, 2, None, 2)
    rest = advance(plain, 2, first["state"], 4)
    assert np.array_equal(np.concatenate([first["score"], rest["score"]]), whole["score"])
    assert np.array_equal(rest["genomes"], whole["genomes"])
    if "+algorithm.final_team=best" in regime and "evaluation.fresh_ic=false" in regime:
        assert np.all(np.diff(whole["score"]) >= 0)                       # the kept iterate never scores less


def test_ppo_fixed_regime_trains_on_the_runs_initial_conditions():
    """evaluation.fresh_ic=false: the environments start from the run's 16 initial conditions, in turn."""
    plain = to_plain(make_cfg(*SMALL, "setup=solo", "generations=1"))
    algo, world = parts(plain).algorithm, make_world("solo")
    ic = world.run_ic(5)
    model = algo._model(ic)
    obs = model.env.reset()
    env = model.env.env
    assert obs.shape == (16 * 4, 39) and env.cursor == 16
    assert np.array_equal(env.heading, np.asarray(ic[1], env.heading.dtype))


def test_ppo_budget_in_agent_steps_and_missing_extra_named(monkeypatch):
    cfg = compose_config("algorithm=ppo", "budget.agent_steps=19200000")
    validate(cfg)
    assert cfg.generations == 1250                                 # 256 envs x 15 steps x 4 rovers per iteration
    assert torch.get_num_threads() >= 1


def test_a_ppo_job_killed_after_a_checkpoint_resumes_bit_identically(tmp_path):
    """The CLI with budget.agent_steps: SIGINT after the first checkpoint, relaunch, the curves and held-out scores
    equal an uninterrupted job's."""
    import json
    import os
    import signal
    import subprocess
    import sys

    from tests.conftest import ROOT, assert_same_curves, run_cli, start_until_checkpoint, sweep_curves
    args = ("-m", *SMALL, "setup=solo", f"budget.agent_steps={16 * 15 * 4 * 8}", "seeds=1", "checkpoint.every=2",
            "parallel=serial", "parallel.chunk=2")
    sweep = tmp_path / "sweep"
    argv = [sys.executable, "-W", "ignore", "-m", "rovermarl.train", *args, f"hydra.sweep.dir={sweep}"]
    proc = start_until_checkpoint(argv, sweep)
    os.killpg(proc.pid, signal.SIGINT)
    proc.communicate(timeout=120)
    out = subprocess.run(argv, cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    ref = run_cli(*args, f"hydra.sweep.dir={tmp_path / 'ref'}", timeout=600)
    assert ref.returncode == 0, ref.stderr[-2000:]
    got = sweep_curves(sweep)
    assert_same_curves(got, sweep_curves(tmp_path / "ref"))
    assert next(iter(got.values()))["score"].shape == (9,)                  # 8 iterations of 16 x 15 x 4
    held = [json.loads(p.read_text())["heldout_score"] for d in (sweep, tmp_path / "ref")
            for p in d.glob("*/summary.json")]
    assert len(held) == 2 and held[0] == held[1]
    from rovermarl.analysis.export import export

    totals = export(tmp_path / "ref", tmp_path / "results", fig6=False, log=lambda *a: None)   # counts its training
    assert totals["team_evals"] == 9 and totals["own_agent_steps"] == 8 * 16 * 15 * 4
    assert totals["agent_steps"] == 9 * 960 + 8 * 16 * 15 * 4


def test_the_sb3_example_runs_and_reports_both_returns():
    import json
    import subprocess
    import sys

    from tests.conftest import ROOT
    out = subprocess.run([sys.executable, "-W", "ignore", "examples/sb3_ppo/sb3_ppo.py", "--envs", "8",
                          "--iterations", "2"], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    got = json.loads(out.stdout.strip().splitlines()[-1])
    assert got["agent_steps"] == 2 * 15 * 8 * 4 and got["random_mean_team_return"] >= 0
