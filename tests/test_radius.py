"""The pre-registered radius study: docs/REPRODUCTION.md's section is the report of results/radius, and the four
criteria are applied exactly as issue 43 wrote them (each bound checked on synthetic summaries, one run either side)."""

import json

from tests.conftest import ROOT, study_module

radius = study_module("radius")
CRITERIA, RADII, block, passing, report, verdicts = (radius.CRITERIA, radius.RADII, radius.block, radius.passing,
                                                    radius.report, radius.verdicts)

DOC = (ROOT / "docs" / "REPRODUCTION.md").read_text()
JOBS = {("duo", "k=1"): "k=1", ("duo", "k=2"): "k=2", ("duo", "homogeneous"): "team=homogeneous",
        ("solo", "k=1"): "k=1", ("solo", "k=4"): "k=4", ("solo", "homogeneous"): "team=homogeneous"}


def test_the_section_is_the_generated_report():
    assert block(DOC) == report(ROOT / "results" / "radius")


def _study(tmp_path, finals: dict):
    """A results dir for radius 3 with the given (setup, method) -> 16 final scores."""
    for (setup, method), scores in finals.items():
        name = f"env.obs_radius=3,env.poi_distance=13,generations=200000,{JOBS[(setup, method)]},seed=16,setup={setup}"
        (tmp_path / name).mkdir(parents=True)
        job = tmp_path / name
        (job / "summary.json").write_text(json.dumps({"final_score": {str(16 + i): s for i, s in enumerate(scores)}}))
    return tmp_path


def _paper_like() -> dict:
    return {("duo", "k=1"): [5.0] * 8 + [4.0] * 8, ("duo", "k=2"): [6.0] + [5.0] * 7 + [4.0] * 8,
            ("duo", "homogeneous"): [4.0] * 16, ("solo", "k=1"): [4.0] * 12 + [3.75] * 4,
            ("solo", "k=4"): [4.0] * 3 + [3.0] * 13, ("solo", "homogeneous"): [4.0] * 3 + [3.0] * 13}


def test_a_world_at_every_bound_passes_and_one_run_across_any_bound_fails(tmp_path):
    assert [c.text for c in CRITERIA][0].startswith("duo k=1 and k=2 each have at least 8 of 16")
    assert passing(_study(tmp_path / "a", _paper_like())) == (["3"], [r for r in RADII if r != "3"])
    changes = {"c1": (("duo", "k=2"), 1, 4.0), "c2": (("duo", "k=2"), 0, 5.0), "c3": (("solo", "k=1"), 0, 3.75),
               "c4k4": (("solo", "k=4"), 3, 4.0), "c4homogeneous": (("solo", "homogeneous"), 3, 4.0)}
    for name, (job, i, value) in changes.items():
        finals = _paper_like()
        finals[job] = list(finals[job])
        finals[job][i] = value
        good, _ = passing(_study(tmp_path / name, finals))
        assert good == [], name


def test_an_unfinished_radius_has_no_verdict(tmp_path):
    finals = _paper_like()
    del finals[("solo", "k=4")]
    good, pending = passing(_study(tmp_path / "s", finals))
    assert good == [] and "3" in pending
    assert "no verdict yet" in report(tmp_path / "s")


def test_the_launcher_runs_the_registered_radii():
    assert f'RADII="${{RADII:-{" ".join(RADII)}}}"' in (ROOT / "launchers" / "radius.sh").read_text()


def test_the_reading_follows_the_criteria():
    """Each count the reading after the section quotes is the committed study's, and "no radius passes" holds."""
    results = ROOT / "results" / "radius"
    reading = DOC.split("<!-- radius:end -->")[1].split("\n## ")[0]
    assert passing(results) == ([], [])
    assert "No radius passes" in reading
    v = {r: [(ok, counts) for _, counts, ok in rows] for r, rows in verdicts(results).items()}
    holds = {c: [r for r in RADII if v[r][c - 1][0]] for c in (1, 2, 3, 4)}     # criterion -> radii where it holds
    assert holds == {1: ["3.5", "4"], 2: ["4"], 3: list(RADII), 4: []}
    assert v["3.5"][0][1] == {("duo", "k=1"): 12, ("duo", "k=2"): 11}
    assert sum(v["4"][1][1].values()) == 3
    assert [v[r][3][1][("solo", "homogeneous")] for r in RADII] == [4, 4, 9, 15]
    assert v["4"][3][1][("solo", "k=4")] == 16
    for quoted in ("k=1 12 of 16 and k=2 11 of 16", "3 runs\nat 6", "4 of 16 runs reach 4 at\n2.5 and at 3",
                   "homogeneous 15 of 16, k=4 16 of 16"):
        assert quoted in reading, quoted
