"""``export`` is all or nothing: it writes next to the results dir and moves the result into place only when
everything succeeded; exports add up (other job dirs stay); a failure leaves the results dir as it was."""

import os
import shutil
from pathlib import Path

import pytest

from rovermarl.analysis.export import export
from rovermarl.analysis.results import ResultsError
from rovermarl.runner.job import run_job
from tests.conftest import make_cfg

JOB = "k=1,setup=duo"


@pytest.fixture(scope="module")
def finished_sweep(tmp_path_factory):
    sweep = tmp_path_factory.mktemp("atomic") / "sweep"
    run_job(make_cfg("setup=duo", "generations=30", "seeds=1", "parallel=serial"), sweep / JOB)
    return sweep


def _snapshot(root):
    """Every entry under ``root``: its bytes (None for a dir) and inode."""
    return {p.relative_to(root).as_posix(): (None if p.is_dir() else p.read_bytes(), p.stat().st_ino)
            for p in sorted(root.rglob("*"))}


def _results_dir(tmp_path, finished_sweep):
    """A results dir from an earlier export, with a job of another sweep and a file the new export drops."""
    out = tmp_path / "results" / "out"
    export(finished_sweep, out, log=lambda m: None)
    (out / "older-job").mkdir()
    (out / "older-job" / "summary.json").write_text('{"older": true}\n')
    (out / JOB / "stale.txt").write_text("from an older export\n")
    return out


def test_a_new_results_dir_is_the_staged_one_renamed(finished_sweep, tmp_path):
    out = tmp_path / "results" / "out"
    export(finished_sweep, out, log=lambda m: None)
    assert sorted(p.name for p in out.iterdir()) == sorted([JOB, "compute.json", "fig6.npz"])
    assert sorted(p.name for p in out.parent.iterdir()) == ["out"]


def test_an_export_replaces_its_jobs_and_keeps_the_others(finished_sweep, tmp_path):
    out = _results_dir(tmp_path, finished_sweep)
    older = _snapshot(out / "older-job")
    export(finished_sweep, out, log=lambda m: None)
    assert sorted(p.name for p in out.iterdir()) == sorted([JOB, "older-job", "compute.json", "fig6.npz"])
    assert not (out / JOB / "stale.txt").exists() and (out / JOB / "curves.npz").is_file()
    assert _snapshot(out / "older-job") == older
    assert sorted(p.name for p in out.parent.iterdir()) == ["out"]


def _without_behaviour(finished_sweep, tmp_path):
    """A copy of the sweep whose run lost behaviour.npz: its jobs export, then the Fig. 6 data fails."""
    sweep = tmp_path / "broken"
    shutil.copytree(finished_sweep, sweep)
    (sweep / JOB / "runs" / "seed_000" / "behaviour.npz").unlink()
    return sweep


def test_a_failed_export_leaves_the_results_dir_as_it_was(finished_sweep, tmp_path):
    out = _results_dir(tmp_path, finished_sweep)
    before = _snapshot(out)
    with pytest.raises(ResultsError, match="no run recorded behaviour.npz"):
        export(_without_behaviour(finished_sweep, tmp_path), out, log=lambda m: None)
    assert _snapshot(out) == before
    assert sorted(p.name for p in out.parent.iterdir()) == ["out"]


def test_a_failed_export_makes_no_results_dir_nor_its_parents(finished_sweep, tmp_path):
    out = tmp_path / "new" / "results" / "out"
    with pytest.raises(ResultsError):
        export(_without_behaviour(finished_sweep, tmp_path), out, log=lambda m: None)
    assert not (tmp_path / "new").exists()


def test_a_move_that_fails_midway_is_undone(finished_sweep, tmp_path, monkeypatch):
    out = _results_dir(tmp_path, finished_sweep)
    before = _snapshot(out)
    rename, swapped = os.rename, []

    def failing(src, dst):                     # the second entry's new version moving in, the first one in place
        if Path(dst) == out / "fig6.npz" and Path(src).parent.name.startswith(".out.export-"):
            swapped.append((out / "compute.json").stat().st_ino != before["compute.json"][1])
            raise OSError("disk gone")
        return rename(src, dst)

    monkeypatch.setattr(os, "rename", failing)
    with pytest.raises(OSError, match="disk gone"):
        export(finished_sweep, out, log=lambda m: None)
    monkeypatch.undo()
    assert swapped == [True]
    assert _snapshot(out) == before
    assert sorted(p.name for p in out.parent.iterdir()) == ["out"]


def test_a_results_path_that_is_a_file_is_refused_before_any_work(finished_sweep, tmp_path):
    out = tmp_path / "out"
    out.write_text("not a dir\n")
    with pytest.raises(ResultsError, match="not a directory"):
        export(finished_sweep, out, log=lambda m: None)
    assert out.read_text() == "not a dir\n" and sorted(p.name for p in tmp_path.iterdir()) == ["out"]
