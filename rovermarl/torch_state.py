"""What the learners on torch (``rovermarl.sb3``, ``rovermarl.marl``) share, one source for both: Adam's moments per
parameter and the torch generator's state as plain arrays for a run's state, and :class:`RunRng`, the run's random
states in force. Imports torch (the ``[rl]`` or ``[marl]`` extra): only those modules import this one."""

from __future__ import annotations

import numpy as np
import torch


def adam_arrays(named: dict, opt_state: dict) -> dict:
    """Adam's ``m``, ``v`` (arrays of each parameter's shape) and ``step`` per parameter name of ``named``
    (name -> parameter), from an optimiser's ``state`` (zeros before its first step)."""
    out = {}
    for name, param in named.items():
        s = opt_state.get(param)
        out[name] = ({"m": s["exp_avg"].numpy().copy(), "v": s["exp_avg_sq"].numpy().copy(), "step": float(s["step"])}
                     if s else {"m": np.zeros(tuple(param.shape), np.float32),
                                "v": np.zeros(tuple(param.shape), np.float32), "step": 0.0})
    return out


def load_adam(named: dict, opt_state: dict, adam: dict) -> None:
    """Put :func:`adam_arrays`' ``adam`` back into an optimiser's ``state`` (parameters not yet stepped stay empty)."""
    for name, param in named.items():
        a = adam[name]
        if a["step"] > 0:
            opt_state[param] = {"step": torch.tensor(float(a["step"])), "exp_avg": torch.from_numpy(np.array(a["m"])),
                                "exp_avg_sq": torch.from_numpy(np.array(a["v"]))}


def seeded(seed: int) -> np.ndarray:
    """The torch CPU generator's state after seeding it with ``seed`` (uint8 array), the caller's state untouched."""
    keep = torch.get_rng_state()
    torch.manual_seed(seed)
    out = torch.get_rng_state().numpy().copy()
    torch.set_rng_state(keep)
    return out


class RunRng:
    """The run's torch random state (and numpy's global one when given: SB3 shuffles with it) in force inside the
    block, the caller's restored after; one torch thread (the run's process has its core; results bit-identical)."""

    def __init__(self, torch_state: np.ndarray, numpy_state: dict | None = None):
        self.run = torch_state, numpy_state

    def __enter__(self):
        self.keep = (torch.get_rng_state(), np.random.get_state(legacy=False), torch.get_num_threads())  # noqa: NPY002
        self.restore(self.run[0])
        if self.run[1] is not None:
            np.random.set_state(self.run[1])  # noqa: NPY002 - SB3 shuffles with it
        torch.set_num_threads(1)
        return self

    def restore(self, torch_state: np.ndarray) -> None:
        torch.set_rng_state(torch.from_numpy(np.array(torch_state, dtype=np.uint8)))

    def state(self) -> np.ndarray:
        """The torch generator's state now (uint8 array)."""
        return torch.get_rng_state().numpy().copy()

    def __exit__(self, *exc):
        torch.set_rng_state(self.keep[0])
        np.random.set_state(self.keep[1])  # noqa: NPY002 - SB3 shuffles with it
        torch.set_num_threads(self.keep[2])
