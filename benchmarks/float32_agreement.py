"""How close ``env.dtype=float32`` is to float64: random teams evaluated in both precisions on the same initial
conditions. Prints one JSON line.

    python benchmarks/float32_agreement.py [--teams 10000] [--setups solo,duo]
    python benchmarks/float32_agreement.py --runs 'SWEEP/*duo*/runs/seed_*' [--setups duo]

With ``--runs``, the teams are instead the final teams (``genomes.npy``) of finished runs of the first setup, each on
its own 16 initial conditions (``initial_conditions.npz``) and on its 256 held-out ones (``World.heldout_ic``):
whether float32 would have told the same story about trained teams, where random teams mostly score 0.

Team ``t`` is the paper's initial genomes (uniform in [-2, 2], ``policy.init_low/high``) drawn from seed ``t``, on the
16 initial conditions ``World.run_ic(t)``. Per setup it counts the episodes whose team return differs, the teams whose
score F differs, and the final POI assignments that differ (a rover-episode whose final position observes another POI,
or none instead of one: the lowest POI index within ``obs_radius``, as the reward and the behaviour events read it);
and the distance between the float32 and float64 final positions (median and max over rover-episodes).
"""

from __future__ import annotations

import argparse
import json
import os
import time

import numpy as np

from rovermarl import make_world


def final_poi(world, xy: np.ndarray) -> np.ndarray:
    """xy (..., N, 2) -> (..., N): the lowest POI index within ``obs_radius`` of each rover, or -1."""
    d = np.linalg.norm(xy[..., None, :] - world.poi_xy, axis=-1)             # (..., N, P)
    inside = d <= world.obs_radius
    return np.where(inside.any(axis=-1), inside.argmax(axis=-1), -1)


def agreement(setup: str, teams: int) -> dict:
    w64, w32 = make_world(setup), make_world(setup, dtype="float32")
    n_ep, n = w64.episodes, w64.n_rovers
    ret_diff = score_diff = poi_diff = poi_ep_diff = scoring = 0
    dist = np.empty((teams, n_ep, n))
    f64, f32 = np.empty((n_ep, n, 2)), np.empty((n_ep, n, 2))
    for t in range(teams):
        genomes = np.random.default_rng(t).uniform(-2.0, 2.0, (n, w64.n_params))
        ic = w64.run_ic(t)
        r64, r32 = w64.returns(genomes, ic, f64), w32.returns(genomes, ic, f32)
        ret_diff += int(np.sum(r64 != r32))
        score_diff += int(r64.mean() != r32.mean())
        scoring += int(r64.any())
        p64, p32 = final_poi(w64, f64), final_poi(w64, f32)
        poi_diff += int(np.sum(p64 != p32))
        poi_ep_diff += int(np.sum((p64 != p32).any(axis=1)))
        dist[t] = np.linalg.norm(f64 - f32, axis=-1)
    episodes = teams * n_ep
    return {"teams": teams, "episodes": episodes, "rover_episodes": episodes * n,
            "teams_scoring_in_float64": scoring,
            "episode_returns_differing": ret_diff, "episode_returns_differing_share": ret_diff / episodes,
            "team_scores_differing": score_diff, "team_scores_differing_share": score_diff / teams,
            "final_pois_differing": poi_diff, "final_pois_differing_share": poi_diff / (episodes * n),
            "episodes_with_a_final_poi_differing": poi_ep_diff,
            "final_xy_distance_median": float(np.median(dist)), "final_xy_distance_p99": float(np.quantile(dist, 0.99)),
            "final_xy_distance_max": float(dist.max())}


def trained(setup: str, pattern: str) -> dict:
    """The agreement on the final teams of the finished runs matching ``pattern``: their own and held-out ICs."""
    import glob
    from pathlib import Path

    w64, w32 = make_world(setup), make_world(setup, dtype="float32")
    runs = sorted(Path(p) for p in glob.glob(pattern) if (Path(p) / "run.json").is_file())
    own = held = own_eps = held_eps = 0
    own_gap, held_gap = [], []
    for run in runs:
        genomes, seed = np.load(run / "genomes.npy"), json.loads((run / "run.json").read_text())["seed"]
        with np.load(run / "initial_conditions.npz") as z:
            ic = (z["xy"], z["heading"])
        for name, ics in (("own", ic), ("held", w64.heldout_ic(seed))):
            r64, r32 = w64.returns(genomes, ics), w32.returns(genomes, ics)
            if name == "own":
                own, own_eps = own + int(np.sum(r64 != r32)), own_eps + len(r64)
                own_gap.append(abs(r64.mean() - r32.mean()))
            else:
                held, held_eps = held + int(np.sum(r64 != r32)), held_eps + len(r64)
                held_gap.append(abs(r64.mean() - r32.mean()))
    return {"runs": len(runs), "pattern": pattern,
            "own_episodes": own_eps, "own_episode_returns_differing": own,
            "own_score_gap_max": float(max(own_gap, default=0.0)),
            "heldout_episodes": held_eps, "heldout_episode_returns_differing": held,
            "heldout_score_gap_max": float(max(held_gap, default=0.0))}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--teams", type=int, default=10_000)
    p.add_argument("--setups", default="solo,duo")
    p.add_argument("--runs", default=None, help="glob of finished run dirs: their final teams instead of random ones")
    a = p.parse_args()
    t = time.perf_counter()
    if a.runs:
        setup = a.setups.split(",")[0]
        print(json.dumps({"benchmark": "float32_agreement", "teams": "final teams of finished runs", "setup": setup,
                          **trained(setup, a.runs), "seconds": round(time.perf_counter() - t, 1)}))
        return
    out = {setup: agreement(setup, a.teams) for setup in a.setups.split(",")}
    print(json.dumps({"benchmark": "float32_agreement", "genomes": "uniform(-2, 2), seed t", "ic": "World.run_ic(t)",
                      **out, "seconds": round(time.perf_counter() - t, 1), "cpus": os.cpu_count()}))


if __name__ == "__main__":
    main()
