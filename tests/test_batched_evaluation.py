"""World.evaluate_many lays several teams' episodes side by side in one rollout's lanes and splits a population over
threads: each score and each team's final positions are the bits World.evaluate gives, in float64 and float32, in
the paper's world and the plug-in examples. World.prepare checks the initial conditions once; a prepared set is a
snapshot, and another world prepares it again."""

import warnings

import numpy as np
import pytest

import rovermarl.env.prepared as prepared
from rovermarl.env import make_world
from tests.test_world_plugins import _world


def _make(name: str, dtype: str):
    return make_world("duo", dtype=dtype) if name == "paper" else _world(name, dtype=dtype)


@pytest.mark.parametrize("dtype", ["float64", "float32"])
@pytest.mark.parametrize("name", ["paper", "obstacles", "random_pois"])
def test_evaluate_many_is_a_loop_of_evaluate_bit_for_bit(name, dtype, monkeypatch):
    world = _make(name, dtype)
    teams = np.random.default_rng(7).uniform(-2, 2, (21, world.n_rovers, world.n_params))
    teams[5] = world.homogeneous(teams[5, 1])
    ic = world.run_ic(3)
    e = ic[1].shape[0]
    final_one = np.empty((21, e, world.n_rovers, 2))
    one = [world.evaluate(t, ic, final_one[b]) for b, t in enumerate(teams)]
    if name == "paper":
        assert 0 < sum(s > 0 for s in one) < 21                     # scoring and zero-scoring teams both
    p = world.prepare(ic)
    for lanes, workers in ((64, 1), (64, 2), (64, 3), (16, 1), (e * 21, 1), (e * 5, 2)):
        monkeypatch.setattr(prepared, "PASS_LANES", lanes)           # 1, 4, 5 or all 21 teams in one pass
        final = np.full_like(final_one, np.nan)
        many = world.evaluate_many(teams, p, final, workers=workers)
        assert many.tolist() == one, (lanes, workers)
        assert final.tobytes() == final_one.tobytes(), (lanes, workers)
    assert world.evaluate_many(teams[:0], p).shape == (0,)


def test_prepare_checks_once_and_is_a_snapshot():
    world = make_world("duo")
    ic = world.run_ic(4)
    team = np.random.default_rng(1).uniform(-2, 2, (world.n_rovers, world.n_params))
    want, want_returns, want_xy = world.evaluate(team, ic), world.returns(team, ic), world.rollout(team, ic).xy
    p = world.prepare(ic)
    assert world.prepare(p) is p
    assert world.evaluate(team, p) == want and world.returns(team, p).tobytes() == want_returns.tobytes()
    assert world.rollout(team, p).xy.tobytes() == want_xy.tobytes()
    assert all(a is b for a, b in zip(world.kernel_args(p), (p.xy, p.heading, p.kernel), strict=True))
    ic.xy[:] += 1.0                                                  # the prepared set does not follow
    assert world.rollout(team, p).xy.tobytes() == want_xy.tobytes()
    assert world.rollout(team, ic).xy[:, 0].tolist() == ic.xy.tolist()
    other = make_world("duo", dtype="float32")                      # another world prepares it again, in float32
    q = other.prepare(p)
    assert q is not p and q.xy.dtype == np.float32 and other.evaluate(team, p) == other.evaluate(team, p.ic)
    with pytest.raises(ValueError, match=r"genomes must have shape \(4, 658\)"):
        world.evaluate(team[:, 1:], p)
    with pytest.raises(ValueError, match="expected xy"):
        world.prepare((ic.xy[:, :3], ic.heading))
    with pytest.raises(ValueError, match="final_xy must"):
        world.evaluate_many(team[None], p, np.empty((1, 16, 4, 3)))


@pytest.mark.parametrize("dtype", ["float64", "float32"])
def test_a_team_that_is_not_finite_is_warned_about_by_each_call(dtype):
    """The check runs in the kernel (it reads every weight anyway): every path warns of such a team, once."""
    world = make_world("solo", dtype=dtype)
    p = world.prepare(world.run_ic(0))
    bad = np.zeros((4, world.n_params))
    bad[1, 7] = np.nan
    for call in (lambda: world.evaluate(bad, p), lambda: world.returns(bad, p)):
        with pytest.warns(RuntimeWarning, match="team 0's genomes hold nan") as record:
            call()
        assert len(record) == 1
    teams = np.zeros((9, 4, world.n_params))
    teams[6] = bad
    with pytest.warns(RuntimeWarning, match="team 6's") as record:
        assert world.evaluate_many(teams, p, workers=2).tolist() == [0.0] * 9
    assert len(record) == 1
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        world.evaluate_many(teams[:6], p, workers=2)                 # finite teams: no warning


def test_threads_share_passes_and_callers_share_the_relay():
    """Two callers at once, each asking for 2 threads, with one relay between them (a caller that finds it busy runs
    its population alone): every score is the bits of a loop of evaluate, whichever thread took each pass."""
    import threading

    world = make_world("duo", dtype="float32")
    p = world.prepare(world.run_ic(1))
    teams = np.random.default_rng(3).uniform(-2, 2, (2, 37, world.n_rovers, world.n_params))
    want = [[world.evaluate(t, p) for t in population] for population in teams]
    got = [None, None]

    def call(i):
        got[i] = [world.evaluate_many(teams[i], p, workers=2).tolist() for _ in range(5)]

    callers = [threading.Thread(target=call, args=(i,)) for i in (0, 1)]
    for t in callers:
        t.start()
    for t in callers:
        t.join()
    assert got == [[want[0]] * 5, [want[1]] * 5]


def test_helpers_follow_the_caller_from_world_to_world_and_call_to_call():
    """The helpers wait for the next population in compiled code, bound to one world's initial conditions: calls that
    alternate worlds, dtypes and initial conditions, and many small back-to-back calls, all get the bits of a loop of
    evaluate."""
    worlds = [make_world("duo"), make_world("duo", dtype="float32"), _world("obstacles")]
    preps = [(w, w.prepare(w.run_ic(k))) for w in worlds for k in (0, 1)]
    rng = np.random.default_rng(5)
    cases = []
    for w, p in preps:
        teams = rng.uniform(-2, 2, (6, w.n_rovers, w.n_params))
        cases.append((w, p, teams, [w.evaluate(t, p) for t in teams]))
    for _ in range(3):
        for w, p, teams, want in cases:
            assert w.evaluate_many(teams, p, workers=2).tolist() == want
    w, p, teams, want = cases[0]
    for _ in range(300):                                       # 2 passes of 4 teams: the helper races the caller
        assert w.evaluate_many(teams[:4], p, workers=2).tolist() == want[:4]


def test_an_error_in_a_helper_thread_is_raised_by_the_call_and_the_next_call_works():
    """A helper that fails inside a job is not waited for forever: the call raises its error once the other threads
    are done, and the next call gets a new relay."""
    import time
    from types import SimpleNamespace

    from rovermarl.env import relay
    from rovermarl.env.kernel import fused, mailbox
    from rovermarl.jit import njit

    @njit(nogil=True)
    def failing_serve(xy0, heading0, fields, box, counters, epoch, idle):
        if epoch >= 0:                                      # (the relay calls it with -1 first, to compile it)
            for _ in range(1000 * idle):                    # bounded: a helper never spins on after the test
                if mailbox.open_job(box, -1, epoch) >= 0:
                    mailbox.add(box, mailbox.INSIDE, 1)
                    raise ValueError("a hook failed in a helper thread")
                mailbox.pause()

    def caller_after_the_helper_joined(*args):             # the caller's passes start once the helper is inside
        deadline = time.monotonic() + 30
        while r.box[mailbox.INSIDE] == 0 and time.monotonic() < deadline:
            time.sleep(1e-4)
        fused.evaluate_many(*args)

    world = make_world("duo")
    p = world.prepare(world.run_ic(0))
    teams = np.random.default_rng(2).uniform(-2, 2, (64, world.n_rovers, world.n_params))
    flat = teams.reshape(64 * world.n_rovers, world.n_params)
    out = np.empty(64), np.empty(64 * p.episodes), np.empty(64, dtype=np.bool_)
    r = relay.relay(1)
    stand_in = SimpleNamespace(serve=failing_serve, evaluate_many=caller_after_the_helper_joined)
    with pytest.raises(ValueError, match="a hook failed in a helper thread"):
        r.run(stand_in, p, (flat, out[1], out[0], out[2], prepared._NO_FINAL, 1), 2)
    assert out[0].tolist() == [world.evaluate(t, p) for t in teams]     # the caller scored every team itself
    assert relay.relay(1) is not r
    assert world.evaluate_many(teams, p, workers=2).tolist() == out[0].tolist()
