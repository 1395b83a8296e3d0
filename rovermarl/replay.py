"""Replay a run in the Rerun viewer: ``python -m rovermarl.replay PATH [--seed S] [--resim [--ic-seed N]]``.

PATH is a run dir (``runs/seed_XXX``), a job dir (pick the run with ``--seed``; default: the first one) or an
``.rrd`` file. Where there is a display, the native viewer opens. Without one (a server reached by ssh), or with
``--web``, the web viewer is served here on 127.0.0.1 until Ctrl-C, and the URL and the ``ssh -L`` port-forward
to use are printed. ``--no-viewer`` prints both ways instead. ``--resim`` re-simulates the run's final genomes on
its own initial conditions, or on fresh ones drawn from ``--ic-seed``, and records a new ``.rrd`` to replay.
"""

from __future__ import annotations

import getpass
import os
import re
import shlex
import shutil
import signal
import socket
import stat
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path
from urllib.parse import quote

import numpy as np
import yaml
from omegaconf import OmegaConf
from omegaconf.errors import OmegaConfBaseException

from rovermarl.analysis.cli import Parser
from rovermarl.errors import ConfigError, plugin_errors, printable


class ReplayError(Exception):
    """Bad input; the message is printed as one line."""


def find_run(path: Path, seed: int | None) -> Path:
    """The run dir (or ``.rrd``) that ``path`` and ``seed`` designate."""
    if not path.exists():
        raise ReplayError(f"{path}: no such file or directory")
    if path.is_file():
        if path.suffix != ".rrd":
            raise ReplayError(f"{path}: not an .rrd file, a run dir or a job dir")
        return path
    if (path / "run.json").exists() or (path / "genomes.npy").exists():
        return path
    runs = sorted(p for p in (path / "runs").glob("seed_*") if p.is_dir() and re.fullmatch(r"seed_\d+", p.name))
    if not runs:
        raise ReplayError(f"{path}: holds no runs (expected a run dir with run.json, a job dir with runs/, or an .rrd)")
    if seed is None:
        return runs[0]
    match = [p for p in runs if p.name == f"seed_{seed:03d}"]
    if not match:
        raise ReplayError(f"{path}: no run for --seed {seed}; seeds here: " +
                          ", ".join(str(int(p.name[5:])) for p in runs))
    return match[0]


def resimulate(run: Path, ic_seed: int | None, out: Path | None, trust: bool = False) -> Path:
    """Record the final team of ``run`` on its initial conditions (or fresh ones from ``ic_seed``) to an .rrd. A world
    plug-in's run needs ``trust`` (``--trust-config``: its module runs code)."""
    from rovermarl.env import World
    from rovermarl.env.trial import plugin_homes
    from rovermarl.record.atomic import beneath
    from rovermarl.record.events import occupancy
    from rovermarl.record.rerun_log import write_rrd
    from rovermarl.record.safe_read import RunSize, check_tree, load_npy, load_npz, read_yaml

    job = run.parent.parent
    if run.parent.name != "runs":                                      # a run dir is JOB/runs/seed_XXX
        raise ReplayError(f"{run}: --resim needs genomes.npy and the job's .hydra/config.yaml: a run dir sits in a "
                          "job's runs/")
    check_tree(job, "job dir")                                         # nothing followed out of it, no FIFO read
    cfg_path = next((p for p in (job / ".hydra" / "config.yaml", job / "config.yaml") if p.exists()), None)
    if cfg_path is None or not (run / "genomes.npy").exists():
        raise ReplayError(f"{run}: --resim needs genomes.npy and the job's .hydra/config.yaml (or config.yaml)")
    config = read_yaml(cfg_path, kind="config")
    try:
        world = World.from_config(OmegaConf.create(config if isinstance(config, dict) else {}), trust)
    except ConfigError as e:
        raise ReplayError(f"{cfg_path}: {e}") from None
    size = RunSize.of(config, world)
    genomes = load_npy(run / "genomes.npy", size.genomes())
    if ic_seed is None:
        z = load_npz(run / "initial_conditions.npz", size.initial_conditions(), ("xy", "heading"), stored=True)
        ic = tuple(z[k] for k in ("xy", "heading", "layout") if k in z)
    else:
        ic = world.initial_conditions(ic_seed)
    with plugin_errors(plugin_homes(world)):                          # a plug-in's hook: one line naming it
        roll = world.rollout(genomes, ic)
    count = occupancy(world, roll.xy[:, -1])
    score = float(roll.returns.mean())
    result = {"seed": 0, "score": np.array([score]), "behaviour_generation": np.zeros(1, dtype=np.int64),
              "behaviour_score": np.array([score]), "behaviour_xy": roll.xy[None].astype(np.float32),
              "occupancy_generation": np.zeros(1, dtype=np.int64), "occupancy_count": count[None]}
    if len(ic) > 2 and np.shape(ic[2])[-1]:
        result["ic_layout"] = np.asarray(ic[2])                         # a plug-in's layouts: POIs that move, drawn
    tag = "own" if ic_seed is None else str(ic_seed)
    root, out = (job, run / f"resim_ic-{tag}.rrd") if out is None else (Path(out).parent, Path(out))
    with beneath(root, create=root != job):                           # a run dir swapped for a link: refused
        write_rrd(out, result, world, recording_id=f"{run.name}-resim-{tag}")
    print(f"re-simulated {run} on initial conditions {tag}: score {score} -> {out}")
    return out


def rerun_exe() -> str | None:
    """The ``rerun`` executable: on PATH, or beside this Python (a venv not activated)."""
    beside = Path(sys.executable).with_name("rerun")
    return shutil.which("rerun") or (str(beside) if beside.exists() else None)


def has_display() -> bool:
    return sys.platform in ("darwin", "win32") or bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def check_rrd(rrd: Path) -> None:
    """Raise :class:`ReplayError` unless ``rrd`` is a complete Rerun recording. A file cut short (a copy or a
    transfer that stopped) fails to decode, or, when cut between two messages, lacks the footer that every
    recording written here ends with."""
    from rerun.chunk import RrdReader

    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            found = RrdReader(str(rrd)).recordings()
    except RuntimeError as e:
        raise ReplayError(f"{rrd}: not a readable Rerun recording (truncated or corrupt?): "
                          f"{str(e).splitlines()[0]}") from None
    if any("no footer" in str(w.message) for w in caught):
        raise ReplayError(f"{rrd}: not a readable Rerun recording (truncated? it has no footer); copy it again, "
                          "or re-record it with --resim")
    if not found:
        raise ReplayError(f"{rrd}: holds no recording")


def port_free(port: int, host: str = "127.0.0.1") -> bool:
    with socket.socket() as s:
        try:
            s.bind((host, port))
        except OSError:
            return False
        return True


def free_port(default: int, avoid: tuple[int, ...] = ()) -> int:
    """``default`` if it can be bound here, else a free port chosen by the system."""
    if port_free(default) and default not in avoid:
        return default
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def web_commands(rrd: Path, exe: str, web_port: int, grpc_port: int, bind: str = "127.0.0.1") -> dict:
    """The ``rerun --web-viewer`` command serving ``rrd``, the URL to open and the ssh port-forward to use."""
    serve = [exe, "--web-viewer", "--bind", bind, "--web-viewer-port", str(web_port), "--port", str(grpc_port),
             str(rrd.resolve())]
    url = f"http://localhost:{web_port}/?url=" + quote(f"rerun+http://localhost:{grpc_port}/proxy", safe="")
    name = socket.gethostname()
    host = f"{getpass.getuser()}@{name if name and not name.startswith('localhost') else 'THIS_HOST'}"
    return {"serve": serve, "url": url,
            "ssh": f"ssh -N -L {web_port}:127.0.0.1:{web_port} -L {grpc_port}:127.0.0.1:{grpc_port} {host}"}


def serve_web(rrd: Path, exe: str, web_port: int, grpc_port: int, bind: str = "127.0.0.1",
              timeout: float = 30.0, why: str = "") -> None:
    """Serve ``rrd`` in the web viewer until Ctrl-C (or SIGTERM); print the URL and the ssh forward first."""
    cmd = web_commands(rrd, exe, web_port, grpc_port, bind)

    def stop(signum, frame):                                 # SIGTERM, or the ssh session closing: clean up
        raise KeyboardInterrupt

    before = {sig: signal.signal(sig, stop) for sig in (signal.SIGTERM, signal.SIGHUP)}
    with tempfile.TemporaryFile("w+") as log:
        proc = subprocess.Popen(cmd["serve"], stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
        try:
            deadline = time.monotonic() + timeout
            while True:                                      # up when both ports are taken
                if proc.poll() is not None:
                    log.seek(0)
                    last = ([ln.strip() for ln in log if ln.strip()] or ["no output"])[-1]
                    raise ReplayError(f"rerun --web-viewer stopped at once (exit {proc.returncode}): {last}")
                if not port_free(web_port) and not port_free(grpc_port):
                    break
                if time.monotonic() > deadline:
                    raise ReplayError(f"rerun --web-viewer did not open port {web_port} within {timeout:g} s")
                time.sleep(0.1)
            print(f"{why}serving {rrd} in the Rerun web viewer (Ctrl-C stops it)\n"
                  f"  1. on your machine, forward the two ports: {cmd['ssh']}\n"
                  f"     (your user and this machine's name as you reach it by ssh)\n"
                  f"  2. open {cmd['url']}", flush=True)
            proc.wait()
        except KeyboardInterrupt:
            print("stopped the web viewer")
        finally:
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGTERM)
                try:
                    proc.wait(10)
                except subprocess.TimeoutExpired:
                    os.killpg(proc.pid, signal.SIGKILL)
                    proc.wait()
            for sig, handler in before.items():
                signal.signal(sig, handler)


def open_viewer(rrd: Path, viewer: bool = True, web: bool = False, web_port: int = 9090, grpc_port: int = 9876,
                bind: str = "127.0.0.1") -> None:
    """Open ``rrd``: the native viewer where there is a display; else (or with ``web``) serve the web viewer and
    say how to reach it; with ``viewer=False`` print both ways instead of starting either."""
    exe = rerun_exe()
    native = f"{shlex.quote(exe or 'rerun')} {shlex.quote(str(rrd.resolve()))}"
    if viewer and exe and has_display() and not web:
        subprocess.Popen([exe, str(rrd)], start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        print(f"opened the Rerun viewer: {native}")
        return
    if viewer and exe:
        web_port = free_port(web_port)
        serve_web(rrd, exe, web_port, free_port(grpc_port, avoid=(web_port,)), bind,
                  why="" if web else "no display here (DISPLAY and WAYLAND_DISPLAY unset): ")
        return
    cmd = web_commands(rrd, exe or "rerun", web_port, grpc_port, bind)
    why = "" if exe else " (no rerun executable here: pip install rerun-sdk)"
    print(f"native viewer (needs a display){why}:\n  {native}\n"
          f"web viewer (a server without a display):\n  {shlex.join(cmd['serve'])}\n"
          f"  then, on your machine: {cmd['ssh']}\n"
          f"  and open {cmd['url']}")


def main(argv: list[str] | None = None) -> None:
    p = Parser(prog="rovermarl.replay", description=__doc__.splitlines()[0])
    p.add_argument("path", type=Path)
    p.add_argument("--seed", type=int, help="which run of a job dir (default: the first)")
    p.add_argument("--resim", action="store_true", help="re-simulate the final genomes and record a new .rrd")
    p.add_argument("--ic-seed", type=int, help="with --resim: draw fresh initial conditions from this seed")
    p.add_argument("--out", type=Path, help="with --resim: where to write the .rrd")
    p.add_argument("--trust-config", dest="trust", action="store_true",
                   help="with --resim: build a world plug-in the job's config names (its module runs code)")
    p.add_argument("--no-viewer", action="store_true", help="print the viewer commands instead of starting one")
    p.add_argument("--web", action="store_true", help="serve the web viewer even where there is a display")
    p.add_argument("--web-port", type=int, default=9090, help="web viewer's HTTP port (default 9090, or a free one)")
    p.add_argument("--grpc-port", type=int, default=9876, help="web viewer's data port (default 9876, or a free one)")
    p.add_argument("--bind", default="127.0.0.1",
                   help="address the web viewer listens on (default 127.0.0.1: reach it through ssh -L)")
    a = p.parse_args(argv)
    try:
        if (a.ic_seed is not None or a.out is not None) and not a.resim:
            raise ReplayError("--ic-seed and --out need --resim")
        target = find_run(a.path, a.seed)
        if a.resim:
            if target.suffix == ".rrd":
                raise ReplayError(f"{target}: --resim needs a run dir or job dir, not an .rrd")
            rrd = resimulate(target, a.ic_seed, a.out, a.trust)
        else:
            rrd = target if target.suffix == ".rrd" else target / "run.rrd"
            if not rrd.exists():
                raise ReplayError(f"{target}: has no run.rrd (recorded with record.rerun=false?); try --resim")
            if not stat.S_ISREG(rrd.stat().st_mode):                # a FIFO would hang the reader
                raise ReplayError(f"{rrd}: not a regular file")
        check_rrd(rrd)
        open_viewer(rrd, viewer=not a.no_viewer, web=a.web, web_port=a.web_port, grpc_port=a.grpc_port, bind=a.bind)
    except (ReplayError, OSError, ValueError, KeyError, yaml.YAMLError, OmegaConfBaseException) as e:
        what = "" if isinstance(e, (ReplayError, OSError)) else f"{a.path}: unreadable run or job files: "
        print(f"rovermarl.replay: error: {what}{printable(' '.join(str(e).split()), 2000)}", file=sys.stderr)
        sys.exit(2)


if __name__ == "__main__":
    main()
