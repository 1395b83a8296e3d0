"""docs/REPRODUCTION.md's "Budget and geometry" section is generated from results/budget and results/geometry, and
its reading holds to them (every number read from results/, none pinned here)."""

import numpy as np

from tests.conftest import ROOT, study_module

bg = study_module("budget_geometry")
_jobs, block, budget_rise, duo_picture, report, solo_c3 = (
    bg._jobs, bg.block, bg.budget_rise, bg.duo_picture, bg.report, bg.solo_c3)

DOC = (ROOT / "docs" / "REPRODUCTION.md").read_text()
READING = " ".join(DOC[DOC.index("Reading. Ten times the budget"):DOC.index("## The radius study")].split())


def test_the_section_is_the_generated_report():
    assert block(DOC) == report(ROOT / "results" / "budget", ROOT / "results" / "geometry")


def test_the_reading_holds_to_the_results():
    geometry, budget = _jobs(ROOT / "results" / "geometry"), _jobs(ROOT / "results" / "budget")
    for j in budget:                                           # "no method's median reaches 5 and no run reaches 6"
        assert j["setup"] == "duo" and np.median(j["final"]) < 5 and (j["final"] < 6).all()
    assert "no method's median reaches 5 and no run reaches 6" in READING
    rise = {m: (up, down, p) for m, up, down, _, p in budget_rise(ROOT / "results" / "budget")}
    assert all(down == 0 for _, down, _ in rise.values()) and "no run's score falls" in READING
    rose = sorted(m for m, (_, _, p) in rise.items() if p < 0.05)
    assert rose == ["homogeneous", "k=2"] and "a rise for the homogeneous team and for k=2" in READING
    assert all(rise[m][2] >= 0.05 for m in ("k=1", "k=adaptive")) and "not for k=1 or EXP3-adaptive" in READING
    worlds = duo_picture(geometry + budget)
    assert ("4", "13") in worlds and "with an observation radius of 4 on the paper's circle" in READING
    c3 = solo_c3(geometry, ("4", "13"))                      # C3 there: the clone team at 4 in more than 3 of 16
    assert c3 and any(hit > 3 for _, hit, _, _ in c3) and "does not give the paper's solo picture" in READING
    assert not any(m == "k=4" for m, *_ in c3) and "solo k=4 was not run there" in READING
