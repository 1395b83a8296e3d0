"""Packaging: the config groups ship in the package, a built wheel works from anywhere; LICENSE and CITATION.cff.

The full non-editable check (a wheel in a second fresh venv running a 50-generation job from an empty directory)
is in .ci/run; here the wheel is built, inspected, and installed without dependencies next to this environment's.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest
import yaml

from rovermarl.resources import CONF_DIR

tomllib = pytest.importorskip("tomllib")  # Python >= 3.11

ROOT = Path(__file__).resolve().parents[1]
PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())
CONF_FILES = sorted(p.relative_to(ROOT / "conf").as_posix() for p in (ROOT / "conf").rglob("*.yaml"))


def source_packages() -> set[str]:
    """Every directory under rovermarl/ that holds Python code, as a dotted package name."""
    return {".".join(d.relative_to(ROOT).parts) for d in [ROOT / "rovermarl", *(ROOT / "rovermarl").rglob("*")]
            if d.is_dir() and d.name != "__pycache__" and any(d.glob("*.py"))}


def test_every_package_is_listed_in_pyproject():
    listed = set(PYPROJECT["tool"]["setuptools"]["packages"])
    missing = source_packages() - listed
    assert not missing, f"add {sorted(missing)} to [tool.setuptools] packages in pyproject.toml"
    stale = {p for p in listed - {"rovermarl.conf"} if not (ROOT / Path(*p.split("."))).is_dir()}
    assert not stale, f"remove {sorted(stale)} from [tool.setuptools] packages in pyproject.toml"
    assert PYPROJECT["tool"]["setuptools"]["package-dir"] == {"rovermarl.conf": "conf"}


def test_conf_dir_is_a_real_directory_shared_by_every_module():
    from rovermarl import config, resources
    from rovermarl.env import make as world  # make_world composes the packaged config, as the CLI does
    from rovermarl.runner import chunk, identity, trust

    assert world.composer is config.composer is resources.composer
    assert all(m.CONF_DIR is CONF_DIR for m in (chunk, identity, trust))
    assert CONF_DIR.is_absolute() and (CONF_DIR / "config.yaml").is_file()
    assert sorted(p.relative_to(CONF_DIR).as_posix() for p in CONF_DIR.rglob("*.yaml")) == CONF_FILES


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    """The wheel that `python -m build --wheel` makes (as .ci/run does)."""
    tmp = tmp_path_factory.mktemp("dist")
    src, out = tmp / "src", tmp / "dist"      # a copy: concurrent builds would share the checkout's build/ dir
    shutil.copytree(ROOT, src, ignore=shutil.ignore_patterns(
        ".git", ".venv", "venv", "build", "dist", "outputs", "multirun", "__pycache__", "*.egg-info", ".*_cache"))
    proc = subprocess.run([sys.executable, "-m", "build", "--wheel", "--outdir", str(out), str(src)],
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    (whl,) = out.glob("rovermarl-*.whl")
    return whl


def test_wheel_holds_the_code_and_the_config_groups(wheel):
    names = set(zipfile.ZipFile(wheel).namelist())
    code = {p.relative_to(ROOT).as_posix() for p in (ROOT / "rovermarl").rglob("*.py") if "__pycache__" not in p.parts}
    assert code - names == set()
    assert {f"rovermarl/conf/{f}" for f in CONF_FILES} - names == set()
    assert not [n for n in names if n.startswith("conf/") or n.startswith("tests/")]
    assert f"rovermarl-{PYPROJECT['project']['version']}.dist-info/licenses/LICENSE" in names


def test_installed_wheel_finds_its_packaged_configs_from_an_empty_dir(wheel, tmp_path):
    site = tmp_path / "site"
    proc = subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--no-index",
                           "--target", str(site), str(wheel)], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    empty = tmp_path / "empty"
    empty.mkdir()
    env = {**os.environ, "PYTHONPATH": str(site)}   # ahead of any editable install of the checkout
    probe = (
        "import rovermarl, rovermarl.resources as r, rovermarl.config as c;"
        "print(rovermarl.__file__); print(r.CONF_DIR);"
        "print(rovermarl.make_world('duo').coupling);"
        "print(c.compose_config('k=2', 'setup=duo').setup.coupling)"
    )
    proc = subprocess.run([sys.executable, "-c", probe], cwd=empty, env=env, capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    init, conf, world_coupling, composed = proc.stdout.splitlines()[-4:]
    assert Path(init) == site / "rovermarl" / "__init__.py"
    assert Path(conf) == site / "rovermarl" / "conf"          # the packaged copy, not the checkout's conf/
    assert world_coupling == "(2, 1, 1, 1, 1, 2, 1, 1, 1, 1)"
    assert composed == "[2, 1, 1, 1, 1, 2, 1, 1, 1, 1]"
    # Hydra's own entry point (@hydra.main on CONF_DIR) composes from the packaged copy too
    proc = subprocess.run([sys.executable, "-m", "rovermarl.train", "--cfg", "job", "setup=duo"], cwd=empty,
                          env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert yaml.safe_load(proc.stdout)["setup"]["coupling"] == [2, 1, 1, 1, 1, 2, 1, 1, 1, 1]
    assert not any(empty.iterdir()), "composing a config wrote files"


def test_license_is_mit():
    text = (ROOT / "LICENSE").read_text()
    assert text.startswith("MIT License") and "Copyright (c) 2026 rovermarl contributors" in text


def test_citation_cff_parses_and_cites_the_paper_and_this_version():
    cff = yaml.safe_load((ROOT / "CITATION.cff").read_text())
    assert cff["cff-version"] == "1.2.0"
    for key in ("message", "title", "authors", "version", "type", "license"):   # CFF 1.2.0 requires the first 3
        assert cff.get(key), key
    assert cff["version"] == PYPROJECT["project"]["version"]
    assert cff["license"] == "MIT"
    paper = cff["preferred-citation"]
    for key in ("type", "title", "authors", "year"):
        assert paper.get(key), key
    assert paper["title"] == "Adaptive Team Cooperative Co-Evolution for a Multi-Rover Distribution Problem"
    assert [a["family-names"] for a in paper["authors"]] == ["Fontbonne", "Maudet", "Bredeche"]
    assert paper["year"] == 2023 and "GECCO 2023" in paper["conference"]["name"]
    assert all(a.get("family-names") or a.get("name") for a in cff["authors"] + paper["authors"])
