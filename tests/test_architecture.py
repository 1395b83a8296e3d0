"""The architecture of docs/ARCHITECTURE.md holds: import layers and no cycles (import-linter), small modules, the
map names every module, and the package writes no benchmark logs."""

import re
import subprocess
import sys
from pathlib import Path

from tests.conftest import ROOT

MODULES = sorted(p.relative_to(ROOT).as_posix() for p in (ROOT / "rovermarl").rglob("*.py"))


def test_import_contracts_hold():
    exe = Path(sys.executable).with_name("lint-imports")
    proc = subprocess.run([str(exe), "--no-cache"], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-2000:]
    assert "2 kept, 0 broken" in proc.stdout


def test_no_module_over_400_lines():
    long = {m: n for m in MODULES if (n := len((ROOT / m).read_text().splitlines())) > 400}
    assert not long


def test_the_architecture_map_names_every_module_and_only_those():
    text = (ROOT / "docs" / "ARCHITECTURE.md").read_text()
    tree = text[text.index("```") + 3:text.index("```", text.index("```") + 3)]
    named, stack = set(), []
    for line in tree.splitlines():
        m = re.match(r"^(\s*)(\S+?\.py|\S+/)\s", line + " ")
        if not m:
            continue
        depth = len(m.group(1)) // 2
        stack[depth:] = [m.group(2)]
        if m.group(2).endswith(".py"):
            named.add("".join(stack))
    assert named == set(MODULES)


def test_the_package_writes_no_benchmark_log():
    offenders = [m for m in MODULES if "ROVERMARL_WORK_LOG" in (ROOT / m).read_text()]
    assert not offenders
