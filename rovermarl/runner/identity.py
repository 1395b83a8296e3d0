"""What identifies a run and names a job's output dir: the one home of the keys left out of each.

- ``RUNTIME``: top-level keys that choose how and where runs execute and what they record, never their numbers
  (backend, Ray, recording, checkpoint interval, resume, Hydra's own node).
- A run's identity (:func:`config_hash`) also leaves out ``seeds`` and ``seed`` (a run has its own seed) and
  ``levels`` (only the job summary reads them): a finished run is reused whatever those say.
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
LATER_KEYS = {("env", "reward"): "final", ("env", "speed"): "affine", ("env", "poi_type"): "coupling",
              ("evaluation", "fresh_ic"): False, ("evaluation", "heldout"): 256}


def config_hash(plain: dict) -> str:
    """Hash of everything in a plain job config that determines a run's numbers."""
    job = {k: dict(v) if isinstance(v, dict) else v for k, v in plain.items() if k not in NOT_IN_RUN_IDENTITY}
    for (section, key), value in LATER_KEYS.items():
        node = job.get(section)
        if isinstance(node, dict) and key in node and node[key] == value and type(node[key]) is type(value):
            del node[key]
            if not node:
                del job[section]
    return hashlib.sha256(json.dumps(job, sort_keys=True, default=str).encode()).hexdigest()
