"""One Rerun recording (``.rrd``) per run, written by the driver from the run's arrays.

Entities (2-D scene units are world units):

- static ``world/pois`` (POI centres, coloured by coupling), ``world/poi_radius`` (circles of the observation
  radius), ``world/start_boxes`` (the rovers' start squares);
- timeline ``generation``: ``metrics/score``, ``metrics/child_score``, ``metrics/k``, ``metrics/accepted``,
  ``bandit/k<arm>`` (bandit selectors), ``occupancy/count`` (tensor episode x POI) and ``occupancy/poi_<j>``
  (mean rovers at POI j over episodes) at each change, ``episodes/<e>/trajectories`` (one line per rover) at
  generation 0, every accepted score change and the last generation;
- timeline ``step``: ``episodes/<e>/rovers``, the final team's positions along each episode.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

ROVER_COLORS = np.array([[31, 119, 180], [255, 127, 14], [44, 160, 44], [214, 39, 40], [148, 103, 189],
                         [140, 86, 75], [227, 119, 194], [127, 127, 127], [188, 189, 34], [23, 190, 207]],
                        dtype=np.uint8)
COUPLING_COLORS = np.array([[90, 90, 90], [230, 160, 0], [200, 40, 40], [120, 0, 160]], dtype=np.uint8)


def rover_colors(n: int) -> np.ndarray:
    return ROVER_COLORS[np.arange(n) % len(ROVER_COLORS)]


def write_rrd(path: Path, result: dict, world, every: int = 1, steps: bool = True, recording_id: str = "",
              arms=None) -> Path:
    """Write ``result`` (a finished run's arrays) to ``path`` atomically; returns the path.

    ``arms`` are the k values of a bandit's probabilities (default 1..K).
    """
    import rerun as rr

    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp")
    rec = rr.RecordingStream("rovermarl", recording_id=recording_id or path.parent.name)
    rec.save(str(tmp))
    try:
        _scene(rec, rr, world)
        _metrics(rec, rr, result, every, arms)
        _occupancy(rec, rr, result)
        _trajectories(rec, rr, result, steps)
        rec.flush()
    finally:
        rec.disconnect()
    os.replace(tmp, path)
    return path


def _scene(rec, rr, world) -> None:
    coupling = np.array(world.coupling)
    colors = COUPLING_COLORS[np.minimum(coupling - 1, len(COUPLING_COLORS) - 1)]
    rec.log("world/pois", rr.Points2D(world.poi_xy, radii=0.3, colors=colors,
                                      labels=[f"POI {j} (c={c})" for j, c in enumerate(coupling)]), static=True)
    theta = np.linspace(0, 2 * np.pi, 65)
    ring = world.obs_radius * np.stack([np.cos(theta), np.sin(theta)], axis=1)
    rec.log("world/poi_radius", rr.LineStrips2D([p + ring for p in world.poi_xy], colors=colors), static=True)
    rec.log("world/start_boxes", rr.LineStrips2D(world.start_squares, colors=rover_colors(world.n_rovers)),
            static=True)


def _series(rec, rr, entity, generations, values) -> None:
    rec.send_columns(entity, indexes=[rr.TimeColumn("generation", sequence=np.asarray(generations, dtype=np.int64))],
                     columns=rr.Scalars.columns(scalars=np.asarray(values, dtype=np.float64)))


def _metrics(rec, rr, result, every, arms) -> None:
    score = result["score"]
    gens = np.arange(len(score))[::every]
    _series(rec, rr, "metrics/score", gens, score[::every])
    if "k" not in result:
        return
    after = gens[gens >= 1]                                       # generation g's child: index g - 1
    _series(rec, rr, "metrics/child_score", after, result["child_score"][after - 1])
    _series(rec, rr, "metrics/k", after, result["k"][after - 1])
    _series(rec, rr, "metrics/accepted", after, result["accepted"][after - 1])
    if "probs" in result:
        for a, arm in enumerate(arms or range(1, result["probs"].shape[1] + 1)):
            _series(rec, rr, f"bandit/k{arm}", after, result["probs"][after - 1, a])


def _occupancy(rec, rr, result) -> None:
    gens, count = result["occupancy_generation"], result["occupancy_count"]
    if len(gens) == 0:
        return
    for j in range(count.shape[2]):
        _series(rec, rr, f"occupancy/poi_{j}", gens, count[:, :, j].mean(axis=1))
    for g, c in zip(gens, count, strict=True):
        rec.set_time("generation", sequence=int(g))
        rec.log("occupancy/count", rr.Tensor(c, dim_names=["episode", "poi"]))
    rec.reset_time()


def _trajectories(rec, rr, result, steps) -> None:
    gens, xy = result["behaviour_generation"], result["behaviour_xy"]       # xy (C, E, T+1, N, 2)
    if len(gens) == 0:
        return
    c, n_ep, t1, n = xy.shape[:4]
    colors = np.tile(rover_colors(n), (c, 1))
    generation = rr.TimeColumn("generation", sequence=np.asarray(gens, dtype=np.int64))
    for e in range(n_ep):                                                  # C rows of N lines each
        strips = xy[:, e].transpose(0, 2, 1, 3).reshape(c * n, t1, 2)
        rec.send_columns(f"episodes/{e}/trajectories", indexes=[generation],
                         columns=rr.LineStrips2D.columns(strips=strips, colors=colors).partition([n] * c))
    if steps:                                                              # T+1 rows of N points each
        step = rr.TimeColumn("step", sequence=np.arange(t1))
        step_colors = np.tile(rover_colors(n), (t1, 1))
        for e in range(n_ep):
            rec.send_columns(f"episodes/{e}/rovers", indexes=[step],
                             columns=rr.Points2D.columns(positions=xy[-1, e].reshape(t1 * n, 2), colors=step_colors,
                                                         radii=np.full(t1 * n, 0.25)).partition([n] * t1))
