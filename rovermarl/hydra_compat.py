"""The one home of Hydra's private API in rovermarl (checked against hydra-core 1.3.8).

Hydra has no public way to parse its command line (``get_args_parser``), expand a sweep into jobs as its basic
sweeper does (``BasicSweeper.split_arguments``), run its main with arguments given rather than read from
``sys.argv`` (``_run_hydra``), or skip the basic sweeper's composition of every job before launching
(``BasicSweeper.validate_batch_is_legal``), which ``config.compose_jobs`` has already done: it cost about 0.5 s per
job, a third of a sweep's start-up. ``tests/test_hydra_compat.py`` fails plainly if a Hydra release changes them.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable

CHECKED_WITH = "1.3.8"


def args_parser() -> argparse.ArgumentParser:
    """Hydra's command-line parser (``python -m rovermarl.train --help`` shows it)."""
    from hydra._internal.utils import get_args_parser
    return get_args_parser()


def split_sweep(parsed_overrides: list) -> list[list[str]]:
    """The jobs of a sweep: parsed overrides (``k=1,2 setup=solo``) -> one override list per job, in Hydra's order."""
    from hydra._internal.core_plugins.basic_sweeper import BasicSweeper
    return [job for batch in BasicSweeper.split_arguments(parsed_overrides, None) for job in batch]


def run(args: argparse.Namespace, parser: argparse.ArgumentParser, task: Callable, config_dir: str,
        config_name: str = "config") -> None:
    """Hydra's main with ``args`` (from :func:`args_parser`) instead of ``sys.argv``: runs ``task(cfg)`` per job."""
    from hydra._internal.core_plugins.basic_sweeper import BasicSweeper
    from hydra._internal.utils import _run_hydra
    from hydra.version import setbase
    setbase("1.3")
    check = BasicSweeper.validate_batch_is_legal
    BasicSweeper.validate_batch_is_legal = _validated                  # the jobs were composed by compose_jobs
    try:
        _run_hydra(args=args, args_parser=parser, task_function=task, config_path=config_dir,
                   config_name=config_name)
    finally:
        BasicSweeper.validate_batch_is_legal = check


def _validated(self, batch) -> None:
    """Hydra's sweeper composes each job of a batch to check it; rovermarl's ``compose_jobs`` already did."""
