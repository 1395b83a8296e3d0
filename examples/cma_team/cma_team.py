"""A team optimised with CMA-ES (the ``cma`` package) through rovermarl's population API: a complete example.

Each CMA-ES generation asks for a population of genomes, scores them all in one call (``World.evaluate_many``:
several teams per pass of the compiled rollout, the population split over the cores) on the initial conditions run
0 of the CLI is scored on (``World.run_ic``, prepared once: ``World.prepare``), and tells CMA-ES their scores
(negated: it minimises). The team is homogeneous (``World.homogeneous``: one genome, N copies),
so the search space is one rover's 658 parameters. At the end the best team is also scored on its held-out initial
conditions (``World.heldout_ic``), as ``summary.json`` does for the CLI's runs.

    pip install cma
    python examples/cma_team/cma_team.py [--setup solo] [--evaluations 20000] [--seed 0]
"""

from __future__ import annotations

import argparse
import json
import time

import cma
import numpy as np

from rovermarl import make_world


def optimise(setup: str = "solo", evaluations: int = 20000, seed: int = 0, sigma: float = 0.5) -> dict:
    world = make_world(setup)
    ic = world.prepare(world.run_ic(seed))                                    # checked once, in the kernel's dtype
    es = cma.CMAEvolutionStrategy(np.zeros(world.n_params), sigma,
                                  {"seed": seed + 1, "verbose": -9, "CMA_diagonal": True})
    best, best_genome, used, t0 = -np.inf, None, 0, time.perf_counter()
    while used < evaluations:
        genomes = np.array(es.ask())                                           # (lambda, P)
        scores = world.evaluate_many(np.stack([world.homogeneous(g) for g in genomes]), ic)   # (lambda,)
        es.tell(list(genomes), list(-scores))
        used += len(scores)
        if scores.max() > best:
            best, best_genome = float(scores.max()), genomes[int(np.argmax(scores))]
    team = world.homogeneous(best_genome)
    return {"setup": setup, "evaluations": used, "best_score": best,
            "heldout_score": world.evaluate(team, world.heldout_ic(seed)),
            "seconds": round(time.perf_counter() - t0, 1)}


if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--setup", default="solo")
    p.add_argument("--evaluations", type=int, default=20000)
    p.add_argument("--seed", type=int, default=0)
    a = p.parse_args()
    print(json.dumps(optimise(a.setup, a.evaluations, a.seed)))
