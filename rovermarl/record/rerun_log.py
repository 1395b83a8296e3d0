"""One Rerun recording (``.rrd``) per run, written by the driver from the run's arrays, with its own layout.

Entities (2-D positions in world units, as simulated; the static ``world`` transform flips y so that y points up,
as in the matplotlib figures, where Rerun's 2-D views point it down):

- static: ``world`` (the flip), ``world/pois`` (coloured by coupling), ``world/poi_labels`` (just outside each
  ring), ``world/poi_radius`` (observation-radius circles), ``world/start_boxes`` (rover colours), ``legend``;
- timeline ``generation``: ``metrics/score``; each declared series at ``Series.path`` (a vector series one entry
  per column, ``<entity>/<column>``), leaving out generations at the series' non-zero ``fill`` (-1, nan: not
  computed); ``occupancy/poi_<j>``, lane j of the occupancy chart (value j, coloured by the mean number of rovers
  at POI j at episode end; at each change and the last generation); ``occupancy/count`` (episode x POI tensor,
  colour range 0..N) at each change;
  ``world/episodes/<e>/trajectories`` and ``.../ends`` at generation 0, each accepted score change and the last;
- timeline ``step``: ``world/episodes/<e>/rovers``, the final team's positions along each episode.

A blueprint (:func:`blueprint`), active and default, opens every run on the same layout.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rovermarl import palette
from rovermarl.record.atomic import atomic_open

FLUSH_S = 60.0                                       # the SDK's flush into memory; it never waits on a disk


def write_rrd(path: Path, result: dict, world, series=(), every: int = 1, steps: bool = True,
              recording_id: str = "") -> Path:
    """Write ``result`` (a finished run's arrays) to ``path`` atomically; returns the path.

    ``result`` holds ``score`` (G+1,), one array (G, *shape) per declared ``series`` (the algorithm's
    :class:`~rovermarl.algorithms.base.Series`; generation g's entry is index g - 1), the behaviour and occupancy
    events (``behaviour_generation``, ``behaviour_xy`` (C, E, T+1, N, 2), ``occupancy_generation``,
    ``occupancy_count`` (M, E, P)). ``every`` thins the per-generation series (the last generation is always
    kept); ``steps`` adds the final team's episodes on the ``step`` timeline.
    """
    import rerun as rr

    path = Path(path)
    series = tuple(s for s in series if s.name in result)
    last = len(result["score"]) - 1
    rec = rr.RecordingStream("rovermarl", recording_id=recording_id or path.parent.name)
    # To memory, the driver writing the file: an I/O error is then an OSError (Rerun's own file sink blocks for ever
    # in its flush on a full disk). drain() encodes what was sent (the SDK's batches stay small); there is one read,
    # at the end, as each read is a whole .rrd (header and footer) of its own.
    stream = rec.binary_stream()
    try:
        def drain() -> None:
            stream.flush(timeout_sec=FLUSH_S)
        vmax = occupancy_vmax(result)
        rec.send_blueprint(blueprint(world, series, last, _ranges(result, series), vmax), make_active=True,
                           make_default=True)
        _scene(rec, rr, world)
        _occupancy(rec, rr, result, world, last, vmax)
        drain()
        _metrics(rec, rr, result, series, every, drain)
        _trajectories(rec, rr, result, steps)
        if steps:
            _moving_pois(rec, rr, result, world)
        rec.log("legend", rr.TextDocument(legend(world, series, vmax), media_type="text/markdown"), static=True)
        data = stream.read(flush=True, flush_timeout_sec=FLUSH_S)
        with atomic_open(path) as f:
            f.write(data or b"")
    finally:
        rec.disconnect()
    return path


# ---- layout ----------------------------------------------------------------------------------------------------

def world_bounds(world) -> float:
    """Half-width of the 2-D view: the POI circle, its observation discs and room for the labels outside them."""
    return float(world.poi_distance + world.obs_radius + 4.0)


def poi_labels(world) -> list[str]:
    """``POI j``, with the coupling when the POIs do not all need one rover."""
    mixed = any(c != 1 for c in world.coupling)
    return [f"POI {j} (c={c})" if mixed else f"POI {j}" for j, c in enumerate(world.coupling)]


def _in_score_view(s) -> bool:
    return s.shape == () and s.name.endswith("score")


def blueprint(world, series=(), last: int = 0, ranges=None, vmax: float = 1.0):
    """The layout of a run's recording (see the module doc): ``last`` is the run's last generation, ``ranges``
    maps entity paths to fixed y ranges, ``vmax`` is the top of the occupancy colour scale."""
    import rerun.blueprint as rrb

    ranges = ranges or {}
    b = world_bounds(world)
    bounds = rrb.VisualBounds2D(x_range=[-b, b], y_range=[-b, b])
    scene = ["/world/pois", "/world/poi_labels", "/world/poi_radius", "/world/start_boxes"]
    span = rrb.TimeAxis(view_range=rrb.TimeRange(start=rrb.TimeRangeBoundary.absolute(0),
                                                 end=rrb.TimeRangeBoundary.absolute(max(last, 1))))
    left = rrb.Tabs(
        rrb.Spatial2DView(name="episode 0", origin="/", contents=[*scene, "/world/episodes/0/**"],
                          visual_bounds=bounds),
        rrb.Spatial2DView(name="all episodes", origin="/", contents="/world/**", visual_bounds=bounds),
        rrb.TensorView(name="occupancy per episode", origin="/occupancy/count",
                       scalar_mapping=rrb.TensorScalarMapping(colormap="Viridis"), view_fit="Fill"),
        rrb.TextDocumentView(name="legend", origin="/legend"),
        active_tab=0,
    )
    score = rrb.TimeSeriesView(name="score (line) and child scores (dots)", origin="/metrics",
                               contents=["/metrics/score", *(f"/{s.path}" for s in series if _in_score_view(s))],
                               axis_x=span, plot_legend=rrb.PlotLegend(corner="RightBottom"))
    scalars = [rrb.TimeSeriesView(name=_title(s), origin=f"/{s.path}", axis_x=span,
                                  axis_y=rrb.ScalarAxis(range=ranges[s.path]) if s.path in ranges else None,
                                  plot_legend=rrb.PlotLegend(visible=False))
               for s in series if s.shape == () and not _in_score_view(s)]
    vectors = [rrb.TimeSeriesView(name=_title(s), origin=f"/{s.path}", axis_x=span,
                                  plot_legend=rrb.PlotLegend(corner="LeftTop"))
               for s in series if s.shape != ()]
    middle = [rrb.Tabs(*scalars, active_tab=0)] if scalars else []
    occupancy = rrb.TimeSeriesView(name=f"POI occupancy, lane j = POI j: mean rovers there at episode end, "
                                        f"dark 0 to yellow {vmax:.3g}",
                                   origin="/occupancy", contents=["/occupancy/**", "- /occupancy/count"], axis_x=span,
                                   axis_y=rrb.ScalarAxis(range=(-0.6, world.n_pois - 0.4), zoom_lock=True),
                                   plot_legend=rrb.PlotLegend(visible=False))
    right = rrb.Vertical(score, rrb.Horizontal(*middle, *vectors), occupancy, row_shares=[3, 2, 3]) \
        if middle or vectors else rrb.Vertical(score, occupancy, row_shares=[1, 1])
    return rrb.Blueprint(
        rrb.Horizontal(left, right, column_shares=[5, 6]),
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
        rrb.TimePanel(state="collapsed", timeline="generation"),
        auto_views=False,
    )


def _title(s) -> str:
    doc = s.doc.split("(")[0].strip()
    if doc and len(doc) <= 24:
        return f"{s.name}: {doc}"
    return s.name if s.path == f"metrics/{s.name}" else f"{s.name} ({s.path})"


def legend(world, series=(), vmax: float = 1.0) -> str:
    """The markdown of the ``legend`` tab."""
    rovers = ", ".join(f"rover {i} {palette.rover_hex(i)}" for i in range(world.n_rovers))
    pois = ", ".join(f"coupling {c}: {palette.poi_hex(c)}" for c in sorted(set(world.coupling)))
    lines = [
        "## rovermarl run",
        f"- **World** (y up, world units): {world.n_pois} POIs on a circle of radius {world.poi_distance:g}; "
        f"rings: observation radius {world.obs_radius:g}. POI colours by coupling: {pois}.",
        f"- **Rovers**: {rovers} (matplotlib's C0, C1, ...); small squares: start boxes. Lines: the trajectories "
        "of the team at the time cursor (generation 0, every accepted score change, the last generation); dots: "
        "where each rover ends.",
        "- **One episode or all**: the tabs *episode 0* and *all episodes*. For another episode, "
        "open the blueprint panel, select the view and add `/world/episodes/<e>/**` to its entity query.",
        "- **Final team, step by step**: choose the `step` timeline in the time panel and press play.",
        f"- **POI occupancy**: lane j is POI j; its colour is the mean number of rovers within the observation "
        f"radius at the end of an episode (over the {world.episodes} episodes): viridis, dark 0 to yellow "
        f"{vmax:.3g} or more. Tab *occupancy per episode*: the counts at the time cursor.",
        "- **Score**: team score F after each generation (line) and the score of each evaluated child (dots).",
    ]
    lines += [f"- **{s.name}** (`{s.path}`): {s.doc}" for s in series if s.doc]
    return "\n".join(lines) + "\n"


# ---- data ------------------------------------------------------------------------------------------------------

def _scene(rec, rr, world) -> None:
    colors = palette.poi_rgb(np.array(world.coupling))
    rec.log("world", rr.Transform3D(scale=[1.0, -1.0, 1.0]), static=True)      # y up on screen
    rec.log("world/pois", rr.Points2D(world.poi_positions(), radii=0.35, colors=colors, draw_order=40.0), static=True)
    out = world.poi_xy * (1 + (world.obs_radius + 0.9) / max(world.poi_distance, 1e-9))
    rec.log("world/poi_labels", rr.Points2D(out, radii=0.0, colors=colors, labels=poi_labels(world),
                                            show_labels=True), static=True)   # outside the rings
    theta = np.linspace(0, 2 * np.pi, 65)
    ring = world.obs_radius * np.stack([np.cos(theta), np.sin(theta)], axis=1)
    rec.log("world/poi_radius", rr.LineStrips2D([p + ring for p in world.poi_xy], colors=colors, radii=-1.5,
                                                draw_order=10.0), static=True)
    rec.log("world/start_boxes", rr.LineStrips2D(world.starts.start_squares, colors=palette.rover_rgb(world.n_rovers),
                                                 radii=-1.0, draw_order=20.0), static=True)
    world.log_static(rec)                                                        # a plug-in's own


def _columns(rr, generations) -> list:
    return [rr.TimeColumn("generation", sequence=np.asarray(generations, dtype=np.int64))]


SLICE = 20_000                                      # rows per send: the SDK's buffers stay small on long runs


def _send_scalars(rec, rr, entity: str, generations: np.ndarray, values: np.ndarray, drain) -> None:
    """``values`` (M,) at ``generations`` (M,) on the generation timeline, in slices written to the file one by one
    by ``drain()`` (one ``send_columns`` of a million rows holds several hundred MB in the SDK)."""
    for i in range(0, len(generations), SLICE):
        rec.send_columns(entity, indexes=_columns(rr, generations[i:i + SLICE]),
                         columns=rr.Scalars.columns(scalars=np.asarray(values[i:i + SLICE], dtype=np.float64)))
        drain()


def _kept(s, values: np.ndarray) -> np.ndarray:
    """Rows whose value is not the series' not-computed marker (a non-zero ``fill``: -1, nan)."""
    fill = float(s.fill)
    if np.isnan(fill):
        return ~np.isnan(values)
    if fill != 0:
        return values != fill
    return np.ones(len(values), dtype=bool)


def _metrics(rec, rr, result, series, every, drain) -> None:
    score = np.asarray(result["score"], dtype=np.float64)
    last = len(score) - 1
    gens = np.unique(np.r_[np.arange(0, last + 1, every), last])
    rec.log("metrics/score", rr.SeriesLines(names="score", colors=palette.rgb(palette.SCORE), widths=2.0,
                                            interpolation_mode="StepAfter"), static=True)
    _send_scalars(rec, rr, "metrics/score", gens, score[gens], drain)
    after = gens[gens >= 1]                                              # generation g's entry: index g - 1
    for s in series:
        values = np.asarray(result[s.name])[after - 1]
        if s.shape == ():
            _one_series(rec, rr, s, s.path, s.name, after, values, palette.series_hex(s.name), drain)
        else:
            for c, column in enumerate(s.columns or [str(c) for c in range(s.shape[0])]):
                _one_series(rec, rr, s, f"{s.path}/{column}", column, after, values[:, c], palette.rover_hex(c),
                            drain)


def _one_series(rec, rr, s, entity, name, gens, values, colour, drain) -> None:
    keep = _kept(s, values.astype(np.float64))
    if np.dtype(s.dtype).kind == "f":                    # one sample per generation: dots
        style = rr.SeriesPoints(names=name, colors=palette.rgb(colour), marker_sizes=1.5)
    else:                                                 # counts and flags hold until the next generation
        style = rr.SeriesLines(names=name, colors=palette.rgb(colour), widths=1.5, interpolation_mode="StepAfter",
                               aggregation_policy="Average")         # zoomed out: the mean over each pixel
    rec.log(entity, style, static=True)
    if keep.any():
        _send_scalars(rec, rr, entity, gens[keep], values[keep], drain)


def occupancy_vmax(result) -> float:
    """Top of the occupancy colour scale: the largest mean number of rovers at a POI, at least 1 (as the figure)."""
    count = np.asarray(result["occupancy_count"])
    return float(max(1.0, count.mean(axis=1).max())) if count.size else 1.0


def _ranges(result, series) -> dict:
    """Fixed y ranges of the integer and flag series: their values +- 0.5 (bools: -0.1..1.1)."""
    out = {}
    for s in series:
        kind = np.dtype(s.dtype).kind
        if s.shape == () and kind in "biu":
            v = np.asarray(result[s.name]).astype(np.float64)
            v = v[_kept(s, v)]
            if kind == "b":
                out[s.path] = (-0.1, 1.1)
            elif v.size:
                out[s.path] = (float(v.min()) - 0.5, float(v.max()) + 0.5)
    return out


def _occupancy(rec, rr, result, world, last, vmax) -> None:
    """Log the occupancy lanes (colours on the scale 0..``vmax``) and the per-episode count tensors."""
    gens, count = np.asarray(result["occupancy_generation"]), np.asarray(result["occupancy_count"])
    if len(gens) == 0:
        return
    mean = count.mean(axis=1)                                            # (M, P) mean rovers per POI
    hold = gens
    if gens[-1] < last:                                                  # the last value holds until the end
        hold, mean = np.r_[gens, last], np.vstack([mean, mean[-1:]])
    width = float(np.clip(150.0 / world.n_pois, 4.0, 16.0))
    for j, c in enumerate(world.coupling):
        rec.log(f"occupancy/poi_{j}", rr.SeriesLines(names=f"POI {j} (c={c})", widths=width,
                                                     interpolation_mode="StepAfter"), static=True)
        rec.send_columns(f"occupancy/poi_{j}", indexes=_columns(rr, hold),
                         columns=[*rr.Scalars.columns(scalars=np.full(len(hold), float(j))),
                                  *rr.SeriesLines.columns(colors=palette.occupancy_rgb(mean[:, j], vmax))])
    for g, c in zip(gens, count, strict=True):                           # colour range 0..N, not the int8 range
        rec.set_time("generation", sequence=int(g))
        rec.log("occupancy/count", rr.Tensor(c, dim_names=["episode", "poi"], value_range=(0, world.n_rovers)))
    rec.reset_time()


def _trajectories(rec, rr, result, steps) -> None:
    gens, xy = result["behaviour_generation"], result["behaviour_xy"]       # xy (C, E, T+1, N, 2)
    if len(gens) == 0:
        return
    c, n_ep, t1, n = xy.shape[:4]
    colors = np.tile(palette.rover_rgb(n), (c, 1))
    generation = _columns(rr, gens)
    for e in range(n_ep):                                                  # C rows of N lines each
        strips = xy[:, e].transpose(0, 2, 1, 3).reshape(c * n, t1, 2)
        rec.send_columns(f"world/episodes/{e}/trajectories", indexes=generation,
                         columns=rr.LineStrips2D.columns(strips=strips, colors=colors).partition([n] * c))
        rec.send_columns(f"world/episodes/{e}/ends", indexes=generation,
                         columns=rr.Points2D.columns(positions=xy[:, e, -1].reshape(c * n, 2), colors=colors,
                                                     radii=np.full(c * n, 0.3)).partition([n] * c))
    if steps:                                                              # the final team, step by step
        for e in range(n_ep):
            _on_steps(rec, rr, f"world/episodes/{e}/rovers", xy[-1, e], palette.rover_rgb(n), 0.3)


def _moving_pois(rec, rr, result, world) -> None:
    """The POIs of each episode where they are at each step (``World.poi_track``), for a world whose POIs move."""
    layout = result.get("ic_layout")
    if layout is None or len(layout) == 0 or world.poi_track(layout[0]) is None:
        return
    colors = palette.poi_rgb(np.array(world.coupling))
    for e in range(len(layout)):
        _on_steps(rec, rr, f"world/episodes/{e}/pois", world.poi_track(layout[e]), colors, 0.35)


def _on_steps(rec, rr, entity: str, points: np.ndarray, colors, radius: float) -> None:
    """``points`` (T+1, K, 2) on the ``step`` timeline: K points, in ``colors`` (K, 3), at each step."""
    t1, k = points.shape[:2]
    rec.send_columns(entity, indexes=[rr.TimeColumn("step", sequence=np.arange(t1))],
                     columns=rr.Points2D.columns(positions=points.reshape(t1 * k, 2), colors=np.tile(colors, (t1, 1)),
                                                 radii=np.full(t1 * k, radius)).partition([k] * t1))
