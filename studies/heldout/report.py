"""Held-out scores and final teams for compact results committed before those features (issues 33 and 43): a one-off
migration, done for every committed results dir; kept for results made by an older rovermarl.

``launchers/heldout.sh`` recomputes each job's runs (a run is a pure function of its config and seed) into a sweep
dir; ``python studies/heldout/report.py merge SWEEP_DIR RESULTS_DIR`` (:func:`merge`) then adds each run's held-out
score and final team to the committed job, once every recomputed run ends at the committed final score, bit for bit:
the curves do not change. ``python studies/heldout/report.py done JOB_DIR`` exits 0 if the job's summary has
held-out scores, 3 if not (or if it is refused: it is recomputed); any other status is a failure of its own.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from rovermarl.analysis.cli import Parser, fail, one_line_errors, say
from rovermarl.analysis.export import final_teams
from rovermarl.analysis.results import ResultsError
from rovermarl.analysis.sweep import RunCurve
from rovermarl.record.atomic import beneath
from rovermarl.record.outputs import atomic_open, write_json
from rovermarl.record.safe_read import check_tree, read_json

PROG = "studies/heldout/report.py"
NOT_DONE = 3                    # done's "no held-out scores": apart from a crash's 1, which heldout.sh must not skip


def done(job: Path) -> bool:
    """Whether the job dir ``job``'s summary.json has held-out scores (False if it is refused: it is recomputed)."""
    try:
        return bool(read_json(Path(job) / "summary.json", kind="summary").get("heldout_score"))
    except (OSError, AttributeError):
        return False


def merge(sweep: Path, results: Path, log=print) -> list[str]:
    """Add the held-out scores and final teams of ``sweep``'s finished jobs to the same-named jobs of ``results``;
    returns the names of the jobs updated. A job whose recomputed final scores differ from the committed ones is
    refused (an error naming it and the first seed that differs), and nothing of it is written."""
    updated = []
    check_tree(results)                                 # a linked job dir would have its summary written elsewhere
    check_tree(sweep)
    for path in sorted(Path(results).glob("*/summary.json")):
        name = path.parent.name
        done = Path(sweep) / name / "summary.json"
        if not done.is_file():
            continue
        try:
            committed, recomputed = read_json(path, kind="summary"), read_json(done, kind="summary")
        except OSError as e:                            # refused (safe_read): one line, the other jobs go on
            log(f"{e}; skipped")
            continue
        want, got = committed.get("final_score") or {}, recomputed.get("final_score") or {}
        held = recomputed.get("heldout_score") or {}
        if not want or set(got) != set(want) or set(held) != set(want):
            log(f"{name}: {len(got)} of {len(want)} runs recomputed: skipped")
            continue
        for seed, value in want.items():
            if got[seed] != value:
                raise ResultsError(f"{name}: seed {seed} ends at {got[seed]} recomputed, {value} committed: "
                                   "not the same run; its held-out score is not added")
        runs = [RunCurve(Path(sweep) / name / "runs" / f"seed_{int(s):03d}", int(s), np.empty(0), None)
                for s in sorted(want, key=int)]
        teams = final_teams(runs)
        added = []
        if teams is not None and not (path.parent / "genomes.npz").is_file():
            with atomic_open(path.parent / "genomes.npz") as f:
                np.savez_compressed(f, **teams)
            added.append(f"final teams of {len(runs)} runs")
        if committed.get("heldout_score") != held:
            committed["heldout_score"] = held
            committed["median_heldout_score"] = float(np.median([held[s] for s in sorted(held, key=int)]))
            write_json(path, committed)
            added.append(f"held-out median {committed['median_heldout_score']:.4g} over {len(held)} runs")
        if added:
            updated.append(name)
            log(f"{name}: " + " and ".join(added) + " added")
    return updated


def main(argv=None) -> None:
    p = Parser(prog=PROG, description="Add recomputed runs' held-out scores to committed compact results.")
    p.add_argument("action", choices=("merge", "done"))
    p.add_argument("paths", type=Path, nargs="+", help="merge: SWEEP_DIR (of launchers/heldout.sh, e.g. "
                   "outputs/heldout/paper) RESULTS_DIR (e.g. results/paper); done: JOB_DIR (exit 0 if its summary "
                   "has held-out scores, 3 if not)")
    args = p.parse_args(argv)
    n = 2 if args.action == "merge" else 1
    if len(args.paths) != n:
        fail(PROG, f"{args.action} takes {n} path(s)")
    with one_line_errors(PROG):
        if args.action == "merge":
            with beneath(args.paths[1], create=False):                  # a job dir swapped for a link: refused
                merge(args.paths[0], args.paths[1], log=say(PROG))
        elif not done(args.paths[0]):
            sys.exit(NOT_DONE)


if __name__ == "__main__":
    main()
