"""Compiled kernel of the world (numba).

- :mod:`~rovermarl.env.kernel.math`: branchless ``atan2``, ``tanh``, ``sincos`` (vectorisable), ``wrap``;
- :mod:`~rovermarl.env.kernel.rules`: one home per rule (POI within radius, sensor encoding, bearing, turn, speed);
- :mod:`~rovermarl.env.kernel.stages`: :func:`sense`, :func:`act`, :func:`move` on batch-first arrays, and their
  flat loops;
- :mod:`~rovermarl.env.kernel.target`: 512-bit vectors on CPUs with AVX-512 (numba's target features, set at import),
  and a warning when numba builds with debug info (not vectorised, yet cached);
- :mod:`~rovermarl.env.kernel.simd`: the register tiles of the MLP's two layers (LLVM-IR intrinsics);
- :mod:`~rovermarl.env.kernel.checks`: what the rollout checks (each step or each rollout) to take its cheaper
  paths, each bit-identical to the general one;
- :mod:`~rovermarl.env.kernel.reward`: :func:`reward` (with :func:`observers` and :func:`payout`), the
  per-step reward readings :func:`fold` and :func:`settle`, the score :func:`score` (numpy's summation order)
  and the phenotypic coupling measure :func:`switched`;
- :mod:`~rovermarl.env.kernel.fused`: :func:`rollout`, the stages fused over E episodes x T steps (the hot path), on
  :class:`KernelWorld`, the world's one record.

numba's cache follows every source a compiled function may reach (:mod:`rovermarl.jit`): an edit of any kernel file
recompiles its callers on the next run; no ``__pycache__`` needs deleting.
"""

from rovermarl.env.kernel import target  # first: it sets numba's target features (512-bit vectors on AVX-512)
from rovermarl.env.kernel.fused import rollout
from rovermarl.env.kernel.math import atan2, sincos, sincos_all, tanh
from rovermarl.env.kernel.record import KernelWorld
from rovermarl.env.kernel.reward import max_return, observers, pairwise_sum, payout, reward, score, switched
from rovermarl.env.kernel.rules import REWARDS, bearing, poi_of
from rovermarl.env.kernel.stages import act, move, sense, sense_libm

__all__ = ["REWARDS", "KernelWorld", "act", "atan2", "bearing", "max_return", "move", "observers", "pairwise_sum",
           "payout", "poi_of", "reward", "rollout", "score", "sense", "sense_libm", "sincos", "sincos_all", "switched",
           "target", "tanh"]
