"""The score levels that runs are measured against, and when a share of the runs gets there: one home each.

- :data:`THRESHOLDS`: the level whose first reaching the paper's dotted lines mark (figures and claims tables);
- :func:`optimum`: the best achievable score, :attr:`World.max_return <rovermarl.env.World.max_return>` of the job;
- :func:`quartile_times`: when 1/4, 1/2 and 3/4 of the runs had reached a level;
- :data:`SETUP_ORDER`: the order in which setups are listed (the paper's Setup 1 and 2 first).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping

import numpy as np

from rovermarl.env import World

THRESHOLDS = {"solo": 4.0, "duo": 5.0, "trio": 5.0}
QUARTILES = (0.25, 0.5, 0.75)
SETUP_ORDER = ("solo", "duo", "trio")


def setup_rank(setup: str) -> int:
    """Position of ``setup`` in :data:`SETUP_ORDER`; other setups come after these."""
    return SETUP_ORDER.index(setup) if setup in SETUP_ORDER else len(SETUP_ORDER)


def threshold_for(setup: str, thresholds: Mapping[str, float] | None = None) -> float | None:
    """A setup's threshold: its own from ``thresholds``, else ``thresholds['*']``, else :data:`THRESHOLDS`, or None."""
    thresholds = thresholds or {}
    return thresholds.get(setup, thresholds.get("*", THRESHOLDS.get(setup)))


def optimum(config, trust: bool = False) -> float:
    """The best score of a job with the composed ``config`` (a DictConfig with setup, env, policy): its world's
    maximum team return, earned in every episode. A world plug-in's only with ``trust`` (``--trust-config``)."""
    return World.from_config(config, trust).max_return


def quartile_times(times, quartiles: Iterable[float] = QUARTILES) -> list[float]:
    """For each q, the ``ceil(q n)``-th smallest of the ``n`` runs' first times at a level (``inf``: never);
    ``inf`` if fewer runs ever got there."""
    t = np.sort(np.asarray(times, dtype=np.float64))
    ranks = [max(1, math.ceil(q * len(t) - 1e-9)) for q in quartiles]
    return [float(t[m - 1]) if m <= len(t) else math.inf for m in ranks]
