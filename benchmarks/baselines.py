"""Single-core throughput of the learners the baselines study compares: team evaluations per second of process CPU
time for CC-(1+1)-ES and the CCEA with each credit (G, D, D++), and the cost of one team's credits. Prints one JSON
line; the rates are measured alternately, ``--repeats`` times each, and the median is reported.

    python benchmarks/baselines.py [--setup duo] [--generations 300] [--repeats 5]
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

from rovermarl.algorithms import credit
from rovermarl.config import compose_config
from rovermarl.runner import Run

METHODS = {"cc11es k=1": (), "ccea G": ("algorithm=ccea", "algorithm.reward=global"),
           "ccea D": ("algorithm=ccea", "algorithm.reward=difference"),
           "ccea D++": ("algorithm=ccea", "algorithm.reward=dpp")}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--setup", default="duo")
    p.add_argument("--generations", type=int, default=300, help="CCEA generations per measurement (cc11es: x11)")
    p.add_argument("--repeats", type=int, default=5)
    args = p.parse_args()
    runs = {}
    for name, overrides in METHODS.items():
        gens = args.generations * (1 if overrides else 11)
        runs[name] = Run(compose_config(*overrides, f"setup={args.setup}", f"generations={gens * (args.repeats + 1)}",
                                        "record=off"), 0)
        runs[name].advance(5)                                        # compile
    rates: dict[str, list[float]] = {name: [] for name in METHODS}
    for _ in range(args.repeats):
        for name, run in runs.items():
            before, t = run.evaluate.calls, time.process_time()
            run.advance(args.generations * (1 if METHODS[name] else 11))
            rates[name].append((run.evaluate.calls - before) / (time.process_time() - t))
    world, team = runs["ccea D++"].parts.world, runs["ccea D++"].team
    ic = world.run_ic(0)
    roll = world.rollout(team, ic)
    credit_us = {}
    for name in ("difference", "dpp"):
        t = time.process_time()
        for _ in range(500):
            credit.credit(name, world, roll.xy, roll.returns)
        credit_us[name] = (time.process_time() - t) / 500 * 1e6
    t = time.process_time()
    for _ in range(500):
        world.rollout(team, ic)
    print(json.dumps({"benchmark": "baselines", "setup": args.setup,
                      "team_evals_per_s": {k: statistics.median(v) for k, v in rates.items()},
                      "credit_us_per_team": credit_us,
                      "rollout_us_per_team": (time.process_time() - t) / 500 * 1e6,
                      "repeats": args.repeats, "evals_per_s_spread": {k: [min(v), max(v)] for k, v in rates.items()}}))


if __name__ == "__main__":
    main()
