"""The baselines study: CC-(1+1)-ES against the classic rover-domain CCEA with G, D and D++ at an equal budget of
team evaluations (``launchers/baselines.sh``, ``docs/BASELINES.md``).

- :func:`export`: a baselines sweep -> ``RESULTS/baselines.json``, a few numbers per run, a compact score curve per
  job and the compute spent. Jobs already there and not in the sweep are kept (at the same budget), so a study that
  spans sessions accumulates its finished jobs in the committed results (:func:`done` lists them);
- :func:`report`: ``RESULTS/baselines.md`` (the table of ``docs/BASELINES.md``) from ``baselines.json``;
- :func:`figures`: ``RESULTS/figures/baselines_<setup>.png``, median score (quartile band) against team evaluations,
  from the compact curves.

``python studies/baselines/report.py {export SWEEP_DIR RESULTS_DIR, done|report|figures RESULTS_DIR}``.

Per run: ``final`` (the score of its last generation: the parent team for cc11es, the team of each population's
best for ccea, both on the run's 16 initial conditions), ``heldout`` (run.json's held-out score) and, per level,
the team evaluations spent when its curve first reached the level (None: never).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from rovermarl.analysis import stats
from rovermarl.analysis.cli import Parser, one_line_errors, say
from rovermarl.analysis.export import compute_of
from rovermarl.analysis.levels import setup_rank
from rovermarl.analysis.results import ResultsError, load_study
from rovermarl.analysis.sweep import find_jobs
from rovermarl.record.atomic import atomic_open
from rovermarl.record.outputs import first_reaching
from rovermarl.record.safe_read import read_json

PROG = "studies/baselines/report.py"
LEVELS = {"solo": (3, 4), "duo": (4, 5, 6), "trio": (4, 5)}   # up to each setup's optimum (4, 6 and 5)
METHODS = ("k=1", "k=2", "adaptive", "ccea G", "ccea D", "ccea D++")   # the study's jobs: every method, every setup
REFERENCE = "k=1"                                            # the method every other is tested against
CURVE_POINTS = 101                                           # points of a job's compact curve


def export(sweep: Path, out: Path, log=print) -> dict:
    """Write ``out/baselines.json`` from every finished job of a baselines sweep, keeping the jobs already there that
    the sweep does not hold (same seed count and budget, else a :class:`ResultsError`); returns it."""
    jobs, notes = find_jobs(sweep)
    for note in notes:
        log(note)
    entries = []
    for job in (j for j in jobs if j.finished):
        levels = LEVELS.get(job.setup, ())
        runs = {}
        for run in sorted(job.runs, key=lambda r: r.seed):
            meta = read_json(run.path / "run.json", kind="run")
            firsts = {str(lv): first_reaching(run.score, lv) for lv in levels}
            runs[str(run.seed)] = {"final": float(run.score[-1]), "heldout": float(meta["heldout_score"]),
                                   "evals_to": {lv: None if g is None else int(job.evals(g))
                                                for lv, g in firsts.items()}}
        generations = len(job.runs[0].score) - 1
        entries.append({"job": job.path.name, "setup": job.setup, "method": job.label, "generations": generations,
                        "evals_per_generation": job.evals_per_generation,
                        "team_evals_per_run": int(job.evals(generations)), "runs": runs,
                        "curve": _curve(job), "compute": compute_of(job)})
    if not entries:
        raise ResultsError(f"{sweep}: no finished job of a baselines sweep")
    entries = _merged(out / "baselines.json", entries)
    data = {"jobs": sorted(entries, key=lambda e: (setup_rank(e["setup"]), e["setup"], _method_rank(e["method"])))}
    out.mkdir(parents=True, exist_ok=True)
    with atomic_open(out / "baselines.json", "w") as f:
        f.write(json.dumps(data, indent=1) + "\n")
    return data


def done(results: Path) -> list[tuple[str, str]]:
    """The (setup, method) jobs that ``results/baselines.json`` holds ([] if none)."""
    if not (Path(results) / "baselines.json").is_file():
        return []
    return [(j["setup"], j["method"]) for j in _load(results)]


def _curve(job) -> dict:
    """A job's score over its runs at ``CURVE_POINTS`` generations: team evaluations, median and quartiles."""
    generations = len(job.runs[0].score) - 1
    g = np.unique(np.linspace(0, generations, CURVE_POINTS).round().astype(np.int64))
    q1, median, q3 = np.percentile(np.stack([run.score[g] for run in job.runs]), [25, 50, 75], axis=0)
    return {"evals": [int(e) for e in job.evals(g)],
            **{name: [round(float(v), 4) for v in q] for name, q in (("median", median), ("q1", q1), ("q3", q3))}}


def _merged(path: Path, entries: list[dict]) -> list[dict]:
    """``entries`` plus the jobs of ``path`` (if any) that they do not replace, all at one seed count and budget."""
    key = lambda e: (e["setup"], e["method"])   # noqa: E731
    new = {key(e) for e in entries}
    kept = [e for e in (_load(path.parent) if path.is_file() else []) if key(e) not in new]
    jobs = kept + entries
    step = max(j["evals_per_generation"] for j in jobs)   # equal budgets differ by less than one generation's cost
    first = jobs[0]
    for j in jobs:
        if len(j["runs"]) != len(first["runs"]) or abs(j["team_evals_per_run"] - first["team_evals_per_run"]) > step:
            raise ResultsError(
                f"{path}: {first['method']} on {first['setup']} has {len(first['runs'])} seeds at "
                f"{first['team_evals_per_run']:,} team evaluations per run, {j['method']} on {j['setup']} has "
                f"{len(j['runs'])} at {j['team_evals_per_run']:,}: another budget (export into another dir)")
    return jobs


def _method_rank(method: str) -> tuple:
    return (METHODS.index(method) if method in METHODS else len(METHODS), method)


def _load(results: Path) -> list[dict]:
    return load_study(results, "baselines")


def _finals(job: dict) -> np.ndarray:
    return np.array([r["final"] for r in job["runs"].values()], dtype=np.float64)


def _evals_to(job: dict, level: int) -> np.ndarray:
    return np.array([math.inf if r["evals_to"][str(level)] is None else r["evals_to"][str(level)]
                     for r in job["runs"].values()], dtype=np.float64)


def report(results: Path) -> tuple[str, dict]:
    """The report of ``results/baselines.json``: markdown (also ``baselines.md``) and its numbers."""
    jobs = _load(results)
    budgets = sorted({j["team_evals_per_run"] for j in jobs})
    seeds = sorted({len(j["runs"]) for j in jobs})
    have = {(j["setup"], j["method"]) for j in jobs}
    missing = [f"{m} on {s}" for s in LEVELS for m in METHODS if (s, m) not in have]
    progress = (f"In progress: {len(have)} of {len(LEVELS) * len(METHODS)} jobs; to come: {', '.join(missing)}. "
                if missing else "")
    lines = ["<!-- generated by `python studies/baselines/report.py report results/baselines`; do not edit -->",
             "", f"{progress}Budget: {min(budgets):,} to {max(budgets):,} team evaluations per run (the initial team's "
             f"included); {', '.join(map(str, seeds))} seeds per job. `final`: median score of the last generation "
             "with a percentile-bootstrap 95% CI; `at L`: runs whose curve reached L, Wilson 95% CI; `evals to L`: "
             "median team evaluations to reach L with a bootstrap CI (`never`: the median run did not); "
             f"`vs {REFERENCE}`: Mann-Whitney U (two-sided) of the final scores against CC-(1+1)-ES k=1 on the same "
             "setup, with P(a>b), the chance that a run of the method scores above one of k=1 (ties half); "
             "`held-out`: median score of the final teams on 256 held-out initial conditions.", ""]
    numbers: dict = {}
    for setup in dict.fromkeys(j["setup"] for j in jobs):
        rows = [j for j in jobs if j["setup"] == setup]
        levels = LEVELS.get(setup, ())
        ref = next((j for j in rows if j["method"] == REFERENCE), None)
        lines += [f"### {setup}", "", "| method | generations | final | " + " | ".join(f"at {lv}" for lv in levels)
                  + " | " + " | ".join(f"evals to {lv}" for lv in levels) + f" | vs {REFERENCE} | held-out |",
                  "|---|---|---|" + "---|" * (2 * len(levels)) + "---|---|"]
        for j in rows:
            x, n = _finals(j), len(j["runs"])
            at = {lv: stats.wilson(int(np.isfinite(_evals_to(j, lv)).sum()), n) for lv in levels}
            to = {lv: stats.median_ci(_evals_to(j, lv)) for lv in levels}
            test = stats.mann_whitney(x, _finals(ref)) if ref is not None and j is not ref else None
            final = stats.median_ci(x)
            held = float(np.median([r["heldout"] for r in j["runs"].values()]))
            numbers[j["job"]] = {"setup": setup, "method": j["method"], "final": final.as_dict(),
                                 "at": {str(lv): e.as_dict() for lv, e in at.items()},
                                 "evals_to": {str(lv): e.as_dict() for lv, e in to.items()},
                                 "vs_reference": test.as_dict() if test else None, "heldout": held}
            lines.append(f"| {j['method']} | {j['generations']:,} | {final.fmt()} | "
                         + " | ".join(stats.format_count(at[lv], n) for lv in levels) + " | "
                         + " | ".join(to[lv].fmt(None) for lv in levels) + " | "
                         + (f"p{stats.format_p(test.p)}, P(a>b)={test.effect:.2f}" if test else "-")
                         + f" | {held:.3g} |")
        lines.append("")
    compute = {k: sum(j["compute"][k] for j in jobs) for k in ("team_evals", "wall_time_s")}
    numbers["compute"] = compute
    lines += [f"Compute: {compute['team_evals']:,} team evaluations, {compute['wall_time_s'] / 3600:.2f} h of wall "
              f"time over {len(jobs)} jobs (each job's `invocations.jsonl`).", ""]
    text = "\n".join(lines) + "\n"
    with atomic_open(Path(results) / "baselines.md", "w") as f:
        f.write(text)
    return text, numbers


def figures(results: Path) -> list[Path]:
    """``results/figures/baselines_<setup>.png``: each method's median score (quartile band) against team
    evaluations, from ``baselines.json``'s compact curves; returns the files written."""
    from rovermarl.analysis.draw import new_figure, save

    jobs, files = _load(results), []
    for setup in dict.fromkeys(j["setup"] for j in jobs):
        fig = new_figure(6.0, 3.6)
        ax = fig.add_subplot(1, 1, 1)
        for j in (r for r in jobs if r["setup"] == setup):
            c, colour = j["curve"], f"C{_method_rank(j['method'])[0] % 10}"   # one colour per method in every setup
            ax.fill_between(c["evals"], c["q1"], c["q3"], color=colour, alpha=0.15, linewidth=0)
            ax.plot(c["evals"], c["median"], color=colour, label=j["method"])
        ax.set(xlabel="team evaluations", ylabel="score (median, quartiles)", title=setup)
        ax.legend(fontsize=7, loc="lower right")
        out = Path(results) / "figures"
        out.mkdir(parents=True, exist_ok=True)
        files += [out / name for name in save(fig, out, f"baselines_{setup}", ["png"])]
    return files


def main(argv=None) -> None:
    p = Parser(prog=PROG, description="The baselines study: export a sweep, the jobs done, the report, figures.")
    sub = p.add_subparsers(dest="action", required=True, parser_class=Parser)
    e = sub.add_parser("export", help="a baselines sweep -> RESULTS_DIR/baselines.json (jobs there kept)")
    e.add_argument("sweep", type=Path, help="the sweep dir, e.g. outputs/baselines")
    e.add_argument("results", type=Path, help="results/baselines")
    for action, text in (("done", "the (setup, method) jobs the results hold, one a line"),
                         ("report", "RESULTS_DIR/baselines.md, printed too"),
                         ("figures", "RESULTS_DIR/figures/baselines_<setup>.png, their paths printed")):
        sub.add_parser(action, help=text).add_argument("results", type=Path, help="results/baselines")
    args = p.parse_args(argv)
    with one_line_errors(PROG):
        if args.action == "export":
            export(args.sweep, args.results, log=say(PROG))
        elif args.action == "done":
            print("".join(f"{setup} {method}\n" for setup, method in done(args.results)), end="")
        elif args.action == "figures":
            print("".join(f"{path}\n" for path in figures(args.results)), end="")
        else:
            print(report(args.results)[0], end="")


if __name__ == "__main__":
    main()
