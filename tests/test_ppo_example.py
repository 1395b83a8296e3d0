"""examples/ppo_vector: PPO (numpy, cleanrl's layout) on the batched env learns: after 60 iterations its policy's mean
team return on fresh initial conditions is above random play's. A few minutes on 2 cores: slow (-m slow)."""

import sys

import pytest

from tests.conftest import ROOT

pytestmark = pytest.mark.slow


def test_ppo_on_the_vector_env_beats_random_play():
    sys.path.insert(0, str(ROOT / "examples" / "ppo_vector"))
    try:
        from ppo_vector import train
    finally:
        sys.path.pop(0)
    out = train("solo", iterations=60, envs=128, seed=0)
    assert out["agent_steps"] == 60 * 15 * 512
    assert out["trained_mean_team_return"] > out["random_mean_team_return"] + 0.25, out
