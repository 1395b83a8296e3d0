"""Every config composes and instantiates; bad configs fail early with one line."""

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from rovermarl import train
from rovermarl.config import group_names, quote_numeric_options
from rovermarl.errors import ConfigError
from rovermarl.resources import CONF_DIR
from rovermarl.runner import build
from rovermarl.runner.validate import validate
from tests.conftest import make_cfg, run_cli

OPTIONS = sorted((g, p.stem) for g in group_names() for p in (CONF_DIR / g).glob("*.yaml"))


def test_groups_are_the_documented_ones():
    assert group_names() == {"setup", "env", "policy", "mutation", "selection", "k", "team", "parallel", "record",
                             "algorithm"}
    assert {o for g, o in OPTIONS if g == "k"} == {"1", "2", "3", "4", "adaptive", "ucb1", "thompson", "egreedy",
                                                   "exp3s", "schedule"}
    assert {o for g, o in OPTIONS if g == "setup"} == {"solo", "duo", "trio", "trio6", "solo20",
                                                       *(f"coupling{c}" for c in range(1, 7))}


@pytest.mark.parametrize("group, option", OPTIONS)
def test_every_option_composes_and_instantiates(group, option):
    cfg = make_cfg(f"{group}={option}")
    module, extra = {"ppo": ("stable_baselines3", "rl"), "mappo": ("torchrl", "marl"),
                     "ippo": ("torchrl", "marl")}.get(option if group == "algorithm" else "", (None, None))
    if module and importlib.util.find_spec(module) is None:
        with pytest.raises(ConfigError, match=rf'pip install -e "\.\[{extra}\]"'):   # the suite runs without it
            validate(cfg)
            build(cfg)
        return
    validate(cfg)
    parts = build(cfg)
    w = parts.world
    assert w.n_params == (3 * w.n_pois + 2 * w.n_rovers) * 16 + 16 + 16 * 2 + 2
    assert w.n_params == 658 or group == "setup"
    if group == "k":
        selector = parts.algorithm.selector
        assert selector.choose(np.random.default_rng(0)) in selector.arms


def test_defaults():
    cfg = make_cfg()
    assert (cfg.seeds, cfg.seed, cfg.generations) == (16, 0, 20000)
    parts = build(cfg)
    algo = parts.algorithm
    assert type(algo).__name__ == "CC11ES" and type(algo.selector).__name__ == "FixedK" and algo.selector.value == 1
    assert algo.mutate.sigma == 0.1 and algo.mutate.p_gaussian == 0.2
    assert not algo.accept.strict and type(algo.composition).__name__ == "HeterogeneousTeam"


def test_quote_numeric_options():
    groups = {"k", "setup"}
    assert quote_numeric_options(["-m", "k=1,2,4,adaptive", "setup=solo,duo", "seeds=4"], groups) == \
        ["-m", "k='1','2','4',adaptive", "setup=solo,duo", "seeds=4"]
    assert quote_numeric_options(["k=3", "k.value=3", "+k=2", "k='2'", "k=choice(1,2)"], groups) == \
        ["k='3'", "k.value=3", "+k='2'", "k='2'", "k=choice(1,2)"]


BAD = [
    (["k=5"], "k=5"),
    (["mutation.sigma=-1"], "mutation.sigma=-1"),
    (["k=adaptive", "k.gamma=0"], "k.gamma=0"),
    (["setup=quartet"], "setup=quartet"),
    (["seeds=0"], "seeds=0"),
    (["generations=-3"], "generations=-3"),
]


@pytest.mark.parametrize("argv, key", BAD + [(["ray.address=127.0.0.1:1"], "ray.address=127.0.0.1:1")])
def test_validation_examples_give_one_line_and_nonzero_exit(argv, key, tmp_path):
    proc = run_cli(*argv, f"hydra.run.dir={tmp_path}/run", cwd=tmp_path)
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2, proc.stderr
    assert len(lines) == 1 and lines[0].startswith(f"rovermarl.train: error: {key}:"), proc.stderr
    assert "Traceback" not in proc.stderr + proc.stdout
    assert not (tmp_path / "run").exists() and not (tmp_path / "outputs").exists()


@pytest.mark.parametrize("argv, key", BAD + [
    (["-m", "k=1,2,7", "setup=solo,duo"], "k=7"),
    (["k=adaptive", "k.arms=[1,5]"], "k.arms=[1, 5]"),
    (["setup.coupling=[1,1,1,1,1,1,1,1,1,9]"], "setup.coupling[9]=9"),
    (["k=1,2"], "k=1,2"),
    (["+foo=1"], "foo=1"),
    (["seeds=abc"], "seeds=abc"),
])
def test_bad_config_never_starts_ray(argv, key, monkeypatch, capsys):
    """In-process: the error comes before ray.init (patched to fail the test if reached)."""
    import ray

    def no_ray(*a, **kw):
        raise AssertionError("Ray started for a bad config")
    monkeypatch.setattr(ray, "init", no_ray)
    with pytest.raises(SystemExit) as exc:
        train.main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"rovermarl.train: error: {key}:"), err


def test_conf_dir_is_the_top_level_conf():
    assert CONF_DIR == Path(__file__).resolve().parents[1] / "conf"


def test_a_job_builds_its_world_and_algorithm_once(tmp_path, monkeypatch):
    """Validation before the launch and the job itself share one build per config (per process)."""
    from rovermarl.runner import chunk
    calls = []
    real = chunk.build
    monkeypatch.setattr(chunk, "build", lambda cfg: calls.append(1) or real(cfg))
    monkeypatch.setattr(chunk, "_CACHE", {})
    train.main(["-m", "k=1,2", "generations=20", "seeds=2", "parallel=serial", "record=off",
                f"hydra.sweep.dir={tmp_path / 'sweep'}", "hydra.callbacks={}"])
    assert len(list((tmp_path / "sweep").glob("*/runs/*/run.json"))) == 4
    assert len(calls) == 2                                        # one per job


def test_configs_from_before_the_algorithm_group_still_build_and_give_the_same_run():
    """Sweeps of rovermarl <= 4c4ae3c: no `algorithm` node, operators under rovermarl.evolution."""
    from omegaconf import OmegaConf

    from rovermarl.runner import Run
    new = make_cfg("k=adaptive", "setup=duo", "generations=40", "record=off")
    old = OmegaConf.create(OmegaConf.to_container(new))
    del old["algorithm"]
    for group in ("k", "selection", "team", "mutation"):
        old[group]["_target_"] = old[group]["_target_"].replace("rovermarl.algorithms.operators.",
                                                                "rovermarl.evolution.")
    a, b = Run(new, seed=3).advance(40), Run(old, seed=3).advance(40)
    for key in a:
        np.testing.assert_array_equal(a[key], b[key])


def test_the_old_overrides_command_says_where_it_went():
    """``python -m rovermarl.config JOB_DIR`` left with the held-out migration (studies/heldout/report.py)."""
    proc = run_cli("results/paper/anything", module="rovermarl.config", timeout=60)
    assert proc.returncode == 2 and proc.stdout == "", proc.stdout + proc.stderr
    assert proc.stderr.strip() == ("rovermarl.config: error: a job's overrides are read back by `python "
                                   "studies/heldout/report.py overrides JOB_DIR` now")
