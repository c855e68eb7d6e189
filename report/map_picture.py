"""The map under the page's drawings (``report.html``): a grey PNG of the free space with its
extent [m], drawn with Pillow straight from the map's data (no matplotlib, so that the page of
a run costs milliseconds, not the second that importing and laying out matplotlib takes).

It shows what :meth:`pushtrain.facility.free_space.World.plot` shows in ``map.png``:

* a map of polygons: the free space light (``#f4f4f4``) and everything else in its bounds,
  padded by 5 %, dark (``#606060``); each polygon is filled with Pillow's scan-line filler, its
  holes dark again;
* an occupancy grid: the map image's grey levels (free light, unknown mid grey, occupied dark,
  as :meth:`~pushtrain.facility.occupancy_grid.MapImage.shade`) where the image is axis-aligned,
  with the cells the polygons drawn on top block (:meth:`~pushtrain.facility.occupancy_grid.
  OccupancyGrid.burn`) dark; a rotated map shows the planner's axis-aligned grid (blocked dark,
  free light), which is what the planner saw. A picture larger than ``pixels`` is reduced by a
  whole factor, each pixel the darkest of those it stands for (a wall one pixel thin stays).
"""

from __future__ import annotations

import base64
import io
import math

import numpy as np

__all__ = ["map_picture", "FREE_GREY", "OBSTACLE_GREY"]

FREE_GREY = 0xF4
"""Grey level of the free space (``#f4f4f4``, as ``World.plot``)."""
OBSTACLE_GREY = 0x60
"""Grey level of walls and obstacles (``#606060``)."""


def _png(grey: np.ndarray) -> str:
    """``grey`` (rows top first, uint8) as a base64 PNG."""
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(grey, dtype=np.uint8), mode="L").save(
        buf, format="PNG", compress_level=1)  # maps are flat: level 1 is small too
    return base64.b64encode(buf.getvalue()).decode("ascii")


def _reduced(grey: np.ndarray, pixels: int) -> tuple[np.ndarray, int]:
    """``grey`` reduced by the smallest whole factor k that brings it within ``pixels`` on
    its longest side, each pixel the darkest of its k x k block (the edge repeated to fill)."""
    height, width = grey.shape
    k = max(1, math.ceil(max(height, width) / pixels))
    if k == 1:
        return grey, 1
    padded = np.pad(grey, ((0, -height % k), (0, -width % k)), mode="edge")
    return padded.reshape(padded.shape[0] // k, k, padded.shape[1] // k, k).min(axis=(1, 3)), k


def _grid_picture(grid, pixels: int) -> dict:
    """The picture of an occupancy grid (module docstring) with its extent."""
    image = getattr(grid, "image", None)
    blocked = np.asarray(grid.blocked, dtype=bool)[::-1]  # rows top first
    aligned = (image is not None and image.shape == blocked.shape
               and abs(math.remainder(float(image.origin[2]), 2.0 * math.pi)) <= 1e-9)
    if aligned:
        grey = np.round(image.shade() * 255.0).astype(np.uint8)
        grey[blocked & image.free] = OBSTACLE_GREY  # burned in by polygons
    else:
        grey = np.where(blocked, 0x40, FREE_GREY).astype(np.uint8)
    grey, k = _reduced(grey, pixels)
    xmin, _, _, ymax = grid.bounds
    h = grid.resolution * k
    rows, cols = grey.shape
    return {"png": _png(grey), "extent": [xmin, xmin + cols * h, ymax - rows * h, ymax]}


def _polygons_picture(world, pixels: int) -> dict:
    """The picture of a map of polygons (module docstring) with its extent."""
    from PIL import Image, ImageDraw
    from shapely.geometry import Polygon

    xmin, ymin, xmax, ymax = world.outline.bounds
    pad = 0.05 * max(xmax - xmin, ymax - ymin, 1e-9)
    extent = [xmin - pad, xmax + pad, ymin - pad, ymax + pad]
    w_m, h_m = extent[1] - extent[0], extent[3] - extent[2]
    scale = pixels / max(w_m, h_m)  # [px/m]
    width, height = max(1, round(w_m * scale)), max(1, round(h_m * scale))
    picture = Image.new("L", (width, height), OBSTACLE_GREY)
    draw = ImageDraw.Draw(picture)

    def pixel_ring(ring) -> list[tuple[float, float]]:
        xy = np.asarray(ring.coords, dtype=float)[:, :2]
        u = (xy[:, 0] - extent[0]) * scale - 0.5
        v = (extent[3] - xy[:, 1]) * scale - 0.5
        return list(zip(u.tolist(), v.tolist(), strict=True))

    free = world.free
    pieces = [p for p in getattr(free, "geoms", [free])
              if isinstance(p, Polygon) and not p.is_empty]
    # the largest first: a piece inside another's hole is drawn after that hole
    pieces.sort(key=lambda p: -p.envelope.area)
    for poly in pieces:
        draw.polygon(pixel_ring(poly.exterior), fill=FREE_GREY)
        for hole in poly.interiors:
            draw.polygon(pixel_ring(hole), fill=OBSTACLE_GREY)
    return {"png": _png(np.asarray(picture)), "extent": extent}


def map_picture(world, pixels: int = 2400) -> dict:
    """``{"png": base64 PNG, "extent": [xmin, xmax, ymin, ymax] (m)}`` of ``world``'s map,
    at most ``pixels`` on its longest side."""
    grid = world.occupancy
    if grid is not None and hasattr(grid, "blocked") and hasattr(grid, "bounds"):
        return _grid_picture(grid, pixels)
    return _polygons_picture(world, pixels)
