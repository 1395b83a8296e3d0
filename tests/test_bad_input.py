"""Bad input to the three CLIs: every malformed invocation exits non-zero with one line naming the problem.

In-process (fast, many cases, some generated with hypothesis): ``rovermarl.train.main`` with ``ray.init``
replaced by a trap, so an accepted config would fail the test instead of starting Ray; ``rovermarl.replay`` and
``rovermarl.plot`` ``main``. Subprocesses (a sample, run concurrently): the real CLIs behave the same, print no
traceback, create no output dir and start no Ray (Ray's temp dir, pointed at by RAY_TMPDIR, never appears).
"""

from __future__ import annotations

import contextlib
import io
import os
import string
import tempfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rovermarl import plot, replay, train
from rovermarl.config import group_names
from rovermarl.resources import CONF_DIR
from tests.conftest import run_cli

TRAIN = "rovermarl.train: error: "
OPTIONS = {g: sorted(p.stem for p in (CONF_DIR / g).glob("*.yaml")) for g in group_names()}   # from conf/
K_OPTIONS = ", ".join(OPTIONS["k"])
SETTINGS = settings(max_examples=30, deadline=None, derandomize=True,
                    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])


class RayStarted(BaseException):
    """Raised by the patched ``ray.init``; a BaseException, so no ``except Exception`` turns it into an error line."""


@pytest.fixture(scope="module", autouse=True)
def no_ray(tmp_path_factory):
    """``ray.init`` fails the test if reached; the cwd is an empty temp dir (default output dirs land there)."""
    import ray

    def trap(*args, **kwargs):
        raise RayStarted("ray.init was called for a bad config")
    cwd = tmp_path_factory.mktemp("cwd")
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(ray, "init", trap)
        mp.chdir(cwd)
        yield cwd
    assert list(cwd.iterdir()) == [], "a bad config created files"


def run_main(main, argv: list[str], prefix: str) -> str:
    """Run ``main(argv)``; check exit 2 and exactly one stderr line starting with ``prefix``; return its rest."""
    err, out = io.StringIO(), io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out), pytest.raises(SystemExit) as exc:
        main(list(argv))
    text = err.getvalue()
    lines = text.strip().splitlines()
    assert exc.value.code == 2, (argv, text)
    assert len(lines) == 1 and lines[0].startswith(prefix), (argv, text)
    assert "Traceback" not in text + out.getvalue(), (argv, text)
    return lines[0][len(prefix):]


def train_error(*argv: str) -> str:
    """The ``key=value: requirement`` part of ``rovermarl.train``'s error line for ``argv``."""
    return run_main(train.main, list(argv), TRAIN)


# ---- hypothesis: generated wrong types and out-of-range values --------------------------------------------------

INTEGERS = {  # key: (least allowed, greatest allowed or None); extra overrides the key needs
    "seeds": (1, None), "seed": (0, None), "generations": (1, None), "checkpoint.every": (1, None),
    "record.every": (1, None), "parallel.chunk": (1, None), "parallel.retries": (0, None),
    "parallel.ic_shards": (1, None), "parallel.workers": (1, None), "ray.num_cpus": (1, None),
    "env.n_rovers": (1, None), "env.steps": (1, None), "env.episodes": (1, None), "policy.hidden": (1, None),
    "k.value": (1, 4),
}
NUMBERS = {  # key: (lo, hi, lo_open); None: unbounded
    "mutation.p_gaussian": (0, 1, False), "mutation.sigma": (0, None, False),
    "mutation.uniform_fraction": (0, 1, False), "k.gamma": (0, 1, True), "env.w_max_deg": (0, 180, False),
    "env.v_max": (0, None, False), "env.start_box": (0, None, False), "env.poi_distance": (0, None, False),
    "env.obs_radius": (0, None, True), "env.sensor_range": (0, None, True),
}
FLAGS = ["record.rerun", "record.behaviour", "record.occupancy", "record.steps", "selection.strict"]
NEEDS = {"k.gamma": ["k=adaptive"]}
SPECIAL = {"true", "false", "null", "nan", "inf", "infinity"}  # words Hydra reads as bool, null or float

words = st.text(string.ascii_lowercase, min_size=1, max_size=8).filter(lambda w: w not in SPECIAL)
non_integral = st.integers(-1000, 1000).map(lambda i: f"{i}.5")
non_numbers = st.one_of(words, st.sampled_from(["true", "false", "null", "[1]", "[]", "{a: 1}", "'1'"]))
non_finite = st.sampled_from(["nan", "inf", "-inf"])


@st.composite
def bad_integer(draw):
    key = draw(st.sampled_from(sorted(INTEGERS)))
    lo, hi = INTEGERS[key]
    below = st.integers(lo - 10**6, lo - 1).map(str)
    above = st.integers(hi + 1, hi + 10**6).map(str) if hi is not None else below
    nullable = key == "parallel.workers" or key == "ray.num_cpus"  # null means "all cores" there
    bad = non_numbers.filter(lambda v: not (nullable and v == "null"))
    return key, draw(st.one_of(below, above, non_integral, non_finite, bad))


@st.composite
def bad_number(draw):
    key = draw(st.sampled_from(sorted(NUMBERS)))
    lo, hi, lo_open = NUMBERS[key]
    floats = st.floats(allow_nan=False, allow_infinity=False, width=32)
    below = floats.filter(lambda x: x < lo or (lo_open and x == lo))
    out = st.one_of(below, floats.filter(lambda x: x > hi)) if hi is not None else below
    return key, draw(st.one_of(out.map(repr), non_finite, non_numbers))


@given(case=bad_integer())
@SETTINGS
def test_generated_bad_integers(case):
    key, value = case
    msg = train_error(*NEEDS.get(key, []), f"{key}={value}")
    assert msg.startswith(f"{key}=") and "must be an integer" in msg, msg


@given(case=bad_number())
@SETTINGS
def test_generated_bad_numbers(case):
    key, value = case
    msg = train_error(*NEEDS.get(key, []), f"{key}={value}")
    assert msg.startswith(f"{key}=") and "must be a finite number" in msg, msg


@given(key=st.sampled_from(FLAGS), value=st.one_of(st.integers(-5, 5).map(str), non_integral, words,
                                                   st.sampled_from(["null", "[true]", "'true'", "nan"])))
@SETTINGS
def test_generated_bad_flags(key, value):
    msg = train_error(f"{key}={value}")
    assert msg.startswith(f"{key}=") and msg.endswith("must be true or false"), msg


@given(group=st.sampled_from(sorted(OPTIONS)),
       option=st.one_of(words, st.integers(-99, 99).map(str)))
@SETTINGS
def test_generated_unknown_group_options(group, option):
    if option in OPTIONS[group]:
        return
    msg = train_error(f"{group}={option}")
    assert msg.startswith(f"{group}={option}: no such option; allowed: " + ", ".join(OPTIONS[group])), msg


SECTIONS = {"env": None, "record": "behaviour every occupancy rerun steps", "parallel": None,
            "checkpoint": "every", "ray": "address num_cpus", "policy": "hidden init_high init_low",
            "setup": "coupling name value"}


@given(section=st.sampled_from(["", *sorted(SECTIONS), "mutation", "selection", "team", "k"]),
       name=words.filter(lambda w: w not in {"every", "steps", "name", "value", "hidden", "chunk", "workers",
                                              "address", "rerun", "retries", "gamma", "arms",
                                              "reward", "sigma", "low", "high", "strict", "episodes"}))
@SETTINGS
def test_generated_extra_keys(section, name):
    key = f"{section}.{name}" if section else name
    config_keys = {"seeds", "seed", "generations", "levels", "resume", "checkpoint", "ray", "hydra", *OPTIONS}
    if not section and name in config_keys:
        return
    msg = train_error(f"+{key}=1")
    if section in ("mutation", "selection", "team", "k"):  # passed to the operator's constructor
        assert msg.startswith(f"{section}=") and f"unexpected keyword argument '{name}'" in msg, msg
    else:
        assert msg.startswith(f"{key}=1: unknown "), msg


@given(n=st.integers(1, 4), arms=st.lists(st.integers(-3, 9), min_size=0, max_size=6))
@SETTINGS
def test_generated_k_arms_outside_1_to_n(n, arms):
    if arms and len(set(arms)) == len(arms) and all(1 <= a <= n for a in arms):
        return  # a valid arm list
    msg = train_error(f"env.n_rovers={n}", "k=adaptive", f"k.arms=[{','.join(map(str, arms))}]")
    assert msg.startswith("k.arms=") and f"in 1..{n}" in msg, msg


MORE_K = "k.value={}: must be an integer in 1..2: k cannot mutate more rovers than env.n_rovers=2"


@given(n=st.integers(1, 3), k=st.integers(2, 9))
@SETTINGS
def test_generated_fixed_k_above_n(n, k):
    if k <= n:
        return
    argv = [f"env.n_rovers={n}", f"k={k}"] if k <= 4 else [f"env.n_rovers={n}", f"k.value={k}"]
    assert train_error(*argv) == (f"k.value={k}: must be an integer in 1..{n}: k cannot mutate more rovers than "
                                  f"env.n_rovers={n}")


# ---- hand-picked cases ------------------------------------------------------------------------------------------

CASES = [  # (argv, the start of the message after "rovermarl.train: error: ")
    # wrong types
    (["seeds=abc"], "seeds=abc: must be an integer"),
    (["generations=1.5"], "generations=1.5: must be an integer"),
    (["mutation.sigma=foo"], "mutation.sigma=foo: must be a finite number"),
    (["k=adaptive", "k.gamma=[1]"], "k.gamma=[1]: must be a finite number"),
    (["selection.strict=maybe"], "selection.strict=maybe: must be true or false"),
    (["record.rerun=3"], "record.rerun=3: must be true or false"),
    (["resume=yes"], "resume=yes: must be true, false or strict"),
    (["resume=1"], "resume=1: must be true, false or strict"),
    (["levels=5"], "levels=5: must be a list"),
    (["levels=[a,4]"], "levels[0]=a: must be a finite number"),
    (["k=adaptive", "k.reward=best"], "k.reward=best: must be one of improved, gain"),
    (["parallel._target_=dask"], "parallel._target_=dask: cannot be imported"),
    (["+env._target_=nowhere_mod.W"], "env._target_=nowhere_mod.W: cannot be imported (ModuleNotFoundError: No module "
                                      "named 'nowhere_mod'); run from its module's folder or put that on PYTHONPATH"),
    (["parallel._target_=rovermarl.policy.MLP"], "parallel._target_=rovermarl.policy.MLP: must name a subclass of "
                                                 "rovermarl.parallel.Backend"),
    (["ray.address=5"], "ray.address=5: must be null"),
    (["ray=5"], "ray=5: must be a mapping"),
    (["setup.value=[1]"], "setup.value=[1]: must be a list of 10 numbers"),
    (["setup.coupling=[]"], "setup.coupling=[]: must be a non-empty list"),
    # out of range
    (["k=adaptive", "k.gamma=1.5"], "k.gamma=1.5: must be a finite number in (0, 1]"),
    (["mutation.p_gaussian=-0.1"], "mutation.p_gaussian=-0.1: must be a finite number in [0, 1]"),
    (["mutation.low=3"], "mutation.high=2.0: must be greater than low=3"),
    (["policy.init_low=5"], "policy.init_high=2.0: must be greater than policy.init_low=5.0"),
    (["env.steps=0"], "env.steps=0: must be an integer >= 1"),
    (["env.n_rovers=0"], "env.n_rovers=0: must be an integer >= 1"),
    (["env.w_max_deg=400"], "env.w_max_deg=400: must be a finite number in [0, 180]"),
    (["policy.hidden=0"], "policy.hidden=0: must be an integer >= 1"),
    (["parallel.chunk=0"], "parallel.chunk=0: must be an integer >= 1"),
    (["checkpoint.every=0"], "checkpoint.every=0: must be an integer >= 1"),
    (["record.every=0"], "record.every=0: must be an integer >= 1"),
    (["parallel.workers=0"], "parallel.workers=0: must be an integer >= 1"),
    (["parallel.ic_shards=17"], "parallel.ic_shards=17: must be an integer in 1..16"),
    (["ray.num_cpus=0"], "ray.num_cpus=0: must be an integer >= 1"),
    (["setup.value=[-1,1,1,1,1,1,1,1,1,1]"], "setup.value[0]=-1: must be a finite number >= 0"),
    # unknown group options
    (["k=9"], "k=9: no such option; allowed: " + K_OPTIONS),
    (["setup=quartet"], "setup=quartet: no such option; allowed: coupling1, coupling2, coupling3, coupling4, "
                        "coupling5, coupling6, duo, solo, solo20, trio, trio6"),
    (["team=mixed"], "team=mixed: no such option"),
    (["selection=lax"], "selection=lax: no such option"),
    (["parallel=dask"], "parallel=dask: no such option"),
    (["record=verbose"], "record=verbose: no such option"),
    (["k=null"], "k=None: must name an option of the group: " + K_OPTIONS),
    (["team=null"], "team=None: must name an option of the group"),
    (["k=[1,2]"], "k=[1, 2]: must name an option of the group"),
    (["-m", "k=choice(1,9)"], "k=1: must name an option of the group: " + K_OPTIONS + " (quote a number: k='1')"),
    (["--config-name=nope"], "--config-name=nope: no such config"),
    (["--config-dir=/nonexistent/conf"], "--config-dir=/nonexistent/conf: no such directory"),
    # extra keys
    (["+foo=1"], "foo=1: unknown top-level key"),
    (["+env.gravity=9"], "env.gravity=9: unknown key"),
    (["k.nonsense=1"], "k.nonsense=1: unknown key"),
    (["+record.colour=red"], "record.colour=red: unknown key"),
    (["+ray.num_gpus=1"], "ray.num_gpus=1: unknown key; allowed: address, num_cpus"),
    (["+policy.layers=2"], "policy.layers=2: unknown key; allowed: hidden, init_high, init_low"),
    (["+setup.colour=red"], "setup.colour=red: unknown key; allowed: coupling, coupling_level, name, value"),
    (["k.arms=[0]"], "k.arms=[0]: unknown key"),  # a fixed k has no arms
    (["env.gravity=9"], "env.gravity=9: unknown key; allowed: dtype, episodes, n_rovers, obs_radius, poi_distance, "
                        "poi_type, reward, sensor_range, speed, start_box, steps, v_max, w_max_deg (+env.gravity=... "
                        "adds a key a plug-in's yaml lacks)"),              # the keys first: the + hint is no dead end
    (["generatons=5"], "generatons=5: unknown key; allowed: algorithm, budget, checkpoint, env, evaluation, "
                       "generations, k, levels"),
    # missing keys
    (["~setup.coupling"], "setup.coupling=None: missing"),
    (["~setup.value"], "setup.value=None: missing"),
    (["~policy.hidden"], "policy.hidden=None: missing"),
    (["~policy.init_low"], "policy.init_low=None: missing"),
    (["~checkpoint.every"], "checkpoint.every=None: missing"),
    (["~record.every"], "record.every=None: missing"),
    (["~parallel.chunk"], "parallel.chunk=None: missing"),
    (["~seeds"], "seeds=None: must be an integer"),
    (["~levels"], "levels=None: must be a list"),
    (["~k"], "k=None: must be a config with a _target_"),
    (["~mutation"], "mutation=None: must be a config with a _target_"),
    (["~env"], "env=None: must be a mapping"),
    (["~setup"], "setup=None: must be a mapping"),
    (["~policy"], "policy=None: must be a mapping"),
    (["~parallel"], "parallel=None: must be a config with a _target_"),
    (["~ray"], "ray=None: must be a mapping"),
    # k lists and k values above N
    (["k=adaptive", "k.arms=[1,5]"], "k.arms=[1, 5]: every k must be an integer in 1..4"),
    (["k=adaptive", "k.arms=[2,2]"], "k.arms=[2, 2]: must be a non-empty list of distinct k"),
    (["k=adaptive", "k.arms=[0]"], "k.arms=[0]: every k must be an integer in 1..4"),
    (["env.n_rovers=2", "k=3"], MORE_K.format(3)),
    (["env.n_rovers=2", "k=4"], MORE_K.format(4)),
    (["env.n_rovers=3", "k=adaptive", "k.arms=[1,2,3,4]"], "k.arms=[1, 2, 3, 4]: every k must be an integer in 1..3"),
    (["setup=duo", "env.n_rovers=1"], "setup.coupling[0]=2: must be an integer in 1..1"),
    (["-m", "k=1,2,7", "setup=solo,duo"], "k=7: no such option"),
    (["-m", "env.n_rovers=4,2", "k=3"], MORE_K.format(3)),
    # malformed overrides
    (["k="], "k='': no such option"),
    (["=3"], "override==3: has no key"),
    (["seeds==4"], "override=seeds==4: Error parsing override"),
    (["k=[1,2"], "override=k=[1,2: no viable alternative"),
    (["+k=2"], "k='2': Multiple values for k"),
    (["k@foo=2"], "k@foo='2': Could not override 'k@foo'"),
    (["hydra.job.chdir=abc"], "hydra.job.chdir=abc: Error merging override"),
    # sweeps without -m
    (["k=1,2"], "k=1,2: is a sweep; add -m"),
    (["seeds=1,2"], "seeds=1,2: is a sweep; add -m"),
    (["setup=solo,duo", "k=adaptive"], "setup=solo,duo: is a sweep; add -m"),
    # output dirs that cannot be written
    (["hydra.run.dir=/etc/hostname/x"], "hydra.run.dir=/etc/hostname/x: cannot write there: /etc/hostname is not a"),
    (["-m", "k=1,2", "hydra.sweep.dir=/etc/hostname/x/y"], "hydra.sweep.dir=/etc/hostname/x/y: cannot write there"),
    (["hydra.run.dir=/proc/rovermarl"], "hydra.run.dir=/proc/rovermarl: cannot write there: /proc"),
    # the first bad job of a sweep is named
    (["-m", "seeds=4,0"], "seeds=0: must be an integer >= 1"),
    (["-m", "mutation.sigma=0.1,-1"], "mutation.sigma=-1: must be a finite number >= 0"),
]


@pytest.mark.parametrize("argv, start", CASES, ids=[" ".join(a) for a, _ in CASES])
def test_train_bad_config(argv, start):
    assert train_error(*argv).startswith(start)


def test_read_only_output_dir(tmp_path):
    """Permission bits bind non-root users only; root cannot create dirs in /sys (read-only or sysfs)."""
    if os.geteuid() != 0:
        parent = tmp_path / "ro"
        parent.mkdir(mode=0o555)
    else:
        parent = Path("/sys")
        try:
            os.rmdir(tempfile.mkdtemp(dir=parent))
        except OSError:
            pass
        else:
            pytest.skip("running as root, and /sys is writable here")
    target = parent / "rovermarl-out"
    msg = train_error(f"hydra.run.dir={target}")
    assert msg.startswith(f"hydra.run.dir={target}: cannot write there: {parent}"), msg
    assert not target.exists()


# ---- replay and plot --------------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def trees(tmp_path_factory) -> Path:
    """Empty dirs, a job dir without runs, a run dir without run.rrd, a non-.rrd file, corrupt job files."""
    root = tmp_path_factory.mktemp("trees")
    for d in ("empty", "job/runs", "job2/runs/seed_000", "run", "bad/runs/seed_000", "bad/.hydra",
              "noenv/runs/seed_000"):
        (root / d).mkdir(parents=True)
    (root / "run" / "run.json").write_text("{}")
    (root / "notes.txt").write_text("x")
    (root / "x.rrd").write_text("")
    (root / "bad/runs/seed_000/curve.npz").write_text("garbage")
    (root / "bad/runs/seed_000/genomes.npy").write_text("garbage")
    (root / "bad/.hydra/config.yaml").write_text("a: [\n")
    (root / "noenv/config.yaml").write_text("setup: {}\n")
    (root / "noenv/runs/seed_000/genomes.npy").write_text("x")
    return root


REPLAY = [  # (argv with {t} for the trees dir, a part of the message)
    (["{t}/missing"], "no such file or directory"),
    (["{t}/empty"], "holds no runs"),
    (["{t}/job"], "holds no runs"),
    (["{t}/notes.txt"], "not an .rrd file, a run dir or a job dir"),
    (["{t}/job2", "--seed", "5"], "no run for --seed 5; seeds here: 0"),
    (["{t}/job2", "--seed", "abc"], "argument --seed: invalid int value: 'abc'"),
    (["{t}/run", "--ic-seed", "3"], "--ic-seed and --out need --resim"),
    (["{t}/run", "--out", "{t}/f.rrd"], "--ic-seed and --out need --resim"),
    (["{t}/run", "--resim", "--ic-seed", "x"], "argument --ic-seed: invalid int value: 'x'"),
    (["{t}/x.rrd", "--resim"], "--resim needs a run dir or job dir, not an .rrd"),
    (["{t}/run", "--no-viewer"], "has no run.rrd"),
    (["{t}/run", "--resim"], "--resim needs genomes.npy and the job's .hydra/config.yaml"),
    (["{t}/bad", "--resim"], "config.yaml is not a readable config"),
    (["{t}/noenv", "--resim"], "unreadable run or job files"),
    ([], "the following arguments are required: path"),
    (["{t}/run", "--bogus"], "unrecognized arguments: --bogus"),
]
PLOT = [
    (["{t}/missing"], "no such directory"),
    (["{t}/empty"], "empty directory"),
    (["{t}/notes.txt"], "not a directory"),
    (["{t}/job"], "no job under"),
    (["{t}/bad"], "no readable run under"),
    (["{t}/job2", "--threshold", "abc"], "argument --threshold: expected SETUP=NUMBER"),
    (["{t}/job2", "--threshold", "duo="], "argument --threshold: expected SETUP=NUMBER"),
    (["{t}/job2", "--threshold", "duo=nan"], "argument --threshold: expected SETUP=NUMBER"),
    (["{t}/job2", "--threshold", "inf"], "argument --threshold: expected SETUP=NUMBER"),
    (["{t}/job2", "--format", "gif"], "argument --format: invalid choice: 'gif'"),
    (["{t}/job2", "--update-gen", "3"], "--update-gen needs --update-run"),
    (["{t}/job2", "--update-gen", "x"], "argument --update-gen: invalid int value: 'x'"),
    ([], "the following arguments are required: path"),
]


@pytest.mark.parametrize("argv, part", REPLAY, ids=[" ".join(a) for a, _ in REPLAY])
def test_replay_bad_input(argv, part, trees):
    msg = run_main(replay.main, [a.format(t=trees) for a in argv], "rovermarl.replay: error: ")
    assert part in msg, msg


@pytest.mark.parametrize("argv, part", PLOT, ids=[" ".join(a) for a, _ in PLOT])
def test_plot_bad_input(argv, part, trees):
    msg = run_main(plot.main, [a.format(t=trees) for a in argv], "rovermarl.plot: error: ")
    assert part in msg, msg
    assert not (trees / "job2" / "figures").exists()


# ---- the real CLIs, as subprocesses -----------------------------------------------------------------------------

SUBPROCESS = [  # (module, argv with {t} for the trees dir, the start of the message after "<module>: error: ")
    ("rovermarl.train", ["generations=1.5"], "generations=1.5: must be an integer"),
    ("rovermarl.train", ["k=adaptive", "k.gamma=1.5"], "k.gamma=1.5: must be a finite number"),
    ("rovermarl.train", ["team=mixed"], "team=mixed: no such option"),
    ("rovermarl.train", ["+env.gravity=9"], "env.gravity=9: unknown key"),
    ("rovermarl.train", ["~policy.hidden"], "policy.hidden=None: missing"),
    ("rovermarl.train", ["env.n_rovers=2", "k=4"], MORE_K.format(4)),
    ("rovermarl.train", ["-m", "k=adaptive", "k.arms=[1,5]", "setup=solo,duo"], "k.arms=[1, 5]: every k"),
    ("rovermarl.train", ["=3"], "override==3: has no key"),
    ("rovermarl.train", ["k=1,2"], "k=1,2: is a sweep; add -m"),
    ("rovermarl.train", ["hydra.run.dir=/etc/hostname/x"], "hydra.run.dir=/etc/hostname/x: cannot write there"),
    ("rovermarl.replay", ["{t}/missing"], "{t}/missing: no such file or directory"),
    ("rovermarl.replay", ["{t}/empty", "--seed", "abc"], "argument --seed: invalid int value"),
    ("rovermarl.plot", ["{t}/empty"], "empty directory: {t}/empty"),
    ("rovermarl.plot", ["{t}/job", "--threshold", "duo=nan"], "argument --threshold"),
]


def test_real_clis_fail_in_one_line_without_ray(tmp_path, trees):
    ray_tmp = tmp_path / "ray-tmp"
    cwd = tmp_path / "cwd"
    cwd.mkdir()

    def run(case):
        module, argv, _ = case
        return run_cli(*[a.format(t=trees) for a in argv], module=module, cwd=cwd,
                       env={"RAY_TMPDIR": str(ray_tmp), "HYDRA_FULL_ERROR": "1"}, timeout=120)

    with ThreadPoolExecutor(max_workers=4) as pool:
        procs = list(pool.map(run, SUBPROCESS))
    for (module, argv, start), proc in zip(SUBPROCESS, procs, strict=True):
        lines = proc.stderr.strip().splitlines()
        prefix = f"{module}: error: {start.format(t=trees)}"
        assert proc.returncode == 2, (argv, proc.stderr)
        assert len(lines) == 1 and lines[0].startswith(prefix), (argv, proc.stderr)
        assert "Traceback" not in proc.stderr + proc.stdout, (argv, proc.stderr)
    assert list(cwd.iterdir()) == [], "a bad invocation created an output dir"
    assert not ray_tmp.exists(), "a bad invocation started Ray"
