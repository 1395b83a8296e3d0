"""Keys added after runs were published leave those runs' identity as it was, with no edit of identity.py: every
packaged option keeps the hash the rule of a hand-kept key list gave, and a new key (rovermarl's or a world
plug-in's) at its default changes no hash, while any other value does."""

import hashlib
import json

import pytest

from rovermarl.resources import CONF_DIR
from rovermarl.runner.chunk import to_plain
from rovermarl.runner.identity import NOT_IN_RUN_IDENTITY, RECORDED, config_hash
from tests.conftest import make_cfg

# The rule before: a hand-kept list of the keys added after the first published runs (history, as it was).
OLD_LATER_KEYS = {("env", "reward"): "final", ("env", "speed"): "affine", ("env", "poi_type"): "coupling",
                  ("evaluation", "fresh_ic"): False, ("evaluation", "heldout"): 256, ("env", "dtype"): "float64"}


def _old_hash(plain: dict) -> str:
    job = {k: dict(v) if isinstance(v, dict) else v for k, v in plain.items() if k not in NOT_IN_RUN_IDENTITY}
    recording = plain.get("record") or {}
    for key in RECORDED:
        if recording.get(key, True) is False:
            job[f"record.{key}"] = False
    for (section, key), value in OLD_LATER_KEYS.items():
        node = job.get(section)
        if isinstance(node, dict) and key in node and node[key] == value and type(node[key]) is type(value):
            del node[key]
            if not node:
                del job[section]
    return hashlib.sha256(json.dumps(job, sort_keys=True, default=str).encode()).hexdigest()


OPTIONS = [f"{p.parent.name}={p.stem}" for p in sorted(CONF_DIR.glob("*/*.yaml"))
           if p.parent.name not in ("parallel", "record", "env")]
WORLD = ["env.reward=any_step", "env.speed=clip", "env.poi_type=value", "env.dtype=float32", "evaluation.fresh_ic=true",
         "evaluation.heldout=64", "env.steps=20", "record.occupancy=false"]


@pytest.mark.parametrize("override", OPTIONS + WORLD)
def test_every_packaged_option_keeps_the_hash_of_the_hand_kept_rule(override):
    plain = to_plain(make_cfg("setup=duo", override))
    before = {k: dict(v) if isinstance(v, dict) else v for k, v in plain.items()}
    assert before["algorithm"].pop("loop") == "auto"        # added after that rule: how runs are computed, not what
    assert config_hash(plain) == config_hash(before) == _old_hash(before)


def test_a_new_key_at_its_default_is_left_out_and_any_other_value_is_not():
    plain = to_plain(make_cfg("setup=solo"))
    base = config_hash(plain)
    for section, key, other in (("evaluation", "fresh_ic", True), ("env", "dtype", "float32")):
        without = {s: dict(v) if isinstance(v, dict) else v for s, v in plain.items()}
        del without[section][key]                         # a run made before the key existed
        assert config_hash(without) == base
        changed = {s: dict(v) if isinstance(v, dict) else v for s, v in plain.items()}
        changed[section][key] = other
        assert config_hash(changed) != base


def test_a_world_plugins_own_keys_at_their_declared_defaults_are_left_out(monkeypatch):
    monkeypatch.syspath_prepend(str(CONF_DIR.parent))     # the repository root: examples.obstacles imports
    plain = to_plain(make_cfg("setup=solo"))
    plugin = {s: dict(v) if isinstance(v, dict) else v for s, v in plain.items()}
    plugin["env"]["_target_"] = "examples.random_pois.random_pois.RandomPois"
    bare = config_hash(plugin)
    assert bare != config_hash(plain)                     # another world: another identity
    plugin["env"].update(ring_inner=8.0, ring_outer=14.0)  # the class's defaults
    assert config_hash(plugin) == bare
    plugin["env"]["ring_inner"] = 9.0
    assert config_hash(plugin) != bare
