"""How close ``env.dtype=float32`` is to float64: random teams evaluated in both precisions on the same initial
conditions. Prints one JSON line.

    python benchmarks/float32_agreement.py [--teams 10000] [--setups solo,duo]

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


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--teams", type=int, default=10_000)
    p.add_argument("--setups", default="solo,duo")
    a = p.parse_args()
    t = time.perf_counter()
    out = {setup: agreement(setup, a.teams) for setup in a.setups.split(",")}
    print(json.dumps({"benchmark": "float32_agreement", "genomes": "uniform(-2, 2), seed t", "ic": "World.run_ic(t)",
                      **out, "seconds": round(time.perf_counter() - t, 1), "cpus": os.cpu_count()}))


if __name__ == "__main__":
    main()
