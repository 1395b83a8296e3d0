"""``python -m rovermarl.analysis {export,claims,selectors} ...``: compact results of a sweep, and the claims report.

- ``export SWEEP_DIR RESULTS_DIR [--generations G] [--no-fig6] [--trust-config]``: write the compact results of
  every finished job, all or nothing (see :mod:`rovermarl.analysis.export`); the Fig. 6 re-run builds only the
  classes of rovermarl's config groups from the sweep's config unless ``--trust-config``.
- ``claims RESULTS_DIR [--trust-config]``: print the statistics of claims C1-C8 and write ``claims.md`` and
  ``claims.json`` (see :mod:`rovermarl.analysis.claims`).
- ``selectors RESULTS_DIR [--against METHOD] [--x evals] [--trust-config]``: the k-selector (or any method) comparison;
  ``selectors.md`` and ``.json``; ``--x evals`` in team evaluations.
- ``heldout merge SWEEP_DIR RESULTS_DIR``: held-out scores of recomputed runs into committed results
  (:mod:`rovermarl.analysis.heldout`, ``launchers/heldout.sh``); ``heldout done JOB_DIR``: exit 0 if the job's
  summary (read through :mod:`rovermarl.record.safe_read`) has them.
- ``verify DIR [--trust-config]``: re-score every committed final team on its run's initial conditions and
  held-out ones; one line per job, exit 1 on any difference, 2 if a job's files or config were refused (its line
  on stderr; the other jobs are verified) (:mod:`rovermarl.analysis.verify`).
- ``radius RESULTS_DIR``: the pre-registered radius study's section of docs/REPRODUCTION.md
  (:mod:`rovermarl.analysis.radius`).
- ``learners RESULTS_DIR [--doc docs/LEARNERS.md]``: the learners study's section of docs/LEARNERS.md and its
  figures (:mod:`rovermarl.analysis.learners`).
- ``budget-geometry BUDGET_DIR GEOMETRY_DIR``: the budget and geometry section of docs/REPRODUCTION.md.
- ``readings {export SWEEP_DIR RESULTS_DIR, lifting RESULTS_DIR, report RESULTS_DIR}``: the readings study
  (see :mod:`rovermarl.analysis.readings`).
- ``baselines {export SWEEP_DIR RESULTS_DIR, done|report|figures RESULTS_DIR}``: the baselines study, CC-(1+1)-ES
  against the CCEA with G, D and D++ (see :mod:`rovermarl.analysis.baselines`).

Bad input exits with status 2 and one line on stderr.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from rovermarl.analysis.results import ResultsError
from rovermarl.analysis.sweep import SweepError
from rovermarl.errors import ConfigError, printable
from rovermarl.record.atomic import beneath

PROG = "rovermarl.analysis"


class _Parser(argparse.ArgumentParser):
    def error(self, message: str):  # one line, no usage block
        print(f"{self.prog}: error: {message}", file=sys.stderr)
        sys.exit(2)


def parser() -> argparse.ArgumentParser:
    p = _Parser(prog=PROG, description="Compact results and claim statistics of the reproduction study.")
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)
    e = sub.add_parser("export", help="compact results (summaries, exact and log-grid curves) of a sweep dir")
    e.add_argument("sweep", type=Path, help="sweep dir, e.g. outputs/paper")
    e.add_argument("out", type=Path, help="results dir, e.g. results/paper")
    e.add_argument("--generations", type=int, default=None, help="export only jobs with this budget")
    e.add_argument("--no-fig6", dest="fig6", action="store_false", help="skip the Fig. 6 data (re-runs one run)")
    e.add_argument("--trust-config", dest="trust", action="store_true",
                   help="let the Fig. 6 re-run build any class the sweep's config names (default: only the "
                   "classes of rovermarl's config groups, at their groups' nodes)")
    c = sub.add_parser("claims", help="statistics of claims C1-C8 from a results dir")
    c.add_argument("results", type=Path, help="results dir written by `export`")
    _trust(c)
    s = sub.add_parser("selectors", help="the k-selector comparison table from a results dir")
    s.add_argument("results", type=Path, help="results dir written by `export`")
    s.add_argument("--against", default="adaptive", help="method the others are tested against")
    s.add_argument("--x", choices=("generation", "evals"), default="generation", dest="x",
                   help="budgets and times in generations or in team evaluations (methods of different cost)")
    _trust(s)
    r = sub.add_parser("readings", help="the readings study: export a sweep, its lifting readings, the report")
    r.add_argument("action", choices=("export", "lifting", "report"))
    r.add_argument("paths", type=Path, nargs="+", help="export: SWEEP_DIR RESULTS_DIR; lifting, report: RESULTS_DIR")
    b = sub.add_parser("baselines", help="the baselines study: export a sweep, the jobs done, the report, figures")
    b.add_argument("action", choices=("export", "done", "report", "figures"))
    b.add_argument("paths", type=Path, nargs="+",
                   help="export: SWEEP_DIR RESULTS_DIR; done, report, figures: RESULTS_DIR")
    h = sub.add_parser("heldout", help="add recomputed runs' held-out scores to committed compact results")
    h.add_argument("action", choices=("merge", "done"))
    h.add_argument("paths", type=Path, nargs="+", help="merge: SWEEP_DIR (of launchers/heldout.sh, e.g. "
                   "outputs/heldout/paper) RESULTS_DIR (e.g. results/paper); done: JOB_DIR (exit 0 if its summary "
                   "has held-out scores)")
    v = sub.add_parser("verify", help="re-score every committed final team; exit 1 on any difference")
    v.add_argument("results", type=Path, help="a results dir (job dirs with genomes.npz), a sweep dir or a job dir")
    _trust(v)
    rd = sub.add_parser("radius", help="the pre-registered radius study: the report section")
    rd.add_argument("results", type=Path, help="results/radius")
    ln = sub.add_parser("learners", help="the learners study: docs/LEARNERS.md's section and one figure per world")
    ln.add_argument("results", type=Path, help="results/learners")
    ln.add_argument("--doc", type=Path, default=Path("docs/LEARNERS.md"), help="the doc whose section is replaced")
    g = sub.add_parser("budget-geometry", help="the duo question along budget and geometry: the report section")
    g.add_argument("budget", type=Path, help="results/budget")
    g.add_argument("geometry", type=Path, help="results/geometry")
    return p


def _trust(p: argparse.ArgumentParser) -> None:
    p.add_argument("--trust-config", dest="trust", action="store_true",
                   help="build a world plug-in the jobs' configs name (its module runs code; default: refused)")


def main(argv=None) -> None:
    args = parser().parse_args(argv)
    try:
        if args.command == "export":
            from rovermarl.analysis.export import export
            export(args.sweep, args.out, args.generations, fig6=args.fig6,
                   log=_say, trust=args.trust)
        elif args.command == "claims":
            from rovermarl.analysis.claims import claims
            text, _ = claims(args.results, args.trust)
            print(text, end="")
        elif args.command == "readings":
            _readings(args.action, args.paths)
        elif args.command == "baselines":
            _baselines(args.action, args.paths)
        elif args.command == "heldout":
            _heldout(args.action, args.paths)
        elif args.command == "radius":
            from rovermarl.analysis.radius import report as radius_report
            print(radius_report(args.results), end="")
        elif args.command == "learners":
            from rovermarl.analysis.learners import write
            write(args.results, args.doc)
        elif args.command == "verify":
            _verify(args.results, args.trust)
        elif args.command == "budget-geometry":
            from rovermarl.analysis.budget_geometry import report
            print(report(args.budget, args.geometry), end="")
        else:
            from rovermarl.analysis.claims import selectors
            text, _ = selectors(args.results, args.against, args.x, args.trust)
            print(text, end="")
    except (ResultsError, SweepError, ConfigError, OSError) as e:   # ConfigError: a config refused; OSError: a file
        print(f"{PROG}: error: {printable(e, 2000)}", file=sys.stderr)
        sys.exit(2)


def _say(message) -> None:
    """One line on stderr; what it quotes from files escaped (:func:`rovermarl.errors.printable`)."""
    print(f"{PROG}: {printable(message, 2000)}", file=sys.stderr)


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


def _heldout(action: str, paths: list[Path]) -> None:
    from rovermarl.analysis import heldout

    if len(paths) != (2 if action == "merge" else 1):
        print(f"{PROG}: error: heldout {action} takes {2 if action == 'merge' else 1} path(s)", file=sys.stderr)
        sys.exit(2)
    if action == "merge":
        with beneath(paths[1], create=False):                           # a job dir swapped for a link: refused
            heldout.merge(paths[0], paths[1], log=_say)
    elif not heldout.done(paths[0]):
        sys.exit(1)


def _paths(study: str, action: str, paths: list[Path]) -> None:
    want = 2 if action == "export" else 1
    if len(paths) != want:
        print(f"{PROG}: error: {study} {action} takes {want} path(s), got {len(paths)}", file=sys.stderr)
        sys.exit(2)


def _baselines(action: str, paths: list[Path]) -> None:
    from rovermarl.analysis import baselines

    _paths("baselines", action, paths)
    if action == "export":
        baselines.export(paths[0], paths[1], log=_say)
    elif action == "done":
        print("".join(f"{setup} {method}\n" for setup, method in baselines.done(paths[0])), end="")
    elif action == "figures":
        print("".join(f"{path}\n" for path in baselines.figures(paths[0])), end="")
    else:
        print(baselines.report(paths[0])[0], end="")


def _readings(action: str, paths: list[Path]) -> None:
    from rovermarl.analysis import readings

    _paths("readings", action, paths)
    if action == "export":
        readings.export(paths[0], paths[1], log=_say)
    elif action == "lifting":
        print("\n".join(readings.lifting(paths[0])))
    else:
        print(readings.report(paths[0])[0], end="")


if __name__ == "__main__":
    main()
