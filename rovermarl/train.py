"""Train: ``python -m rovermarl.train [-m] [group=option ...] [key=value ...]``.

Every job is composed and validated (its world built) before anything runs and before Ray starts: a bad config or
plug-in exits 2 with one line on stderr (a plug-in's error later: 1, one line naming its file). Output dirs are named
after the command's overrides (``outputs/multirun/<overrides>/<job overrides>``): relaunching it resumes it. Signals
(exit 130 / 143 from the imports on) and Ray's processes: docs/GUIDE.md, "What rovermarl promises"."""

from __future__ import annotations

import os
import signal
import sys


def _before_work(signum, frame):
    """SIGINT / SIGTERM while this module imports: nothing is started or written yet, so end at once, in one line."""
    term = signum == signal.SIGTERM
    os.write(2, f"rovermarl.train: {'terminated' if term else 'interrupted'}\n".encode())
    os._exit(143 if term else 130)


if __name__ == "__main__":               # also where the shell started it with SIGINT ignored (a background job)
    for _sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(_sig, _before_work)

import argparse  # noqa: E402 - after the handlers above
import contextlib  # noqa: E402
import errno  # noqa: E402
import tempfile  # noqa: E402
import threading  # noqa: E402
from pathlib import Path  # noqa: E402

from hydra.core.hydra_config import HydraConfig  # noqa: E402
from omegaconf import DictConfig, OmegaConf  # noqa: E402

from rovermarl import hydra_compat  # noqa: E402
from rovermarl.algorithms.base import AlgorithmError  # noqa: E402
from rovermarl.config import compose_jobs, dirname, job_dirs, quote_numeric_options, sweepname  # noqa: E402
from rovermarl.errors import ConfigError, config_plugin_line, verbose  # noqa: E402
from rovermarl.parallel import BackendError, backend  # noqa: E402
from rovermarl.record import lock  # noqa: E402
from rovermarl.record.atomic import check_output_dir  # noqa: E402
from rovermarl.record.safe_read import Unsafe  # noqa: E402
from rovermarl.resources import CONF_DIR  # noqa: E402
from rovermarl.runner.compile import announce, warm  # noqa: E402
from rovermarl.runner.job import all_finished, run_job  # noqa: E402
from rovermarl.runner.validate import validate  # noqa: E402

OmegaConf.register_new_resolver("rovermarl_dirname", dirname, replace=True)
PROG = "rovermarl.train"
BUSY = 75                                                              # EX_TEMPFAIL: another launch holds the dir
STORAGE_ERRORS = (errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EIO, errno.EACCES, errno.EPERM, errno.ENOENT)  # 1 line


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
    except Unsafe as e:
        raise Stop(f"{PROG}: error: {name}: {e}", 2) from None
    except OSError as e:
        if e.errno not in STORAGE_ERRORS or verbose():
            raise
        raise Stop(f"{PROG}: error: {name}: cannot write {e.filename or 'a result file'}: {e.strerror}; fix it and "
                   "relaunch the same command to resume") from None
    except AlgorithmError as e:                       # on Ray, a RayTaskError that is also the cause's type
        raise Stop(f"{PROG}: error: {name}: {' '.join(str(getattr(e, 'cause', None) or e).split())}") from None
    except Exception as e:
        if _SIGNALS:   # cleanup code raised over our interrupt (numpy's savez closing its zip): it is the interrupt
            raise (Terminated() if signal.SIGTERM in _SIGNALS else KeyboardInterrupt()) from None
        if (line := config_plugin_line(e, [cfg])) is None:
            raise
        raise Stop(f"{PROG}: error: {name}: a plug-in failed: {line} (HYDRA_FULL_ERROR=1: the full text)") from None


class Stop(SystemExit):
    """The launch ends with one line on stderr and ``code``; :func:`main` prints it once Ray is down (last)."""

    def __init__(self, line: str, code: int = 1):
        super().__init__(code)
        self.line = line


def check(argv: list[str]) -> tuple[argparse.Namespace, argparse.ArgumentParser, list[DictConfig]]:
    """Parse, compose and validate every job of ``argv`` (already quoted); raises ConfigError. Returns Hydra's parsed
    arguments with the output dir made explicit (``outputs/multirun/<overrides>``, or ``outputs/run/<overrides>``
    without -m), the parser, and the job configs."""
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
    check_output_dir(Path(out))             # a copied results dir: no link followed out of it, no FIFO, no hard link
    if not given:
        args.overrides = [*args.overrides, f"{key}='{out}'"]
    args.out_dir = Path(out)
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
    on_ray = [c for c in cfgs if backend(c.parallel).uses_ray]
    if not on_ray:
        return
    if not on_ray[0].ray.address:                      # an embedded Ray: its CPUs are known before it starts
        _check_shards(on_ray, on_ray[0].ray.num_cpus or os.cpu_count() or 1)
    import ray

    from rovermarl.parallel.ray_backend import ensure_ray
    try:
        ensure_ray(on_ray[0].ray)
    except SystemExit as e:                            # Ray's own SIGTERM handler, set while it starts
        if e.code != signal.SIGTERM:
            raise
        _SIGNALS.append(signal.SIGTERM)
        raise Terminated() from None
    except Exception as e:  # Ray raises several types; all end the same way
        where = on_ray[0].ray.address or "local"
        first = (str(e).strip().splitlines() or [type(e).__name__])[0]
        hint = (" A cluster started by `ray start` (Ray >= 2.59) checks a token: on the head node use "
                "ray.address=auto, elsewhere export RAY_AUTH_MODE=token and the cluster's token."
                if on_ray[0].ray.address and "nothing answers" not in first else "")
        raise ConfigError("ray.address", where, f"cannot start or join Ray: {first}.{hint}") from None
    finally:
        _handle_signals()                              # Ray's init replaced the SIGTERM handler
    _check_shards(on_ray, int(ray.cluster_resources().get("CPU", 0)))


def _compile_while_ray_starts(cfgs: list[DictConfig]) -> None:
    """A first run compiles the kernel: said before Ray starts (it holds file descriptor 2 meanwhile), done here once
    (Ray's workers then load it), left out of the jobs' rates (:mod:`rovermarl.runner.compile`); in a thread on one
    core while Ray starts on the other (a daemon: a failed start or a signal does not wait for it)."""
    todo = announce(cfgs, log=lambda m: print(f"{PROG}: {m}", file=sys.stderr, flush=True))
    seconds, failed = [], []

    def compile_() -> None:
        try:
            seconds.extend(warm(cfg) for cfg in todo)
        except BaseException as e:  # re-raised in the main thread
            failed.append(e)

    thread = threading.Thread(target=compile_, name="rovermarl-compile", daemon=True)
    thread.start()
    connect(cfgs)
    thread.join()
    if failed:
        raise failed[0]
    if todo:
        print(f"{PROG}: compiled in {sum(seconds):.0f} s; cached for later runs", file=sys.stderr, flush=True)


def _all_finished(args, cfgs: list[DictConfig]) -> bool:
    """Whether every job of the invocation is finished in its dir (:func:`rovermarl.runner.job.all_finished`)."""
    if not cfgs:
        return False
    dirs = job_dirs([o for o in args.overrides if not o.startswith("hydra.")], args.multirun, args.out_dir)
    return len(dirs) == len(cfgs) and all(all_finished(c, d) for c, d in zip(cfgs, dirs, strict=True))


def _check_shards(cfgs: list[DictConfig], cpus: int) -> None:
    for c in cfgs:
        if backend(c.parallel).shards > cpus:      # each shard actor holds a CPU for the whole run
            raise ConfigError("parallel.ic_shards", c.parallel.ic_shards, f"must be at most the {cpus} CPUs of Ray")


def main(argv: list[str] | None = None) -> None:
    """Compose and validate every job, hold the output dir, start Ray, run the jobs; SIGINT and SIGTERM at any
    point end it with one line and exit 130 / 143, Ray and its processes gone."""
    argv = quote_numeric_options(list(sys.argv[1:] if argv is None else argv))
    ray = sys.modules.get("ray")
    ours = ray is None or not ray.is_initialized()                  # a Ray this call starts is this call's to stop
    previous = _handle_signals()
    hook, sys.unraisablehook = sys.unraisablehook, _unraisable
    _SIGNALS.clear()
    _REARM.clear()
    if ours:
        _adopt_orphans()
    stop, cfgs = None, []
    try:
        args, parser, cfgs = check(argv)
        # the output dir's lock (each job then its own, in run_job), before Ray starts: a busy dir stops at once
        with lock.hold(args.out_dir, clean=True) if getattr(args, "out_dir", None) else contextlib.nullcontext():
            if not _all_finished(args, cfgs):                      # a relaunch with nothing to compute: no Ray
                _compile_while_ray_starts(cfgs)
            hydra_compat.run(args, parser, task, str(CONF_DIR))
    except (ConfigError, Unsafe) as e:
        stop = Stop(f"{PROG}: error: {e}", 2)
    except lock.Locked as e:
        stop = Stop(f"{PROG}: error: {e}", BUSY)
    except KeyboardInterrupt:
        if verbose():
            raise
        if not _SIGNALS:                                             # a KeyboardInterrupt of the user's code
            _SIGNALS.append(signal.SIGINT)
    except Stop as e:
        stop = e
    except Exception as e:                                           # the compile ahead: a plug-in's hook failed
        if (line := config_plugin_line(e, cfgs)) is None:
            raise
        stop = Stop(f"{PROG}: error: a plug-in failed: {line} (HYDRA_FULL_ERROR=1: the full text)")
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        sys.unraisablehook = hook
        if _SIGNALS:              # also when the interrupt was swallowed (raised in a finalizer) and the work went on
            term = signal.SIGTERM in _SIGNALS
            stop = Stop(f"{PROG}: {'terminated' if term else 'interrupted'}; relaunch the same command to resume",
                        143 if term else 130)
        if stop:                                                     # first: what Ray's shutdown says is hidden
            print(stop.line, file=sys.stderr, flush=True)
        if ours:
            if _SIGNALS and _CLI:
                _exit_by(SIGNAL_EXIT_S, stop.code)
            with _quiet_stderr() if stop else contextlib.nullcontext():
                _stop_ray()
    if stop:
        sys.exit(stop.code)


def _handle_signals() -> dict:
    """Unwind on SIGINT and SIGTERM (:func:`_signalled`); returns the handlers to restore afterwards (Python's
    defaults in place of this module's own)."""
    default = {signal.SIGINT: signal.default_int_handler, signal.SIGTERM: signal.SIG_DFL}
    previous = {sig: signal.signal(sig, _signalled) for sig in default}
    return {sig: default[sig] if h in (_before_work, _signalled) else h for sig, h in previous.items()}


def _adopt_orphans() -> None:
    """Linux: become the subreaper of this launch's processes, so that a Ray process whose parent died (Ray cut
    while it starts) is still this driver's descendant, and :func:`_stop_ray` ends it."""
    with contextlib.suppress(Exception):
        import ctypes
        ctypes.CDLL(None, use_errno=True).prctl(36, 1, 0, 0, 0)      # PR_SET_CHILD_SUBREAPER


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised where the driver is, so that it unwinds like Ctrl-C (files are written atomically)."""


_SIGNALS: list[int] = []                                             # SIGINT / SIGTERM received by this launch
_REARM: list[bool] = []                                              # the last interrupt was dropped: raise again


def _signalled(signum, frame):
    """Unwind on SIGINT or SIGTERM, once (the unwinding is not interrupted again); the launch then ends with exit
    130 / 143, whatever caught the exception."""
    first = not _SIGNALS or bool(_REARM)
    _SIGNALS.append(signum)
    if first:
        _REARM.clear()
        raise Terminated() if signum == signal.SIGTERM else KeyboardInterrupt()


def _unraisable(unraisable) -> None:
    """Python drops an exception raised in a finalizer (``__del__``, a weakref callback): when that was our
    interrupt, deliver it again to the main thread, from another thread once this hook has returned. After an
    interrupt, nothing else is shown (a finalizer of what it cut short, a half-written zip: no noise)."""
    if not _SIGNALS:
        sys.__unraisablehook__(unraisable)
    elif unraisable.exc_type is not None and issubclass(unraisable.exc_type, KeyboardInterrupt):
        _REARM.append(True)
        threading.Timer(0.01, _redeliver, (_SIGNALS[0],)).start()


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
    """Shut down the Ray this process started (also one cut while it started); no process of Ray's that this driver
    started outlives it (Ray leaves its agents behind when its GCS or raylet died, or its start was cut)."""
    import psutil

    started = [p for p in psutil.Process().children(recursive=True) if _is_ray(p)]
    ray = sys.modules.get("ray")
    if ray is not None:
        from rovermarl.parallel.ray_backend import forget_pool
        forget_pool()                                                # its actors go with this Ray
        with contextlib.suppress(Exception):                         # a dead GCS can make the shutdown fail
            ray.shutdown()
    for _ in range(3):                                               # and orphans re-parented to us meanwhile
        started = [p for p in {*started, *psutil.Process().children(recursive=True)} if _is_ray(p)]
        if not started:
            return
        _, alive = psutil.wait_procs(started, timeout=1)
        for p in alive:
            with contextlib.suppress(psutil.Error):
                p.kill()
        psutil.wait_procs(alive, timeout=1)


SIGNAL_EXIT_S = 3.0      # after a signal, Ray's shutdown may take this long (seconds) before the launch ends anyway
_CLI: list[bool] = []    # set by _cli: main runs as the command, so it may end the process itself


def _exit_by(seconds: float, code: int) -> None:
    """End the process with ``code`` in ``seconds`` if it has not ended by then (Ray's shutdown is slow on a loaded
    machine): Ray's processes are killed first. Ray's shutdown comes first because killing its raylet under a
    connected driver makes Ray's core end the driver with status 1."""
    def end() -> None:
        import psutil
        for p in psutil.Process().children(recursive=True):
            if _is_ray(p):
                with contextlib.suppress(psutil.Error):
                    p.kill()
        os._exit(code)
    timer = threading.Timer(seconds, end)
    timer.daemon = True
    timer.start()


def _is_ray(p) -> bool:
    """A process of Ray's (GCS, raylet, agents, workers), not one that the user's code started."""
    import psutil
    try:
        return p.is_running() and ("ray" in " ".join(p.cmdline()[:6]).lower() or p.name() in ("raylet", "gcs_server"))
    except psutil.Error:
        return False


def _cli() -> None:
    """``main`` as a command. After a signal, the process ends without Python's finalizers: those of a Ray cut while
    it started can abort the process (SIGABRT, SIGSEGV seen) after the launch's line was printed."""
    _CLI.append(True)
    try:
        main()
    except SystemExit as e:
        if e.code not in (130, 143):
            raise
        import logging
        logging.shutdown()
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(e.code)


if __name__ == "__main__":
    _cli()
