"""A run's identity covers the recording switches; a run dir made under another identity is set aside
(``seed_XXX.<hash>``) and the run starts afresh, so a finished run never mixes two configs' data."""

import json

import numpy as np

from rovermarl.record.checkpoint import RunRecord
from rovermarl.record.outputs import write_run_json
from rovermarl.runner.chunk import advance, parts, to_plain
from rovermarl.runner.identity import config_hash
from rovermarl.runner.job import run_job
from tests.conftest import make_cfg

BASE = ("setup=duo", "k=1", "generations=300", "seeds=1", "parallel=serial", "parallel.chunk=100",
        "checkpoint.every=100")


def _arrays(run):
    out = {}
    for f in sorted(run.glob("*.np[yz]")):
        if f.suffix == ".npy":
            out[f.name] = np.load(f)
        else:
            with np.load(f) as z:
                out.update({f"{f.name}:{k}": z[k] for k in z.files})
    return out


def test_recording_switches_are_part_of_the_identity_only_when_off():
    on, off = (to_plain(make_cfg(*BASE, r)) for r in ("record=default", "record=off"))
    assert config_hash(on) == config_hash(to_plain(make_cfg(*BASE, "record.rerun=false", "record.every=5")))
    assert config_hash(on) != config_hash(off)
    assert config_hash(on) != config_hash(to_plain(make_cfg(*BASE, "record.occupancy=false")))


def test_a_record_off_checkpoint_resumed_with_recording_on_starts_afresh_beside_it(tmp_path):
    off = to_plain(make_cfg(*BASE, "record=off"))
    job = tmp_path / "job"
    out = job / "runs" / "seed_000"
    rec = RunRecord(0, 300, parts(off).algorithm.series)            # a real checkpoint, 100 generations in
    rec.add(advance(off, 0, None, 100))
    out.mkdir(parents=True)
    rec.save(out / "checkpoint.bin", config_hash(off))
    run_job(make_cfg(*BASE), job)
    aside = job / "runs" / f"seed_000.{config_hash(off)[:12]}"
    assert (aside / "checkpoint.bin").is_file() and not (aside / "run.json").exists()
    run_job(make_cfg(*BASE), tmp_path / "fresh")
    got, want = _arrays(out), _arrays(tmp_path / "fresh" / "runs" / "seed_000")
    assert got.keys() == want.keys() and "behaviour.npz:xy" in got
    for key in want:
        np.testing.assert_array_equal(got[key], want[key], err_msg=key)
    assert got["behaviour.npz:generation"][0] == 0 and (got["curve.npz:switched"] >= 0).all()


def test_a_finished_run_of_another_config_is_set_aside_not_overwritten(tmp_path):
    job = tmp_path / "job"
    run_job(make_cfg(*BASE, "record=off"), job)
    old = json.loads((job / "runs/seed_000/run.json").read_text())
    summary = run_job(make_cfg(*BASE), job)
    aside = job / "runs" / f"seed_000.{old['config_hash'][:12]}"
    assert json.loads((aside / "run.json").read_text()) == old
    assert (job / "runs/seed_000/behaviour.npz").is_file() and summary["seeds"] == [0]


def test_a_finished_run_whose_files_do_not_verify_is_recomputed(tmp_path, caplog):
    job = tmp_path / "job"
    run_job(make_cfg(*BASE), job)
    out = job / "runs" / "seed_000"
    meta = json.loads((out / "run.json").read_text())
    assert set(meta["files"]) == {"curve.npz", "genomes.npy", "initial_conditions.npz", "behaviour.npz",
                                  "occupancy.npz", "run.rrd"}
    want = _arrays(out)
    curve = out / "curve.npz"
    curve.write_bytes(curve.read_bytes()[:-100])                       # cut short, as by a full disk or a copy
    with caplog.at_level("WARNING", logger="rovermarl"):
        run_job(make_cfg(*BASE), job)
    assert f"{curve} has" in caplog.text and "recomputing the run" in caplog.text
    got = _arrays(out)
    for key in want:
        np.testing.assert_array_equal(got[key], want[key], err_msg=key)
    assert set(json.loads((out / "run.json").read_text())["files"]) == set(meta["files"])


def test_checkpoint_bytes_grow_with_the_generations_done_not_asked(tmp_path):
    sizes = {}
    for asked in (300, 30_000):
        plain = to_plain(make_cfg(*BASE, f"generations={asked}", "record=off"))
        rec = RunRecord(0, asked, parts(plain).algorithm.series)
        rec.add(advance(plain, 0, None, 100))
        rec.save(tmp_path / f"{asked}.bin", "x")
        sizes[asked] = (tmp_path / f"{asked}.bin").stat().st_size
        back = RunRecord.load(tmp_path / f"{asked}.bin", "x")
        np.testing.assert_array_equal(back.score[:101], rec.score[:101])
        assert back.score.shape == (asked + 1,) and back.history["k"].shape == (asked,)
    assert abs(sizes[30_000] - sizes[300]) < 2_000, sizes


def test_stale_summary_wrong_seed_checkpoint_and_nan_curve_are_not_trusted(tmp_path, caplog):
    job = tmp_path / "job"
    run_job(make_cfg(*BASE, "seeds=2"), job)
    assert run_job(make_cfg(*BASE, "seeds=1"), job)["seeds"] == [0]                 # not the 2-seed summary
    assert json.loads((job / "summary.json").read_text())["seeds"] == [0]
    with np.load(job / "runs/seed_001/curve.npz") as z:
        arrays = {k: z[k] for k in z.files}
    arrays["score"][:] = np.nan
    np.savez(job / "runs/seed_001/curve.npz", **arrays)
    meta = json.loads((job / "runs/seed_001/run.json").read_text())
    del meta["files"]                                                     # as a run.json from before the checksums
    write_run_json(job / "runs/seed_001", meta)                           # even with a valid checksum of its own
    with caplog.at_level("WARNING", logger="rovermarl"):
        summary = run_job(make_cfg(*BASE, "seeds=2"), job)
    assert "lists no files to check; recomputing the run" in caplog.text
    assert np.isfinite(list(summary["final_score"].values())).all()
    plain = to_plain(make_cfg(*BASE, "seeds=3", "seed=0"))
    rec = RunRecord(0, 300, parts(plain).algorithm.series)                 # seed 0's checkpoint in seed 2's dir
    rec.add(advance(plain, 0, None, 100))
    (job / "runs/seed_002").mkdir()
    rec.save(job / "runs/seed_002/checkpoint.bin", config_hash(plain))
    caplog.clear()
    with caplog.at_level("WARNING", logger="rovermarl"):
        run_job(make_cfg(*BASE, "seeds=3"), job)
    assert "holds seed 0, not 2; ignoring it" in caplog.text
    fresh = run_job(make_cfg(*BASE, "seeds=1", "seed=2"), tmp_path / "fresh")
    assert json.loads((job / "summary.json").read_text())["final_score"]["2"] == fresh["final_score"]["2"]
