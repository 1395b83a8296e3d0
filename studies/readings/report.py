"""The readings study: does the duo result hinge on our reading of the paper? (``launchers/readings.sh``)

A readings sweep holds one job per (reading, setup, method): the SPEC reading and each alternative of SPEC section 8
(``env.reward``, ``env.speed``, ``env.poi_type``, ``evaluation.fresh_ic``, sigma read as a variance), for duo with
k=1, k=2 and the homogeneous team, and solo k=1 and the combination for the readings that lift duo.

- :func:`export`: the sweep -> ``RESULTS/readings.json``, a few numbers per run (below) and the compute spent;
- :func:`lifting`: the single readings that lift duo above the SPEC reading;
- :func:`report`: ``RESULTS/readings.md`` (the section of ``docs/REPRODUCTION.md``) from ``readings.json``.

``python studies/readings/report.py {export SWEEP_DIR RESULTS_DIR, lifting RESULTS_DIR, report RESULTS_DIR}``.

Per run: ``final`` (its last score, in its own reading), ``final_step`` (its final team scored on its 16 initial
conditions by the SPEC reward, positions after the last step, in the reading's world otherwise: the yardstick that
compares readings; ``final`` itself for readings that keep that reward and fixed initial conditions), ``heldout``
(run.json's held-out score, own reading) and the first generation reaching 4 and 5 on its own curve.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
from omegaconf import OmegaConf

from rovermarl.analysis import stats
from rovermarl.analysis.cli import Parser, one_line_errors, say
from rovermarl.analysis.export import compute_of
from rovermarl.analysis.results import ResultsError, load_study
from rovermarl.analysis.sweep import find_jobs
from rovermarl.env import World
from rovermarl.record.atomic import atomic_open
from rovermarl.record.safe_read import RunSize, load_npy, load_npz, read_json

PROG = "studies/readings/report.py"
SPEC = "spec"
# Each alternative reading (a job override) and the sentence of the paper that allows it.
READINGS = {
    SPEC: "SPEC sections 1-6: reward after the last step, speed (a0 + 1) / 2, type c - 1, 16 fixed ICs, sigma a "
          "standard deviation",
    "env.reward=any_step": "\"Each POI delivers some reward if the n agents that visit it are in their radius of "
                           "observation\"",
    "env.reward=best_step": "\"Each POI delivers some reward if the n agents that visit it are in their radius "
                            "of observation\", read as a per-step reward of which the episode keeps its best step "
                            "(a stretch: the paper computes the reward \"after\" the T steps)",
    "env.reward=mean_step": "the same sentence read as a per-step reward averaged over the episode (a stretch, "
                            "for the same reason)",
    "env.speed=clip": "\"speed (a0 in [0, 1] for [stop, maximum speed])\" with a tanh output in [-1, 1]",
    "env.poi_type=sign": "\"3 sensors per POI that get information about their distance, angle and type\"",
    "env.poi_type=value": "\"... and type\" (read as: the reward the POI pays)",
    "evaluation.fresh_ic=true": "\"using the possibly noisy team-level score obtained during evaluation\"",
    "mutation.sigma=0.316": "\"a perturbation centred on the current parameter value, with a variance sigma\"",
}
METHODS = ("k=1", "k=2", "homogeneous")
LEVELS = (4, 5)
NOT_READING = ("setup", "k", "team", "generations", "seeds", "seed", "parallel", "ray", "record", "checkpoint",
               "resume", "hydra", "levels")


def reading_of(overrides: list[str]) -> str:
    """The reading of a job from its overrides: ``spec``, one override, or several joined by ``+`` (sorted)."""
    keys = sorted(o for o in overrides if o.split("=", 1)[0].split(".")[0].lstrip("+~") not in NOT_READING)
    keys = [k[:-5] + "=true" if k.endswith("=True") else k[:-6] + "=false" if k.endswith("=False") else k
            for k in keys]                                           # Hydra writes booleans as True / False
    return "+".join(keys) or SPEC


def _method(job) -> str:
    return "homogeneous" if job.homogeneous else job.k_name


def _final_step(world: World, run_dir: Path, size: RunSize) -> float:
    """The final team's F on the run's initial conditions, positions after the last step (SPEC reward); the files
    checked against the run's ``size`` before they are read."""
    ic = load_npz(run_dir / "initial_conditions.npz", size.initial_conditions(), ("xy", "heading"), stored=True)
    return world.evaluate(load_npy(run_dir / "genomes.npy", size.genomes()), (ic["xy"], ic["heading"]))


def export(sweep: Path, out: Path, log=print) -> dict:
    """Write ``out/readings.json`` from every finished job of a readings sweep; returns it."""
    jobs, notes = find_jobs(sweep)
    for note in notes:
        log(note)
    entries = []
    for job in jobs:
        if not job.finished:
            continue
        summary = read_json(job.path / "summary.json", kind="summary")
        world = World.from_config(OmegaConf.merge(OmegaConf.create(job.config), {"env": {"reward": "final"}}))
        size = RunSize.of(job.config, world)
        runs = {}
        for run in sorted(job.runs, key=lambda r: r.seed):
            meta = read_json(run.path / "run.json", kind="run")
            runs[str(run.seed)] = {
                "final": float(run.score[-1]), "final_step": _final_step(world, run.path, size),
                "heldout": float(meta["heldout_score"]),
                "first": {str(lv): _first(run.score, lv) for lv in LEVELS}}
        entries.append({"job": job.path.name, "reading": reading_of(job.overrides), "setup": job.setup,
                        "method": _method(job), "generations": len(job.runs[0].score) - 1, "runs": runs,
                        "compute": compute_of(job),
                        "median_heldout_score": summary["median_heldout_score"]})
    if not entries:
        raise ResultsError(f"{sweep}: no finished job of a readings sweep")
    data = {"jobs": sorted(entries, key=lambda e: (e["setup"], _rank(e["reading"]), METHODS.index(e["method"])
                                                   if e["method"] in METHODS else 9, e["method"]))}
    out.mkdir(parents=True, exist_ok=True)
    with atomic_open(out / "readings.json", "w") as f:
        f.write(json.dumps(data, indent=1) + "\n")
    return data


def _first(score: np.ndarray, level: float) -> int | None:
    hits = np.flatnonzero(score >= level)
    return int(hits[0]) if hits.size else None


def _rank(reading: str) -> tuple:
    keys = list(READINGS)
    return (reading.count("+"), keys.index(reading) if reading in keys else len(keys), reading)


def _load(results: Path) -> list[dict]:
    return load_study(results, "readings")


def _values(job: dict, what: str) -> np.ndarray:
    return np.array([r[what] for r in job["runs"].values()], dtype=np.float64)


def _times(job: dict, level: int) -> np.ndarray:
    return np.array([math.inf if r["first"][str(level)] is None else r["first"][str(level)]
                     for r in job["runs"].values()], dtype=np.float64)


def lifting(results_or_jobs) -> list[str]:
    """Single readings whose duo final-step score lifts above the SPEC reading's for some method: a higher median,
    or more runs at 5 or more."""
    jobs = _load(results_or_jobs) if isinstance(results_or_jobs, (str, Path)) else results_or_jobs
    duo = {(j["reading"], j["method"]): j for j in jobs if j["setup"] == "duo"}
    out = []
    for reading in dict.fromkeys(r for r, _ in duo):
        if reading == SPEC or "+" in reading:
            continue
        for method in METHODS:
            job, base = duo.get((reading, method)), duo.get((SPEC, method))
            if job is None or base is None:
                continue
            x, y = _values(job, "final_step"), _values(base, "final_step")
            if np.median(x) > np.median(y) or (x >= 5).sum() > (y >= 5).sum():
                out.append(reading)
                break
    return out


def report(results: Path) -> tuple[str, dict]:
    """The report of ``results/readings.json``: markdown (also ``readings.md``) and its numbers."""
    jobs = _load(results)
    base = {j["method"]: j for j in jobs if j["setup"] == "duo" and j["reading"] == SPEC}
    budgets = sorted({j["generations"] for j in jobs})
    seeds = sorted({len(j["runs"]) for j in jobs})
    ids = sorted({int(s) for j in jobs for s in j["runs"]})
    lines = ["<!-- generated by `python studies/readings/report.py report results/readings`; do not edit -->",
             "", f"Budget: {', '.join(f'{g:,}' for g in budgets)} generations per run; {', '.join(map(str, seeds))} "
             f"seeds per job (seeds {ids[0]}-{ids[-1]}). Medians with percentile-bootstrap 95% CIs; counts with "
             "Wilson 95% CIs; `vs SPEC`: Mann-Whitney U (two-sided) of the final-step score against the SPEC "
             "reading's, same method, with P(a>b), the chance that a run of the reading scores above one of the "
             "SPEC's (ties half).",
             "`final`: the run's last score in its own reading; `final-step`: its final team on its 16 initial "
             "conditions scored by the SPEC reward (after the last step), the yardstick across readings; runs at 5 "
             "and 6 count final-step scores; times to 4 and 5 are on the run's own curve (`never` past the budget); "
             "`held-out`: 256 held-out initial conditions, own reading.", ""]
    numbers: dict = {}
    for setup in ("duo", "solo"):
        rows = [j for j in jobs if j["setup"] == setup]
        if not rows:
            continue
        lines += [f"### {setup}", "",
                  "| reading | method | final | final-step | runs at 5 | runs at 6 | time to 4 | time to 5 | "
                  "vs SPEC | held-out |", "|---|---|---|---|---|---|---|---|---|---|"]
        for j in rows:
            x, n = _values(j, "final_step"), len(j["runs"])
            row = {"final": stats.median_ci(_values(j, "final")), "final_step": stats.median_ci(x),
                   "at5": stats.wilson(int((x >= 5).sum()), n), "at6": stats.wilson(int((x >= 6).sum()), n),
                   "t4": stats.median_ci(_times(j, 4)), "t5": stats.median_ci(_times(j, 5)),
                   "heldout": float(np.median(_values(j, "heldout")))}
            ref = base.get(j["method"]) if setup == "duo" else None
            test = stats.mann_whitney(x, _values(ref, "final_step")) if ref and j["reading"] != SPEC else None
            numbers[j["job"]] = {k: v if isinstance(v, float) else v.as_dict() for k, v in row.items()}
            numbers[j["job"]]["vs_spec"] = test.as_dict() if test else None
            lines.append(f"| {_label(j['reading'])} | {j['method']} | {row['final'].fmt()} | "
                         f"{row['final_step'].fmt()} | {stats.format_count(row['at5'], n)} | "
                         f"{stats.format_count(row['at6'], n)} | "
                         f"{row['t4'].fmt(None)} | {row['t5'].fmt(None)} | "
                         f"{f'p{stats.format_p(test.p)}, P(a>b)={test.effect:.2f}' if test else '-'} | "
                         f"{row['heldout']:.3g} |")
        lines.append("")
    lifts = lifting(jobs)
    numbers["lifting"] = lifts
    compute = {k: sum(j["compute"][k] for j in jobs) for k in ("team_evals", "wall_time_s")}
    numbers["compute"] = compute
    lines += ["Readings that lift duo (for some method, a higher median final-step score than the SPEC reading, or "
              f"more runs at 5 or more): {', '.join(f'`{r}`' for r in lifts) or 'none'}.", "",
              f"Compute: {compute['team_evals']:,} team evaluations, {compute['wall_time_s'] / 3600:.2f} h of wall "
              f"time over {len(jobs)} jobs (each job's `invocations.jsonl`).", "",
              "Where each reading comes from:", ""]
    lines += [f"- `{r}`: {text}" for r, text in READINGS.items() if any(j["reading"] == r for j in jobs)]
    text = "\n".join(lines) + "\n"
    with atomic_open(Path(results) / "readings.md", "w") as f:
        f.write(text)
    return text, numbers


def _label(reading: str) -> str:
    return " + ".join(f"`{r}`" for r in reading.split("+")) if reading != SPEC else "SPEC"


def main(argv=None) -> None:
    p = Parser(prog=PROG, description="The readings study: export a sweep, its lifting readings, the report.")
    sub = p.add_subparsers(dest="action", required=True, parser_class=Parser)
    e = sub.add_parser("export", help="a readings sweep -> RESULTS_DIR/readings.json")
    e.add_argument("sweep", type=Path, help="the sweep dir, e.g. outputs/readings")
    e.add_argument("results", type=Path, help="results/readings")
    for action, text in (("lifting", "the single readings that lift duo, one a line"),
                         ("report", "RESULTS_DIR/readings.md, printed too")):
        sub.add_parser(action, help=text).add_argument("results", type=Path, help="results/readings")
    args = p.parse_args(argv)
    with one_line_errors(PROG):
        if args.action == "export":
            export(args.sweep, args.results, log=say(PROG))
        elif args.action == "lifting":
            print("\n".join(lifting(args.results)))
        else:
            print(report(args.results)[0], end="")


if __name__ == "__main__":
    main()
