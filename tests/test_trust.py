"""A results directory runs no code of its own: read paths never build a ``_target_`` from a job's config unless it
is a class of one of rovermarl's config groups at that group's node, or the caller trusts it (``--trust-config``);
a refused export leaves its results dir as it was."""

import copy
import shutil

import pytest
import yaml

from rovermarl import errors
from rovermarl.config import compose_config
from rovermarl.runner.job import run_job
from rovermarl.runner.trust import check_targets, groups
from tests.conftest import make_cfg, run_cli, run_study

JOB = "k=1,setup=duo"
OPERATORS = ("k", "selection", "team", "mutation")
REFUSED = "a results directory may not run code; pass --trust-config if you trust it"


@pytest.fixture(scope="module")
def finished_job(tmp_path_factory):
    """A finished duo k=1 job (the one the Fig. 6 data re-runs), made once; tests tamper with copies."""
    job = tmp_path_factory.mktemp("trust") / "sweep" / JOB
    run_job(make_cfg("setup=duo", "generations=30", "seeds=1", "parallel=serial"), job)
    return job


def _copy(finished_job, tmp_path):
    job = tmp_path / "sweep" / JOB
    shutil.copytree(finished_job, job)
    return job


def _tampered_sweep(finished_job, tmp_path):
    """A finished duo k=1 job whose saved config builds its mutation with ``builtins.open(PWNED, "w")``."""
    job = _copy(finished_job, tmp_path)
    pwned = tmp_path / "pwned"
    cfg = yaml.safe_load((job / "config.yaml").read_text())
    cfg["mutation"] = {"_target_": "builtins.open", "file": str(pwned), "mode": "w"}
    cfg["algorithm"]["mutation"] = copy.deepcopy(cfg["mutation"])       # not one object: yaml would alias it
    (job / "config.yaml").write_text(yaml.safe_dump(cfg))
    return job, pwned


def _hydra_sweep(finished_job, tmp_path, payload=None):
    """A copy of the job with its config as Hydra saves it into ``.hydra/`` (the algorithm reads the operator groups
    by interpolation, ``k: ${k}``; the choices in ``hydra.yaml``), after ``payload(cfg)`` edited it."""
    job = _copy(finished_job, tmp_path)
    cfg = yaml.safe_load((job / "config.yaml").read_text())
    cfg["algorithm"].update({g: "${" + g + "}" for g in OPERATORS})
    cfg["algorithm"].update(init_low="${policy.init_low}", init_high="${policy.init_high}")
    if payload is not None:
        payload(cfg)
    (job / ".hydra").mkdir()
    (job / ".hydra" / "config.yaml").write_text(yaml.safe_dump(cfg))
    choices = {"setup": "duo", "k": "1", "selection": "soft", "team": "heterogeneous", "mutation": "mixed",
               "algorithm": "cc11es", "parallel": "serial"}
    (job / ".hydra" / "hydra.yaml").write_text(yaml.safe_dump({"hydra": {"runtime": {"choices": choices}}}))
    return job


def _save(path):
    """A node that writes a file when built: ``OmegaConf.save`` reached through rovermarl.train's namespace."""
    return {"_target_": "rovermarl.train.OmegaConf.save", "config": {"pwned": True}, "f": str(path)}


def _nested(cfg, pwned):                                  # in an allowed class's arguments
    cfg["mutation"]["sigma"] = _save(pwned)


def _np_save(cfg, pwned):                                 # a group's class: an attribute chain to numpy.save
    cfg["mutation"] = {"_target_": "rovermarl.record.outputs.np.save", "file": str(pwned), "arr": [1, 2]}


def _ray_init(cfg, pwned):                                # ... to ray.init, which makes its temp dir
    cfg["mutation"] = {"_target_": "rovermarl.parallel.ray_backend.ray.init", "_temp_dir": str(pwned),
                       "num_cpus": 1, "include_dashboard": False}


def _omegaconf_save(cfg, pwned):                          # ... to OmegaConf.save
    cfg["selection"] = _save(pwned)


def _in_list(cfg, pwned):                                 # in a list: an allowed class's positional arguments
    cfg["k"]["_args_"] = [_save(pwned)]


def _unknown_key(cfg, pwned):                             # under a key that is no config group, reached by the run
    cfg["payload"] = _save(pwned)
    cfg["mutation"] = "${payload}"


PAYLOADS = {  # name: (edit, the refused key, its value)
    "nested mutation.sigma": (_nested, "mutation.sigma._target_", "rovermarl.train.OmegaConf.save"),
    "np.save chain": (_np_save, "mutation._target_", "rovermarl.record.outputs.np.save"),
    "ray.init chain": (_ray_init, "mutation._target_", "rovermarl.parallel.ray_backend.ray.init"),
    "OmegaConf.save chain": (_omegaconf_save, "selection._target_", "rovermarl.train.OmegaConf.save"),
    "in a list": (_in_list, "k._args_[0]._target_", "rovermarl.train.OmegaConf.save"),
    "unknown top-level key": (_unknown_key, "payload._target_", "rovermarl.train.OmegaConf.save"),
}


def _snapshot(root):
    """Every entry under ``root``: its bytes (None for a dir), inode and mtime."""
    return {p.relative_to(root).as_posix(): (None if p.is_dir() else p.read_bytes(), p.stat().st_ino,
                                             p.stat().st_mtime_ns) for p in sorted(root.rglob("*"))}


def _export(sweep, out, *extra):
    return run_cli("export", str(sweep), str(out), *extra, module="rovermarl.analysis")


def test_no_read_path_runs_a_target_from_the_results(finished_job, tmp_path):
    job, pwned = _tampered_sweep(finished_job, tmp_path)
    sweep, run = job.parent, job / "runs" / "seed_000"
    export = _export(sweep, tmp_path / "out")
    assert export.returncode == 2
    assert export.stderr.strip().splitlines()[-1] == (
        f"rovermarl.analysis: error: algorithm.mutation._target_=builtins.open: is outside rovermarl, in {job}: "
        "a results directory may not run code; pass --trust-config if you trust it")
    for argv, module in ((["export", str(sweep), str(tmp_path / "r")], "studies/readings"),
                         ([str(sweep), "--out", str(tmp_path / "fig")], "rovermarl.plot"),
                         ([str(run), "--resim", "--no-viewer"], "rovermarl.replay")):
        proc = run_study("readings", *argv) if module == "studies/readings" else run_cli(*argv, module=module)
        assert "Traceback" not in proc.stderr, (module, proc.stderr[-2000:])
    assert not pwned.exists()


def test_trusting_the_config_builds_its_targets(finished_job, tmp_path):
    # the same payload with --trust-config really runs: the guard, not luck, kept the file from being created
    job, pwned = _tampered_sweep(finished_job, tmp_path)
    _export(job.parent, tmp_path / "out", "--trust-config")
    assert pwned.exists()


@pytest.mark.parametrize("name", PAYLOADS)
def test_export_refuses_every_target_but_a_group_class_and_writes_nothing(finished_job, tmp_path, name):
    edit, key, value = PAYLOADS[name]
    pwned = tmp_path / "pwned.npy"
    job = _hydra_sweep(finished_job, tmp_path, lambda cfg: edit(cfg, pwned))
    parent = tmp_path / "results"
    parent.mkdir()
    proc = _export(job.parent, parent / "out")
    assert proc.returncode == 2, proc.stderr[-2000:]
    assert proc.stderr.splitlines() == [proc.stderr.strip()]                     # exactly one line
    assert proc.stderr.startswith(f"rovermarl.analysis: error: {key}={value}: ")
    assert proc.stderr.strip().endswith(f", in {job}: {REFUSED}")
    assert not pwned.exists()
    assert list(parent.iterdir()) == []                                          # no OUT, no temp dir


@pytest.mark.parametrize("name", ["nested mutation.sigma", "np.save chain", "OmegaConf.save chain", "in a list",
                                  "unknown top-level key"])
def test_the_payloads_are_live(finished_job, tmp_path, name):
    # trusted, the payloads really write their file (ray.init aside: it would start Ray): the check stops them
    pwned = tmp_path / "pwned.npy"
    job = _hydra_sweep(finished_job, tmp_path, lambda cfg: PAYLOADS[name][0](cfg, pwned))
    _export(job.parent, tmp_path / "out", "--trust-config")
    assert pwned.exists()


def test_a_refused_export_leaves_an_existing_results_dir_as_it_was(finished_job, tmp_path):
    out = tmp_path / "results" / "out"
    legit = _hydra_sweep(finished_job, tmp_path / "a")
    first = _export(legit.parent, out)
    assert first.returncode == 0, first.stderr[-2000:]
    (out / "older-job").mkdir()
    (out / "older-job" / "summary.json").write_text("{}\n")
    before = _snapshot(out)
    pwned = tmp_path / "pwned.yaml"
    job = _hydra_sweep(finished_job, tmp_path / "b", lambda cfg: _nested(cfg, pwned))
    proc = _export(job.parent, out)
    assert proc.returncode == 2 and len(proc.stderr.splitlines()) == 1, proc.stderr[-2000:]
    assert _snapshot(out) == before
    assert sorted(p.name for p in out.parent.iterdir()) == ["out"]
    assert not pwned.exists()


def test_a_config_as_hydra_saves_it_still_exports(finished_job, tmp_path):
    job = _hydra_sweep(finished_job, tmp_path)
    proc = _export(job.parent, tmp_path / "out")
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert (tmp_path / "out" / "fig6.npz").is_file() and (tmp_path / "out" / JOB / "curves.npz").is_file()
    assert "fig6:" in proc.stderr


# ---- the allow-list --------------------------------------------------------------------------------------------------
def test_the_allow_list_is_the_packaged_config_groups():
    allow = groups()
    assert set(allow.classes) == {"algorithm", "k", "mutation", "parallel", "selection", "team"}
    assert allow.classes["parallel"] == {"rovermarl.parallel.Serial", "rovermarl.parallel.ray_backend.Ray"}
    ops = "rovermarl.algorithms.operators."
    assert allow.classes["algorithm"] == {"rovermarl.algorithms.cc11es.CC11ES", "rovermarl.algorithms.ccea.CCEA",
                                          "rovermarl.algorithms.cma.SepCMA", "rovermarl.sb3.PPO",
                                          "rovermarl.marl.MAPPO", "rovermarl.marl.IPPO"}
    assert allow.classes["k"] == {ops + f"selectors.{c}" for c in
                                  ("FixedK", "EXP3", "EXP3S", "EpsilonGreedy", "Schedule", "Thompson", "UCB1")}
    assert allow.classes["mutation"] == {ops + "mutation.MixedMutation"}
    assert allow.classes["team"] == {ops + "team.HeterogeneousTeam", ops + "team.HomogeneousTeam"}
    assert allow.slots[("algorithm", "rovermarl.algorithms.cc11es.CC11ES")] == {g: g for g in OPERATORS}
    assert allow.slots[("algorithm", "rovermarl.algorithms.ccea.CCEA")] == {"mutation": "mutation"}


@pytest.mark.parametrize("overrides", [(), ("k=adaptive",), ("k=schedule", "selection=strict"),
                                       ("team=homogeneous",), ("algorithm=ccea",), ("algorithm=ccea", "reward=dpp")])
def test_every_packaged_option_passes(overrides):
    overrides = tuple(o.replace("reward=", "algorithm.reward=") for o in overrides)
    check_targets(compose_config(*overrides), "composed")


def test_configs_from_before_the_algorithm_group_pass_as_the_runner_upgrades_them():
    from omegaconf import OmegaConf
    old = OmegaConf.to_container(compose_config("k=adaptive"))
    del old["algorithm"]
    for group in OPERATORS:
        old[group]["_target_"] = old[group]["_target_"].replace("rovermarl.algorithms.operators.",
                                                                "rovermarl.evolution.")
    check_targets(old, "old")
    old["k"]["_target_"] = "rovermarl.evolution.os.system"
    with pytest.raises(errors.ConfigError, match=r"^k\._target_=rovermarl\.evolution\.os\.system: is not a class"):
        check_targets(old, "old")


@pytest.mark.parametrize("edit, key", [
    (lambda c: c["algorithm"].update(k={"_target_": "rovermarl.algorithms.operators.team.HomogeneousTeam"}),
     "algorithm.k._target_"),                                                   # another group's class
    (lambda c: c.update(_target_="builtins.exec"), "config._target_"),
    (lambda c: c["env"].update(_target_="rovermarl.algorithms.cc11es.CC11ES"), "env._target_"),
    (lambda c: c["k"].update(value="${oc.create:{_target_: builtins.open, file: x}}"), "k.value._target_"),
    (lambda c: c["k"].update(value="\\${oc.create:{_target_: builtins.open}}"), "k.value"),   # a second resolution
])
def test_interpolations_and_other_places_are_refused_too(edit, key):
    from omegaconf import OmegaConf
    cfg = copy.deepcopy(OmegaConf.to_container(compose_config()))
    edit(cfg)
    with pytest.raises(errors.ConfigError) as e:
        check_targets(cfg, "SRC")
    assert e.value.key == key and str(e.value).endswith(f", in SRC: {REFUSED}") and "\n" not in str(e.value)
