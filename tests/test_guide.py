"""docs/GUIDE.md's snippets for RL users run as written (the PettingZoo env, the vector env, the Gymnasium view and,
with the [rl] extra, the stable-baselines3 view)."""

import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SECTION = ROOT.joinpath("docs", "GUIDE.md").read_text().split("## For RL users: the environments")[1].split("\n## ")[0]
SNIPPETS = re.findall(r"```python\n(.*?)```", SECTION, re.S)


def test_the_section_has_the_four_views():
    assert len(SNIPPETS) == 4
    for name in ("parallel_env", "VectorEnv", "GymVectorEnv", "rovermarl.sb3"):
        assert any(name in s for s in SNIPPETS), name


@pytest.mark.parametrize("code", SNIPPETS, ids=["pettingzoo", "vector", "gymnasium", "sb3"])
def test_a_snippet_runs(code):
    if "stable_baselines3" in code:
        pytest.importorskip("stable_baselines3", reason="the [rl] extra is not installed")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600, cwd=ROOT)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.strip()
