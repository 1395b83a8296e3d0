"""Figures: ``python -m rovermarl.plot PATH [--out DIR] [--threshold SETUP=VALUE ...] [--format ...] [--xscale log]
[--x evals]``.

Draws the paper's figures from a finished (or partly finished) sweep, one job dir, or exported results
(``results/paper``) into ``PATH/figures/`` (see :mod:`rovermarl.analysis.figures`). Bad input exits with
status 2 and one line on stderr. Files are written beneath PATH (or ``--out``) only
(:func:`rovermarl.record.atomic.beneath`: a ``figures/`` swapped for a link fails in one line).
:class:`PlotCallback` does the same when a Hydra multirun ends, and never fails it.
"""

from __future__ import annotations

import argparse
import contextlib
import logging
import math
import sys
from collections.abc import Sequence
from pathlib import Path

from hydra.experimental.callback import Callback

from rovermarl.analysis.cli import Parser
from rovermarl.analysis.levels import THRESHOLDS
from rovermarl.analysis.results import ResultsError
from rovermarl.analysis.sweep import SweepError
from rovermarl.errors import PluginError, Printable, printable
from rovermarl.record.atomic import beneath

log = logging.getLogger("rovermarl.plot")
PROG = "rovermarl.plot"


def _threshold(text: str) -> tuple[str, float]:
    """``duo=5`` -> ("duo", 5.0); a bare ``5`` applies to every setup ("*")."""
    setup, _, value = text.rpartition("=")
    try:
        number = float(value)
    except ValueError:
        number = math.nan
    if not math.isfinite(number):
        raise argparse.ArgumentTypeError(f"expected SETUP=NUMBER or NUMBER (a finite number), got {text!r}")
    return setup or "*", number


def parser() -> argparse.ArgumentParser:
    from rovermarl.analysis.stamp import FORMATS  # light: matplotlib is imported when figures are drawn

    p = Parser(prog=PROG, description="Draw the paper's figures (PNG/PDF) from a sweep dir or one job dir.")
    p.add_argument("path", type=Path, help="sweep dir (from `rovermarl.train -m`) or one job dir")
    p.add_argument("--out", type=Path, default=None,
                   help="output dir (default: PATH/figures; for exported results outputs/figures/<name>)")
    p.add_argument("--threshold", type=_threshold, action="append", default=[], metavar="SETUP=VALUE",
                   help="score whose first reaching is marked by quartile lines (default "
                        + ", ".join(f"{setup}={level:g}" for setup, level in THRESHOLDS.items()) + ")")
    p.add_argument("--format", nargs="+", choices=("png", "pdf", "svg"), default=list(FORMATS), dest="formats")
    p.add_argument("--xscale", choices=("linear", "log"), default="linear",
                   help="generation axes: linear, or log (generation 0 included)")
    p.add_argument("--x", choices=("auto", "generation", "evals"), default="auto", dest="x",
                   help="score curves against generations or team evaluations (auto: evaluations when the methods "
                        "of a setup spend different numbers per generation, e.g. cc11es against ccea)")
    p.add_argument("--update-run", type=Path, default=None, metavar="RUN_DIR",
                   help="run dir (runs/seed_XXX) whose behaviour.npz the update figure shows")
    p.add_argument("--update-gen", type=int, default=None, metavar="G",
                   help="logged generation shown 'after' in the update figure (default: first score rise)")
    p.add_argument("--trust-config", dest="trust", action="store_true",
                   help="build world plug-ins the jobs' configs name (env._target_: their modules run code)")
    return p


def main(argv: Sequence[str] | None = None) -> None:
    args = parser().parse_args(argv)
    if args.update_gen is not None and args.update_run is None:
        parser().error("--update-gen needs --update-run")
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(Printable(f"{PROG}: %(message)s"))               # what a file holds, escaped
    logging.basicConfig(level=logging.INFO, handlers=[handler])
    out = args.out if args.out is not None else default_out(args.path)
    kwargs = {"thresholds": dict(args.threshold), "formats": args.formats, "update_run": args.update_run,
              "update_gen": args.update_gen, "xscale": args.xscale, "x": args.x, "trust": args.trust}
    from rovermarl.analysis.stamp import current_index
    try:
        index = current_index(args.path, out, **kwargs)
        if index is not None:
            print(f"{PROG}: {len(index['figures'])} figures in {out}, up to date (their inputs did not change)")
            return
        from rovermarl.analysis.figures import plot_sweep
        own = args.out is None and out == args.path / "figures"           # PATH/figures: written beneath PATH
        with (beneath(args.path if own else out, create=not own) if args.path.is_dir()
              else contextlib.nullcontext()):                         # no PATH: plot_sweep says so, writes nothing
            index = plot_sweep(args.path, out, log=log, **kwargs)
    except (SweepError, ResultsError, OSError, PluginError) as e:     # OSError: a link, FIFO or corrupt file
        print(f"{PROG}: error: {printable(e, 2000)}", file=sys.stderr)
        sys.exit(2)
    n_files = sum(len(f["files"]) for f in index["figures"])
    n = len(index["figures"])
    print(f"{PROG}: {n} figure{'s' * (n != 1)} ({n_files} files) in {out}")


def default_out(path: Path) -> Path:
    """Where figures go without ``--out``: ``PATH/figures`` for a sweep or job dir; for a results dir of
    ``analysis export`` (committed data, ``compute.json`` at its top) ``outputs/figures/<its name>``, so that drawing
    never rewrites results others cite."""
    path = Path(path)
    return Path("outputs") / "figures" / path.resolve().name if (path / "compute.json").is_file() else path / "figures"


class PlotCallback(Callback):
    """Hydra callback: draw the figures into ``<sweep dir>/figures`` when a multirun ends (register it in
    ``conf/config.yaml`` as ``hydra.callbacks.plot._target_: rovermarl.plot.PlotCallback``). Problems are logged as a
    warning and never raised, so a finished sweep is never marked failed. Only the job dirs this launch ran are read
    (:func:`own_jobs`, from the launch's own overrides, not from any file of the sweep dir): their world plug-ins are
    the ones the command line named, so they are built; a job dir planted beside them is not read. ``formats`` None:
    :data:`rovermarl.analysis.stamp.FORMATS`. matplotlib is imported when the sweep ends, sparing every job's start.
    """

    def __init__(self, formats: Sequence[str] | None = None, thresholds: dict | None = None) -> None:
        self.formats = None if formats is None else list(formats)
        self.thresholds = dict(thresholds or {})

    def on_multirun_end(self, config, **kwargs) -> None:
        sweep = "?"
        try:
            from rovermarl.analysis.stamp import FORMATS, current_index

            sweep = Path(str(config.hydra.sweep.dir))
            kwargs = {"thresholds": self.thresholds, "formats": self.formats or list(FORMATS), "trust": True}
            if current_index(sweep, **kwargs) is not None:      # nothing they are drawn from changed
                log.info("figures in %s are up to date", sweep / "figures")
                return
            from rovermarl.analysis.figures import plot_sweep
            with beneath(sweep, create=False):
                index = plot_sweep(sweep, only=own_jobs(config, sweep), **kwargs)   # this launch's jobs: trusted
            log.info("%d figures in %s", len(index["figures"]), sweep / "figures")
        except Exception as e:  # figures are a by-product; never fail a finished sweep
            log.warning("no figures for sweep %s: %s: %s", printable(sweep), type(e).__name__, printable(e, 2000))


def own_jobs(config, sweep: Path) -> list[Path]:
    """The job dirs of the launch whose Hydra config is ``config``: its task overrides expanded as its sweeper did
    (:func:`rovermarl.config.job_dirs`), under ``sweep``."""
    from rovermarl.config import job_dirs

    overrides = [str(o) for o in config.hydra.overrides.task if not str(o).startswith("hydra.")]
    return job_dirs(overrides, True, sweep)


if __name__ == "__main__":
    main()
