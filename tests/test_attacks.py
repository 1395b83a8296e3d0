"""A copied results dir attacked as a careful user's adversary would (issue 39): planted world modules, links out
of the dir, a FIFO, odd values that become path parts, odd YAML. Each read command creates no file, follows no link
and prints one line. (Bombs and doctored checkpoints: tests/test_bombs.py.)"""

import json
import os
import shutil
import subprocess
import sys

import pytest
import yaml

from rovermarl.runner.job import run_job
from tests.conftest import ROOT, make_cfg, run_cli, run_study

JOB = "generations=30,k=1,setup=duo"
SWEEP = ("-m", "k=1", "setup=duo", "generations=30", "seeds=1", "parallel=serial")
ENV = {"PYTHONPATH": str(ROOT)}                       # rovermarl from this checkout, whatever the working dir
PWN = "import pathlib\npathlib.Path({marker!r}).write_text('pwned')\nfrom rovermarl.worlds import World\n"


@pytest.fixture(scope="module")
def sweep(tmp_path_factory):
    """A finished one-job sweep made by the CLI (its .hydra/, multirun.yaml, figures): tests tamper with copies."""
    path = tmp_path_factory.mktemp("attacks") / "sweep"
    proc = run_cli(*SWEEP, f"hydra.sweep.dir={path}", timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return path


def _copy(src, tmp_path, name="sweep"):
    dst = tmp_path / name
    shutil.copytree(src, dst, symlinks=True)
    return dst


def _plant(where, marker, module="pwn"):
    """``where/<module>.py``: importing it writes ``marker``."""
    (where / f"{module}.py").write_text(PWN.format(marker=str(marker)))


def _set_world(config_path, target):
    cfg = yaml.safe_load(config_path.read_text())
    cfg["env"]["_target_"] = target
    config_path.write_text(yaml.safe_dump(cfg))


def _one_line(proc):
    lines = [x for x in proc.stderr.splitlines() if x.strip()]
    assert proc.returncode != 0 and len(lines) == 1 and "Traceback" not in proc.stderr, proc.stderr[-2000:]
    return lines[0]


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    """A copy of results/paper (the 13 jobs the claims need) under <tmp>/results/evil, with a planted module."""
    base = tmp_path_factory.mktemp("evil")
    dst = base / "results" / "evil"
    shutil.copytree(ROOT / "results" / "paper", dst, ignore=shutil.ignore_patterns("figures"))
    return base


def _compare(command, base, *args):
    """``claims`` (the paper study's report, a script) or ``selectors`` (``python -m rovermarl.analysis``) on ``args``
    from ``base``, whose planted modules are importable either way."""
    env = {**ENV, "PYTHONPATH": f"{ROOT}{os.pathsep}{base}"}
    if command == "claims":
        return run_study("paper", *args, cwd=base, env=env)
    return run_cli(command, *args, module="rovermarl.analysis", cwd=base, env=env)


@pytest.mark.parametrize("command", ["claims", "selectors"])
@pytest.mark.parametrize("target", ["results.evil.pwn.World", "this.World"])
def test_claims_and_selectors_import_nothing_a_results_dir_names(results, tmp_path, command, target):
    base = _copy(results, tmp_path, "base")
    marker = tmp_path / "PWNED"
    _plant(base / "results" / "evil", marker)
    for config in (base / "results" / "evil").glob("*/config.yaml"):
        _set_world(config, target)
    proc = _compare(command, base, "results/evil")
    assert not marker.exists()
    assert "Beautiful is better than ugly" not in proc.stdout + proc.stderr      # `import this` prints the Zen
    assert "env._target_" in _one_line(proc)


@pytest.mark.parametrize("command", ["claims", "selectors"])
def test_trust_config_is_the_one_switch_that_builds_a_named_world(results, tmp_path, command):
    """The flag the user gives on the command line, and only it, lets claims and selectors import a plug-in."""
    base = _copy(results, tmp_path, "base")
    marker = tmp_path / "PWNED"
    _plant(base / "results" / "evil", marker)
    for config in (base / "results" / "evil").glob("*/config.yaml"):
        _set_world(config, "results.evil.pwn.World")
    _compare(command, base, "results/evil", "--trust-config")
    assert marker.exists()


def _planted_job(sweep_dir, marker, module_dir, target="pwn.World", setup="evil"):
    """A job dir the launch never wrote, beside the sweep's own: a copy whose world is a planted module's."""
    planted = sweep_dir / "planted"
    shutil.copytree(sweep_dir / JOB, planted)
    _plant(module_dir, marker)
    _set_world(planted / ".hydra" / "config.yaml", target)
    summary = json.loads((planted / "summary.json").read_text())
    summary["choices"]["setup"] = setup                    # a setup of its own: its world is the one drawn
    (planted / "summary.json").write_text(json.dumps(summary))
    return planted


def test_readings_export_imports_no_planted_world(sweep, tmp_path):
    sw = _copy(sweep, tmp_path)
    marker = tmp_path / "PWNED"
    _planted_job(sw, marker, tmp_path)
    proc = run_study("readings", "export", str(sw), str(tmp_path / "out"), cwd=tmp_path, env=ENV)
    assert not marker.exists()
    assert "env._target_" in _one_line(proc)


@pytest.mark.parametrize("module", ["rovermarl.plot", "rovermarl.replay"])
def test_plot_and_replay_import_no_planted_world(sweep, tmp_path, module):
    sw = _copy(sweep, tmp_path)
    marker = tmp_path / "PWNED"
    planted = _planted_job(sw, marker, tmp_path)
    args = (str(sw), "--format", "png") if module == "rovermarl.plot" else (str(planted), "--resim", "--no-viewer")
    proc = run_cli(*args, module=module, cwd=tmp_path, env=ENV)
    assert not marker.exists()
    if module == "rovermarl.replay":
        assert "env._target_" in _one_line(proc)


def test_a_relaunch_draws_only_its_own_jobs_and_imports_no_planted_world(sweep, tmp_path):
    sw = _copy(sweep, tmp_path)
    marker = tmp_path / "PWNED"
    _planted_job(sw, marker, tmp_path)
    proc = run_cli(*SWEEP, f"hydra.sweep.dir={sw}", cwd=tmp_path, env=ENV, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert not marker.exists()
    index = json.loads((sw / "figures" / "index.json").read_text())
    assert [j["dir"] for j in index["jobs"]] == [JOB]                  # the planted job is not read


def test_a_world_name_is_refused_by_its_string_before_any_import():
    code = ("import sys\nfrom rovermarl.env.world import world_class\n"
            "for target, trust in (('this.World', False), ('this.World', {'other.World'}), (['a'], True)):\n"
            "    try:\n        world_class(target, trust)\n"
            "    except Exception as e:\n        print(type(e).__name__)\n"
            "print('this' in sys.modules)\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env={**os.environ, **ENV})
    assert "Beautiful" not in proc.stdout
    assert proc.stdout.split() == ["ConfigError", "ConfigError", "ConfigError", "False"], proc.stdout + proc.stderr


def _victim(tmp_path, name="victim"):
    victim = tmp_path / "outside" / name
    victim.parent.mkdir(exist_ok=True)
    victim.write_text("precious")
    return victim


def _untouched(tmp_path):
    """Every file under tmp_path/outside, with its content."""
    return {p: p.read_bytes() for p in sorted((tmp_path / "outside").rglob("*")) if p.is_file()}


@pytest.mark.parametrize("link", [".lock", f"{JOB}/.lock", f"{JOB}/.hydra/config.yaml", "multirun.yaml",
                                  f"{JOB}/train.log", f"{JOB}/runs/seed_000", "figures", JOB])
def test_a_relaunch_follows_no_link_out_of_the_sweep(sweep, tmp_path, link):
    sw = _copy(sweep, tmp_path)
    target = sw / link
    outside = tmp_path / "outside"
    if target.is_dir():
        shutil.copytree(target, outside / "dir")
        shutil.rmtree(target)
        target.symlink_to(outside / "dir")
    else:
        target.unlink(missing_ok=True)
        target.symlink_to(_victim(tmp_path))
    before = _untouched(tmp_path)
    proc = run_cli(*SWEEP, f"hydra.sweep.dir={sw}", cwd=tmp_path, env=ENV, timeout=600)
    assert _untouched(tmp_path) == before
    assert "symbolic link" in _one_line(proc)


def test_run_job_follows_no_lock_or_run_dir_link(tmp_path):
    cfg = make_cfg("setup=duo", "generations=5", "seeds=1", "parallel=serial", "record=off")
    for link in (".lock", "runs/seed_000"):
        job = tmp_path / link.replace("/", "_") / "job"
        (job / link).parent.mkdir(parents=True, exist_ok=True)
        victim = _victim(tmp_path, link.replace("/", "_"))
        (job / link).symlink_to(victim if link == ".lock" else victim.parent)
        before = _untouched(tmp_path)
        with pytest.raises(OSError, match="symbolic link"):
            run_job(cfg, job)
        assert _untouched(tmp_path) == before


def test_plot_writes_no_figure_through_a_linked_figures_dir(sweep, tmp_path):
    sw = _copy(sweep, tmp_path)
    shutil.rmtree(sw / "figures")
    (tmp_path / "outside").mkdir()
    (sw / "figures").symlink_to(tmp_path / "outside")
    proc = run_cli(str(sw), "--format", "png", module="rovermarl.plot")
    assert list((tmp_path / "outside").iterdir()) == []
    assert "symbolic link" in _one_line(proc)


def test_heldout_merge_writes_no_summary_through_a_linked_job_dir(sweep, tmp_path):
    results = tmp_path / "results"
    results.mkdir()
    shutil.copytree(sweep / JOB, tmp_path / "outside" / JOB)
    (results / JOB).symlink_to(tmp_path / "outside" / JOB)
    before = _untouched(tmp_path)
    proc = run_study("heldout", "merge", str(sweep), str(results))
    assert _untouched(tmp_path) == before
    assert "symbolic link" in _one_line(proc)


def test_replay_resim_writes_nothing_through_a_linked_run_dir(sweep, tmp_path):
    sw = _copy(sweep, tmp_path)
    run = sw / JOB / "runs" / "seed_000"
    shutil.copytree(run, tmp_path / "outside" / "run")
    shutil.rmtree(run)
    run.symlink_to(tmp_path / "outside" / "run")
    before = _untouched(tmp_path)
    proc = run_cli(str(run), "--resim", "--no-viewer", module="rovermarl.replay")
    assert _untouched(tmp_path) == before
    assert "symbolic link" in _one_line(proc)


@pytest.mark.parametrize("module", ["rovermarl.plot", "rovermarl.train"])
def test_a_fifo_config_does_not_hang_plot_or_a_relaunch(sweep, tmp_path, module):
    sw = _copy(sweep, tmp_path)
    (sw / JOB / ".hydra" / "config.yaml").unlink()
    os.mkfifo(sw / JOB / ".hydra" / "config.yaml")
    args = (str(sw), "--format", "png") if module == "rovermarl.plot" else (*SWEEP, f"hydra.sweep.dir={sw}")
    proc = run_cli(*args, module=module, timeout=120)                   # hangs (a TimeoutExpired) if it reads it
    assert "not a regular file" in _one_line(proc)


@pytest.mark.parametrize("value", ["/../../../xx/", 12345])
def test_an_odd_config_hash_in_run_json_costs_one_warning(tmp_path, caplog, value):
    cfg = make_cfg("setup=duo", "generations=5", "seeds=1", "parallel=serial", "record=off")
    want = run_job(cfg, tmp_path / "ref")
    job = tmp_path / "job"
    shutil.copytree(tmp_path / "ref", job)
    meta = json.loads((job / "runs" / "seed_000" / "run.json").read_text())
    (job / "runs" / "seed_000" / "run.json").write_text(json.dumps({**meta, "config_hash": value}))
    with caplog.at_level("WARNING", logger="rovermarl"):
        got = run_job(cfg, job)
    warned = [r.getMessage() for r in caplog.records if r.levelname == "WARNING"]
    assert len(warned) <= 2 and any("unknown" in w for w in warned), warned
    assert got["final_score"] == want["final_score"]
    assert sorted(p.name for p in (job / "runs").iterdir()) == ["seed_000", "seed_000.unknown"]


def test_a_list_target_in_a_results_config_is_one_line(sweep, tmp_path):
    sw = _copy(sweep, tmp_path)
    config = sw / JOB / ".hydra" / "config.yaml"
    cfg = yaml.safe_load(config.read_text())
    cfg["mutation"]["_target_"] = ["a", "b"]
    config.write_text(yaml.safe_dump(cfg))
    proc = run_cli("export", str(sw), str(tmp_path / "out"), module="rovermarl.analysis")
    assert "mutation._target_" in _one_line(proc)


def test_a_python_tag_in_a_config_file_is_one_line(tmp_path):
    marker = tmp_path / "PWNED"
    (tmp_path / "conf" / "env").mkdir(parents=True)
    (tmp_path / "conf" / "env" / "tag.yaml").write_text(
        f"defaults: [rovers, _self_]\nx: !!python/object/apply:os.system ['touch {marker}']\n")
    proc = run_cli("env=tag", f"hydra.searchpath=[file://{tmp_path / 'conf'}]", "generations=2", "seeds=1",
                   "parallel=serial", f"hydra.run.dir={tmp_path / 'run'}")
    assert not marker.exists()
    assert "ConstructorError" in _one_line(proc)


# ---- issue 51, the read side: a name is only a name; what a file holds reaches the terminal escaped -----------------
EVIL_NAMES = {"code": "generations=20,k=1,setup=solo,+hydra.callbacks.pwn._target_=res.pwn.X",
              "connect": "generations=20,k=1,setup=solo,ray.address=127.0.0.1:46379"}
# Stands in for Python: a train command is only recorded (its arguments are the attack), the rest runs for real.
LOGGING_PYTHON = """#!/usr/bin/env bash
if [ "$1 $2" = "-m rovermarl.train" ]; then printf '%s\\n' "$@" > "$TRAIN_ARGS"; exit 0; fi
exec {python} "$@"
"""


def _compact_job(results, name, **choices):
    """A compact results job dir ``results/name``: the config.yaml of setup=solo generations=20, its summary."""
    from omegaconf import OmegaConf

    from rovermarl.config import compose_config
    job = results / name
    job.mkdir(parents=True)
    (job / "config.yaml").write_text(OmegaConf.to_yaml(compose_config("setup=solo", "generations=20")))
    (job / "summary.json").write_text(json.dumps({"choices": {"setup": "solo", "k": "1", **choices},
                                                  "final_score": {"0": 1.0}, "seeds": [0]}))
    return job


@pytest.mark.parametrize("attack", sorted(EVIL_NAMES))
def test_heldout_launcher_takes_no_override_from_a_dir_name(tmp_path, attack):
    marker = tmp_path / "PWNED"
    (tmp_path / "res").mkdir()
    _plant(tmp_path / "res", marker)                                    # res/pwn.py, importable from the cwd
    _compact_job(tmp_path / "results" / "evil", EVIL_NAMES[attack])
    python = tmp_path / "python"
    python.write_text(LOGGING_PYTHON.format(python=sys.executable))
    python.chmod(0o755)
    args = tmp_path / "train_args"
    env = {**os.environ, **ENV, "PYTHON": str(python), "TRAIN_ARGS": str(args), "RESULTS": "results/evil",
           "OUT": str(tmp_path / "out"), "SEEDS": "1"}
    proc = subprocess.run(["bash", str(ROOT / "launchers" / "heldout.sh")], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=120)
    assert "Traceback" not in proc.stderr, proc.stderr[-2000:]
    if attack == "connect":                                             # ':' is no part of a job's name
        assert not args.exists() and "must be a directory whose name is" in proc.stderr, proc.stderr
    else:
        train = args.read_text().splitlines()
        run_dir = f"hydra.run.dir='{tmp_path / 'out' / EVIL_NAMES[attack]}'"      # the name as a path, quoted
        assert train == ["-m", "rovermarl.train", "generations=20", "seeds=1", run_dir], train  # from config.yaml
    assert not marker.exists()


def test_heldout_done_reads_the_summary_through_the_safe_reader(tmp_path):
    job = _compact_job(tmp_path, "job")
    done = lambda: run_study("heldout", "done", str(job), timeout=60)  # noqa: E731
    assert done().returncode == 3                                       # not done
    summary = json.loads((job / "summary.json").read_text())
    (job / "summary.json").write_text(json.dumps({**summary, "heldout_score": {"0": 1.0}}))
    assert done().returncode == 0
    (job / "summary.json").write_text("[" * 200_000 + "]" * 200_000)
    proc = done()
    assert proc.returncode == 3 and proc.stderr == "", proc.stderr[-2000:]     # refused: recomputed, no traceback


@pytest.mark.parametrize("override, dropped", [("+hydra.callbacks.pwn._target_=res.pwn.X", False),
                                               ("ray.address=127.0.0.1:46379", True),
                                               ("env.steps=${oc.env:HOME}", False)])
def test_a_jobs_hydra_overrides_are_allow_listed(sweep, tmp_path, override, dropped):
    sw = _copy(sweep, tmp_path)
    path = sw / JOB / ".hydra" / "overrides.yaml"
    path.write_text(yaml.safe_dump([*yaml.safe_load(path.read_text()), override]))
    proc = run_study("heldout", "overrides", str(sw / JOB), timeout=60)
    if dropped:
        assert proc.returncode == 0 and "ray" not in proc.stdout, proc.stdout + proc.stderr
        assert sorted(proc.stdout.split()) == ["generations=30", "k='1'", "setup=duo"]
    else:
        assert "is not a plain KEY=VALUE" in _one_line(proc)


def test_verify_skips_the_run_dirs_a_relaunch_set_aside(sweep, tmp_path):
    sw = _copy(sweep, tmp_path)
    shutil.copytree(sw / JOB / "runs" / "seed_000", sw / JOB / "runs" / "seed_000.0123456789ab")
    proc = run_cli("verify", str(sw), module="rovermarl.analysis", timeout=120)
    assert proc.returncode == 0 and "Traceback" not in proc.stderr, proc.stdout + proc.stderr
    assert proc.stdout.startswith(f"ok  {JOB}: 1 teams re-score"), proc.stdout


def test_export_refuses_a_summary_of_another_generation_of_the_runs(sweep, tmp_path):
    """A relaunch rewriting a job: its old summary.json beside a new curve. Export pairs neither."""
    sw = _copy(sweep, tmp_path)
    path = sw / JOB / "summary.json"
    summary = json.loads(path.read_text())
    summary["final_score"]["0"] += 1.0
    path.write_text(json.dumps(summary))
    proc = run_cli("export", str(sw), str(tmp_path / "out"), "--no-fig6", module="rovermarl.analysis", timeout=120)
    assert "not the same generation of the run" in _one_line(proc)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("seeds", [[0], ["0"]])
def test_strings_from_files_reach_the_terminal_escaped(sweep, tmp_path, seeds):
    """A choices.setup with an escape sequence (retitles a terminal) and a newline (forges a line) is printed
    escaped: in plot's note on the setup, and in the line that refuses the file (seeds of strings)."""
    sw = _copy(sweep, tmp_path)
    path = sw / JOB / "summary.json"
    summary = json.loads(path.read_text())
    summary["choices"]["setup"], summary["seeds"] = "\x1b]0;pwned\x07\nrovermarl.plot: forged", seeds
    path.write_text(json.dumps(summary))
    proc = run_cli(str(sw), "--format", "png", module="rovermarl.plot", timeout=120)
    out = proc.stdout + proc.stderr
    assert "\x1b" not in out and "\x07" not in out and "Traceback" not in out, out
    assert not any(line.startswith("rovermarl.plot: forged") for line in out.splitlines()), out
    if seeds == [0]:
        assert "note: \\x1b]0;pwned\\x07\\nrovermarl.plot: forged: no threshold" in out, out
    else:
        assert "seeds[0] is '0', not an integer; job skipped" in _one_line(proc)


def test_every_string_printed_from_a_file_is_escaped_by_one_helper():
    from rovermarl.errors import printable
    assert printable("a\x1b]0;t\x07\nrovermarl.plot: x\r\u202e") == "a\\x1b]0;t\\x07\\nrovermarl.plot: x\\r\\u202e"
    assert printable("plain k=1, setup=duo") == "plain k=1, setup=duo"
