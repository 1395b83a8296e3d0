"""World plug-ins from outside the package (examples/obstacles, random_pois, moving_pois): each trains from its README
command, replays and draws; its rollout is compiled around its own hooks and agrees with the step-by-step
environment; its PettingZoo env passes PettingZoo's parallel API test; its world rules hold."""

import json
import sys

import numpy as np
import pytest
from omegaconf import OmegaConf
from pettingzoo.test import parallel_api_test

from rovermarl.env import kernel
from rovermarl.env.kernel import fused
from rovermarl.pettingzoo import RoverParallelEnv
from tests.conftest import ROOT, run_cli

PLUGINS = ("obstacles", "random_pois", "moving_pois")
DRAWN = {"obstacles": "/world/obstacles", "random_pois": "/world/ring", "moving_pois": "/world/drift"}


def _world(name: str, **env):
    sys.path.insert(0, str(ROOT)) if str(ROOT) not in sys.path else None
    from rovermarl.env.world import World
    cfg = OmegaConf.merge(OmegaConf.load(ROOT / "conf/env/rovers.yaml"),
                          OmegaConf.load(ROOT / f"examples/{name}/env/{name}.yaml"), env)
    cfg.pop("defaults")
    setup = OmegaConf.load(ROOT / "conf/setup/duo.yaml")
    return World.from_config(OmegaConf.create({"setup": setup, "env": cfg, "policy": {"hidden": 16}}), trust=True)


@pytest.fixture(scope="module", params=PLUGINS)
def trained(request, tmp_path_factory):
    """The README command of a plug-in (``generations=200 seeds=2``), serial, into a temporary dir."""
    name = request.param
    out = tmp_path_factory.mktemp(name)
    lines = [ln.strip() for ln in (ROOT / "README.md").read_text().splitlines()]
    found = [ln for ln in lines if ln.startswith("python -m rovermarl.train") and f"env={name} " in ln]
    assert len(found) == 1 and "generations=200 seeds=2" in found[0], found
    proc = run_cli(*found[0].split()[3:], "parallel=serial", f"hydra.run.dir={out}", timeout=900)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return name, out


def test_a_plugin_trains_from_its_command_and_its_scores_are_its_worlds(trained):
    name, out = trained
    run = out / "runs" / "seed_000"
    assert {"curve.npz", "run.rrd", "genomes.npy", "initial_conditions.npz"} <= {p.name for p in run.iterdir()}
    from rovermarl.env.world import World
    world = World.from_config(OmegaConf.load(out / ".hydra" / "config.yaml"), trust=True)   # the run's own world
    assert type(world).__name__ == type(_world(name)).__name__
    with np.load(run / "initial_conditions.npz") as z:
        ic = tuple(z[k] for k in ("xy", "heading", "layout") if k in z)
    assert len(ic) == (3 if world.layout_dim else 2)
    with np.load(run / "curve.npz") as c:
        final = c["score"][-1]
    assert world.evaluate(np.load(run / "genomes.npy"), ic) == final      # trained in its own world
    summary = json.loads((out / "summary.json").read_text())
    assert summary["median_heldout_score"] is not None


def test_a_plugin_draws_and_replays_only_when_trusted(trained, tmp_path):
    name, out = trained
    plain = run_cli(str(out), "--format", "png", "--out", str(tmp_path / "plain"), module="rovermarl.plot")
    assert plain.returncode == 0 and "--trust-config" in plain.stderr
    assert not list((tmp_path / "plain").glob("update_*.png"))              # no world figure without trust
    trusted = run_cli(str(out), "--format", "png", "--out", str(tmp_path / "fig"), "--trust-config",
                      module="rovermarl.plot")
    assert trusted.returncode == 0, trusted.stderr[-2000:]
    assert list((tmp_path / "fig").glob("update_*.png")) and list((tmp_path / "fig").glob("curves_*.png"))
    refused = run_cli(str(out / "runs/seed_000"), "--resim", "--no-viewer", "--out", str(tmp_path / "r.rrd"),
                      module="rovermarl.replay")
    assert refused.returncode != 0 and "--trust-config" in refused.stderr and len(refused.stderr.splitlines()) == 1
    assert not (tmp_path / "r.rrd").exists()
    replay = run_cli(str(out / "runs/seed_000"), "--resim", "--trust-config", "--no-viewer", "--out",
                     str(tmp_path / "r.rrd"), module="rovermarl.replay")
    assert replay.returncode == 0, replay.stderr[-2000:]
    from rerun.chunk import RrdReader
    for rrd in (tmp_path / "r.rrd", out / "runs/seed_000/run.rrd"):
        entities = {str(c.entity_path) for c in RrdReader(str(rrd)).stream()}
        assert DRAWN[name] in entities
        if name == "moving_pois":                                           # the POIs where they are at each step
            assert "/world/episodes/0/pois" in entities


@pytest.mark.parametrize("name", PLUGINS)
def test_a_plugins_pettingzoo_env_passes_the_parallel_api_test(name):
    parallel_api_test(RoverParallelEnv(_world(name)), num_cycles=40)


@pytest.mark.parametrize("name", PLUGINS)
def test_a_plugins_rollout_is_compiled_and_equals_its_env_step_by_step(name):
    world = _world(name)
    assert world.compiled is not fused and world.compiled.__name__.startswith("rovermarl_world_")
    rng = np.random.default_rng(4)
    team = rng.uniform(-2, 2, (world.n_rovers, world.n_params))
    ic = world.initial_conditions(seed=9, n=5)
    roll = world.rollout(team, ic)
    assert world.compiled.rollout.signatures                               # compiled, not a Python loop per step
    np.testing.assert_array_equal(world.episode_return(roll.xy, ic.layout), roll.returns)
    xy, heading = ic.xy.copy(), ic.heading.copy()
    k = world.kernel_for(ic.layout)
    obs, act = np.empty((5, world.n_rovers, world.obs_dim)), np.empty((5, world.n_rovers, 2))
    s = world.compiled.state_of(xy, k)                                     # the world's state (World.state)
    for t in range(world.steps):                                           # the env's functions, one step at a time
        world.compiled.observe(xy, heading, k, s, obs)
        kernel.act(team, obs, world.policy.hidden, act)
        world.compiled.step(xy, heading, act, k, s)
        np.testing.assert_allclose(xy, roll.xy[:, t + 1], atol=1e-9)
    env = RoverParallelEnv(world)
    observations, _ = env.reset(seed=9)
    np.testing.assert_array_equal(env.xy[0], world.initial_conditions(seed=9, n=1).xy[0])


def test_obstacles_are_never_entered_and_are_sensed():
    world = _world("obstacles")
    discs = np.array(world.obstacles)
    rng = np.random.default_rng(0)
    for t in range(20):
        roll = world.rollout(rng.uniform(-2, 2, (world.n_rovers, world.n_params)), world.initial_conditions(t))
        gap = np.linalg.norm(roll.xy[..., None, :] - discs[:, :2], axis=-1) - discs[:, 2]
        assert (gap >= -1e-9).all()                                        # (E, T+1, N, M): outside every disc
    xy, heading = np.array([[[0.0, 3.0], [9.0, 0.0], [0.0, -40.0], [1.0, 1.0]]]), np.zeros((1, 4))
    obs = world.observe(xy, heading)[0, :, 38:].reshape(4, -1, 2)            # the obstacle block
    centre = discs[:, :2][None] - xy[0, :, None]
    dist = np.maximum(np.linalg.norm(centre, axis=-1) - discs[:, 2], 0)
    seen = dist <= world.sensor_range
    np.testing.assert_allclose(obs[..., 0], np.where(seen, dist / world.sensor_range, 1.0), atol=1e-12)
    bearing = np.arctan2(centre[..., 1], centre[..., 0]) / np.pi
    bearing = np.where(bearing >= 1, bearing - 2, bearing)                  # [-1, 1), as the paper's sensors
    np.testing.assert_allclose(obs[..., 1], np.where(seen, bearing, 0), atol=1e-9)


def test_random_pois_draws_its_pois_in_the_ring_per_episode_and_senses_them():
    world = _world("random_pois")
    ic = world.initial_conditions(seed=3, n=200)
    pois = ic.layout.reshape(200, world.n_pois, 2)
    radius = np.linalg.norm(pois, axis=-1)
    assert (radius >= world.ring_inner).all() and (radius <= world.ring_outer).all()
    assert len({tuple(p.round(6).ravel()) for p in pois}) == 200              # a layout of its own per episode
    np.testing.assert_array_equal(world.initial_conditions(seed=3, n=200).layout, ic.layout)
    np.testing.assert_array_equal(world.initial_conditions(seed=3, n=200).xy, _world("obstacles").initial_conditions(
        seed=3, n=200).xy)                                                  # the starts are the paper's draw
    obs = world.observe(ic.xy[:2], ic.heading[:2], ic.layout[:2])
    d = np.linalg.norm(pois[:2, None] - ic.xy[:2, :, None], axis=-1)       # (E, N, P)
    np.testing.assert_allclose(obs[..., 0:3 * world.n_pois:3], np.minimum(d / world.sensor_range, 1), atol=1e-12)
    with pytest.raises(ValueError, match="layout"):
        world.evaluate(np.zeros((world.n_rovers, world.n_params)), ic[:2])


@pytest.mark.parametrize("path", ["examples/obstacles/obstacles.py", "examples/random_pois/random_pois.py",
                                  "examples/moving_pois/moving_pois.py", "tests/data/battery/battery.py",
                                  "benchmarks/twin_world.py"])
def test_a_plugin_imports_only_the_public_worlds_module(path):
    """World authors import everything from rovermarl.worlds: no plug-in reaches into rovermarl.env or the kernel."""
    import ast
    tree = ast.parse((ROOT / path).read_text())
    names = [a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names]
    names += [n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) and n.module]
    assert "rovermarl.worlds" in names and not [m for m in names if m.startswith("rovermarl") and
                                                 m != "rovermarl.worlds"], names
