"""Every Python block of the README runs as written."""

import re
import subprocess
import sys

import pytest

from tests.conftest import ROOT

BLOCKS = re.findall(r"```python\n(.*?)```", (ROOT / "README.md").read_text(), flags=re.S)


def test_the_readme_has_python_blocks():
    assert len(BLOCKS) >= 3


@pytest.mark.parametrize("block", BLOCKS, ids=[b.splitlines()[0][:40] for b in BLOCKS])
def test_readme_python_block_runs(block, tmp_path):
    proc = subprocess.run([sys.executable, "-c", block], cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]


def test_the_readme_is_for_users_and_short():
    """At most 300 lines (the rest is in docs/), and every relative link in it points to a file that exists."""
    text = (ROOT / "README.md").read_text()
    assert len(text.splitlines()) <= 300
    for target in re.findall(r"\]\(((?:docs|examples|results)/[^)#]+)", text):
        assert (ROOT / target).exists(), target


def test_the_readme_config_table_lists_every_option_of_its_groups():
    """Each group row of the README's config table names every option in conf/<group> (`a`-`b` ranges expanded)."""
    text = (ROOT / "README.md").read_text()
    rows = re.findall(r"^\| `(\w+)` \| (.+?) \|", text, flags=re.M)
    assert len(rows) >= 8
    for group, cell in rows:
        listed = set(re.findall(r"`([\w.]+)`", cell))
        for lo, hi in re.findall(r"`(\w*?\d+)`-`(\w*?\d+)`", cell):
            stem = lo.rstrip("0123456789")
            listed |= {f"{stem}{i}" for i in range(int(lo[len(stem):]), int(hi[len(stem):]) + 1)}
        options = {p.stem for p in (ROOT / "conf" / group).glob("*.yaml")}
        assert options and options <= listed, f"{group}: not in the README's table: {sorted(options - listed)}"
