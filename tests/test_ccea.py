"""The CCEA baseline and its credits: G, D and D++ against hand-computed values on hand-built positions; the runs
resume bit-identically, count their team evaluations, and run through the CLI with figures and recordings."""

import json
import os
import signal
import subprocess
import sys

import numpy as np
import pytest

from rovermarl.algorithms import credit
from rovermarl.config import compose_config
from rovermarl.env import make_world
from rovermarl.runner import Run
from rovermarl.runner.chunk import advance, to_plain
from tests.conftest import ROOT, assert_same_curves, make_cfg, run_cli, start_until_checkpoint, sweep_curves

FAR = (0.0, 0.0)                                  # the centre: 13 from every POI, within obs_radius of none
DUO0, DUO5, SOLO1 = (13.0, 0.0), (-13.0, 0.0), (13 * np.cos(0.2 * np.pi), 13 * np.sin(0.2 * np.pi))


def final(world, *ends):
    """A trajectory (E=1, T+1, N, 2) whose rovers sit at the centre until the last step, then at ``ends``."""
    xy = np.zeros((1, world.steps + 1, world.n_rovers, 2))
    xy[0, -1] = ends
    return xy


@pytest.mark.parametrize("ends,g,d,dpp", [
    ((DUO0, FAR, FAR, FAR), 0, [0, 0, 0, 0], [3, 0, 0, 0]),            # alone on a duo POI: D 0, D++ one partner 3
    ((DUO0, DUO0, FAR, FAR), 3, [3, 3, 0, 0], [3, 3, 0, 0]),           # the pair: each is needed, D++ = D
    ((DUO0, DUO0, DUO0, FAR), 3, [0, 0, 0, 0], [0, 0, 0, 0]),          # three on it: no one is needed, no gain
    ((SOLO1, FAR, FAR, FAR), 1, [1, 0, 0, 0], [1, 0, 0, 0]),           # a solo POI: D 1; partners add nothing
    ((DUO0, DUO5, SOLO1, SOLO1), 1, [0, 0, 0, 0], [3, 3, 0, 0]),       # two lonely duo rovers; two on one solo POI
])
def test_difference_and_dpp_hand_computed_duo(ends, g, d, dpp):
    w = make_world("duo")
    xy = final(w, *ends)
    assert credit.global_reward(w, xy)[:, 0].tolist() == [g] * 4
    assert credit.difference(w, xy)[:, 0].tolist() == d
    assert credit.dpp(w, xy)[:, 0].tolist() == dpp


def test_dpp_takes_the_fewest_partners_that_beat_the_most_trio():
    w = make_world("trio")                                   # POI 0 needs 3 rovers and is worth 4
    xy = final(w, DUO0, DUO0, FAR, FAR)
    assert credit.difference(w, xy)[:, 0].tolist() == [0, 0, 0, 0]
    # rover 0 with 3 partners: 4/3 per partner; with 1 partner 3 rovers are there: 4/1 = 4 beats 4/3
    assert credit.dpp(w, xy)[:, 0].tolist() == [4, 4, 0, 0]
    alone = final(w, DUO0, FAR, FAR, FAR)                    # alone: 1 partner earns nothing, 2 earn 4/2 = 2 > 4/3
    assert credit.dpp(w, alone)[:, 0].tolist() == [2, 0, 0, 0]


def test_credits_follow_the_world_reading():
    w = make_world("duo", reward="any_step")                 # the pair meets at step 1 only, then leaves
    xy = final(w, FAR, FAR, FAR, FAR)
    xy[0, 1, :2] = DUO0
    assert credit.global_reward(w, xy)[0, 0] == 3 and make_world("duo").episode_return(xy)[0] == 0
    assert credit.difference(w, xy)[:, 0].tolist() == [3, 3, 0, 0]


def test_counterfactual_teams_have_the_right_rovers():
    xy = np.arange(1 * 2 * 3 * 2, dtype=float).reshape(1, 2, 3, 2)
    out = credit.without(xy)
    assert out.shape == (3, 1, 2, 2, 2) and (out[1] == xy[:, :, [0, 2]]).all()
    out = credit.with_partners(xy, 2)
    assert out.shape == (3, 1, 2, 5, 2) and (out[2, :, :, :3] == xy).all() and (out[2, :, :, 3:] == xy[:, :, 2:3]).all()


@pytest.mark.parametrize("reward", ["global", "difference", "dpp"])
def test_ccea_resumes_bit_identically_and_counts_evaluations(reward):
    cfg = make_cfg("algorithm=ccea", f"algorithm.reward={reward}", "algorithm.pop_size=4", "setup=duo",
                   "generations=30", "record=off")
    plain = to_plain(cfg)
    whole = advance(plain, 3, None, 30)
    first = advance(plain, 3, None, 12)
    rest = advance(plain, 3, first["state"], 30)
    assert np.array_equal(np.concatenate([first["score"], rest["score"]]), whole["score"])
    for name in ("team_evals", "fitness"):
        assert np.array_equal(np.concatenate([first["series"][name], rest["series"][name]]), whole["series"][name])
    assert whole["series"]["team_evals"].tolist() == [1 + 5 * (g + 1) for g in range(30)]
    assert whole["evaluations"] == 1 + 5 * 30                    # what the runner counts: the same
    team = np.asarray(whole["genomes"])
    assert make_world("duo").evaluate(team, make_world("duo").run_ic(3)) == whole["score"][-1]


def test_ccea_learns_under_each_reward():
    scores = {}
    for reward in ("global", "difference", "dpp"):
        run = Run(make_cfg("algorithm=ccea", f"algorithm.reward={reward}", "setup=solo", "generations=150",
                           "record=off"), 0)
        scores[reward] = (run.initial_score, run.advance(150)["score"][-20:].max())
    assert all(after > before for before, after in scores.values()), scores


def test_bad_ccea_values_get_one_line(tmp_path):
    for arg, key in (("algorithm.reward=shaped", "algorithm.reward"), ("algorithm.pop_size=1", "algorithm.pop_size"),
                     ("algorithm.elites=0", "algorithm.elites")):
        out = run_cli("algorithm=ccea", arg, "parallel=serial", f"hydra.run.dir={tmp_path / 'x'}")
        assert out.returncode == 2 and len(out.stderr.strip().splitlines()) == 1 and key in out.stderr, out.stderr


@pytest.mark.slow
def test_the_issue_command_runs_with_figures_resume_and_recordings(tmp_path):
    """The issue's command on Ray, interrupted (SIGINT) after its first checkpoint and relaunched, equals an
    uninterrupted serial run; figures and recordings are written."""
    args = ("-m", "algorithm=ccea", "algorithm.reward=global,difference,dpp", "setup=duo", "generations=100",
            "seeds=2", "checkpoint.every=10", "parallel.chunk=10")
    sweep = tmp_path / "sweep"
    argv = [sys.executable, "-m", "rovermarl.train", *args, "ray.num_cpus=2", f"hydra.sweep.dir={sweep}"]
    proc = start_until_checkpoint(argv, sweep)
    os.killpg(proc.pid, signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err[-2000:]
    out = subprocess.run(argv, cwd=ROOT, capture_output=True, text=True, timeout=600)   # the relaunch resumes
    assert out.returncode == 0, out.stderr[-2000:]
    ref = run_cli(*args, "parallel=serial", f"hydra.sweep.dir={tmp_path / 'ref'}", timeout=600)
    assert ref.returncode == 0, ref.stderr[-2000:]
    got = sweep_curves(sweep)
    assert len(got) == 3 * 2
    assert_same_curves(got, sweep_curves(tmp_path / "ref"))
    for c in got.values():
        assert c["score"].shape == (101,) and c["team_evals"][-1] == 1 + 11 * 100
    assert sorted(p.name for p in (sweep / "figures").glob("curves_*.png")) == ["curves_duo.png"]
    for run in sweep.glob("*/runs/seed_*"):
        assert (run / "run.rrd").stat().st_size > 0 and (run / "behaviour.npz").is_file()
    for summary in sweep.glob("*/summary.json"):                  # what the analysis puts on its x-axis
        assert json.loads(summary.read_text())["evals_per_generation"] == 11


def _dpp_reference(world, xy, layout=None):
    """D++ one rover and one episode at a time, straight from the published algorithm (AADI's reading); episode e on
    its own layout ``layout[e]`` if given."""
    n = xy.shape[-2]
    out = np.zeros((n, xy.shape[0]))
    for e in range(xy.shape[0]):
        ep = xy[e]
        ret = (lambda z: world.episode_return(z)) if layout is None else \
            (lambda z, lay=layout[e]: world.episode_return(z, lay))
        g = ret(ep)
        for i in range(n):
            d = g - ret(np.delete(ep, i, axis=-2))
            gain = {k: (ret(np.concatenate([ep] + [ep[:, i:i + 1]] * k, axis=-2)) - g) / k for k in range(1, n)}
            best = gain[n - 1]
            if best <= d:
                out[i, e] = d
                continue
            out[i, e] = next((gain[k] for k in range(1, n - 1) if gain[k] > best), best)
    return out


@pytest.mark.parametrize("setup,reward", [("duo", "final"), ("trio", "final"), ("duo", "any_step"),
                                          ("trio", "best_step"), ("duo", "mean_step")])
def test_credits_equal_a_one_episode_at_a_time_reference(setup, reward):
    w = make_world(setup, reward=reward)
    rng = np.random.default_rng(1)
    pois = w.poi_xy[rng.integers(0, 3, (64, w.steps + 1, w.n_rovers))]     # rovers crowd POIs 0-2 (a duo/trio POI)
    xy = pois + rng.normal(0, 1.2, pois.shape)
    want_d = np.array([[w.episode_return(ep) - w.episode_return(np.delete(ep, i, axis=-2)) for ep in xy]
                       for i in range(w.n_rovers)])
    assert np.array_equal(credit.difference(w, xy), want_d)
    assert np.array_equal(credit.dpp(w, xy), _dpp_reference(w, xy))
    if reward == "final":                                                     # the cases D++ is for occur
        assert (credit.dpp(w, xy) != credit.difference(w, xy)).any()


def _crowding(world, layout, seed=1):
    """Trajectories (E, T+1, N, 2) whose rovers crowd the first three POIs of each episode (a duo POI among them),
    where the episode's layout (E, K) puts them at each step."""
    rng = np.random.default_rng(seed)
    e, t1, n = len(layout), world.steps + 1, world.n_rovers
    track = np.stack([world.poi_track(lay) if world.poi_track(lay) is not None else
                      np.broadcast_to(world.poi_positions(lay), (t1, world.n_pois, 2)) for lay in layout])
    pick = rng.integers(0, 3, (e, t1, n))
    xy = np.take_along_axis(track[:, :, :, None, :], pick[:, :, None, :, None], axis=2)[:, :, 0]
    return xy + rng.normal(0, 1.2, xy.shape)


@pytest.mark.parametrize("name", ["random_pois", "moving_pois"])
def test_credits_read_each_episodes_own_pois(name):
    """D and D++ on worlds that draw their POIs per episode score every counterfactual team on that episode's POIs:
    equal to a one-episode-at-a-time reference, different from the credits on another episode's POIs, and on the
    paper's POIs equal to the paper world's credits."""
    from tests.test_world_plugins import _world
    w = _world(name)
    ic = w.initial_conditions(seed=3, n=48)
    xy = _crowding(w, ic.layout)
    want_d = np.array([[w.episode_return(ep, lay) - w.episode_return(np.delete(ep, i, axis=-2), lay)
                        for ep, lay in zip(xy, ic.layout, strict=True)] for i in range(w.n_rovers)])
    got_d, got_dpp = credit.difference(w, xy, layout=ic.layout), credit.dpp(w, xy, layout=ic.layout)
    assert np.array_equal(got_d, want_d)
    assert np.array_equal(got_dpp, _dpp_reference(w, xy, ic.layout))
    assert (got_dpp != got_d).any() and got_d.any()                             # the cases D++ is for occur
    shifted = np.roll(ic.layout, 1, axis=0)                                      # another episode's POIs
    assert not np.array_equal(credit.dpp(w, xy, layout=shifted), got_dpp)
    with pytest.raises(ValueError, match="needs an episode's POIs"):             # never the fixed POIs silently
        credit.dpp(w, xy)


def test_credits_on_the_papers_pois_drawn_as_a_layout_are_the_paper_worlds():
    from tests.test_world_plugins import _world
    w, paper = _world("random_pois"), make_world("duo")
    layout = np.broadcast_to(paper.poi_xy.reshape(-1), (32, 2 * paper.n_pois))
    xy = _crowding(paper, np.zeros((32, 0)), seed=4)
    for name in ("difference", "dpp"):
        assert np.array_equal(credit.credit(name, w, xy, layout=layout), credit.credit(name, paper, xy)), name


def test_ccea_dpp_runs_on_a_world_with_drawn_pois(tmp_path):
    """The learners study's CCEA D++ cell on random_pois: trains, its rollouts carry each episode's layout."""
    out = run_cli("env=random_pois", "hydra.searchpath=[file://examples/random_pois]", "algorithm=ccea",
                  "algorithm.reward=dpp", "generations=3", "seeds=1", "parallel=serial",
                  f"hydra.run.dir={tmp_path}", timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    curve = np.load(next(tmp_path.glob("**/curve.npz")))
    assert curve["score"].shape == (4,) and curve["team_evals"][-1] == 1 + 11 * 3


def test_ccea_mutates_by_a_gaussian_unless_told_otherwise():
    """algorithm=ccea picks mutation=gaussian (every parameter perturbed); the command line's mutation wins, and
    CC-(1+1)-ES keeps the paper's mixed operator."""
    assert compose_config("algorithm=ccea").mutation.p_gaussian == 1.0
    assert compose_config("algorithm=ccea", "mutation=mixed").mutation.p_gaussian == 0.2
    assert compose_config("algorithm=ccea", "mutation.sigma=0.3").mutation.sigma == 0.3
    assert compose_config().mutation.p_gaussian == 0.2
