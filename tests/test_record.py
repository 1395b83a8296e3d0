"""Recording: behaviour/occupancy events, the .rrd read back with RrdReader, replay; checkpoints and resume."""

import json
import os

import numpy as np
import pytest
from rerun.chunk import RrdReader

from rovermarl.record import checkpoint
from rovermarl.record.checkpoint import CheckpointError, RunRecord
from rovermarl.record.events import occupancy
from rovermarl.runner.chunk import advance, parts, to_plain
from rovermarl.runner.identity import config_hash
from rovermarl.runner.job import run_job
from tests.conftest import make_cfg, run_cli


def _entities(path):
    """entity path -> (rows on a timeline, static only?, first record batch: a timeline's if any) of an .rrd."""
    out = {}
    for chunk in RrdReader(str(path)).stream():
        rows, static, batch = out.get(chunk.entity_path, (0, True, None))
        if chunk.is_static:
            out[chunk.entity_path] = (rows, static, batch or chunk.to_record_batch())
        else:                                                  # beside a static style (e.g. SeriesLines)
            out[chunk.entity_path] = (rows + chunk.num_rows, False, chunk.to_record_batch() if static else batch)
    return out


def test_events_match_the_history():
    cfg = make_cfg("setup=duo", "k=2", "generations=400")
    res = _chunks(cfg, 5, [400]).result()
    world = parts(to_plain(cfg)).world
    expected, moved = [0], False                              # every score change, with its exact "before"
    for g in range(1, 401):
        if res["accepted"][g - 1] and res["score"][g] != res["score"][g - 1]:
            expected += [g - 1, g] if moved else [g]
            moved = False
        elif res["accepted"][g - 1]:
            moved = True
    expected += [] if expected[-1] == 400 else [400]
    assert len(expected) > 3
    np.testing.assert_array_equal(res["behaviour_generation"], expected)
    np.testing.assert_array_equal(res["behaviour_score"], res["score"][res["behaviour_generation"]])
    last = world.rollout(res["genomes"], (res["ic_xy"], res["ic_heading"]))
    np.testing.assert_array_equal(res["behaviour_xy"][-1], last.xy.astype(np.float32))
    # occupancy: the latest entry is the final team's, and replaying it gives the score
    count = res["occupancy_count"][-1]
    np.testing.assert_array_equal(count, occupancy(world, last.xy[:, -1]))
    coupling, value = np.array(world.coupling), np.array(world.value)
    assert np.mean(((count >= coupling) * value).sum(axis=1)) == res["score"][-1]
    assert res["occupancy_generation"][0] == 0 and np.all(np.diff(res["occupancy_generation"]) > 0)
    assert len(res["occupancy_generation"]) > 1


def test_tiny_sweep_leaves_one_rrd_per_run_with_the_right_entities(tmp_path):
    sweep = tmp_path / "sweep"
    proc = run_cli("-m", "k=1,adaptive", "setup=duo", "generations=300", "seeds=4", f"hydra.sweep.dir={sweep}",
                   "ray.num_cpus=2", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    for job, bandit in (("generations=300,k=1,setup=duo", False),
                        ("generations=300,k=adaptive,setup=duo", True)):
        rrds = sorted((sweep / job / "runs").glob("seed_*/run.rrd"))
        assert [p.parent.name for p in rrds] == [f"seed_{s:03d}" for s in range(4)]
        run = rrds[0].parent
        ent = _entities(rrds[0])
        with np.load(run / "behaviour.npz") as b, np.load(run / "occupancy.npz") as o:
            n_changes, n_occ = len(b["generation"]), len(o["generation"])
            held = n_occ + (o["generation"][-1] < 300)                      # the last value holds to the end
            assert b["xy"].shape == (n_changes, 16, 16, 4, 2) and o["count"].shape == (n_occ, 16, 10)
        rows, static, batch = ent["/world/pois"]
        assert static and len(batch.column("Points2D:positions")[0]) == 10
        assert ent["/world/poi_radius"][1] and ent["/world/start_boxes"][1]
        assert ent["/metrics/score"][0] == 301 and ent["/metrics/k"][0] == 300
        assert ent["/occupancy/count"][0] == n_occ
        assert all(ent[f"/occupancy/poi_{j}"][0] == held for j in range(10))
        for e in range(16):
            assert ent[f"/world/episodes/{e}/trajectories"][0] == n_changes
            assert ent[f"/world/episodes/{e}/rovers"][0] == 16               # T + 1 steps
        assert len(RrdReader(str(rrds[0])).blueprints()) == 1                 # the layout (see test_replay.py)
        traj = ent["/world/episodes/0/trajectories"][2]
        assert len(traj.column("LineStrips2D:strips")[0]) == 4                # one line per rover
        assert ("/bandit/k1" in ent) == bandit
        if bandit:
            assert all(ent[f"/bandit/k{k}"][0] == 300 for k in (1, 2, 3, 4))
    index = json.loads((sweep / "figures" / "index.json").read_text())     # drawn by the sweep's callback
    curves = next(f for f in index["figures"] if f["name"] == "curves_duo")
    assert curves["methods"] == ["k=1", "adaptive"] and curves["panels"] == 3
    for fig in index["figures"]:
        assert all((sweep / "figures" / name).stat().st_size > 0 for name in fig["files"])
    assert {"curves_duo", "bandit_duo", "update_duo", "occupancy_duo"} <= {f["name"] for f in index["figures"]}


def test_record_off_writes_no_rrd_and_no_events(tmp_path):
    run_job(make_cfg("record=off", "generations=30", "seeds=1", "parallel=serial"), tmp_path)
    run = tmp_path / "runs" / "seed_000"
    assert not (run / "run.rrd").exists()
    with np.load(run / "behaviour.npz") as b:
        assert b["generation"].size == 0


def test_replay_prints_the_command_and_resimulates(tmp_path):
    run_job(make_cfg("generations=30", "seeds=2", "parallel=serial"), tmp_path)
    proc = run_cli(str(tmp_path), "--seed", "1", "--no-viewer", module="rovermarl.replay")
    assert proc.returncode == 0 and "runs/seed_001/run.rrd\n" in proc.stdout, proc.stderr
    assert "ssh -N -L 9090:127.0.0.1:9090 -L 9876:127.0.0.1:9876 " in proc.stdout and "open http://localhost:9090/" \
        in proc.stdout
    out = tmp_path / "fresh.rrd"
    proc = run_cli(str(tmp_path / "runs" / "seed_000"), "--resim", "--ic-seed", "9", "--out", str(out),
                   "--no-viewer", module="rovermarl.replay")
    assert proc.returncode == 0, proc.stderr
    ent = _entities(out)
    assert ent["/world/episodes/3/trajectories"][0] == 1 and ent["/world/episodes/3/rovers"][0] == 16


@pytest.mark.parametrize("args", [["/no/such/path"], ["{empty}"], ["{tmp}", "--seed", "7"], ["{tmp}/x.txt"],
                                  ["{tmp}", "--ic-seed", "3"]])
def test_replay_bad_input_is_one_line(tmp_path, args):
    (tmp_path / "empty").mkdir()
    (tmp_path / "x.txt").write_text("x")
    (tmp_path / "runs" / "seed_000").mkdir(parents=True)
    args = [a.format(tmp=tmp_path, empty=tmp_path / "empty") for a in args]
    proc = run_cli(*args, "--no-viewer", module="rovermarl.replay")
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2 and len(lines) == 1 and lines[0].startswith("rovermarl.replay: error:"), proc.stderr


# ---- checkpoints and resume ---------------------------------------------------------------------

def _chunks(cfg, seed, sizes):
    """A RunRecord advanced by chunks of the given sizes."""
    job = to_plain(cfg)
    rec = RunRecord(seed, cfg.generations, parts(job).algorithm.series)
    for n in sizes:
        rec.add(advance(job, seed, rec.state, n))
    return rec


def _same(a: dict, b: dict):
    assert set(a) == set(b)
    for key in a:
        np.testing.assert_array_equal(a[key], b[key], err_msg=key)


def test_chunked_and_checkpointed_runs_are_bit_identical(tmp_path):
    cfg = make_cfg("k=adaptive", "setup=duo", "generations=240")
    whole = _chunks(cfg, 4, [240])
    rec = _chunks(cfg, 4, [37, 50])
    rec.save(tmp_path / "checkpoint.bin", "h")
    rec = RunRecord.load(tmp_path / "checkpoint.bin", "h")
    for n in (100, 100):
        rec.add(advance(to_plain(cfg), 4, rec.state, n))
    assert rec.done
    _same(whole.result(), rec.result())


def test_corrupt_checkpoint_is_named_and_the_previous_one_is_used(tmp_path):
    cfg = make_cfg("generations=100")
    path = tmp_path / "checkpoint.bin"
    _chunks(cfg, 1, [20]).save(path, "h")
    _chunks(cfg, 1, [20, 20]).save(path, "h")
    assert checkpoint.previous(path).exists()
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])                                     # truncated
    with pytest.raises(CheckpointError, match="checkpoint.bin: checksum mismatch"):
        RunRecord.load(path, "h")
    warnings = []
    rec = checkpoint.resume(path, "h", warnings.append)
    assert rec.generation == 20 and "checksum mismatch" in warnings[0] and str(path) in warnings[0]
    with pytest.raises(CheckpointError, match="different config"):
        RunRecord.load(checkpoint.previous(path), "other")
    path.write_bytes(b"garbage")
    checkpoint.previous(path).write_bytes(checkpoint.MAGIC + b" 00\n")
    warnings.clear()
    assert checkpoint.resume(path, "h", warnings.append) is None and len(warnings) == 2


def test_job_resumes_from_checkpoints_and_skips_finished_runs(tmp_path, caplog):
    over = ["setup=duo", "k=2", "generations=120", "seeds=3", "parallel=serial", "parallel.chunk=25",
            "checkpoint.every=25"]
    ref = run_job(make_cfg(*over), tmp_path / "ref")
    cfg = make_cfg(*over)
    key = config_hash(to_plain(cfg))
    job = tmp_path / "job"
    run_job(make_cfg(*over[:-3], "seeds=1", "parallel=serial"), job)          # seed 0 finished
    half = _chunks(cfg, 1, [25, 25])                                         # seed 1 at generation 50
    half.save(job / "runs" / "seed_001" / "checkpoint.bin", key)
    finished = job / "runs" / "seed_000"
    mtimes = {p.name: p.stat().st_mtime_ns for p in finished.iterdir()}
    with caplog.at_level("INFO", logger="rovermarl"):
        resumed = run_job(cfg, job)
    assert "seed 1 resumes at generation 50" in caplog.text and "1 of 3 runs already finished" in caplog.text
    assert {p.name: p.stat().st_mtime_ns for p in finished.iterdir()} == mtimes
    assert resumed["final_score"] == ref["final_score"]
    for s in range(3):
        for name in ("curve.npz", "behaviour.npz", "occupancy.npz"):
            with np.load(job / "runs" / f"seed_{s:03d}" / name) as a, \
                    np.load(tmp_path / "ref" / "runs" / f"seed_{s:03d}" / name) as b:
                _same(dict(a), dict(b))
    assert not list(job.glob("runs/*/checkpoint*"))
    assert json.loads((job / "runs" / "seed_001" / "run.json").read_text())["config_hash"] == key
    os.utime(job / "summary.json", ns=(1, 1))
    run_job(cfg, job)                                                        # everything finished: no rewrite
    assert (job / "summary.json").stat().st_mtime_ns == 1


def test_job_with_only_corrupt_checkpoints_says_so_and_starts_from_scratch(tmp_path, caplog):
    cfg = make_cfg("generations=60", "seeds=1", "parallel=serial")
    ref = run_job(cfg, tmp_path / "ref")
    ckpt = tmp_path / "job" / "runs" / "seed_000" / "checkpoint.bin"
    ckpt.parent.mkdir(parents=True)
    ckpt.write_bytes(checkpoint.MAGIC + b" deadbeef\npayload")
    with caplog.at_level("INFO", logger="rovermarl"):
        out = run_job(cfg, tmp_path / "job")
    assert f"{ckpt}: checksum mismatch" in caplog.text and "starts from scratch" in caplog.text
    assert out["final_score"] == ref["final_score"]


def test_a_killed_launch_keeps_its_compute(tmp_path):
    """launch.json holds a running launch's compute; the next launch files it in invocations.jsonl as interrupted,
    and a finished launch's own line follows."""
    from rovermarl.record.outputs import close_launch, launch_progress

    close_launch(tmp_path)                                        # nothing left behind: nothing filed
    assert not (tmp_path / "invocations.jsonl").exists()
    launch_progress(tmp_path, {"wall_time_s": 1.0, "team_evals": 100, "runs_advanced": 2})
    launch_progress(tmp_path, {"wall_time_s": 2.5, "team_evals": 300, "runs_advanced": 2})   # replaced, not added
    close_launch(tmp_path)
    close_launch(tmp_path, {"wall_time_s": 4.0, "team_evals": 500, "runs_advanced": 1})
    lines = [json.loads(x) for x in (tmp_path / "invocations.jsonl").read_text().splitlines()]
    assert lines == [{"wall_time_s": 2.5, "team_evals": 300, "runs_advanced": 2, "interrupted": True},
                     {"wall_time_s": 4.0, "team_evals": 500, "runs_advanced": 1}]
    assert not (tmp_path / "launch.json").exists()
