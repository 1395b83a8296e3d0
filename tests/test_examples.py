"""examples/random_search: an algorithm from outside the package, with the README's command; resume after a kill,
its own series in curve.npz and run.rrd, and figures."""

import os
import signal
import subprocess
import sys
import time

import numpy as np
from rerun.chunk import RrdReader

from tests.conftest import ROOT, run_cli


def readme_command() -> list[str]:
    """The README's one command that runs the example (a line starting `python -m rovermarl.train`)."""
    lines = [ln.strip() for ln in (ROOT / "README.md").read_text().splitlines()]
    found = [ln for ln in lines if ln.startswith("python -m rovermarl.train") and "algorithm=random_search" in ln]
    assert len(found) == 1, found
    return found[0].split()[3:]


def test_readme_random_search_command_resumes_records_and_plots(tmp_path):
    args = readme_command()
    assert any(a.startswith("hydra.searchpath=") for a in args)
    out = tmp_path / "run"
    argv = [sys.executable, "-m", "rovermarl.train", *args, "generations=1000", "parallel=serial",
            "parallel.chunk=50", "checkpoint.every=50", f"hydra.run.dir={out}"]
    driver = subprocess.Popen(argv, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                              start_new_session=True)
    deadline = time.time() + 240
    while time.time() < deadline and driver.poll() is None and not list(out.glob("runs/*/checkpoint.bin")):
        time.sleep(0.05)
    assert driver.poll() is None, "the run ended before it could be killed"
    os.killpg(driver.pid, signal.SIGKILL)
    driver.wait()
    proc = subprocess.run(argv, cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "resumes at generation" in proc.stdout + proc.stderr

    ref = run_cli(*args, "generations=1000", "parallel=serial", f"hydra.run.dir={tmp_path / 'ref'}", timeout=600)
    assert ref.returncode == 0, ref.stderr[-3000:]
    for seed in ("seed_000", "seed_001"):
        with np.load(out / "runs" / seed / "curve.npz") as a, np.load(tmp_path / "ref" / "runs" / seed /
                                                                       "curve.npz") as b:
            assert a.files == ["score", "best_child"] and len(a["best_child"]) == 1000
            for key in a.files:
                np.testing.assert_array_equal(a[key], b[key])
        entities = {str(c.entity_path) for c in RrdReader(str(out / "runs" / seed / "run.rrd")).stream()}
        assert "/metrics/best_child" in entities and "/metrics/score" in entities
    plot = run_cli(str(out), "--out", str(tmp_path / "fig"), module="rovermarl.plot")
    assert plot.returncode == 0, plot.stderr
    assert list((tmp_path / "fig").glob("*.png"))
