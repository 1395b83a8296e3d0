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
    monkeypatch.setattr(prepared, "MIN_TEAMS", 1)                    # chunks of any size
    monkeypatch.setattr(prepared, "MIN_CHUNK", 1)
    monkeypatch.setattr(prepared, "cpus", lambda: 4)                 # 3 threads even on a 2-CPU machine
    for lanes, workers in ((64, 1), (64, 2), (64, 3), (16, 1), (e * 21, 1), (e * 5, 2), (e * 5, 4)):
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


def test_two_callers_at_once_share_the_pool():
    """Two callers at once, each asking for 2 threads, with one pool between them: every score is the bits of a loop
    of evaluate, whichever thread scored each chunk."""
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


def test_threads_follow_the_caller_from_world_to_world_and_call_to_call(monkeypatch):
    """Calls that alternate worlds, dtypes and initial conditions, and many small back-to-back calls, split over
    threads, all get the bits of a loop of evaluate."""
    monkeypatch.setattr(prepared, "MIN_TEAMS", 2)
    monkeypatch.setattr(prepared, "MIN_CHUNK", 2)
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
    for _ in range(300):                                       # 2 chunks of 2 teams, back to back
        assert w.evaluate_many(teams[:4], p, workers=2).tolist() == want[:4]


def test_an_error_in_a_pool_thread_is_raised_by_the_call_and_the_next_call_works(monkeypatch):
    """A chunk that fails in a pool thread: the call raises its error once the other chunks are done (the caller
    took them, each scored right), and the next call works."""
    import threading
    import time

    world = make_world("duo")
    p = world.prepare(world.run_ic(0))
    teams = np.random.default_rng(2).uniform(-2, 2, (32, world.n_rovers, world.n_params))
    want = [world.evaluate(t, p) for t in teams]
    real = world.compiled.evaluate_many
    seen = []

    def failing(*args):
        caller = threading.current_thread() is threading.main_thread()
        seen.append(caller)
        if not caller:
            raise ValueError("a hook failed in a pool thread")
        deadline = time.monotonic() + 30
        while False not in seen and time.monotonic() < deadline:  # a pool thread has taken a chunk first
            time.sleep(1e-4)
        real(*args)
        seen.append(args[5].tolist())                          # the caller's chunks' scores

    failing.overloads = real.overloads                         # what jit.say_if_cold reads
    monkeypatch.setattr(world.compiled, "evaluate_many", failing)
    with pytest.raises(ValueError, match="a hook failed in a pool thread"):
        world.evaluate_many(teams, p, workers=2)
    caller = [x for x in seen if isinstance(x, list)]
    cuts = prepared.guided(32, 2)                                # 7 chunks: 8, 6, 5, 4, 4, 4, 1 teams
    slices = [want[b0:b1] for b0, b1 in zip(cuts, cuts[1:], strict=False)]
    assert seen.count(False) == 1 and len(caller) == len(slices) - 1    # the pool's task ended at its error: the
    assert all(caller.count(x) == 1 and x in slices for x in caller)    # caller took the others, each scored right
    monkeypatch.undo()
    assert world.evaluate_many(teams, p, workers=2).tolist() == want


def test_guided_chunks_shrink_to_min_chunk_and_cover_the_population():
    """prepared.guided: each chunk a (2 * threads)-th of what is left, at least MIN_CHUNK teams (the last what is
    left); one thread, one chunk; no team, no chunk."""
    assert prepared.guided(64, 2) == [0, 16, 28, 37, 44, 49, 53, 57, 61, 64]
    assert prepared.guided(17, 2) == [0, 5, 9, 13, 17]
    assert prepared.guided(64, 1) == [0, 64]
    assert prepared.guided(0, 1) == prepared.guided(0, 3) == [0]


def test_workers_are_capped_at_the_cpus_of_this_process_and_small_populations_stay_on_one_thread(monkeypatch):
    """workers=1000 starts no more threads than the CPUs this process may use (os.sched_getaffinity), nor more than
    B // MIN_TEAMS, in guided chunks. Counted by the chunks the compiled call is given, and the pool's threads."""
    import threading

    world = make_world("duo")
    p = world.prepare(world.run_ic(0))
    teams = np.random.default_rng(4).uniform(-2, 2, (64, world.n_rovers, world.n_params))
    want = world.evaluate_many(teams, p, workers=1).tolist()
    real, chunks, threads = world.compiled.evaluate_many, [], set()

    def counted(*args):
        chunks.append(args[5].shape[0])
        threads.add(threading.get_ident())
        real(*args)

    counted.overloads = real.overloads                         # what jit.say_if_cold reads
    monkeypatch.setattr(world.compiled, "evaluate_many", counted)
    before = threading.active_count()
    assert world.evaluate_many(teams, p, workers=1000).tolist() == want           # this machine's CPUs
    cuts = prepared.guided(64, min(prepared.cpus(), 64 // prepared.MIN_TEAMS))
    assert sorted(chunks) == sorted(np.diff(cuts).tolist()) and sum(chunks) == 64
    assert len(threads) <= prepared.cpus() and threading.active_count() <= before + prepared.cpus() - 1
    chunks.clear()
    threads.clear()
    monkeypatch.setattr(prepared, "cpus", lambda: 3)
    for _ in range(20):
        assert world.evaluate_many(teams, p, workers=1000).tolist() == want
        assert sorted(chunks, reverse=True) == [11, 9, 8, 6, 5, 5, 4, 4, 4, 4, 4]    # a sixth of what is left, >= 4
        assert len(threads) <= 3                               # the caller and 2 pool threads at most, each call
        chunks.clear()
        threads.clear()
    assert world.evaluate_many(teams[:2 * prepared.MIN_TEAMS - 1], p, workers=1000).tolist() == \
        want[:2 * prepared.MIN_TEAMS - 1]
    assert chunks == [2 * prepared.MIN_TEAMS - 1]               # too small to split
    for bad in (0, -1, 1.5, "2", True):
        with pytest.raises(ValueError, match=r"^workers must be None or an integer >= 1, got"):
            world.evaluate_many(teams, p, workers=bad)


@pytest.mark.parametrize("call", ["evaluate", "returns", "evaluate_many"])
def test_final_xy_is_checked_alike_and_never_truncated_or_recompiled(call):
    """final_xy of another dtype (int64, float32), strided, read-only or of another shape is refused in one line by
    evaluate, returns and evaluate_many alike (no silent truncation into int64, no compile for another layout)."""
    world = make_world("duo")
    p = world.prepare(world.run_ic(0))
    team = np.random.default_rng(6).uniform(-2, 2, (world.n_rovers, world.n_params))
    shape = p.xy.shape if call != "evaluate_many" else (1, *p.xy.shape)

    def run(final):
        if call == "evaluate_many":
            return world.evaluate_many(team[None], p, final)
        return getattr(world, call)(team, p, final)

    readonly = np.zeros(shape)
    readonly.flags.writeable = False
    for bad in (np.zeros(shape, np.int64), np.zeros(shape, np.float32), np.zeros((*shape[:-1], 4))[..., :2],
                readonly, np.zeros(shape[1:] if call == "evaluate_many" else shape[:-1]), [[0.0, 0.0]]):
        with pytest.raises(ValueError, match=r"^final_xy must be a writeable C-ordered float64 array of shape") as e:
            run(bad)
        assert "\n" not in str(e.value)
    good = np.zeros(shape)
    run(good)
    assert good.tobytes() == world.rollout(team, p).xy[:, -1].tobytes()


def test_initial_conditions_that_are_not_finite_or_hold_no_episode_are_refused_in_one_line():
    """NaN or inf in xy or heading (which would score 0.0 with no word), and zero episodes (a NaN score), are
    refused by prepare and so by every call that takes initial conditions."""
    world = make_world("duo")
    ic = world.run_ic(0)
    team = np.zeros((world.n_rovers, world.n_params))
    for k, value in ((0, np.nan), (1, np.inf), (0, -np.inf)):
        bad = (ic.xy.copy(), ic.heading.copy())
        bad[k][3, 1, ...] = value
        for call in (world.prepare, lambda b: world.evaluate(team, b), lambda b: world.evaluate_many(team[None], b)):
            with pytest.raises(ValueError, match=r"^initial conditions must be finite numbers: episode 3's xy or "
                                                 r"heading holds nan or inf$"):
                call(bad)
    for call in (lambda: world.prepare((ic.xy[:0], ic.heading[:0])), lambda: world.evaluate(team, (ic.xy[:0],
                                                                                                 ic.heading[:0]))):
        with pytest.raises(ValueError, match=r"^initial conditions must hold E >= 1 episodes"):
            call()
