"""The coupling section of docs/LEARNERS.md is the committed results/coupling's (studies/coupling/report.py), and its
drop levels are re-derived here from the summaries alone."""

import json
from pathlib import Path

import numpy as np

from tests.conftest import study_module

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "results" / "coupling"


def test_the_doc_section_is_the_committed_results():
    report = study_module("coupling")
    doc = (ROOT / "docs" / "LEARNERS.md").read_text()
    assert report.block(doc) == report.report(RESULTS)


def test_each_drop_level_is_the_datas():
    """half: the first level whose held-out median is below half the c = 1 median (numpy's median, by hand)."""
    report = study_module("coupling")
    learners = study_module("learners")
    scores = {}
    for job in RESULTS.iterdir():
        if (job / "summary.json").is_file():
            s = json.loads((job / "summary.json").read_text())
            scores[(learners.classify(job.name)[1], s["coupling_level"])] = list(s["heldout_score"].values())
    assert scores, "results/coupling holds no job"
    found = report.drops(report.cells(RESULTS))
    for learner, v in found.items():
        base = np.median(scores[(learner, 1)])
        want = next((c for c in range(2, 7) if (learner, c) in scores and np.median(scores[(learner, c)]) < base / 2),
                    None)
        assert v["half"] == want, learner


def test_a_family_that_never_halves_is_said_to_hold(tmp_path):
    """merl(): a family above half at every level run is named as holding, one below as falling."""
    report = study_module("coupling")
    base = report.stats.median_exact([1.0, 1.0, 1.0])[0]
    d = {"ppo": {"base": base, "half": 3, "surely": None, "top": 6, "at": {}},
         "cces_k1": {"base": base, "half": None, "surely": None, "top": 6, "at": {}}}
    text = " ".join(report.merl(d))
    assert "fell below half its c = 1 level for PPO (SB3) (c = 3)" in text
    assert "did not fall below half for CC-ES k=1 (to c = 6)" in text
    assert "every evolutionary family kept half its c = 1 level to a higher coupling (c = 6 or more)" in text
    assert "(c = 2 at most): MERL's trend." in text


def test_when_every_family_falls_the_report_says_which_kind_kept_half_longer_and_what_the_top_level_holds():
    report = study_module("coupling")
    est = {v: report.stats.median_exact([v] * 3)[0] for v in (0.0, 0.5, 1.0)}
    d = {"ppo": {"base": est[1.0], "half": 4, "surely": 4, "top": 4, "at": {4: est[0.0]}},
         "ccea_dpp": {"base": est[1.0], "half": 2, "surely": 3, "top": 4, "at": {4: est[0.5]}}}
    text = " ".join(report.merl(d))
    assert "did not fall below half" not in text and "no family" not in text
    assert "every policy-gradient family kept half its c = 1 level to a higher coupling (c = 3 or more)" in text
    assert "(c = 1 at most): on this measure the data run against MERL's trend" in text
    assert ("At c = 4, the highest coupling every family has run, the highest held-out median is CCEA D++'s, 0.5 "
            "[0.5, 0.5], whose interval overlaps no other's") in text
    assert "a median of 0 for PPO (SB3)" in text
    d["ccea_dpp"]["half"] = 4
    assert "neither trend is shown" in " ".join(report.merl(d))


def test_a_family_with_only_its_c1_cell_makes_no_trend():
    """merl(): a family run only at c = 1 is not said to hold (nothing was run past it)."""
    report = study_module("coupling")
    base = report.stats.median_exact([1.0, 1.0, 1.0])[0]
    d = {"ppo": {"base": base, "half": None, "surely": None, "top": 1, "at": {}},
         "cces_k1": {"base": base, "half": 2, "surely": 2, "top": 6, "at": {}}}
    text = " ".join(report.merl(d))
    assert text == "Not yet comparable: the sweep has no policy-gradient family run past c = 1 so far."
