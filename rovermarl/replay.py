"""Replay a run in the Rerun viewer: ``python -m rovermarl.replay PATH [--seed S] [--resim [--ic-seed N]]``.

PATH is a run dir (``runs/seed_XXX``), a job dir (pick the run with ``--seed``; default: the first one) or an
``.rrd`` file. The viewer opens when one can start here (a ``rerun`` executable and a display); otherwise the
exact ``rerun`` command is printed. ``--resim`` re-simulates the run's final genomes on its own initial
conditions, or on fresh ones drawn from ``--ic-seed``, and records a new ``.rrd`` to replay.
"""

from __future__ import annotations

import argparse
import os
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import yaml
from omegaconf import OmegaConf
from omegaconf.errors import OmegaConfBaseException


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
    runs = sorted(p for p in (path / "runs").glob("seed_*") if p.is_dir())
    if not runs:
        raise ReplayError(f"{path}: holds no runs (expected a run dir with run.json, a job dir with runs/, or an .rrd)")
    if seed is None:
        return runs[0]
    match = [p for p in runs if p.name == f"seed_{seed:03d}"]
    if not match:
        raise ReplayError(f"{path}: no run for --seed {seed}; seeds here: " +
                          ", ".join(str(int(p.name[5:])) for p in runs))
    return match[0]


def resimulate(run: Path, ic_seed: int | None, out: Path | None) -> Path:
    """Record the final team of ``run`` on its initial conditions (or fresh ones from ``ic_seed``) to an .rrd."""
    from rovermarl.env import World
    from rovermarl.record.events import Recorder
    from rovermarl.record.rerun_log import write_rrd

    job = run.parent.parent
    cfg_path = next((p for p in (job / ".hydra" / "config.yaml", job / "config.yaml") if p.exists()), None)
    if cfg_path is None or not (run / "genomes.npy").exists():
        raise ReplayError(f"{run}: --resim needs genomes.npy and the job's .hydra/config.yaml (or config.yaml)")
    world = World.from_config(OmegaConf.load(cfg_path))
    genomes = np.load(run / "genomes.npy")
    if ic_seed is None:
        with np.load(run / "initial_conditions.npz") as z:
            ic = z["xy"], z["heading"]
    else:
        ic = world.initial_conditions(ic_seed)
    roll = world.rollout(genomes, ic)
    count = Recorder(world, ic, {}).occupancy(roll.xy[:, -1])
    score = float(roll.returns.mean())
    result = {"seed": 0, "score": np.array([score]), "behaviour_generation": np.zeros(1, dtype=np.int64),
              "behaviour_score": np.array([score]), "behaviour_xy": roll.xy[None].astype(np.float32),
              "occupancy_generation": np.zeros(1, dtype=np.int64), "occupancy_count": count[None]}
    tag = "own" if ic_seed is None else str(ic_seed)
    out = out or run / f"resim_ic-{tag}.rrd"
    write_rrd(out, result, world, recording_id=f"{run.name}-resim-{tag}")
    print(f"re-simulated {run} on initial conditions {tag}: score {score:.4g} -> {out}")
    return out


def open_viewer(rrd: Path, viewer: bool = True) -> None:
    """Start the Rerun viewer on ``rrd`` if possible, else print the command that would."""
    exe = shutil.which("rerun") or (str(Path(sys.executable).with_name("rerun"))
                                    if Path(sys.executable).with_name("rerun").exists() else None)
    display = sys.platform in ("darwin", "win32") or os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
    command = f"{shlex.quote(exe or 'rerun')} {shlex.quote(str(rrd.resolve()))}"
    if viewer and exe and display:
        subprocess.Popen([exe, str(rrd)], start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        print(f"opened the Rerun viewer: {command}")
    else:
        why = "no display" if exe else "no rerun executable on PATH"
        print(f"cannot start the viewer here ({why}); run:\n{command}")


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(prog="rovermarl.replay", description=__doc__.splitlines()[0])

    def error(message: str):  # one line, no usage block
        print(f"rovermarl.replay: error: {message}", file=sys.stderr)
        sys.exit(2)
    p.error = error
    p.add_argument("path", type=Path)
    p.add_argument("--seed", type=int, help="which run of a job dir (default: the first)")
    p.add_argument("--resim", action="store_true", help="re-simulate the final genomes and record a new .rrd")
    p.add_argument("--ic-seed", type=int, help="with --resim: draw fresh initial conditions from this seed")
    p.add_argument("--out", type=Path, help="with --resim: where to write the .rrd")
    p.add_argument("--no-viewer", action="store_true", help="print the rerun command instead of starting it")
    a = p.parse_args(argv)
    try:
        if (a.ic_seed is not None or a.out is not None) and not a.resim:
            raise ReplayError("--ic-seed and --out need --resim")
        target = find_run(a.path, a.seed)
        if a.resim:
            if target.suffix == ".rrd":
                raise ReplayError(f"{target}: --resim needs a run dir or job dir, not an .rrd")
            rrd = resimulate(target, a.ic_seed, a.out)
        else:
            rrd = target if target.suffix == ".rrd" else target / "run.rrd"
            if not rrd.exists():
                raise ReplayError(f"{target}: has no run.rrd (recorded with record.rerun=false?); try --resim")
        open_viewer(rrd, viewer=not a.no_viewer)
    except (ReplayError, OSError, ValueError, KeyError, yaml.YAMLError, OmegaConfBaseException) as e:
        what = "" if isinstance(e, (ReplayError, OSError)) else f"{a.path}: unreadable run or job files: "
        print(f"rovermarl.replay: error: {what}{' '.join(str(e).split())}", file=sys.stderr)
        sys.exit(2)


if __name__ == "__main__":
    main()
