"""numba's cache cannot go stale: after an edit of a callee in another file, the caller recompiles (rovermarl.jit).

A copy of the package gets a probe module whose cached function calls ``rules.within``; the probe runs, ``within``
is edited, the probe runs again in a new process on the same cache: it must see the edit. numba's own stamp (the
caller's file) would load the old machine code.
"""

import os
import shutil
import subprocess
import sys

import pytest

from tests.conftest import ROOT

PROBE = '''from rovermarl.jit import njit
from rovermarl.env.kernel.rules import within


@njit(cache=True)
def probe(x):
    return within(13.0, 0.0, x, 0.0, 2.0)
'''


def _probe(tmp_path, env) -> str:
    code = "from rovermarl.env.kernel.probe import probe; print(probe(14.5), sum(probe.stats.cache_hits.values()))"
    proc = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env, capture_output=True, text=True,
                          timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return proc.stdout.split()


@pytest.mark.slow
def test_editing_a_callee_in_another_file_recompiles_the_caller(tmp_path):
    pkg = tmp_path / "copy"
    shutil.copytree(ROOT / "rovermarl", pkg / "rovermarl", ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copytree(ROOT / "conf", pkg / "conf")
    (pkg / "rovermarl" / "env" / "kernel" / "probe.py").write_text(PROBE)
    env = {**os.environ, "PYTHONPATH": str(pkg), "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    assert _probe(tmp_path, env) == ["True", "0"]                       # compiled and cached
    assert _probe(tmp_path, env) == ["True", "1"]                       # loaded from the cache
    rules = pkg / "rovermarl" / "env" / "kernel" / "rules.py"
    text = rules.read_text()
    assert "return math.sqrt(dx * dx + dy * dy) <= radius" in text
    rules.write_text(text.replace("return math.sqrt(dx * dx + dy * dy) <= radius",
                                  "return math.sqrt(dx * dx + dy * dy) <= radius / 2"))
    assert _probe(tmp_path, env) == ["False", "0"]                      # the edit is seen: recompiled
    assert _probe(tmp_path, env) == ["False", "1"]


PLUGIN_PROBE = '''import sys
import numpy as np
sys.path.insert(0, sys.argv[1])
from obstacles import Obstacles
w = Obstacles(coupling=(1,) * 10, value=(1.0,) * 10)
team = np.random.default_rng(0).uniform(-2, 2, (4, w.n_params))
xy = w.rollout(team, w.initial_conditions(0)).xy
print(repr(float(xy.sum())), sum(w.compiled.rollout.stats.cache_hits.values()))
'''


@pytest.mark.slow
def test_editing_a_world_plugins_hook_recompiles_its_rollout(tmp_path):
    plug = tmp_path / "plug"
    plug.mkdir()
    shutil.copy(ROOT / "examples" / "obstacles" / "obstacles.py", plug / "obstacles.py")
    (tmp_path / "probe.py").write_text(PLUGIN_PROBE)

    def probe():
        proc = subprocess.run([sys.executable, str(tmp_path / "probe.py"), str(plug)], cwd=tmp_path,
                              capture_output=True, text=True, timeout=900)
        assert proc.returncode == 0, proc.stderr[-2000:]
        return proc.stdout.split()

    first, cached = probe(), probe()
    assert first[1] == "0" and cached == [first[0], "1"]                   # compiled, then loaded from the cache
    source = plug / "obstacles.py"
    text = source.read_text()
    assert "x[q] = discs[m, 0] + dx * (r / d)" in text
    source.write_text(text.replace("x[q] = discs[m, 0] + dx * (r / d)", "x[q] = discs[m, 0] + dx * (2 * r / d)"))
    edited = probe()
    assert edited[0] != first[0] and edited[1] == "0"                     # the edit is seen: recompiled
    assert probe() == [edited[0], "1"]
