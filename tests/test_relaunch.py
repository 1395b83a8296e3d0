"""A relaunch that computes nothing is quick: a finished sweep's relaunch starts no Ray and redraws no figure whose
inputs did not change; a new seed (something to compute) does start Ray, and a changed input redraws. plot on
exported results writes nothing into them unless --out names a place."""

import subprocess
import tempfile
from pathlib import Path

import pytest

from tests.conftest import ROOT, run_cli

SWEEP = ("-m", "k=1,2", "setup=solo", "generations=30", "ray.num_cpus=1")


@pytest.fixture
def ray_tmpdir():
    with tempfile.TemporaryDirectory(prefix="rmray") as d:           # short: Ray's unix sockets
        yield Path(d)


@pytest.mark.slow
def test_a_finished_sweep_relaunches_without_ray_or_drawing(tmp_path, ray_tmpdir):
    sweep = tmp_path / "sw"
    first = run_cli(*SWEEP, "seeds=2", f"hydra.sweep.dir={sweep}", env={"RAY_TMPDIR": str(ray_tmpdir)}, timeout=900)
    assert first.returncode == 0, first.stderr[-2000:]
    assert list(ray_tmpdir.iterdir())                                 # the first launch computed on Ray
    index = sweep / "figures" / "index.json"
    drawn = index.stat().st_mtime_ns
    with tempfile.TemporaryDirectory(prefix="rmray") as fresh:
        again = run_cli(*SWEEP, "seeds=2", f"hydra.sweep.dir={sweep}", env={"RAY_TMPDIR": fresh}, timeout=300)
        assert again.returncode == 0, again.stderr[-2000:]
        assert list(Path(fresh).iterdir()) == []                      # no Ray session
    assert "up to date" in again.stdout + again.stderr and index.stat().st_mtime_ns == drawn
    with tempfile.TemporaryDirectory(prefix="rmray") as fresh:       # a third seed: work, so Ray, and new figures
        more = run_cli(*SWEEP, "seeds=3", f"hydra.sweep.dir={sweep}", env={"RAY_TMPDIR": fresh}, timeout=900)
        assert more.returncode == 0, more.stderr[-2000:]
        assert list(Path(fresh).iterdir())
    assert index.stat().st_mtime_ns != drawn


def test_plot_on_exported_results_writes_nothing_into_them(tmp_path):
    before = subprocess.run(["git", "status", "--porcelain", "--", "results/paper"], cwd=ROOT, capture_output=True,
                            text=True).stdout
    proc = run_cli("results/paper", "--format", "png", "--xscale", "log", module="rovermarl.plot", timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "outputs/figures/paper" in proc.stdout
    after = subprocess.run(["git", "status", "--porcelain", "--", "results/paper"], cwd=ROOT, capture_output=True,
                           text=True).stdout
    assert after == before
    out = run_cli("results/paper", "--format", "png", "--out", str(tmp_path / "f"), module="rovermarl.plot",
                  timeout=600)
    assert out.returncode == 0 and (tmp_path / "f" / "index.json").exists()
