"""Where rovermarl's packaged files are: the Hydra config groups, ``CONF_DIR``, and :func:`composer`, Hydra's compose
on it (the one way code composes the packaged config: the CLI's jobs, ``compose_config``, ``make_world``).

A wheel or ``pip install .`` ships the top-level ``conf/`` as ``rovermarl/conf/**.yaml`` (``pyproject.toml``). It
holds YAML only, so ``rovermarl.conf`` is a namespace package, found without importing it. Where there is none, the
code runs from a checkout (``pip install -e .``, whose editable finder does not map a nested namespace package;
``PYTHONPATH=.``; the repository root) and the ``conf/`` next to the package is the one (in a wheel, that path,
``site-packages/conf``, is never used). ``CONF_DIR`` is always an absolute path to a real directory, usable as Hydra's
``config_path`` and with ``initialize_config_dir``.
"""

from __future__ import annotations

import contextlib
import copy
import functools
import importlib.util
from pathlib import Path

CONF_PACKAGE = "rovermarl.conf"


def _conf_dir() -> Path:
    spec = importlib.util.find_spec(CONF_PACKAGE)
    for location in (spec.submodule_search_locations or []) if spec is not None else []:
        path = Path(location).resolve()
        if (path / "config.yaml").is_file():
            return path
    checkout = Path(__file__).resolve().parents[1] / "conf"
    if (checkout / "config.yaml").is_file():
        return checkout
    raise FileNotFoundError(
        f"rovermarl: the config groups are missing: no package {CONF_PACKAGE} and no {checkout}/config.yaml; "
        "reinstall rovermarl (pip install .)"
    )


CONF_DIR: Path = _conf_dir()


@functools.cache
def _load(relative: str) -> dict:
    from omegaconf import OmegaConf
    return OmegaConf.to_container(OmegaConf.load(CONF_DIR / relative), resolve=False)


def packaged(relative: str) -> dict:
    """A packaged yaml file (e.g. ``"config.yaml"``, ``"env/rovers.yaml"``) as plain containers, uninterpolated: the
    one source of the defaults and key sets that code checks configs against (a copy; change it freely)."""
    return copy.deepcopy(_load(relative))


def group_names() -> set[str]:
    """The packaged config groups (``k``, ``setup``, ...)."""
    return {p.name for p in CONF_DIR.iterdir() if p.is_dir() and p.name != "__pycache__"}


def options(group: str) -> list[str]:
    """The packaged options of config group ``group``, sorted."""
    return sorted(p.stem for p in (CONF_DIR / group).glob("*.yaml"))


@functools.cache
def option_keys(group: str) -> tuple[frozenset[str], frozenset[str]]:
    """``(allowed, required)``: the keys any option of config group ``group`` has, and those every option has
    (``_target_`` and ``defaults`` left out; an option that sets other groups too contributes its ``group`` node)."""
    keys = []
    for option in options(group):
        node = _load(f"{group}/{option}.yaml") or {}
        node = node[group] if isinstance(node.get(group), dict) else node
        keys.append(set(node) - {"_target_", "defaults"})
    return frozenset(set().union(*keys)), frozenset(set.intersection(*keys))


@contextlib.contextmanager
def composer(keep_hydra: bool = False):
    """Hydra's ``compose`` function, initialised on ``CONF_DIR``. ``keep_hydra``: the Hydra state around it (a caller's
    own Hydra app) is restored afterwards; else it is left cleared, for the next Hydra launch."""
    from hydra import compose, initialize_config_dir
    from hydra.core.global_hydra import GlobalHydra
    from hydra.initialize import get_gh_backup, restore_gh_from_backup

    backup = get_gh_backup() if keep_hydra else None
    GlobalHydra.instance().clear()
    try:
        with initialize_config_dir(str(CONF_DIR), version_base="1.3", job_name="rovermarl"):
            yield compose
    finally:
        if backup is not None:
            restore_gh_from_backup(backup)
