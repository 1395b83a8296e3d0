"""Provenance: run.json and summary.json say which code made them; runs made by other code are reported, kept, and
recomputed under resume=strict."""

import json

from rovermarl.record.outputs import write_run_json
from rovermarl.record.provenance import CORE, PACKAGES, provenance
from rovermarl.runner.job import run_job
from tests.conftest import make_cfg

OVER = ["generations=30", "seeds=2", "parallel=serial", "record=off"]


def test_run_and_summary_record_versions_and_commit(tmp_path):
    summary = run_job(make_cfg(*OVER), tmp_path / "job")
    meta = json.loads((tmp_path / "job" / "runs" / "seed_000" / "run.json").read_text())
    for record in (meta["provenance"], summary["provenance"]):
        assert record["rovermarl"] == provenance()["rovermarl"] is not None
        assert set(record["packages"]) == set(PACKAGES) and all(record["packages"][name] for name in CORE)
        assert record["cpu"] and record["machine"] and record["python"]             # torch's numbers depend on them
        assert len(record["commit"]) == 40 and isinstance(record["dirty"], bool)   # the tests run from a checkout


def test_runs_of_other_code_are_reported_kept_and_recomputed_when_strict(tmp_path, caplog):
    job = tmp_path / "job"
    run_job(make_cfg(*OVER), job)
    path = job / "runs" / "seed_001" / "run.json"
    meta = json.loads(path.read_text())
    meta["provenance"]["commit"] = "0" * 40
    meta["final_score"] = -1.0                                   # marks the old file
    write_run_json(path.parent, meta)                            # as that code wrote it: its checksum holds
    with caplog.at_level("INFO", logger="rovermarl"):
        run_job(make_cfg(*OVER), job)
    line = [r.message for r in caplog.records if "other code" in r.message]
    assert len(line) == 1 and "1 finished run(s)" in line[0] and "at 00000000" in line[0] and "kept" in line[0]
    assert json.loads(path.read_text())["final_score"] == -1.0   # kept: results never vanish
    caplog.clear()
    with caplog.at_level("INFO", logger="rovermarl"):
        run_job(make_cfg(*OVER, "resume=strict"), job)
    assert any("recomputed (resume=strict)" in r.message for r in caplog.records)
    again = json.loads(path.read_text())
    assert again["final_score"] != -1.0 and again["provenance"]["commit"] == provenance()["commit"]
