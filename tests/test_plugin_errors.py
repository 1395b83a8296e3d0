"""An error a world plug-in's own code raises ends the launch with one line naming it (its type, message, file and
line), also when it is raised in a Ray worker (here: the held-out scoring of a finished run draws 256 layouts)."""

import os

import pytest

from rovermarl import errors
from tests.conftest import ROOT, run_cli

PLUGIN = '''
import numpy as np

from rovermarl.worlds import World


class Picky(World):
    layout_dim = 1

    def draw_layout(self, rng, n):
        if n > 16:
            raise ValueError("picky: at most 16 layouts at once,\\n not %d" % n)
        return np.zeros((n, 1))
'''


@pytest.fixture
def picky(tmp_path):
    (tmp_path / "picky.py").write_text(PLUGIN)
    (tmp_path / "env").mkdir()
    (tmp_path / "env" / "picky.yaml").write_text("defaults:\n  - rovers\n  - _self_\n_target_: picky.Picky\n")
    return tmp_path


def test_a_plugins_error_is_one_line_with_its_place():
    try:
        raise ValueError("bad\n value")
    except ValueError as e:
        line = errors.plugin_line(e, [os.path.dirname(__file__)])
        assert errors.plugin_line(e, []) is None                        # not in a plug-in's directory
    assert line.startswith("ValueError: bad value (in ") and __file__ in line and "\n" not in line
    from ray.exceptions import RayTaskError
    text = 'Traceback (most recent call last):\n  File "/elsewhere/picky.py", line 14, in draw_layout\n    raise'
    remote = RayTaskError("advance", text, ValueError("bad\n value")).as_instanceof_cause()   # as ray.get raises it
    want = "ValueError: bad value (in /elsewhere/picky.py:14, draw_layout)"
    assert errors.plugin_line(remote, ["/elsewhere"]) == want
    assert errors.plugin_homes({"env": {"_target_": "os.path.join"}, "k": [{"_target_": "rovermarl.x.Y"}]}) == [
        os.path.dirname(os.path.__file__)]


@pytest.mark.parametrize("parallel", ["serial", "ray"])
def test_a_plugin_error_in_a_worker_reaches_the_user_in_one_line(picky, parallel):
    proc = run_cli("env=picky", f"hydra.searchpath=[file://{picky}]", "generations=20", "seeds=1",
                   f"parallel={parallel}", f"hydra.run.dir={picky / 'out'}", cwd=picky,
                   env={"PYTHONPATH": str(ROOT), "HYDRA_FULL_ERROR": "0"}, timeout=600)
    assert proc.returncode != 0
    last = proc.stderr.strip().splitlines()[-1]
    assert "a plug-in failed: ValueError: picky: at most 16 layouts at once, not 256 (in " in last, proc.stderr[-3000:]
    assert "picky.py:" in last and "Traceback" not in proc.stderr, proc.stderr[-3000:]
    assert os.path.isdir(picky)


@pytest.mark.parametrize("body, said", [
    ("    radius: float = 1.0\n", "Old declares parameters on the World (radius): declare them as fields of its"),
    ("    class Params(World.Params):\n        radius: float = 1.0\n",
     "Old.Params must be a subclass of World.Params decorated with @dataclass(frozen=True)"),
])
def test_a_world_refused_when_made_is_one_line_on_the_command_line(tmp_path, body, said):
    """Issue 52 item 3: a parameter off its Params stops the plug-in's import; the CLI says so in one line."""
    (tmp_path / "old.py").write_text(f"from rovermarl.worlds import World\n\n\nclass Old(World):\n{body}")
    (tmp_path / "env").mkdir()
    (tmp_path / "env" / "old.yaml").write_text("defaults:\n  - rovers\n  - _self_\n_target_: old.Old\n")
    proc = run_cli("env=old", f"hydra.searchpath=[file://{tmp_path}]", "generations=2", "seeds=1", cwd=tmp_path,
                   env={"PYTHONPATH": str(ROOT), "HYDRA_FULL_ERROR": "0"})
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1, proc.stderr
    assert said in proc.stderr and "env._target_=old.Old: cannot be imported (TypeError: " in proc.stderr
