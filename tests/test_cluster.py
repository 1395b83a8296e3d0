"""A real Ray cluster: ``ray start --head`` plus a second worker node on this machine, one CPU each.

A sweep joined to it with ``ray.address=127.0.0.1:PORT`` must give exactly the arrays of the same sweep
run serially, and the test must stop exactly the cluster it started. Never ``ray stop`` here: it would
also stop the session's embedded Ray (``ray_session``) and any other Ray on the machine. The drivers run
as subprocesses, so this process never joins the cluster. The machinery lives in
``benchmarks/cluster_check.py``, which researchers can run as a script.
"""

import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
_spec = importlib.util.spec_from_file_location("cluster_check", ROOT / "benchmarks" / "cluster_check.py")
cc = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(cc)

OVERRIDES = ["k=1,adaptive", "setup=duo", "generations=200", "seeds=3", "parallel.chunk=50"]


@pytest.mark.skipif(cc.ray_cli() is None, reason="no `ray` command line")
@pytest.mark.slow
def test_cluster_sweep_equals_local(tmp_path):
    with cc.local_cluster(nodes=2, cpus=1, timeout=60) as (address, env, temp_dir):
        assert address.startswith("127.0.0.1:")
        assert env["RAY_AUTH_MODE"] == "token" and env["RAY_AUTH_TOKEN"]
        assert sum(cc._name(p) == "raylet" for p in cc.processes(temp_dir)) == 2  # head + worker node
        # from a directory outside the repo: the workers import the installed package, not the driver's cwd
        cc.sweep(tmp_path / "cluster", [*OVERRIDES, f"ray.address={address}"], env, cwd=tmp_path, timeout=90)
        nodes = cc.nodes_that_ran(temp_dir)
    # the context manager has stopped the cluster and raises if anything survived; check it all the same
    assert cc.processes(temp_dir) == []
    assert not Path(temp_dir).exists()
    # two runs in flight, one CPU per node: the second chunk task cannot start on the node of the first
    assert len(nodes) == 2, f"ChunkWorker.advance ran on {len(nodes)} node(s)"

    cc.sweep(tmp_path / "local", [*OVERRIDES, "parallel=serial"], timeout=90)
    jobs = sorted(p.name for p in (tmp_path / "cluster").iterdir() if (p / "runs").is_dir())
    assert jobs == ["generations=200,k=1,setup=duo", "generations=200,k=adaptive,setup=duo"]
    assert cc.compare(tmp_path / "local", tmp_path / "cluster") >= 2 * 3 * 2  # curve + genomes, every run


def test_stop_leaves_others_alone():
    """``stop`` only touches processes that name its temp dir (or descend from one)."""
    other = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)", "/tmp/rmc_not_ours/x"])
    try:
        assert cc.processes("/tmp/rmc_not_ou") == []                  # a prefix of the path is not a match
        assert [p.pid for p in cc.processes("/tmp/rmc_not_ours")] == [other.pid]
        assert cc.stop("/tmp/rmc_nobody_here") == []
        assert other.poll() is None
    finally:
        other.kill()
        other.wait()


def test_cluster_launcher_config_is_valid_for_ray_up():
    """launchers/cluster.yaml passes Ray's own cluster-config schema, and the commands it documents exist."""
    import yaml
    from ray.autoscaler._private.util import prepare_config, validate_config
    text = (ROOT / "launchers" / "cluster.yaml").read_text()
    cfg = yaml.safe_load(text)
    validate_config(prepare_config(cfg))                                 # fills the defaults of `ray up`
    assert cfg["provider"]["type"] == "local" and cfg["file_mounts"]["~/rovermarl"] == "."
    assert "launchers/paper.sh ray.address=auto" in text and (ROOT / "launchers" / "paper.sh").is_file()
