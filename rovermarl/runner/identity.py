"""What identifies a run and names a job's output dir: the one home of the keys left out of each.

- ``RUNTIME``: top-level keys that choose how and where runs execute and what they record, never their numbers.
- A run's identity (:func:`config_hash`) also leaves out ``seeds``, ``seed`` (a run has its own) and ``levels``
  (only the job summary reads them): a finished run is reused whatever those say.
- ``record.occupancy`` and ``record.behaviour`` (:data:`RECORDED`) change what a run's files hold and its C8 measure
  (``switched``): they join its identity when off (on, the default, leaves it as it was before this rule).
- A key not in :data:`PUBLISHED` (added since runs were published, by rovermarl or a plug-in) is left out while it
  holds its default (:func:`default`), so a finished run of an earlier version stays finished; a new key needs no
  edit here.
- A job's dir name (:data:`NOT_IN_DIR_NAMES`) keeps ``seed`` and ``levels`` (they change what the job dir holds) but
  not ``seeds``, so raising the seed count reuses the runs already done.
"""

from __future__ import annotations

import dataclasses
import hashlib
import inspect
import json

from rovermarl.resources import CONF_DIR, packaged

RUNTIME = ("parallel", "ray", "record", "checkpoint", "resume", "hydra")
NOT_IN_RUN_IDENTITY = (*RUNTIME, "seeds", "seed", "levels")
NOT_IN_DIR_NAMES = (*RUNTIME, "seeds")
RECORDED = ("occupancy", "behaviour")
# The keys each section carried when runs were published: frozen history, never edited.
PUBLISHED = {
    "algorithm": ("_recursive_", "_target_", "elites", "init_high", "init_low", "k", "mutation", "pop_size", "reward",
                  "selection", "team"),
    "env": ("episodes", "n_rovers", "obs_radius", "poi_distance", "sensor_range", "start_box", "steps", "v_max",
            "w_max_deg"),
    "evaluation": (),
    "k": ("_target_", "alpha", "arms", "beta", "c", "end", "epsilon", "gamma", "horizon", "initial", "reward", "start",
          "value"),
    "mutation": ("_target_", "high", "low", "p_gaussian", "sigma", "uniform_fraction"),
    "policy": ("hidden", "init_high", "init_low"),
    "selection": ("_target_", "strict"),
    "setup": ("coupling", "name", "value"),
    "team": ("_target_",),
}
MISSING = object()
LABELS = {"setup": ("coupling_level",)}   # keys with no value that reproduces older runs: always in the identity


def default(section: str, node: dict, key: str):
    """The value of ``section.key`` that reproduces the runs made before the key existed: the packaged option of the
    node's class (``conf/<section>/*.yaml`` with its ``_target_``; the option without one for the paper's world) or
    ``conf/config.yaml``'s node, else the default the class declares (a plug-in's own parameter), else MISSING."""
    target = node.get("_target_")
    files = [CONF_DIR / "config.yaml"] if (CONF_DIR / "config.yaml").is_file() else []
    for path in [*sorted((CONF_DIR / section).glob("*.yaml")), *files]:
        option = packaged(str(path.relative_to(CONF_DIR))) or {}
        option = option.get(section) if path.parent == CONF_DIR or isinstance(option.get(section), dict) else option
        if isinstance(option, dict) and option.get("_target_") == target and key in option:
            return option[key]
    return _declared(target, key) if isinstance(target, str) else MISSING


def _declared(target: str, key: str):
    """The default a class declares for parameter ``key`` (a field of the dataclass or of a World's ``Params``, or
    an ``__init__`` argument)."""
    from hydra.utils import get_class
    try:
        cls = get_class(target)
        fields = getattr(cls, "__dataclass_fields__", None) or getattr(getattr(cls, "Params", None),
                                                                       "__dataclass_fields__", {})
        if key in fields:
            f = fields[key]
            value = f.default if f.default is not dataclasses.MISSING else f.default_factory()
        else:
            value = inspect.signature(cls).parameters[key].default
    except Exception:   # not importable, no such parameter, no default: the key stays in the identity
        return MISSING
    return MISSING if value is inspect.Parameter.empty or value is dataclasses.MISSING else value


def _later(section: str, node: dict, key: str) -> bool:
    """Whether ``section.key`` came after the published runs and holds the value that reproduces them."""
    if key in PUBLISHED.get(section, ()) or key in LABELS.get(section, ()) or key == "_target_":
        return False
    value = default(section, node, key)
    return value is not MISSING and json.dumps(value, sort_keys=True) == json.dumps(node[key], sort_keys=True)


def config_hash(plain: dict) -> str:
    """Hash of everything in a plain job config that determines a run's numbers."""
    job = {k: dict(v) if isinstance(v, dict) else v for k, v in plain.items() if k not in NOT_IN_RUN_IDENTITY}
    recording = plain.get("record") or {}
    for key in RECORDED:
        if recording.get(key, True) is False:
            job[f"record.{key}"] = False
    for section in [k for k, v in job.items() if isinstance(v, dict)]:
        node = job[section]
        for key in [k for k in node if _later(section, node, k)]:
            del node[key]
        if not node:
            del job[section]
    return hashlib.sha256(json.dumps(job, sort_keys=True, default=str).encode()).hexdigest()
