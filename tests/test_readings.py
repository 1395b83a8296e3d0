"""The world options of SPEC section 8 (other readings of the paper): hand-built scenes that each reading scores
differently, the kernel against the numpy reference under every option, and their validation."""

import numpy as np
import pytest

from rovermarl import errors, make_world
from tests import reference

READINGS = [{}, {"reward": "any_step"}, {"reward": "best_step"}, {"reward": "mean_step"}, {"speed": "clip"},
            {"poi_type": "sign"}, {"poi_type": "value"}]
FAR = (-30.0, -30.0)        # a parked rover: observes nothing, moves away from every POI


def constant_team(world, a0, a1):
    """Genomes (N, G) whose MLP outputs the constant actions a0[i], a1[i] (only the output biases are set)."""
    g = np.zeros((world.n_rovers, world.n_params))
    g[:, -2], g[:, -1] = np.arctanh(np.clip(a0, -1 + 1e-16, 1 - 1e-16)), np.arctanh(a1)
    return g


def straight(world, starts, headings, a0):
    """Returns (1,) of one episode: rover i starts at starts[i] with headings[i] and runs at constant a0[i]."""
    xy = np.array(starts, dtype=np.float64)[None]
    heading = np.array(headings, dtype=np.float64)[None]
    return world.returns(constant_team(world, a0, np.zeros(world.n_rovers)), (xy, heading))[0]


# ---- env.reward -------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("reward,want", [("final", 0.0), ("any_step", 3.0), ("best_step", 3.0),
                                         ("mean_step", 3.0 * 4 / 15)])
def test_two_rovers_meet_at_a_duo_poi_and_leave_it(reward, want):
    # Duo POI 0 at (13, 0). Two rovers start at x = 5.5 side by side and run at speed 1 along +x: after step t they
    # are at x = 5.5 + t, within 2 of the POI after steps 6..9 only (x 11.5..14.5), and at 20.5 at the end.
    world = make_world("duo", reward=reward)
    got = straight(world, [(5.5, 0.0), (5.5, 0.1), FAR, FAR], [0.0, 0.0, np.pi, np.pi], [1.0, 1.0, 1.0, 1.0])
    assert got == pytest.approx(want, abs=1e-15)


def test_reward_readings_on_hand_built_trajectories():
    # Trajectories (1, T+1, N, 2) written by hand: rover 0 sits on solo POI 0 after steps 2..4, rover 1 on solo
    # POI 5 after steps 10..11, both elsewhere otherwise; the start (index 0) on POI 0 counts for no reading.
    world = make_world("solo", steps=12)
    traj = np.tile(np.array([[0.0, 0.0], [0.0, 1.0], FAR, FAR]), (1, 13, 1, 1))
    traj[0, 0, 0] = world.poi_xy[0]
    traj[0, 2:5, 0] = world.poi_xy[0] + 0.5
    traj[0, 10:12, 1] = world.poi_xy[5] - 0.5
    want = {"final": 0.0, "any_step": 2.0, "best_step": 1.0, "mean_step": 5 / 12}
    for reward, value in want.items():
        w = make_world("solo", steps=12, reward=reward)
        assert w.episode_return(traj)[0] == pytest.approx(value, abs=1e-15), reward
        assert reference.episode_return(w, traj)[0] == pytest.approx(value, abs=1e-15), reward


def test_any_step_needs_the_coupling_at_one_and_the_same_step():
    # Duo POI 0 (coupling 2): rover 0 is there after step 3, rover 1 after step 5: never two at once.
    world = make_world("duo", steps=6, reward="any_step")
    traj = np.tile(np.array([[0.0, 0.0], [0.0, 1.0], FAR, FAR]), (1, 7, 1, 1))
    traj[0, 3, 0] = world.poi_xy[0]
    traj[0, 5, 1] = world.poi_xy[0]
    assert world.episode_return(traj)[0] == 0.0
    traj[0, 5, 0] = world.poi_xy[0] + 1.0                 # now both after step 5
    assert world.episode_return(traj)[0] == 3.0


# ---- env.speed --------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("speed,want", [("affine", 1.0), ("clip", 0.0)])
def test_half_throttle_reaches_a_poi_only_under_affine(speed, want):
    # a0 = 0: affine moves 0.5 per step (15 steps: from x = 4 to 11.5, within 2 of POI 0 at (13, 0)); clip stands.
    world = make_world("solo", speed=speed)
    assert straight(world, [(4.0, 0.0), FAR, FAR, FAR], [0.0, np.pi, np.pi, np.pi], [0.0, 1.0, 1.0, 1.0]) == want


def test_clip_stands_still_for_every_non_positive_a0():
    world = make_world("solo", speed="clip")
    traj = world.rollout(constant_team(world, [-1.0, -0.5, 0.0, 0.4], [0.3, 0.0, 0.0, 0.0]),
                         world.run_ic(0))
    moved = np.linalg.norm(traj.xy[:, -1] - traj.xy[:, 0], axis=-1)      # (E, N)
    assert (moved[:, :3] == 0).all()
    np.testing.assert_allclose(moved[:, 3], 0.4 * world.steps, rtol=1e-12)


# ---- env.poi_type -----------------------------------------------------------------------------------------------

@pytest.mark.parametrize("poi_type,want", [("coupling", (1.0, 0.0)), ("sign", (1.0, -1.0)), ("value", (3.0, 1.0))])
def test_poi_type_is_the_sensor_third_number(poi_type, want):
    world = make_world("duo", poi_type=poi_type)
    obs = world.observe(np.array([[1.0, 0.0], FAR, FAR, FAR]), np.zeros(4))
    assert (obs[0, 2], obs[0, 5]) == want                  # duo POI 0, solo POI 1, both in range
    assert obs[1, 2] == 0.0 and obs[1, 5] == 0.0           # out of range: 0 in every reading
    duo = np.array(world.coupling) == 2
    np.testing.assert_array_equal(world.poi_sensor_type, np.where(duo, want[0], want[1]))


@pytest.mark.parametrize("poi_type,want", [("coupling", 1.0), ("sign", 0.0)])
def test_a_policy_that_reads_the_solo_type_turns_only_under_sign(poi_type, want):
    # Rover 0 runs at full speed toward POI 0; its turn output is tanh(3 * tanh(type of POI 1)): 0 when solo POIs
    # read 0 (coupling), a hard turn when they read -1 (sign), so it misses POI 0.
    world = make_world("solo", poi_type=poi_type)
    g = constant_team(world, [1.0, 1.0, 1.0, 1.0], [0.0] * 4)
    h = world.policy.hidden
    g[0, (3 * 1 + 2) * h + 0] = 5.0                         # W1[type of POI 1, hidden 0]
    g[0, world.obs_dim * h + h + 2 * 0 + 1] = 3.0           # W2[hidden 0, a1]
    ic = (np.array([[(-0.5, 0.0), FAR, FAR, FAR]]), np.array([[0.0, np.pi, np.pi, np.pi]]))   # ends at x = 14.5
    assert world.returns(g, ic)[0] == want
    assert reference.rollout(world, g, ic)[0] == want


# ---- every option: kernel == reference on evolved teams ---------------------------------------------------------

def scoring_team(world, seed):
    """A team that scores: each rover runs straight at its nearest POI at a speed that ends near it."""
    rng = np.random.default_rng(seed)
    return constant_team(world, rng.uniform(0.3, 0.9, 4), rng.uniform(-0.05, 0.05, 4))


@pytest.mark.parametrize("opts", READINGS, ids=lambda o: ",".join(f"{k}={v}" for k, v in o.items()) or "spec")
def test_kernel_matches_reference_under_every_option(opts):
    world = make_world("duo", **opts)
    for seed in range(4):
        ic = world.run_ic(seed)
        g = scoring_team(world, seed) + np.random.default_rng(seed).normal(0, 0.3, (4, world.n_params))
        traj = world.rollout(g, ic)
        np.testing.assert_array_equal(world.returns(g, ic), traj.returns)
        np.testing.assert_array_equal(world.episode_return(traj.xy), traj.returns)
        np.testing.assert_array_equal(reference.rollout(world, g, ic), traj.returns)


def test_default_options_are_the_spec_reading():
    a, b = make_world("duo"), make_world("duo", reward="final", speed="affine", poi_type="coupling")
    g = np.random.default_rng(0).normal(0, 1, (4, a.n_params))
    np.testing.assert_array_equal(a.rollout(g, a.run_ic(1)).xy, b.rollout(g, b.run_ic(1)).xy)


def test_any_step_bound_is_every_poi():
    assert make_world("duo").max_return == 6.0
    assert make_world("duo", reward="best_step").max_return == 6.0
    assert make_world("duo", reward="any_step").max_return == 14.0


@pytest.mark.parametrize("key,value", [("reward", "every_step"), ("speed", "linear"), ("poi_type", 1),
                                       ("dtype", "float16")])
def test_bad_option_is_one_line(key, value):
    with pytest.raises(errors.ConfigError, match=f"^env.{key}={value}: must be one of") as e:
        make_world("duo", **{key: value})
    assert "\n" not in str(e.value)


# ---- evaluation.fresh_ic ----------------------------------------------------------------------------------------

def test_fresh_ic_scores_each_generation_on_its_own_draw_parents_included():
    from rovermarl.config import compose_config
    from rovermarl.runner.chunk import Run

    cfg = compose_config("setup=duo", "k=2", "generations=30", "evaluation.fresh_ic=true", "parallel=serial")
    run, world = Run(cfg, seed=5), make_world("duo")
    assert run.initial_score == world.evaluate(run.team, world.run_ic(5))           # generation 0: the fixed set
    kept = 0
    for g in range(1, 31):
        parents = run.team
        arrays = run.advance(1)
        ic = world.run_ic(5, g)
        assert arrays["score"][0] == world.evaluate(run.team, ic)                   # the kept team, on draw g
        assert arrays["child_score"][0] <= arrays["score"][0]                       # soft: the better of the two
        if not arrays["accepted"][0]:
            kept += 1
            assert arrays["score"][0] == world.evaluate(parents, ic)                # parents re-scored on draw g
    assert 0 < kept < 30
    fixed = Run(compose_config("setup=duo", "k=2", "generations=30", "parallel=serial"), seed=5)
    assert not np.array_equal(fixed.advance(30)["score"], Run(cfg, seed=5).advance(30)["score"])


def test_fresh_ic_resumes_bit_identically():
    from rovermarl.config import compose_config
    from rovermarl.runner.chunk import Run

    cfg = compose_config("k=adaptive", "generations=40", "evaluation.fresh_ic=true", "parallel=serial")
    whole = Run(cfg, seed=2).advance(40)
    first = Run(cfg, seed=2)
    head = first.advance(17)
    tail = Run(cfg, seed=2, state=first.state()).advance(23)
    for key in whole:
        np.testing.assert_array_equal(whole[key], np.concatenate([head[key], tail[key]]), err_msg=key)


@pytest.mark.parametrize("override,message", [
    ("evaluation.fresh_ic=yes", "evaluation.fresh_ic=yes: must be true or false"),
    ("evaluation.heldout=0", "evaluation.heldout=0: must be an integer in 1..1000000"),
    ("+evaluation.fresh=true", "evaluation.fresh=True: unknown key; allowed: fresh_ic, heldout"),
])
def test_bad_evaluation_value_is_one_line(override, message):
    from rovermarl.config import compose_config
    from rovermarl.runner.validate import validate

    with pytest.raises(errors.ConfigError) as e:
        validate(compose_config(override))
    assert str(e.value) == message


def test_an_algorithm_without_fresh_draws_refuses_fresh_ic():
    from rovermarl.algorithms import Algorithm
    from rovermarl.runner.chunk import _evaluation

    with pytest.raises(errors.ConfigError, match="^evaluation.fresh_ic=True: the algorithm Algorithm does not"):
        _evaluation({"fresh_ic": True}, Algorithm(make_world("solo")))


def test_new_options_at_their_defaults_keep_a_runs_identity():
    from rovermarl.config import compose_config
    from rovermarl.runner.chunk import to_plain
    from rovermarl.runner.identity import config_hash

    plain = to_plain(compose_config("k=2"))
    before = {k: v for k, v in plain.items() if k != "evaluation"}
    before["env"] = {k: v for k, v in plain["env"].items() if k not in ("reward", "speed", "poi_type", "dtype")}
    assert config_hash(plain) == config_hash(before)
    for override in ("env.reward=any_step", "env.speed=clip", "env.poi_type=sign", "evaluation.fresh_ic=true",
                     "evaluation.heldout=64", "env.dtype=float32"):
        assert config_hash(to_plain(compose_config("k=2", override))) != config_hash(plain), override
