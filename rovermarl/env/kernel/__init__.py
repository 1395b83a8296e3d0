"""The world's compiled kernel (numba): :func:`rollout` (``fused.py``, the hot path), built from the rules
(``rules.py``), the stages (``stages.py``) and the reward (``reward.py``), each callable alone; docs/ARCHITECTURE.md
maps every module of it.

numba's cache follows every source a compiled function may reach (:mod:`rovermarl.jit`): an edit of any kernel file
recompiles its callers on the next run; no ``__pycache__`` needs deleting.
"""

from rovermarl.env.kernel import target  # first: it sets numba's target features (512-bit vectors on AVX-512)
from rovermarl.env.kernel.fused import rollout
from rovermarl.env.kernel.math import atan2, sincos, sincos_all, tanh
from rovermarl.env.kernel.record import KernelWorld
from rovermarl.env.kernel.reward import max_return, observers, pairwise_sum, payout, reward, score, switched
from rovermarl.env.kernel.rules import REWARDS, bearing, poi_of
from rovermarl.env.kernel.stages import act, sense_libm

__all__ = ["REWARDS", "KernelWorld", "act", "atan2", "bearing", "max_return", "observers", "pairwise_sum", "payout",
           "poi_of", "reward", "rollout", "score", "sense_libm", "sincos", "sincos_all", "switched", "target", "tanh"]
