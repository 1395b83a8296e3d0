"""512-bit vectors on AVX-512 CPUs (rovermarl.env.kernel.target): the choice, the vectors LLVM then uses, and the
same bits either way."""

import json
import os
import subprocess
import sys

import pytest
from llvmlite import binding as llvm

from rovermarl.env.kernel import target
from tests.conftest import ROOT

PROBE = """
import hashlib, json, re
import numpy as np
from numba import njit
from rovermarl import make_world
from rovermarl.env.kernel import stages, target
from rovermarl.env.kernel.math import FAST
world = make_world("duo")
rng = np.random.default_rng(0)
digest = hashlib.sha256()
for seed in range(4):
    run = world.rollout(rng.uniform(-2, 2, (world.n_rovers, world.n_params)), world.initial_conditions(seed=seed))
    for a in (run.returns, run.xy, run.heading):
        digest.update(a.tobytes())
sense = njit(**{k: v for k, v in FAST.items() if k != "cache"})(stages.sense_flat.py_func)
ne = 4 * world.episodes
sense(*np.random.default_rng(1).random((4, ne)), 4, world.poi_xy, world.task.sensor_type, 5.0, np.empty(38 * ne))
asm = list(sense.inspect_asm().values())[0]
print(json.dumps({"set": target.SET, "digest": digest.hexdigest(), "zmm": len(re.findall("zmm", asm))}))
"""


def _probe(choice: str) -> dict:
    env = {**os.environ, "ROVERMARL_VECTORS": choice, "NUMBA_CPU_NAME": "skylake-avx512"}
    env.pop("NUMBA_CPU_FEATURES", None)
    proc = subprocess.run([sys.executable, "-c", PROBE], cwd=ROOT, env=env, capture_output=True, text=True,
                          timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


@pytest.mark.skipif(not llvm.get_host_cpu_features().get("avx512f"), reason="needs a CPU with AVX-512")
@pytest.mark.slow
def test_512_bit_vectors_on_an_intel_target_and_the_same_bits():
    """Skylake-SP is tuned to prefer 256-bit vectors: with ROVERMARL_VECTORS=512 the kernel's sensing loop uses zmm
    registers, with off it does not, and rollouts give the same returns and trajectories bit for bit."""
    wide, narrow = _probe("512"), _probe("off")
    assert wide["set"].endswith(",-prefer-256-bit") and narrow["set"] is None
    assert wide["zmm"] > 0 and narrow["zmm"] == 0
    assert wide["digest"] == narrow["digest"]


@pytest.mark.parametrize("host, kwargs, want", [
    ("+avx512f,+fma", {}, "+avx512f,+fma,-prefer-256-bit"),
    ("+avx2,-avx512f", {}, None),                                         # no AVX-512: numba's own choice
    ("+avx512f", {"cpu_features": "+avx2"}, None),                       # the user's features rule
    ("+avx512f", {"cpu_name": "skylake-avx512"}, None),                  # auto leaves a named CPU alone
    ("+avx512f", {"choice": "512", "cpu_name": "skylake-avx512"}, "+avx512f,-prefer-256-bit"),
    ("+avx512f", {"choice": "off"}, None),
])
def test_the_choice(host, kwargs, want):
    assert target.features(host, **kwargs) == want


def test_a_bad_choice_names_itself():
    with pytest.raises(ValueError, match=r"^ROVERMARL_VECTORS='wide': must be one of auto, 512, off$"):
        target.features("+avx512f", "wide")


@pytest.mark.parametrize("env, warned", [({"NUMBA_DEBUGINFO": "1"}, True),
                                         ({"NUMBA_ENABLE_PROFILING": "1"}, True),
                                         ({"NUMBA_ENABLE_PROFILING": "1", "NUMBA_DEBUGINFO": "0"}, False),
                                         ({}, False)])
def test_a_debug_build_is_named_at_import(env, warned, tmp_path):
    """numba's debug-info build (not vectorised, and cached under the fast build's key) is warned about in one line
    when the kernel is imported; profiling with NUMBA_DEBUGINFO=0 is not."""
    clean = {k: v for k, v in os.environ.items() if k not in ("NUMBA_DEBUGINFO", "NUMBA_ENABLE_PROFILING")}
    proc = subprocess.run([sys.executable, "-W", "always", "-c", "import rovermarl.env.kernel"], cwd=ROOT,
                          env={**clean, **env, "NUMBA_CACHE_DIR": str(tmp_path)}, capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    lines = [line for line in proc.stderr.splitlines() if "UserWarning: numba builds with debug info" in line]
    assert len(lines) == (1 if warned else 0), proc.stderr[-2000:]
