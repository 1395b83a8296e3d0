"""The generated kernel of a world plug-in is stamped with every hook's source (rovermarl.env.kernel.compose).

A plug-in that keeps the paper's ``sense`` and replaces ``move`` is edited between two processes on one cache: the
second must run the edit. One plug-in imported under two module paths (its package's root on ``sys.path``, then its
own directory) shares one cache without numba's ``ModuleNotFoundError``; neither writes into rovermarl's package.
"""

import os
import subprocess
import sys

import pytest

from tests.conftest import ROOT

PLUGIN = '''
from rovermarl.worlds import Hooks, move_flat, njit, World


@njit(cache=True)
def move(x, y, heading, sin_h, cos_h, a0, a1, w, s):
    move_flat(x, y, heading, sin_h, cos_h, a0, a1, w.v_max, w.w_max, w.speed_mode)
    for q in range(x.shape[0]):
        pass  # EDIT


class Drift(World):
    hooks = Hooks(move=move)
'''
EDIT = "pass  # EDIT"
TO_POI = "x[q], y[q] = w.poi_xy[0, 0], w.poi_xy[0, 1]"

PROBE = '''import sys
import numpy as np
sys.path.insert(0, sys.argv[1])
import importlib
cls = importlib.import_module(sys.argv[2]).Drift
w = cls(coupling=(1,) * 10, value=(1.0,) * 10)
team = np.random.default_rng(0).uniform(-2, 2, (4, w.n_params))
print(repr(float(w.returns(team, w.initial_conditions(0)).sum())), w.compiled.__file__)
'''


def _run(tmp_path, path, module, env):
    proc = subprocess.run([sys.executable, str(tmp_path / "probe.py"), str(path), module], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=1200)
    assert proc.returncode == 0, proc.stderr[-2000:]
    total, generated = proc.stdout.split()
    assert not generated.startswith(str(ROOT / "rovermarl")), generated       # never in rovermarl's package
    return float(total)


@pytest.fixture
def plugin(tmp_path):
    plug = tmp_path / "pkg" / "plug"
    plug.mkdir(parents=True)
    (tmp_path / "pkg" / "__init__.py").write_text("")
    (plug / "__init__.py").write_text("")
    (plug / "drift.py").write_text(PLUGIN)
    (tmp_path / "probe.py").write_text(PROBE)
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    env.update(PYTHONPATH=str(ROOT), XDG_CACHE_HOME=str(tmp_path / "cache"))
    return plug, env


@pytest.mark.slow
def test_an_edit_of_a_move_hook_beside_the_papers_sense_is_run(tmp_path, plugin):
    plug, env = plugin
    before = _run(tmp_path, tmp_path, "pkg.plug.drift", env)
    source = plug / "drift.py"
    source.write_text(source.read_text().replace(EDIT, TO_POI))
    after = _run(tmp_path, tmp_path, "pkg.plug.drift", env)
    assert after == 16 * 1.0 and before != after                             # every rover on POI 0: 1 per episode


@pytest.mark.slow
def test_one_plugin_under_two_module_paths_shares_the_cache(tmp_path, plugin):
    plug, env = plugin
    first = _run(tmp_path, tmp_path, "pkg.plug.drift", env)                  # as the CLI imports it
    assert _run(tmp_path, plug, "drift", env) == first                       # its own directory on sys.path
    assert _run(tmp_path, tmp_path, "pkg.plug.drift", env) == first
