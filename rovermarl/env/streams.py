"""The random streams, one map: which ``SeedSequence`` serves what. Every stream of a run or an environment is
created here and handed on explicitly; no other module spawns or names a spawn key.

A run of seed ``s`` draws from children of ``SeedSequence(s)`` by spawn key (:class:`RunStreams`):

==================== ============= =========================================================================
stream               spawn key     serves
==================== ============= =========================================================================
initial conditions   ``(0,)``      the run's E starts (``World.run_ic``); under ``evaluation.fresh_ic``
                                   generation g >= 1 draws from ``(0, g)``
algorithm            ``(1,)``      the algorithm's initial genomes
mutation             ``(2,)``      which rovers, which changes (CC-(1+1)-ES); the CCEA's shuffles,
                                   tournaments and mutations
selector             ``(3,)``      the k-selector's draws (CC-(1+1)-ES)
held-out             ``(2**31,)``  the held-out initial conditions (``World.heldout_ic``)
==================== ============= =========================================================================

An environment (``rovermarl.vector``, ``rovermarl.pettingzoo``) reset with seed ``s`` draws its starts, episode
after episode, from the root ``SeedSequence(s)`` itself (:func:`env_stream`; a list of seeds: one root per
environment).

The keys are those of the runs published since 4c4ae3c (``tests/test_streams.py`` pins them): a new stream takes a
new key here, never a place among the others.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

INITIAL_CONDITIONS = 0
ALGORITHM = 1
MUTATION = 2
SELECTOR = 3
HELDOUT = 2**31


def _child(seed: int, *key: int) -> np.random.SeedSequence:
    return np.random.SeedSequence(int(seed), spawn_key=key)


class RunStreams(NamedTuple):
    """The named streams of run ``seed`` (see the module's map), each a ``SeedSequence``; what a plug-in
    algorithm receives in :meth:`Algorithm.init <rovermarl.algorithms.Algorithm.init>`."""

    seed: int

    def initial_conditions(self, generation: int = 0) -> np.random.SeedSequence:
        """The run's initial conditions (generation 0), or generation ``g``'s under ``evaluation.fresh_ic``."""
        return _child(self.seed, INITIAL_CONDITIONS) if generation == 0 else \
            _child(self.seed, INITIAL_CONDITIONS, int(generation))

    algorithm = property(lambda self: _child(self.seed, ALGORITHM), doc="The algorithm's initial genomes.")
    mutation = property(lambda self: _child(self.seed, MUTATION),
                        doc="The algorithm's variation: which rovers, which changes.")
    selector = property(lambda self: _child(self.seed, SELECTOR), doc="The k-selector's draws.")
    heldout = property(lambda self: _child(self.seed, HELDOUT),
                       doc="The held-out initial conditions, which the algorithm never sees.")


def env_stream(seed) -> np.random.Generator:
    """The generator of an environment's starts after ``reset(seed=seed)`` (:func:`env_seed` checks ``seed``)."""
    return np.random.default_rng(np.random.SeedSequence(env_seed(seed)))


def env_seed(seed) -> int:
    """An environment's reset seed: an integer >= 0 (a Python or NumPy integer, not a bool), else a one-line
    ``ValueError``."""
    if isinstance(seed, (bool, np.bool_)) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed={_show(seed)}: must be None or an integer >= 0")
    return int(seed)


def _show(value, width: int = 60) -> str:
    text = " ".join(repr(value).split())
    return text if len(text) <= width else text[:width - 3] + "..."
