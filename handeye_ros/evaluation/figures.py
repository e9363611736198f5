"""The canvas the report's figures share (:mod:`.plots`, :mod:`.rig_report`): matplotlib's
object API with the Agg canvas (no pyplot state, no display, safe in worker processes), and
lines thinned to what a plot can show.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:  # matplotlib is imported when a figure is drawn
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

#: Points per plotted line at most.
MAX_POINTS = 20_000
DPI = 110


def canvas(
    rows: int, cols: int = 1, height: float = 3.0, width: float = 9.0
) -> tuple[Figure, NDArray[np.object_]]:
    """A figure of rows x cols axes (always a 2-D array), ``height`` inches a row."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height * rows), dpi=DPI, layout='constrained')
    return fig, fig.subplots(rows, cols, squeeze=False)


def save(fig: Figure, path: Path) -> None:
    """Write the figure as a PNG."""
    fig.savefig(path, format='png')


def say_empty(ax: Axes, message: str) -> None:
    """Say in the plot why it has nothing to show."""
    ax.text(0.5, 0.5, message, ha='center', va='center', transform=ax.transAxes)


def thinned(n: int) -> slice:
    """Every k-th of n samples, so that a line has at most MAX_POINTS."""
    return slice(None, None, max(1, -(-n // MAX_POINTS)))
