"""Configs read back from a results directory run no code of their own.

A job dir's ``.hydra/config.yaml`` (or ``config.yaml``) names the classes that built its runs (``_target_``). A read
path that rebuilds a run from it (``python -m rovermarl.analysis export`` re-runs one run for the Fig. 6 data)
first checks every ``_target_``: only rovermarl's own (``rovermarl.``) pass, unless the caller trusts the config
(``--trust-config``: e.g. your own plug-in on ``hydra.searchpath``). Nothing is imported before the check.
"""

from __future__ import annotations

from omegaconf import OmegaConf

from rovermarl import errors

TRUSTED = ("rovermarl.",)


def targets(node, path: str = "") -> list[tuple[str, str]]:
    """Every ``(key, _target_)`` in a config tree (a DictConfig or plain containers), e.g. ``("mutation", "...")``."""
    if OmegaConf.is_config(node):
        node = OmegaConf.to_container(node, resolve=False)
    found = []
    if isinstance(node, dict):
        if "_target_" in node:
            found.append((path or "config", str(node["_target_"])))
        for key, value in node.items():
            found += targets(value, f"{path}.{key}" if path else str(key))
    elif isinstance(node, list):
        for i, value in enumerate(node):
            found += targets(value, f"{path}[{i}]")
    return found


def check_targets(config, source: str) -> None:
    """Raise :class:`~rovermarl.errors.ConfigError` (one line) if ``config`` read from ``source`` names a
    ``_target_`` outside rovermarl."""
    for key, target in targets(config):
        if not target.startswith(TRUSTED):
            raise errors.ConfigError(f"{key}._target_", target, f"is outside rovermarl, in {source}: a results "
                                     "directory may not run code; pass --trust-config if you trust it")
