"""What every figure of :mod:`pushtrain.report` shares: resolution and colours, argument checks,
access to the columns of ``Result.data``, new figures and atomic saving.

Nothing here imports pyplot: figures use the Agg canvas directly, so they never reach a GUI and
the global pyplot state is untouched.
"""

from __future__ import annotations

import logging
import warnings
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib import colormaps
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.cm import ScalarMappable
from matplotlib.colors import BoundaryNorm, LinearSegmentedColormap, ListedColormap
from matplotlib.figure import Figure
from matplotlib.layout_engine import ConstrainedLayoutEngine

from pushtrain.errors import PlotError
from pushtrain.files import atomic_write
from pushtrain.report.data import col

log = logging.getLogger(__name__)

__all__ = [
    "DPI",
    "GIF_DPI",
    "C_ROBOT",
    "C_LAST",
    "C_REF",
    "C_PATH",
    "C_SLIP",
    "C_JACK",
    "C_DIST",
    "DIRECTION_BANDS",
    "SNAPSHOT_CMAP",
    "output_path",
    "atomic",
    "save",
    "new_figure",
    "add_note",
    "legend_place",
    "nothing_to_draw",
    "series_colors",
    "index_colorbar",
    "intervals",
    "disturbance_mask",
    "shade",
]

DPI = 120
"""Resolution of the PNG figures [dots per inch]."""

GIF_DPI = 80
"""Resolution of the animation frames [dots per inch] (kept low so 150 frames render in seconds)."""

# colours shared by the figures
C_ROBOT = "tab:red"
C_LAST = "tab:blue"
C_REF = "black"
C_PATH = "0.55"
C_SLIP = "tab:orange"
C_JACK = "magenta"
C_DIST = "tab:red"
DIRECTION_BANDS = ((1, "#d5e5f6", "push (trailer first)"), (-1, "#fbe0c3", "pull (robot first)"),
                   (0, "#e6e6e6", "rest"))
"""(direction value, background colour, legend label) of the reference's direction bands."""
SNAPSHOT_CMAP = LinearSegmentedColormap.from_list("snapshot_fade", ["#b9c8d8", "#17324d"])
"""Train snapshots fade from light (early) to dark (late)."""


# ---------------------------------------------------------------------------------------------
# figures and files
# ---------------------------------------------------------------------------------------------
def output_path(out_path, allowed: Sequence[str] | None = None) -> Path:
    """``out_path`` as a Path whose suffix names a format this package can write."""
    path = Path(out_path)
    fmt = path.suffix.lower().lstrip(".")
    if allowed is None:
        allowed = sorted(FigureCanvasAgg(Figure()).get_supported_filetypes())
    if fmt not in allowed:
        raise PlotError(f"out_path = {str(out_path)!r}: the suffix must be one of "
                        f"{', '.join('.' + a for a in allowed)}")
    return path


def atomic(path: Path, write) -> Path:
    """Call ``write(partial)`` on a temporary name in ``path``'s folder, then rename it to ``path``.

    The temporary name keeps the suffix (matplotlib and Pillow choose the format by it); it is
    removed whatever happens, so a failure leaves neither a partial file nor a changed ``path``.
    """
    path.parent.mkdir(parents=True, exist_ok=True)
    return atomic_write(path, write, keep_suffix=True)


def save(fig: Figure, out_path, dpi: float = DPI) -> Path:
    """Save ``fig`` atomically in the format named by the suffix of ``out_path``.

    The layout is computed once, then fixed (the engine removed): ``savefig`` on a figure with
    a layout engine draws it twice (once without pixels) and lays it out before each draw, for
    the same picture.
    """
    path = output_path(out_path)
    fmt = path.suffix.lower().lstrip(".")
    with warnings.catch_warnings(record=True) as caught:  # to the log, not the user's terminal
        warnings.simplefilter("always")
        engine = fig.get_layout_engine()
        if engine is not None and dpi == fig.dpi:
            engine.execute(fig)
            fig.set_layout_engine(None)
        atomic(path, lambda partial: fig.savefig(partial, format=fmt, dpi=dpi))
    for w in caught:  # e.g. a layout that cannot fit a long legend: the picture is still made
        log.info("%s: %s: %s", path.name, w.category.__name__, w.message)
    return path


def add_note(fig: Figure, note: str) -> None:
    """``note`` in red under ``fig``'s axes (wrapped to the figure's width), with room made
    for it by the layout (a figure-level x label)."""
    import textwrap

    width = max(40, int(fig.get_figwidth() * 15))
    fig.supxlabel("\n".join(textwrap.wrap(note, width)[:6]), fontsize=8, color="tab:red")


def nothing_to_draw(out_path, what: str, note: str | None = None) -> Path:
    """A small picture at ``out_path`` (PNG, or a one-frame GIF) saying ``what`` could not be
    drawn and why (and ``note``): the file a run names exists and says what happened."""
    import textwrap

    fig = Figure(figsize=(6.0, 2.0), dpi=DPI)  # no layout: there are no axes
    FigureCanvasAgg(fig)
    text = "\n".join(textwrap.wrap(what, 70) + (textwrap.wrap(note, 80)[:6] if note else []))
    fig.text(0.5, 0.5, text, ha="center", va="center", fontsize=9, color="tab:red")
    path = Path(out_path)
    if path.suffix.lower() != ".gif":
        return save(fig, path)
    from PIL import Image

    fig.canvas.draw()
    image = Image.fromarray(np.asarray(fig.canvas.buffer_rgba())[..., :3])
    return atomic(path, lambda partial: image.save(partial, format="GIF"))


_LEGEND_PLACES = ((1.0, 1.0, "upper right"), (0.0, 1.0, "upper left"), (0.0, 0.0, "lower left"),
                  (1.0, 0.0, "lower right"), (1.0, 0.5, "center right"),
                  (0.0, 0.5, "center left"), (0.5, 0.0, "lower center"),
                  (0.5, 1.0, "upper center"))


def legend_place(ax, size: tuple[float, float] = (0.4, 0.3), most: int = 2000) -> str:
    """Where a legend of about ``size`` (fractions of the axes' width and height) hides the
    fewest points of ``ax``'s lines: matplotlib's ``loc="best"`` rule (the first of its places
    with the fewest points under the box), counted on at most ``most`` points a line. With
    25,000-row lines matplotlib's own count took 0.1-0.2 s a figure; this takes milliseconds.
    """
    ax.get_xlim(), ax.get_ylim()  # the limits, autoscaled to the data now
    to_axes = ax.transAxes.inverted()
    us, vs = [], []
    for line in ax.get_lines():  # in axes fractions (an axhline's x is one already)
        xy = np.asarray(line.get_xydata(), dtype=float)
        xy = to_axes.transform(line.get_transform().transform(xy[::max(1, len(xy) // most)]))
        if len(xy) == 2 and line.get_transform() != ax.transData:  # a line across the axes
            xy = np.column_stack([np.linspace(xy[0, 0], xy[1, 0], 50),
                                  np.linspace(xy[0, 1], xy[1, 1], 50)])
        us.append(xy[:, 0])
        vs.append(xy[:, 1])
    if not us:
        return "upper right"
    u, v = np.concatenate(us), np.concatenate(vs)
    w, h = size
    counts = []
    for fx, fy, _name in _LEGEND_PLACES:
        left, bottom = fx * (1.0 - w), fy * (1.0 - h)
        counts.append(int(np.count_nonzero((u >= left) & (u <= left + w)
                                           & (v >= bottom) & (v <= bottom + h))))
    return _LEGEND_PLACES[int(np.argmin(counts))][2]


def new_figure(width: float, height: float, dpi: float = DPI, *,
               fixed_aspect: bool = False) -> Figure:
    """A ``width`` x ``height`` [in] Figure on an Agg canvas with constrained layout.

    ``fixed_aspect`` (for maps with equal axis scales) lets the layout compress the margins
    around axes that the aspect has shrunk (``compress=True``); without it the layout does not
    converge when a legend beside such axes is anchored to them, and on wide maps the y label
    and the legend end up outside the figure.
    """
    layout = ConstrainedLayoutEngine(compress=True) if fixed_aspect else "constrained"
    fig = Figure(figsize=(width, height), dpi=dpi, layout=layout)
    FigureCanvasAgg(fig)
    return fig


def series_colors(count: int, categorical: bool = True) -> list:
    """Colours of ``count`` series: tab10 when ``categorical`` and count <= 10, else viridis."""
    if categorical and count <= 10:
        return [colormaps["tab10"](k) for k in range(count)]
    return [colormaps["viridis"](v) for v in np.linspace(0.0, 0.9, count)]


def index_colorbar(fig, ax, colors: list, label: str) -> None:
    """A discrete colour bar mapping colors[k] to index k + 1."""
    count = len(colors)
    norm = BoundaryNorm(np.arange(0.5, count + 1.0), count)
    bar = fig.colorbar(ScalarMappable(norm=norm, cmap=ListedColormap(colors)), ax=ax, pad=0.01)
    bar.set_ticks(np.unique(np.linspace(1, count, min(count, 10)).round()))
    bar.set_label(label)


# ---------------------------------------------------------------------------------------------
# time intervals
# ---------------------------------------------------------------------------------------------
def intervals(t: np.ndarray, mask: np.ndarray) -> list[tuple[float, float]]:
    """Time intervals [s] where ``mask`` holds; each lasts until the next sample after it ends."""
    mask = np.asarray(mask, dtype=bool)
    if not mask.any():
        return []
    edges = np.diff(np.concatenate(([0], mask.astype(np.int8), [0])))
    starts = np.flatnonzero(edges == 1)
    stops = np.flatnonzero(edges == -1)  # first index after each run
    last = len(t) - 1
    return [(float(t[a]), float(t[min(b, last)])) for a, b in zip(starts, stops, strict=True)]


def disturbance_mask(data) -> np.ndarray:
    """Rows with an external push force or an imposed slide."""
    names = data.dtype.names
    mask = np.zeros(len(data), dtype=bool)
    for name in ("push_x", "push_y", "slide"):
        if name in names:
            mask |= np.abs(col(data, name)) > 0.0
    return mask


def shade(ax, spans, color, alpha, label=None, **kwargs) -> None:
    """Shade the time ``spans`` of ``ax``; only the first span carries ``label``."""
    for k, (a, b) in enumerate(spans):
        ax.axvspan(a, b, color=color, alpha=alpha, lw=0, label=label if k == 0 else None, **kwargs)
