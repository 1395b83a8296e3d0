"""Colours shared by the matplotlib figures and the Rerun recordings: one palette, one home.

Rovers take matplotlib's ``tab10`` cycle (rover ``i`` is ``C{i % 10}``); POIs are coloured by coupling, in hues
that no rover of a shipped world uses (coupling 2's purple is C4, but no world with five or more rovers has
coupling-2 POIs; three or more: a yellow outside the cycle, for the coupling family's 6-12 rovers), so a POI is never
mistaken for a rover. The Rerun plots add the score, series and occupancy colours below.

>>> rover_hex(1), poi_hex(2)
('#ff7f0e', '#9467bd')
"""

from __future__ import annotations

import numpy as np

TAB10 = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22",
         "#17becf")
POI_BY_COUPLING = {1: "#bcbd22", 2: "#9467bd"}   # tab:olive: one rover needed; tab:purple: two
POI_OTHER = "#f0e442"                              # yellow (Okabe-Ito), in no rover's cycle: three or more
OCCUPANCY = {1: "tab:red", 2: "tab:blue"}          # the paper's Fig. 6: POI observed by one rover, by two
OCCUPANCY_CMAP = "viridis"                         # mean rovers at a POI, 0 (dark) .. max (yellow)
SCORE = "#009e73"                                  # team score in the Rerun plots (legible on light and dark themes)
SERIES = {"child_score": "#999999"}                # other per-generation series in the Rerun plots; default below
SERIES_DEFAULT = "#0072b2"


def rover_hex(i: int) -> str:
    """Colour of rover ``i`` (matplotlib's ``C{i}``)."""
    return TAB10[i % len(TAB10)]


def poi_hex(coupling: int) -> str:
    """Colour of a POI that needs ``coupling`` rovers."""
    return POI_BY_COUPLING.get(int(coupling), POI_OTHER)


def rgb(hex_colour: str) -> tuple[int, int, int]:
    """``'#ff7f0e'`` -> ``(255, 127, 14)``."""
    return tuple(bytes.fromhex(hex_colour.lstrip("#")[:6]))


def rover_rgb(n: int) -> np.ndarray:
    """(n, 3) uint8: the colours of rovers 0..n-1."""
    return np.array([rgb(rover_hex(i)) for i in range(n)], dtype=np.uint8)


def poi_rgb(coupling) -> np.ndarray:
    """(P, 3) uint8: the colour of each POI from its coupling (P,)."""
    return np.array([rgb(poi_hex(c)) for c in coupling], dtype=np.uint8)


def series_hex(name: str) -> str:
    """Colour of the per-generation series ``name`` in the Rerun plots."""
    return SERIES.get(name, SERIES_DEFAULT)


def occupancy_rgb(values, vmax: float) -> np.ndarray:
    """(M, 3) uint8: :data:`OCCUPANCY_CMAP` colours of ``values`` (M,) on the scale 0..``vmax`` (clipped)."""
    from matplotlib import colormaps

    x = np.clip(np.asarray(values, dtype=np.float64) / vmax, 0.0, 1.0)
    return (colormaps[OCCUPANCY_CMAP](x)[:, :3] * 255).round().astype(np.uint8)
