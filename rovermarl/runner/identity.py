"""What identifies a run and names a job's output dir: the one home of the keys left out of each.

- ``RUNTIME``: top-level keys that choose how and where runs execute and what they record, never their numbers
  (backend, Ray, recording, checkpoint interval, resume, Hydra's own node).
- A run's identity (:func:`config_hash`) also leaves out ``seeds`` and ``seed`` (a run has its own seed) and
  ``levels`` (only the job summary reads them): a finished run is reused whatever those say.
- The recording switches ``record.occupancy`` and ``record.behaviour`` (:data:`RECORDED`) change what a run's files
  hold and its C8 measure (``switched``), so they are part of its identity when off (on, the default, leaves the
  identity as it was before this rule).
- Keys added after runs were published (:data:`LATER_KEYS`) are left out of a run's identity while they hold the
  value that reproduces those runs, so a finished run of an earlier version stays finished (its numbers are the same).
- A job's dir name (:data:`NOT_IN_DIR_NAMES`) keeps ``seed`` and ``levels`` (they change what the job dir holds) but
  not ``seeds``, so raising the seed count reuses the runs already done.
"""

from __future__ import annotations

import hashlib
import json

RUNTIME = ("parallel", "ray", "record", "checkpoint", "resume", "hydra")
NOT_IN_RUN_IDENTITY = (*RUNTIME, "seeds", "seed", "levels")
NOT_IN_DIR_NAMES = (*RUNTIME, "seeds")
RECORDED = ("occupancy", "behaviour")
LATER_KEYS = {("env", "reward"): "final", ("env", "speed"): "affine", ("env", "poi_type"): "coupling",
              ("evaluation", "fresh_ic"): False, ("evaluation", "heldout"): 256,
              ("env", "dtype"): "float64"}


def config_hash(plain: dict) -> str:
    """Hash of everything in a plain job config that determines a run's numbers."""
    job = {k: dict(v) if isinstance(v, dict) else v for k, v in plain.items() if k not in NOT_IN_RUN_IDENTITY}
    recording = plain.get("record") or {}
    for key in RECORDED:
        if recording.get(key, True) is False:
            job[f"record.{key}"] = False
    for (section, key), value in LATER_KEYS.items():
        node = job.get(section)
        if isinstance(node, dict) and key in node and node[key] == value and type(node[key]) is type(value):
            del node[key]
            if not node:
                del job[section]
    return hashlib.sha256(json.dumps(job, sort_keys=True, default=str).encode()).hexdigest()
