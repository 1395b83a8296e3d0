"""Compile ahead: ``python -m rovermarl.warmup [OVERRIDE ...]`` compiles (numba) what a job of these overrides runs.

numba compiles the kernel on first use and caches it (``__pycache__``, or ``NUMBA_CACHE_DIR``), so a first run on a
fresh install or image starts with a compile (the default job: 27 s more than a warm run on 2 idle cores), which
``rovermarl.train`` announces, does once while Ray starts and leaves out of its rates. This pays it ahead, in an image
build or before a cluster job (no overrides: the default job):

    python -m rovermarl.warmup setup=duo env.dtype=float32 env=obstacles hydra.searchpath=[file://examples/obstacles]

It runs the job itself for 2 generations with 1 seed, serially, into a temporary dir (every compiled function the
job uses, its recording included), and prints how long that took.
"""

from __future__ import annotations

import sys
import time

from rovermarl.runner.compile import warm

PROG = "rovermarl.warmup"


def main(argv: list[str] | None = None) -> None:
    from rovermarl.config import compose_jobs, quote_numeric_options
    from rovermarl.errors import ConfigError
    argv = quote_numeric_options(list(sys.argv[1:] if argv is None else argv))
    try:
        cfgs = compose_jobs(argv, multirun=any("," in a.partition("=")[2] for a in argv))
    except ConfigError as e:
        print(f"{PROG}: error: {e}", file=sys.stderr)
        sys.exit(2)
    t0 = time.perf_counter()
    for cfg in cfgs:
        warm(cfg)
    print(f"{PROG}: {len(cfgs)} job(s) compiled and cached in {time.perf_counter() - t0:.1f} s")


if __name__ == "__main__":
    main()
