"""Train: ``python -m rovermarl.train [-m] [group=option ...] [key=value ...]``.

Every job of an invocation is composed and validated before anything runs (and before Ray starts); a bad config
exits with status 2 and one line on stderr. Output dirs are named after the command's overrides
(``outputs/multirun/<overrides>/<job overrides>``), so relaunching the same command resumes it. Ctrl-C (SIGINT) and
SIGTERM stop it with one line and exit 130 / 143 (``HYDRA_FULL_ERROR=1``: the traceback too); Ray is shut down.
"""

from __future__ import annotations

import argparse
import contextlib
import errno
import os
import signal
import sys
import tempfile
import threading
from pathlib import Path

from hydra.core.hydra_config import HydraConfig
from omegaconf import DictConfig, OmegaConf

from rovermarl import hydra_compat
from rovermarl.algorithms.base import AlgorithmError
from rovermarl.config import compose_jobs, dirname, quote_numeric_options, sweepname
from rovermarl.errors import ConfigError
from rovermarl.parallel import BackendError
from rovermarl.record import lock
from rovermarl.resources import CONF_DIR
from rovermarl.runner.job import run_job
from rovermarl.runner.validate import validate

OmegaConf.register_new_resolver("rovermarl_dirname", dirname, replace=True)
PROG = "rovermarl.train"
BUSY = 75                                                              # EX_TEMPFAIL: another launch holds the dir
STORAGE_ERRORS = (errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EPERM)   # one line, not a traceback


def task(cfg: DictConfig) -> float:
    """One Hydra job: its runs, into Hydra's output dir."""
    hc = HydraConfig.get()
    choices = {g: c for g, c in hc.runtime.choices.items() if not g.startswith("hydra/")}
    name = dirname(hc.overrides.task) if hc.overrides.task else "run"
    try:
        return run_job(cfg, Path(hc.runtime.output_dir), name=name, choices=choices)["median_final_score"]
    except lock.Locked as e:
        raise Stop(f"{PROG}: error: {e}", BUSY) from None
    except BackendError as e:
        raise Stop(f"{PROG}: error: {name}: {e}; relaunch the same command to resume") from None
    except OSError as e:
        if e.errno not in STORAGE_ERRORS or os.environ.get("HYDRA_FULL_ERROR") == "1":
            raise
        raise Stop(f"{PROG}: error: {name}: cannot write {e.filename or 'a result file'}: {e.strerror}; fix it and "
                   "relaunch the same command to resume") from None
    except AlgorithmError as e:                       # on Ray, a RayTaskError that is also the cause's type
        cause = getattr(e, "cause", None) or e
        raise Stop(f"{PROG}: error: {name}: {' '.join(str(cause).split())}") from None


class Stop(SystemExit):
    """The launch ends with one line on stderr and ``code``; :func:`_run` prints it once Ray is down, so that nothing
    Ray logs while it shuts down comes after it."""

    def __init__(self, line: str, code: int = 1):
        super().__init__(code)
        self.line = line


def check(argv: list[str]) -> tuple[argparse.Namespace, argparse.ArgumentParser, list[DictConfig]]:
    """Parse, compose and validate every job of ``argv`` (already quoted); raises ConfigError.

    Returns Hydra's parsed arguments with the output dir made explicit (``outputs/multirun/<overrides>``, or
    ``outputs/run/<overrides>`` without -m), the parser, and the job configs.
    """
    parser = hydra_compat.args_parser()
    parser.exit_on_error = False
    try:
        args, unknown = parser.parse_known_args(argv)
    except argparse.ArgumentError as e:
        raise ConfigError(e.argument_name or "argument", " ".join(argv), e.message) from None
    if unknown:
        raise ConfigError("option", unknown[0], "unrecognized; see --help (overrides are KEY=VALUE)")
    if args.help or args.hydra_help or args.cfg or args.info or args.shell_completion:
        return args, parser, []  # Hydra's own informational modes
    cfgs = compose_jobs(args.overrides, args.multirun, args.config_name or "config", args.config_dir)
    for cfg in cfgs:
        validate(cfg)
    key = "hydra.sweep.dir" if args.multirun else "hydra.run.dir"
    given = [a.partition("=")[2].strip("'\"") for a in args.overrides if a.startswith(key + "=")]
    out = given[-1] if given else f"outputs/{'multirun' if args.multirun else 'run'}/{sweepname(args.overrides)}"
    writable(key, Path(out))
    if not given:
        args.overrides = [*args.overrides, f"{key}='{out}'"]
    return args, parser, cfgs


def writable(key: str, path: Path) -> None:
    """Fail early, in one line, on an output dir that cannot be created or written (creates nothing)."""
    existing = path.absolute()
    while not existing.exists():
        existing = existing.parent
    if not existing.is_dir():
        raise ConfigError(key, str(path), f"cannot write there: {existing} is not a directory")
    try:                                        # a real probe: access() says yes to root on read-only mounts
        os.rmdir(tempfile.mkdtemp(prefix=".rovermarl-probe-", dir=existing))
    except OSError as e:
        raise ConfigError(key, str(path), f"cannot write there: {existing}: {e.strerror or e}") from None


def connect(cfgs: list[DictConfig]) -> None:
    """Start (or join) the one Ray instance that all jobs of this invocation share, if any job uses Ray."""
    on_ray = [c for c in cfgs if c.parallel.backend == "ray"]
    if not on_ray:
        return
    import ray

    from rovermarl.parallel.ray_backend import ensure_ray
    try:
        ensure_ray(on_ray[0].ray)
    except Exception as e:  # Ray raises several types; all end the same way
        where = on_ray[0].ray.address or "local"
        first = (str(e).strip().splitlines() or [type(e).__name__])[0]
        hint = (" A cluster started by `ray start` (Ray >= 2.59) checks a token: on the head node use "
                "ray.address=auto, elsewhere export RAY_AUTH_MODE=token and the cluster's token."
                if on_ray[0].ray.address and "nothing answers" not in first else "")
        raise ConfigError("ray.address", where, f"cannot start or join Ray: {first}.{hint}") from None
    cpus = int(ray.cluster_resources().get("CPU", 0))
    for c in on_ray:
        if c.parallel.get("ic_shards", 1) > cpus:      # each shard actor holds a CPU for the whole run
            raise ConfigError("parallel.ic_shards", c.parallel.ic_shards, f"must be at most the {cpus} CPUs of Ray")


def main(argv: list[str] | None = None) -> None:
    argv = quote_numeric_options(list(sys.argv[1:] if argv is None else argv))
    try:
        args, parser, cfgs = check(argv)
        ray = sys.modules.get("ray")
        ours = ray is None or not ray.is_initialized()              # a Ray this call starts is this call's to stop
        with _sweep_lock(args):                                    # before Ray starts: a busy dir stops at once
            connect(cfgs)
            _run(args, parser, ours)
    except ConfigError as e:
        print(f"{PROG}: error: {e}", file=sys.stderr)
        sys.exit(2)
    except lock.Locked as e:
        print(f"{PROG}: error: {e}", file=sys.stderr)
        sys.exit(BUSY)


def _run(args, parser, stop_ray: bool = True) -> None:
    """Hydra's main, with SIGINT and SIGTERM turned into one line and Ray shut down however it ends."""
    previous = {sig: signal.signal(sig, _signalled) for sig in (signal.SIGINT, signal.SIGTERM)}   # after Ray's init
    hook, sys.unraisablehook = sys.unraisablehook, _unraisable
    _SIGNALS.clear()
    _REARM.clear()
    stop = None
    try:
        hydra_compat.run(args, parser, task, str(CONF_DIR))
    except KeyboardInterrupt:
        if os.environ.get("HYDRA_FULL_ERROR") == "1":
            raise
        if not _SIGNALS:                                             # a KeyboardInterrupt of the user's code
            _SIGNALS.append(signal.SIGINT)
    except Stop as e:
        stop = e
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        sys.unraisablehook = hook
        if stop_ray:
            with _quiet_stderr() if stop or _SIGNALS else contextlib.nullcontext():   # Ray's shutdown after a
                _stop_ray()                                                          # fault is noise
    if _SIGNALS:                  # also when the interrupt was swallowed (raised in a finalizer) and the work went on
        term = signal.SIGTERM in _SIGNALS
        stop = Stop(f"{PROG}: {'terminated' if term else 'interrupted'}; relaunch the same command to resume",
                    143 if term else 130)
    if stop:
        print(stop.line, file=sys.stderr)
        sys.exit(stop.code)


def _sweep_lock(args):
    """The launch holds its output dir's lock (the sweep dir of a multirun, each job then its own job dir's too, in
    :func:`run_job`; the run dir of a single run)."""
    key = "hydra.sweep.dir=" if args.multirun else "hydra.run.dir="
    given = [a.partition("=")[2].strip("'\"") for a in args.overrides if a.startswith(key)]
    return lock.hold(Path(given[-1])) if given else contextlib.nullcontext()


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised where the driver is, so that it unwinds like Ctrl-C (files are written atomically)."""


_SIGNALS: list[int] = []                                             # SIGINT / SIGTERM received by this launch
_REARM: list[bool] = []                                              # the last interrupt was dropped: raise again


def _signalled(signum, frame):
    """Unwind on SIGINT or SIGTERM, once (the unwinding is not interrupted again); the launch then ends with exit
    130 / 143, whatever caught the exception."""
    if not _SIGNALS or _REARM:
        _REARM.clear()
        _SIGNALS.append(signum)
        raise Terminated() if signum == signal.SIGTERM else KeyboardInterrupt()
    _SIGNALS.append(signum)


def _unraisable(unraisable) -> None:
    """Python drops an exception raised in a finalizer (``__del__``, a weakref callback): when that was our
    interrupt, deliver it again to the main thread, from another thread once this hook has returned."""
    if _SIGNALS and unraisable.exc_type is not None and issubclass(unraisable.exc_type, KeyboardInterrupt):
        _REARM.append(True)
        threading.Timer(0.01, _redeliver, (_SIGNALS[0],)).start()
        return
    sys.__unraisablehook__(unraisable)


def _redeliver(signum: int) -> None:
    """The dropped interrupt again, to the main thread, while the launch still handles it."""
    if _REARM and signal.getsignal(signum) is _signalled:
        signal.pthread_kill(threading.main_thread().ident, signum)


@contextlib.contextmanager
def _quiet_stderr():
    """File descriptor 2 to /dev/null for a while (Ray's C++ core writes there directly)."""
    sys.stderr.flush()
    saved = os.dup(2)
    with open(os.devnull, "w") as null:
        os.dup2(null.fileno(), 2)
    try:
        yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)


def _stop_ray() -> None:
    """Shut down the Ray this process started or joined; then no process this driver started outlives it (Ray
    leaves its agents behind when its GCS or raylet died)."""
    ray = sys.modules.get("ray")
    if ray is None or not ray.is_initialized():
        return
    import psutil

    from rovermarl.parallel.ray_backend import forget_pool
    started = psutil.Process().children(recursive=True)
    forget_pool()                                                    # its actors go with this Ray
    with contextlib.suppress(Exception):                             # a dead GCS can make the shutdown fail
        ray.shutdown()
    _, alive = psutil.wait_procs(started, timeout=3)
    for p in alive:
        with contextlib.suppress(psutil.Error):
            p.kill()


if __name__ == "__main__":
    main()
