"""Every file of a job is verified or rebuilt: an unreadable summary.json or launch.json, a checkpoint whose
numbers disagree with the config (with a valid checksum). Each case: at most one WARNING line, then the job goes on
to the results of an undisturbed one."""

import hashlib
import io
import json

import numpy as np

from rovermarl.record.checkpoint import MAGIC
from rovermarl.runner.job import run_job
from tests.conftest import make_cfg

ARGS = ("setup=duo", "k=1", "generations=300", "seeds=2", "parallel=serial", "parallel.chunk=100",
        "checkpoint.every=100", "record=off")


def _warnings(caplog) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.levelname == "WARNING"]


def _retag(path, **meta_changes) -> None:
    """Rewrite a checkpoint's metadata and give it a valid checksum again (what a careless or hostile edit does)."""
    payload = path.read_bytes().partition(b"\n")[2]
    with np.load(io.BytesIO(payload)) as z:
        arrays = {k: z[k] for k in z.files}
    meta = json.loads(str(arrays.pop("_meta")))
    meta.update(meta_changes)
    buf = io.BytesIO()
    np.savez(buf, _meta=np.array(json.dumps(meta)), **arrays)
    payload = buf.getvalue()
    path.write_bytes(MAGIC + b" " + hashlib.sha256(payload).hexdigest().encode() + b"\n" + payload)


def test_unreadable_summary_is_rebuilt_from_the_runs(tmp_path, caplog):
    want = run_job(make_cfg(*ARGS), tmp_path)
    text = (tmp_path / "summary.json").read_text()
    (tmp_path / "summary.json").write_text(text[:len(text) // 2])               # truncated
    with caplog.at_level("WARNING", logger="rovermarl"):
        got = run_job(make_cfg(*ARGS), tmp_path)
    assert len(_warnings(caplog)) == 1 and "summary.json is unreadable" in _warnings(caplog)[0]
    assert got["final_score"] == want["final_score"] and got["heldout_score"] == want["heldout_score"]
    assert json.loads((tmp_path / "summary.json").read_text())["final_score"] == want["final_score"]


def test_garbage_launch_json_with_an_unfinished_run_resumes(tmp_path, caplog):
    want = run_job(make_cfg(*ARGS), tmp_path / "ref")
    run_job(make_cfg(*ARGS[:2], "generations=300", "seeds=1", *ARGS[4:]), tmp_path / "job")   # seed 0 done only
    (tmp_path / "job" / "launch.json").write_text("garbage{")
    with caplog.at_level("WARNING", logger="rovermarl"):
        got = run_job(make_cfg(*ARGS), tmp_path / "job")
    assert len(_warnings(caplog)) == 1 and "launch.json is unreadable" in _warnings(caplog)[0]
    assert got["final_score"] == want["final_score"]
    assert not (tmp_path / "job" / "launch.json").exists()


def test_a_checkpoint_with_a_valid_checksum_and_absurd_numbers_is_not_believed(tmp_path, caplog):
    from rovermarl.record.checkpoint import RunRecord
    from rovermarl.runner.chunk import advance, parts, to_plain
    from rovermarl.runner.identity import config_hash

    want = run_job(make_cfg(*ARGS), tmp_path / "ref")
    plain = to_plain(make_cfg(*ARGS))
    for changes in ({"generations": 10**13}, {"generation": 10**13}, {"generation": -1}, {"seed": "0"},
                    {"history_keys": ["nope"]}):
        job = tmp_path / f"job_{len(list(tmp_path.iterdir()))}"
        rec = RunRecord(0, 300, parts(plain).algorithm.series)
        rec.add(advance(plain, 0, None, 100))
        (job / "runs/seed_000").mkdir(parents=True)
        rec.save(job / "runs/seed_000/checkpoint.bin", config_hash(plain))
        _retag(job / "runs/seed_000/checkpoint.bin", **changes)
        caplog.clear()
        with caplog.at_level("WARNING", logger="rovermarl"):
            got = run_job(make_cfg(*ARGS), job)
        warned = _warnings(caplog)
        assert len(warned) == 1 and "checkpoint.bin" in warned[0] and "starts from scratch" in warned[0], warned
        assert got["final_score"] == want["final_score"], changes
