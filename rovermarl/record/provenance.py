"""Where a result came from: the rovermarl version, its git commit (and whether the tree was dirty) when the
package runs from a git checkout, the versions of the libraries that compute and record it (the learners' torch,
stable-baselines3, gymnasium and MARL libraries among them: None when not installed), and the machine: torch on the
CPU is deterministic on one machine, not across CPUs, so a learner's numbers are only comparable on the same ``cpu``.
"""

from __future__ import annotations

import platform
import subprocess
from functools import cache
from importlib import metadata
from pathlib import Path

CORE = ("numpy", "numba", "ray", "hydra-core", "omegaconf", "rerun-sdk")            # always installed
LEARNERS = ("torch", "stable-baselines3", "gymnasium", "torchrl", "tensordict", "benchmarl")   # extras: None if absent
PACKAGES = CORE + LEARNERS


@cache
def provenance() -> dict:
    """``rovermarl`` (version), ``commit`` and ``dirty`` (None outside a checkout), ``packages`` (name -> version),
    ``python``, ``machine`` (e.g. x86_64) and ``cpu`` (its model name, None where the system does not say)."""
    commit, dirty = _git()
    return {"rovermarl": _version("rovermarl"), "commit": commit, "dirty": dirty,
            "packages": {name: _version(name) for name in PACKAGES}, "python": platform.python_version(),
            "machine": platform.machine(), "cpu": _cpu()}


def same_code(recorded: dict | None) -> bool:
    """Whether a run's recorded ``provenance`` names this code (version, and commit when both have one)."""
    if not recorded:
        return False
    now = provenance()
    if recorded.get("rovermarl") != now["rovermarl"]:
        return False
    return recorded.get("commit") is None or now["commit"] is None or recorded.get("commit") == now["commit"]


def describe(recorded: dict | None) -> str:
    """``0.1.0 at 1a2b3c4d (dirty)`` for a provenance record; ``unknown code`` for none."""
    if not recorded:
        return "unknown code (no provenance)"
    text = str(recorded.get("rovermarl"))
    if recorded.get("commit"):
        text += f" at {recorded['commit'][:8]}" + (" (dirty)" if recorded.get("dirty") else "")
    return text


def _cpu() -> str | None:
    """The CPU's model name (Linux: /proc/cpuinfo; elsewhere platform.processor(), or None)."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()[:200]
    except OSError:
        pass
    return platform.processor() or None


def _version(name: str) -> str | None:
    try:
        return metadata.version(name)
    except metadata.PackageNotFoundError:
        return None


def _git() -> tuple[str | None, bool | None]:
    """HEAD and dirtiness of the checkout holding this package, if it is one (an editable install)."""
    root = Path(__file__).resolve().parents[2]
    if not (root / ".git").exists():
        return None, None
    try:
        head = subprocess.run(["git", "-C", str(root), "rev-parse", "HEAD"], capture_output=True, text=True,
                              timeout=10, check=True).stdout.strip()
        status = subprocess.run(["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no"],
                                capture_output=True, text=True, timeout=10, check=True).stdout
    except (OSError, subprocess.SubprocessError):
        return None, None
    return head or None, bool(status.strip())
