"""``python -m rovermarl.analysis {export,selectors,verify} ...`` (``--help`` describes each).

Exit status: 2 with one line on stderr for bad input; ``verify`` exits 1 when a team does not re-score (2 if a job's
files or config were refused, after verifying the other jobs). The studies' report generators live beside their
launchers: ``python studies/<name>/report.py`` (docs/ARCHITECTURE.md, Studies), the paper's claims C1-C8
(``studies/paper/report.py``) and the held-out migration (``studies/heldout/report.py``) among them.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from rovermarl.analysis.cli import Parser, fail, one_line_errors, say
from rovermarl.errors import printable

PROG = "rovermarl.analysis"
_say = say(PROG)


def parser() -> argparse.ArgumentParser:
    p = Parser(prog=PROG, description="Compact results of a sweep, method comparisons, re-scored teams.")
    sub = p.add_subparsers(dest="command", required=True, parser_class=Parser)
    e = sub.add_parser("export", help="compact results (summaries, exact and log-grid curves) of a sweep dir")
    e.add_argument("sweep", type=Path, help="sweep dir, e.g. outputs/paper")
    e.add_argument("out", type=Path, help="results dir, e.g. results/paper")
    e.add_argument("--generations", type=int, default=None, help="export only jobs with this budget")
    e.add_argument("--no-fig6", dest="fig6", action="store_false", help="skip the Fig. 6 data (re-runs one run)")
    e.add_argument("--trust-config", dest="trust", action="store_true",
                   help="let the Fig. 6 re-run build any class the sweep's config names (default: only the "
                   "classes of rovermarl's config groups, at their groups' nodes)")
    s = sub.add_parser("selectors", help="the k-selector comparison table from a results dir")
    s.add_argument("results", type=Path, help="results dir written by `export`")
    s.add_argument("--against", default="adaptive", help="method the others are tested against")
    s.add_argument("--x", choices=("generation", "evals"), default="generation", dest="x",
                   help="budgets and times in generations or in team evaluations (methods of different cost)")
    _trust(s)
    v = sub.add_parser("verify", help="re-score every committed final team; exit 1 on any difference")
    v.add_argument("results", type=Path, help="a results dir (job dirs with genomes.npz), a sweep dir or a job dir")
    _trust(v)
    return p


def _trust(p: argparse.ArgumentParser) -> None:
    p.add_argument("--trust-config", dest="trust", action="store_true",
                   help="build a world plug-in the jobs' configs name (its module runs code; default: refused)")


MOVED = {"claims": "the claims report is the paper study's: python studies/paper/report.py RESULTS_DIR "
                   "[--trust-config]",
         "heldout": "the held-out migration is beside its launcher: python studies/heldout/report.py {merge,done}"}


def main(argv=None) -> None:
    command = (sys.argv[1:] if argv is None else argv)[:1]
    if command and command[0] in MOVED:                                  # commands that moved with their study
        fail(PROG, MOVED[command[0]])
    args = parser().parse_args(argv)
    with one_line_errors(PROG):     # a result, sweep or config refused, or a file error: one line, exit 2
        if args.command == "export":
            from rovermarl.analysis.export import export
            export(args.sweep, args.out, args.generations, fig6=args.fig6, log=_say, trust=args.trust)
        elif args.command == "verify":
            _verify(args.results, args.trust)
        else:
            from rovermarl.analysis.claims import selectors
            print(selectors(args.results, args.against, args.x, args.trust)[0], end="")


def _verify(path: Path, trust: bool) -> None:
    from rovermarl.analysis.verify import verify

    checked = verify(path, trust)
    for c in checked:
        if c.refused:                                    # one line on stderr, then the other jobs
            print(f"{PROG}: error: {printable(c.line, 2000)}", file=sys.stderr)
        else:
            print(printable(f"{'ok' if c.ok else 'DIFFERS'}  {c.job}: {c.line}", 2000))
    if any(c.refused for c in checked):
        sys.exit(2)
    bad = sum(not c.ok for c in checked)
    if bad:
        print(f"{PROG}: error: {bad} of {len(checked)} jobs do not re-score", file=sys.stderr)
        sys.exit(1)


if __name__ == "__main__":
    main()
