"""A full disk and a read-only one: one line, a non-zero exit, no temp file left; after space is freed the relaunch
completes and every finished run verifies. Needs a real small filesystem (a tmpfs; skipped where mounting is not
permitted)."""

import json
import subprocess
import uuid

import pytest

from rovermarl.record.outputs import verify
from tests.conftest import assert_same_curves, run_cli, sweep_curves

ARGS = ("-m", "k=1,2", "setup=duo", "generations=3000", "seeds=4", "parallel=serial", "~hydra.callbacks.plot")


@pytest.fixture
def tmpfs(tmp_path):
    """mount(size) -> a fresh tmpfs of that size (e.g. "3m"); unmounted after the test."""
    mounted = []

    def mount(size: str, *options: str):
        where = tmp_path / f"fs-{uuid.uuid4().hex[:6]}"
        where.mkdir()
        opts = ",".join((f"size={size}", *options))
        proc = subprocess.run(["mount", "-t", "tmpfs", "-o", opts, "tmpfs", str(where)], capture_output=True)
        if proc.returncode != 0:
            pytest.skip(f"cannot mount a tmpfs here: {proc.stderr.decode().strip()}")
        mounted.append(where)
        return where
    yield mount
    for where in mounted:
        subprocess.run(["umount", str(where)], capture_output=True)


@pytest.mark.slow
def test_a_full_disk_stops_in_one_line_and_the_relaunch_completes(tmpfs, tmp_path):
    disk = tmpfs("3m")
    sweep = disk / "sweep"
    full = run_cli(*ARGS, f"hydra.sweep.dir={sweep}", timeout=300)
    assert full.returncode == 1
    lines = full.stderr.strip().splitlines()
    assert len(lines) == 1 and "No space left on device; fix it and relaunch the same command to resume" in lines[0]
    assert lines[0].startswith("rovermarl.train: error: ") and f"cannot write {sweep}/" in lines[0]
    assert not [p for p in sweep.rglob("*") if p.name.endswith(".tmp") or p.name.startswith(".checkpoint")]
    subprocess.run(["mount", "-o", "remount,size=64m", str(disk)], check=True)
    again = run_cli(*ARGS, f"hydra.sweep.dir={sweep}", timeout=300)
    assert again.returncode == 0, again.stderr[-3000:]
    runs = sorted(sweep.glob("*/runs/seed_*"))
    assert len(runs) == 8
    for run in runs:
        assert verify(run, json.loads((run / "run.json").read_text())) is None
    ref = run_cli(*ARGS, f"hydra.sweep.dir={tmp_path / 'ref'}", timeout=300)
    assert ref.returncode == 0
    got, want = sweep_curves(sweep), sweep_curves(tmp_path / "ref")
    assert len(want) == 8
    assert_same_curves(got, want)


def test_a_read_only_output_dir_is_refused_before_any_work(tmpfs):
    disk = tmpfs("1m", "ro")
    proc = run_cli("generations=5", f"hydra.run.dir={disk / 'run'}", timeout=120)
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == [
        f"rovermarl.train: error: hydra.run.dir={disk / 'run'}: cannot write there: {disk}: Read-only file system"]
