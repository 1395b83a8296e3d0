"""Where rovermarl's packaged files are: the Hydra config groups, ``CONF_DIR``.

The config groups live in the repository's top-level ``conf/``. The build backend ships that directory as the
package ``rovermarl.conf`` (``pyproject.toml``: ``package-dir`` and ``package-data``), so a wheel,
``pip install .``, ``pip install git+...`` and a container image hold them as ``rovermarl/conf/**.yaml`` next to
the code, and the import system finds them there: ``rovermarl.conf`` holds YAML only (no ``__init__.py``), so it
is a namespace package whose directory is its ``submodule_search_locations`` entry (found without importing it).

Where there is no ``rovermarl.conf`` the code runs from a checkout, and the checkout's ``conf/`` next to the
package is the one: an editable install (``pip install -e .``: setuptools' editable finder does not map a nested
namespace package, so it resolves to the same ``conf/`` this way), ``PYTHONPATH=.``, or a run from the repository
root. In a wheel that path would be ``site-packages/conf``, which is never used: the packaged copy is found first.

``CONF_DIR`` is an absolute :class:`~pathlib.Path` to a real directory in every case, usable as Hydra's
``config_path`` and with ``initialize_config_dir``.
"""

from __future__ import annotations

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


@functools.cache
def option_keys(group: str) -> tuple[frozenset[str], frozenset[str]]:
    """``(allowed, required)``: the keys any option of config group ``group`` has, and those every option has
    (``_target_`` and ``defaults`` left out; an option that sets other groups too contributes its ``group`` node)."""
    options = []
    for path in sorted((CONF_DIR / group).glob("*.yaml")):
        node = _load(f"{group}/{path.name}") or {}
        node = node[group] if isinstance(node.get(group), dict) else node
        options.append(set(node) - {"_target_", "defaults"})
    return frozenset(set().union(*options)), frozenset(set.intersection(*options))
