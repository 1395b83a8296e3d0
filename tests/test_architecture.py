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
    kept, broken = map(int, re.search(r"(\d+) kept, (\d+) broken", proc.stdout).groups())
    contracts = (ROOT / "pyproject.toml").read_text().count("[[tool.importlinter.contracts]]")
    assert broken == 0 and kept == contracts > 0                      # every contract kept, however many


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


def test_no_import_cycle_between_any_two_modules_packages_included():
    # a package's __init__ is a module too: rovermarl.parallel -> ray_backend -> rovermarl.parallel was a cycle
    import grimp

    graph = grimp.build_graph("rovermarl")
    modules = sorted(graph.modules)
    state, cycles = dict.fromkeys(modules, 0), []

    def visit(m, path):
        state[m] = 1
        for n in sorted(graph.find_modules_directly_imported_by(m)):
            if state.get(n) == 1:
                cycles.append(path[path.index(n):] + [n])
            elif state.get(n) == 0:
                visit(n, path + [n])
        state[m] = 2

    for m in modules:
        if state[m] == 0:
            visit(m, [m])
    assert not cycles, cycles[:5]
