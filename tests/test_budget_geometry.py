"""docs/REPRODUCTION.md's "Budget and geometry" section is generated from results/budget and results/geometry, and
its reading holds to them."""

import numpy as np

from rovermarl.analysis.budget_geometry import _jobs, block, paper_picture, report
from tests.conftest import ROOT

DOC = (ROOT / "docs" / "REPRODUCTION.md").read_text()
READING = " ".join(DOC.split("<!-- budget-geometry:end -->")[1].split("\n\n## ")[0].split())   # the prose after it


def test_the_section_is_the_generated_report():
    assert block(DOC) == report(ROOT / "results" / "budget", ROOT / "results" / "geometry")


def test_the_reading_holds_to_the_results():
    geometry, budget = _jobs(ROOT / "results" / "geometry"), _jobs(ROOT / "results" / "budget")
    assert paper_picture(geometry + budget) == [("4", "13")]
    for j in budget:                                           # ten times the budget: below 5, no run at 6
        assert j["setup"] == "duo" and np.median(j["final"]) < 5 and (j["final"] < 6).all()
        assert np.median(j["final"]) == 4.0 or j["method"] == "homogeneous"
    homogeneous = next(j["final"] for j in budget if j["method"] == "homogeneous")
    assert 4 < np.median(homogeneous) < 5                      # keeps climbing, still below 5
    assert f"to {np.median(homogeneous):.3g} ({(homogeneous >= 5).sum()} runs at 5)" in READING
    big = {j["method"]: j["final"] for j in geometry if (j["obs_radius"], j["poi_distance"], j["setup"]) ==
           ("4", "13", "duo")}
    assert all(np.median(v) >= 5 for v in big.values()) and (big["k=2"] >= 6).any()
    solo = [j["final"] for j in geometry
            if j["setup"] == "solo" and (j["obs_radius"], j["poi_distance"]) == ("4", "13")]
    assert solo and all((v == 4).all() for v in solo)
    three = {j["method"]: j["final"] for j in geometry if (j["obs_radius"], j["poi_distance"], j["setup"]) ==
             ("3", "13", "duo")}
    best = max(np.median(v) for v in three.values())
    assert 4 < best < 5 and (three["k=2"] >= 6).sum() == 1       # part of the way
    assert f"4 to {best:.3g}; one k=2 run at 6" in READING
