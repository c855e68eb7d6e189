"""atlas.png and matrix.png (:mod:`pushtrain.report.atlas`): the matrix's cell in row A and
column B holds the answer from A to B, read back from the PNG's pixels and from its labels."""

from __future__ import annotations

import numpy as np
from matplotlib import colormaps
from matplotlib.colors import to_rgb
from PIL import Image

from pushtrain.report.atlas import matrix_figure, save_figure

NAMES = ["dock", "bay", "hall"]
ANSWERS = {("dock", "bay"): 0, ("dock", "hall"): 3, ("bay", "dock"): 4, ("bay", "hall"): 1,
           ("hall", "dock"): 2, ("hall", "bay"): 5}  # no two mirrored cells equal
TOP = 5


def _color(n: int):
    """The documented colours: grey for no trailer, then viridis (reversed), light to dark."""
    if n == 0:
        return np.array(to_rgb("#9a9a9a"))
    return np.array(colormaps["viridis_r"].resampled(TOP + 1)(n)[:3])


def test_matrix_png_has_the_answer_from_row_to_column(tmp_path):
    answers = [{"from": a, "to": b, "max_trailers": k} for (a, b), k in ANSWERS.items()]
    fig = matrix_figure(NAMES, answers, TOP)
    png = save_figure(fig, tmp_path / "matrix.png")
    pixels = np.asarray(Image.open(png).convert("RGB"), dtype=float) / 255.0
    ax = fig.axes[0]
    height = pixels.shape[0]
    assert (pixels.shape[1], height) == tuple(int(v) for v in fig.canvas.get_width_height())
    labels = {(round(t.get_position()[1]), round(t.get_position()[0])): t.get_text()
              for t in ax.texts}
    ylabels = [t.get_text() for t in ax.get_yticklabels()]
    xlabels = [t.get_text() for t in ax.get_xticklabels()]
    assert ylabels == NAMES and xlabels == NAMES
    for (a, b), k in ANSWERS.items():
        row, col = NAMES.index(a), NAMES.index(b)  # rows: from; columns: to
        x, y = ax.transData.transform((col + 0.3, row + 0.3))  # off the centre's number
        got = pixels[int(round(height - y)), int(round(x))]
        assert np.abs(got - _color(k)).max() < 0.03, (a, b, k, got)
        assert labels[(row, col)] == str(k)
    for k in range(len(NAMES)):
        assert labels[(k, k)] == "-"
