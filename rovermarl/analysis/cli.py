"""One-line errors for the analysis commands: ``python -m rovermarl.analysis`` and the studies' report scripts
(``studies/<name>/report.py``). Bad input exits with status 2 and one line on stderr, never a traceback."""

from __future__ import annotations

import argparse
import contextlib
import sys
from pathlib import Path

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


def section_main(prog: str, description: str, results: str, write, argv=None, doc: str = "docs/LEARNERS.md") -> None:
    """The command line of a study whose report is a doc's generated section: ``RESULTS [--doc DOC]``, then
    ``write(results, doc)``, with one-line errors."""
    p = Parser(prog=prog, description=description)
    p.add_argument("results", type=Path, help=results)
    p.add_argument("--doc", type=Path, default=Path(doc), help="the doc whose section is replaced")
    args = p.parse_args(argv)
    with one_line_errors(prog):
        write(args.results, args.doc)
