"""One-line errors for the analysis commands: ``python -m rovermarl.analysis`` and the studies' report scripts
(``studies/<name>/report.py``). Bad input exits with status 2 and one line on stderr, never a traceback."""

from __future__ import annotations

import argparse
import contextlib
import sys

from rovermarl.analysis.results import ResultsError
from rovermarl.analysis.sweep import SweepError
from rovermarl.errors import ConfigError, printable


class Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line (no usage block) and exit 2."""

    def error(self, message: str):
        fail(self.prog, message)


def fail(prog: str, message) -> None:
    """``prog: error: message`` on stderr (what it quotes from files escaped), then exit 2."""
    print(f"{prog}: error: {printable(message, 2000)}", file=sys.stderr)
    sys.exit(2)


@contextlib.contextmanager
def one_line_errors(prog: str):
    """A refused result, sweep or config, or a file error (OSError), inside the block: one line and exit 2."""
    try:
        yield
    except (ResultsError, SweepError, ConfigError, OSError) as e:
        fail(prog, e)


def say(prog: str):
    """A log function writing one line on stderr, prefixed ``prog:`` (quoted file text escaped)."""
    return lambda message: print(f"{prog}: {printable(message, 2000)}", file=sys.stderr)
