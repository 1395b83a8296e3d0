"""The compile notice of a launch comes before Ray starts: Ray's start holds file descriptor 2 (its C++ core's lines)
and drops what it held, so a notice said beside it was lost on the default launch (an outside check saw it 3 of 3)."""

import sys
import time

from omegaconf import OmegaConf

from rovermarl import jit, train
from rovermarl.runner import compile as compile_ahead


def test_the_notice_is_said_before_ray_starts(monkeypatch, capsys):
    def slow_cold(cfg):                                  # what the check of numba's cache costs, made longer
        time.sleep(0.2)
        return {"the rover world's kernel": ["rollout"]}

    seen_at_connect = []
    monkeypatch.setattr(jit, "_SAID", [])               # this process's "said it compiles", restored after
    monkeypatch.setattr(compile_ahead, "cold", slow_cold)
    monkeypatch.setattr(train, "warm", lambda cfg: 1.0)
    monkeypatch.setattr(train, "connect", lambda cfgs: seen_at_connect.append(capsys.readouterr().err))
    cfg = {"env": {"_target_": "rovermarl.env.World", "dtype": "float64", "reward": "final"},
           "algorithm": {"_target_": "rovermarl.algorithms.CC11ES"}}
    train._compile_while_ray_starts([OmegaConf.create(cfg)])
    sys.stderr.flush()
    assert "numba compiles the rover world's kernel (rollout)" in seen_at_connect[0]
    assert "compiled in 1 s" in capsys.readouterr().err
