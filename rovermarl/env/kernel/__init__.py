"""Compiled kernel of the world (numba).

- :mod:`~rovermarl.env.kernel.math`: branchless ``atan2``, ``tanh``, ``sincos`` (vectorisable), ``wrap``;
- :mod:`~rovermarl.env.kernel.rules`: one home per rule (POI within radius, sensor encoding, bearing, turn, speed);
- :mod:`~rovermarl.env.kernel.stages`: :func:`sense`, :func:`act`, :func:`move`, :func:`reward` (with
  :func:`observers` and :func:`payout`) on batch-first arrays, and their flat loops;
- :mod:`~rovermarl.env.kernel.fused`: :func:`rollout`, the stages fused over E episodes x T steps (the hot path).

numba's cache (``cache=True``) checks only the file of the function it compiled, not the files of its callees: after
editing ``math.py``, ``rules.py`` or ``stages.py``, delete ``rovermarl/env/kernel/__pycache__`` (and
``rovermarl/record/__pycache__``, whose event functions call :func:`poi_of`) so that their callers recompile.
"""

from rovermarl.env.kernel.fused import rollout
from rovermarl.env.kernel.math import atan2, sincos, sincos_all, tanh, wrap
from rovermarl.env.kernel.rules import bearing, poi_of, reading, speed, turn, within
from rovermarl.env.kernel.stages import act, move, observers, payout, reward, sense, sense_libm

__all__ = ["act", "atan2", "bearing", "move", "observers", "payout", "poi_of", "reading", "reward", "rollout",
           "sense", "sense_libm", "sincos", "sincos_all", "speed", "tanh", "turn", "within", "wrap"]
