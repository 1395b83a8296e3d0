"""Drawing primitives shared by the figure modules: bare figures, downsampled lines, rover scenes, atomic saving.

Figures are bare :class:`~matplotlib.figure.Figure` objects on the Agg canvas (no pyplot state). Colours come from
:mod:`rovermarl.palette`: rover ``i`` is ``C{i}``, a POI is coloured by its coupling.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Circle, Patch

from rovermarl.env import World
from rovermarl.palette import POI_BY_COUPLING, poi_hex, rover_hex
from rovermarl.record.outputs import atomic_open

MAX_POINTS = 2000
POI_ALPHA = 0.3


def new_figure(width: float, height: float) -> Figure:
    fig = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def panels(n: int, top_height: float = 1.4, max_cols: int = 4) -> tuple[Figure, object, list]:
    """A figure with a wide top axis and ``n`` panels below it (rows of at most ``max_cols``, shared y)."""
    cols = max(1, min(n, max_cols))
    rows = math.ceil(n / cols)
    fig = new_figure(3.2 * cols + 0.6, 2.9 * top_height + 2.5 * rows)
    grid = fig.add_gridspec(1 + rows, cols, height_ratios=[top_height] + [1] * rows)
    top = fig.add_subplot(grid[0, :])
    bottom: list = []
    for i in range(n):
        bottom.append(fig.add_subplot(grid[1 + i // cols, i % cols], sharey=bottom[0] if bottom else None))
    return fig, top, bottom


def downsample(y: np.ndarray, max_points: int = MAX_POINTS) -> tuple[np.ndarray, np.ndarray]:
    """(x, y[x]) with at most ``max_points`` points: exact for step curves with few steps, else evenly spaced."""
    y = np.asarray(y)
    n = len(y)
    if n <= max_points:
        return np.arange(n), y
    steps = np.flatnonzero(np.diff(y) != 0)
    if 2 * steps.size + 2 <= max_points:
        x = np.unique(np.concatenate([[0, n - 1], steps, steps + 1]))
    else:
        x = np.unique(np.linspace(0, n - 1, max_points).round().astype(np.int64))
    return x, y[x]


def line(ax, y, x=None, **kw) -> None:
    """Plot y (G,) against 0..G-1 (downsampled), or against the given x (M,) as is."""
    if x is None:
        x, y = downsample(y)
    ax.plot(x, y, **kw)


def scene(ax, world: World, xy: np.ndarray, lim: float, lw: float, ms: float, alpha: float | None = None,
          layout: np.ndarray | None = None) -> None:
    """The world's POIs (discs of the observation radius, coloured by coupling; ``World.poi_positions`` of the
    episode ``layout`` (K,)), what a world plug-in draws (``World.draw``) and rover paths xy (E, T+1, N, 2) of E
    episodes overlaid (each path ends in a dot, in the rover's colour), on a bare square of half-width ``lim``."""
    for (px, py), c in zip(world.poi_positions(layout), world.coupling, strict=True):
        colour = poi_hex(c)
        ax.add_patch(Circle((px, py), world.obs_radius, fc=colour, ec=colour, alpha=POI_ALPHA))
    world.draw(ax, layout)
    for episode in xy:
        for i in range(episode.shape[1]):
            ax.plot(episode[:, i, 0], episode[:, i, 1], color=rover_hex(i), lw=lw, alpha=alpha)
            ax.plot(episode[-1, i, 0], episode[-1, i, 1], "o", color=rover_hex(i), ms=ms)
    ax.set(xlim=(-lim, lim), ylim=(-lim, lim), aspect="equal", xticks=[], yticks=[])


def poi_handles(world: World) -> list:
    """Legend entries of the POI colours of the paper's couplings present in ``world``."""
    return [Patch(color=colour, alpha=POI_ALPHA, label=f"POI c={c}") for c, colour in POI_BY_COUPLING.items()
            if c in world.coupling]


def rover_handles(n: int) -> list:
    """Legend entries of rovers 0..n-1."""
    return [Line2D([], [], color=rover_hex(i), label=f"rover {i}") for i in range(n)]


def save(fig: Figure, out: Path, name: str, formats: Sequence[str]) -> list[str]:
    """Write ``fig`` as ``out/name.<fmt>`` for each format, atomically; returns the file names."""
    files = []
    for fmt in formats:
        with atomic_open(Path(out) / f"{name}.{fmt}", "wb") as f:
            fig.savefig(f, format=fmt, dpi=150)
        files.append(f"{name}.{fmt}")
    return files
