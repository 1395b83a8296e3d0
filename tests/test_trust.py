"""A results directory runs no code of its own: read paths never build a ``_target_`` outside rovermarl from a job's
config unless told to trust it (``--trust-config``)."""

import yaml

from rovermarl.runner.job import run_job
from tests.conftest import make_cfg, run_cli


def _tampered_sweep(tmp_path):
    """A finished duo k=1 job whose saved config builds its mutation with ``builtins.open(PWNED, "w")``."""
    job = tmp_path / "sweep" / "k=1,setup=duo"
    run_job(make_cfg("setup=duo", "generations=30", "seeds=1", "parallel=serial"), job)
    pwned = tmp_path / "pwned"
    cfg = yaml.safe_load((job / "config.yaml").read_text())
    cfg["mutation"] = {"_target_": "builtins.open", "file": str(pwned), "mode": "w"}
    cfg["algorithm"]["mutation"] = cfg["mutation"]
    (job / "config.yaml").write_text(yaml.safe_dump(cfg))
    return job, pwned


def test_no_read_path_runs_a_target_from_the_results(tmp_path):
    job, pwned = _tampered_sweep(tmp_path)
    sweep, run = job.parent, job / "runs" / "seed_000"
    export = run_cli("export", str(sweep), str(tmp_path / "out"), module="rovermarl.analysis")
    assert export.returncode == 2
    assert export.stderr.strip().splitlines()[-1] == (
        f"rovermarl.analysis: error: algorithm.mutation._target_=builtins.open: is outside rovermarl, in {job}: "
        "a results directory may not run code; pass --trust-config if you trust it")
    for argv, module in ((["readings", "export", str(sweep), str(tmp_path / "r")], "rovermarl.analysis"),
                         ([str(sweep), "--out", str(tmp_path / "fig")], "rovermarl.plot"),
                         ([str(run), "--resim", "--no-viewer"], "rovermarl.replay")):
        proc = run_cli(*argv, module=module)
        assert "Traceback" not in proc.stderr, (module, proc.stderr[-2000:])
    assert not pwned.exists()


def test_trusting_the_config_builds_its_targets(tmp_path):
    # the same payload with --trust-config really runs: the guard, not luck, kept the file from being created
    job, pwned = _tampered_sweep(tmp_path)
    run_cli("export", str(job.parent), str(tmp_path / "out"), "--trust-config", module="rovermarl.analysis")
    assert pwned.exists()
