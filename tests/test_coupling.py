"""The coupling family (conf/setup/coupling<c>.yaml, issue 55): at level c every POI needs c rovers at once, with
N = 2c rovers and the paper's 10 POIs of value 1, so the optimum (World.max_return) is 2 at every level; a job
records its level in summary.json."""

import json

import numpy as np
import pytest

from rovermarl.config import compose_config
from rovermarl.env import make_world
from tests.conftest import run_cli

LEVELS = range(1, 7)


@pytest.mark.parametrize("c", LEVELS)
def test_every_level_has_the_stated_world_and_optimum(c):
    w, solo = make_world(f"coupling{c}"), make_world("solo")
    assert w.n_rovers == 2 * c and w.coupling == (c,) * 10 and w.value == (1,) * 10
    assert np.array_equal(w.poi_xy, solo.poi_xy)                      # the paper's layout at every level
    assert w.max_return == 2.0 == (w.n_rovers // c) * 1               # 2 POIs with c rovers each
    cfg = compose_config(f"setup=coupling{c}")
    assert cfg.setup.coupling_level == c and cfg.env.n_rovers == 2 * c


def test_a_team_of_c_rovers_per_poi_scores_the_optimum_and_one_fewer_scores_nothing():
    w = make_world("coupling3")
    xy = np.repeat(w.poi_xy[[0, 5]], 3, axis=0)                        # rovers 0-2 at POI 0, 3-5 at POI 5
    assert w.team_return(xy) == 2.0
    xy[0] = w.poi_xy[1]
    assert w.team_return(xy) == 1.0


def test_a_job_records_its_coupling_level(tmp_path):
    out = run_cli("setup=coupling2", "generations=2", "seeds=1", "record=off", "parallel=serial",
                  f"hydra.run.dir={tmp_path}", timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    assert json.loads((tmp_path / "summary.json").read_text())["coupling_level"] == 2
    out = run_cli("setup=solo", "generations=2", "seeds=1", "record=off", "parallel=serial",
                  f"hydra.run.dir={tmp_path / 'solo'}", timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    assert "coupling_level" not in json.loads((tmp_path / "solo" / "summary.json").read_text())


FAKE_PYTHON = r"""#!/usr/bin/env bash
echo "$*" >> "$LAUNCH_LOG"
"""


def test_the_launcher_runs_every_family_at_every_level_and_refuses_an_unknown_level(tmp_path):
    import os
    import subprocess

    from tests.conftest import ROOT
    fake = tmp_path / "python"
    fake.write_text(FAKE_PYTHON)
    fake.chmod(0o755)
    env = {**os.environ, "PYTHON": str(fake), "LAUNCH_LOG": str(tmp_path / "log"), "OUT": str(tmp_path / "out"),
           "RESULTS": str(tmp_path / "results"), "AGENT_STEPS": "96000", "SEEDS": "2"}
    proc = subprocess.run(["bash", "launchers/coupling.sh", "parallel=serial"], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    trains = [line for line in (tmp_path / "log").read_text().splitlines() if line.startswith("-m rovermarl.train")]
    assert len(trains) == 6 * 7
    for c in LEVELS:
        mine = [t for t in trains if f"setup=coupling{c} " in t]
        assert len(mine) == 7 and all("budget.agent_steps=96000" in t and "seeds=2" in t for t in mine)
        assert {a for t in mine for a in t.split() if a.startswith("algorithm=")} == {
            "algorithm=ccea", "algorithm=cma", "algorithm=ppo", "algorithm=mappo", "algorithm=ippo"}
    proc = subprocess.run(["bash", "launchers/coupling.sh"], cwd=ROOT, env={**env, "LEVELS": "1 7"},
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2 and "no coupling level '7'" in proc.stderr
