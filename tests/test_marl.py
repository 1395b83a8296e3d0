"""MAPPO and IPPO from TorchRL (the [marl] extra): the plug-ins train, resume bit-identically, their team is the
shared actor's deterministic policy (a genome the world scores) and their held-out score is the runner's. Skipped
where torchrl is absent; slow (CI runs it in its slow subset, after pip install -e ".[marl]")."""

import numpy as np
import pytest

pytest.importorskip("torchrl", reason="the [marl] extra (torch, torchrl) is not installed")

import torch  # noqa: E402
from tensordict import TensorDict  # noqa: E402

from rovermarl import policy  # noqa: E402
from rovermarl.config import compose_config  # noqa: E402
from rovermarl.env import make_world  # noqa: E402
from rovermarl.errors import ConfigError  # noqa: E402
from rovermarl.marl import A, _agents  # noqa: E402
from rovermarl.runner.chunk import advance, parts, to_plain  # noqa: E402
from rovermarl.runner.validate import validate  # noqa: E402
from rovermarl.vector import VectorEnv  # noqa: E402
from tests.conftest import make_cfg  # noqa: E402

pytestmark = pytest.mark.slow

SMALL = ("+algorithm.num_envs=16", "+algorithm.minibatches=4", "+algorithm.n_epochs=2", "record=off")


@pytest.mark.parametrize("name", ["mappo", "ippo"])
def test_it_trains_resumes_bit_identically_and_its_team_is_its_actor(name):
    plain = to_plain(make_cfg(f"algorithm={name}", *SMALL, "setup=duo", "generations=4"))
    whole = advance(plain, 1, None, 4)
    first = advance(plain, 1, None, 2)
    rest = advance(plain, 1, first["state"], 4)
    assert np.array_equal(np.concatenate([first["score"], rest["score"]]), whole["score"])
    got, want = rest["state"]["algorithm"], whole["state"]["algorithm"]
    for key in want["params"]:
        assert np.array_equal(got["params"][key], want["params"][key]), key
        assert np.array_equal(got["adam"][key]["m"], want["adam"][key]["m"]), key
    log_std = "actor_network_params.module.0.module.log_std"
    assert not np.array_equal(first["state"]["algorithm"]["params"][log_std], want["params"][log_std])   # it learns
    algo = parts(plain).algorithm
    loss = algo._loss()
    algo._load(loss, algo.state_type.from_dict(want))
    world = make_world("duo")
    obs = np.random.default_rng(0).uniform(0, 1, (8, 4, world.obs_dim + 1))              # sensors, t / T
    loc, _ = loss.actor_network.module[0].module(TensorDict({A: _agents(obs, 8, 4)}, batch_size=[8])[A, "sensors"])
    genomes = whole["genomes"]
    assert genomes.shape == (4, world.n_params) and (genomes == genomes[0]).all()          # parameter sharing
    assert np.allclose(np.tanh(loc.detach().numpy()), policy.forward(genomes[0], obs[..., :-1], world.policy.hidden),
                       atol=1e-6)
    assert whole["heldout_score"] == world.evaluate(genomes, world.heldout_ic(1, 256))


@pytest.mark.parametrize("regime", [("evaluation.fresh_ic=false", "+algorithm.final_team=best"),
                                    ("evaluation.fresh_ic=true", "+algorithm.final_team=best")], ids=["fixed", "fresh"])
def test_the_regimes_resume_bit_identically(regime):
    """The fair contest's rules (PPO's): fixed starts in turn or fresh ones, the best iterate kept; resumable."""
    plain = to_plain(make_cfg("algorithm=mappo", *SMALL, "setup=solo", "generations=3", *regime))
    whole = advance(plain, 1, None, 3)
    first = advance(plain, 1, None, 1)
    rest = advance(plain, 1, first["state"], 3)
    assert np.array_equal(np.concatenate([first["score"], rest["score"]]), whole["score"])
    assert np.array_equal(rest["genomes"], whole["genomes"])
    fixed = "evaluation.fresh_ic=false" in regime
    cursor = whole["state"]["algorithm"]["cursor"]                       # starts taken (resets and auto-resets)
    assert (cursor > 0 and cursor % 16 == 0) if fixed else cursor == 0
    if fixed:
        assert np.all(np.diff(whole["score"]) >= 0)


def test_it_trains_on_sampled_actions_with_their_log_probabilities():
    algo = parts(to_plain(make_cfg("algorithm=mappo", *SMALL))).algorithm
    loss = algo._loss()
    data = algo._collect(loss.actor_network, VectorEnv(8, world=algo.world))
    assert data.batch_size == torch.Size([8, 15]) and data[A, "action"].shape == (8, 15, 4, 2)
    mode = torch.tanh(data[A, "loc"])                                      # the deterministic policy's actions
    assert (data[A, "action"] - mode).abs().min() > 0 and data[A, "log_prob"].isfinite().all()
    assert (data["next", A, "done"][:, -1]).all() and not data["next", A, "done"][:, :-1].any()


def test_the_critics_differ_only_in_what_they_read():
    mappo, ippo = (parts(to_plain(make_cfg(f"algorithm={n}", *SMALL))).algorithm._loss() for n in ("mappo", "ippo"))
    w = make_world("solo")
    first, second = ({k: tuple(v.shape) for k, v in loss.named_parameters()} for loss in (mappo, ippo))
    critic = "critic_network_params.module.params.0.weight"
    assert first[critic] == (64, 4 * (w.obs_dim + 1)) and second[critic] == (64, w.obs_dim + 1)   # every rover's; own
    assert {k: v for k, v in first.items() if k.startswith("actor")} == {
        k: v for k, v in second.items() if k.startswith("actor")}


def test_budget_in_agent_steps_and_bad_settings_named():
    cfg = compose_config("algorithm=mappo", "budget.agent_steps=19200000")
    validate(cfg)
    assert cfg.generations == 1250                                 # 256 envs x 15 steps x 4 rovers per iteration
    cfg = compose_config("algorithm=ippo", "setup=coupling3", "budget.agent_steps=19200000")
    validate(cfg)
    assert cfg.generations == 19200000 // (256 * 15 * 6)
    with pytest.raises(ConfigError, match="n_steps") as e:
        parts(to_plain(make_cfg("algorithm=mappo", "+algorithm.n_steps=20")))
    assert "\n" not in str(e.value)
    assert torch.get_num_threads() >= 1
    cfg = compose_config("algorithm=ippo", "evaluation.fresh_ic=false", "parallel.ic_shards=2")
    with pytest.raises(ConfigError, match=r"^parallel.ic_shards='> 1': IPPO trains on the run's initial conditions"):
        validate(cfg)                                              # refused before any work (a traceback before)


def test_a_mappo_job_killed_after_a_checkpoint_resumes_bit_identically(tmp_path):
    """The CLI with budget.agent_steps on a coupling world: SIGINT after the first checkpoint, relaunch; the curves,
    genomes and held-out scores equal an uninterrupted job's, and the summary records the coupling level."""
    import json
    import os
    import signal
    import subprocess
    import sys

    from tests.conftest import ROOT, assert_same_curves, run_cli, start_until_checkpoint, sweep_curves
    args = ("-m", "algorithm=mappo", *SMALL, "setup=coupling2", f"budget.agent_steps={16 * 15 * 4 * 8}", "seeds=1",
            "checkpoint.every=2", "parallel=serial", "parallel.chunk=2")
    sweep = tmp_path / "sweep"
    argv = [sys.executable, "-W", "ignore", "-m", "rovermarl.train", *args, f"hydra.sweep.dir={sweep}"]
    proc = start_until_checkpoint(argv, sweep)
    os.killpg(proc.pid, signal.SIGINT)
    proc.communicate(timeout=120)
    out = subprocess.run(argv, cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    assert "resumes at generation" in out.stdout + out.stderr
    ref = run_cli(*args, f"hydra.sweep.dir={tmp_path / 'ref'}", timeout=600)
    assert ref.returncode == 0, ref.stderr[-2000:]
    got = sweep_curves(sweep)
    assert_same_curves(got, sweep_curves(tmp_path / "ref"))
    assert next(iter(got.values()))["score"].shape == (9,)                  # 8 iterations of 16 x 15 x 4
    genomes = [np.load(p) for d in (sweep, tmp_path / "ref") for p in d.glob("*/runs/seed_000/genomes.npy")]
    assert len(genomes) == 2 and np.array_equal(*genomes)
    summaries = [json.loads(p.read_text()) for d in (sweep, tmp_path / "ref") for p in d.glob("*/summary.json")]
    assert len(summaries) == 2 and summaries[0]["heldout_score"] == summaries[1]["heldout_score"]
    assert summaries[0]["coupling_level"] == 2
