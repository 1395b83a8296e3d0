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
