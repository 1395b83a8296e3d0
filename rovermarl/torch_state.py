"""What the learners on torch (``rovermarl.sb3``, ``rovermarl.marl``) keep in a run's state as plain arrays, one
source for both: Adam's moments per parameter and the torch generator's seeded state. Imports torch (the ``[rl]`` or
``[marl]`` extra): only those modules import this one."""

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
