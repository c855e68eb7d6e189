"""The page's map picture (report/map_picture.py, Pillow, no matplotlib) shows the free space
where the planner's map has it: checked against shapely's point-in-polygon test for a map of
polygons and against the planner's blocked cells for an occupancy grid."""

import base64
import io
from pathlib import Path

import numpy as np
import shapely
from PIL import Image

from pushtrain.mission.runner import world_of
from pushtrain.mission.scenario import load_scenario
from pushtrain.report.map_picture import FREE_GREY, map_picture

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def _grey(picture: dict) -> np.ndarray:
    with Image.open(io.BytesIO(base64.b64decode(picture["png"]))) as image:
        assert image.mode == "L"
        return np.asarray(image)


def test_a_map_of_polygons_is_light_exactly_where_it_is_free():
    world = world_of(load_scenario(str(EXAMPLES / "floor_dxf.toml")))
    picture = map_picture(world, pixels=600)
    grey = _grey(picture)
    x0, x1, y0, y1 = picture["extent"]
    rows, cols = grey.shape
    scale = cols / (x1 - x0)
    assert abs(rows / (y1 - y0) - scale) < 0.01 * scale  # square pixels
    r, c = np.mgrid[0:rows, 0:cols]
    x, y = x0 + (c + 0.5) / scale, y1 - (r + 0.5) / scale
    free = shapely.contains_xy(world.free, x, y)
    # pixels whose centre is within 1.5 px of a wall may go either way
    near = shapely.dwithin(world.free.boundary, shapely.points(x, y), 1.5 / scale)
    assert (~near).sum() > 0.9 * grey.size
    assert np.array_equal((grey == FREE_GREY)[~near], free[~near])


def test_an_occupancy_grid_is_dark_exactly_on_the_planners_blocked_cells():
    world = world_of(load_scenario(str(EXAMPLES / "warehouse_grid.toml")))
    grid = world.occupancy
    picture = map_picture(world, pixels=10_000)  # no reduction: one pixel a cell
    grey = _grey(picture)
    assert grey.shape == grid.blocked.shape
    assert np.array_equal(grey < 240, grid.blocked[::-1])  # row 0 of the picture is the top
    assert picture["extent"] == [grid.bounds[0], grid.bounds[2], grid.bounds[1], grid.bounds[3]]
    reduced = map_picture(world, pixels=100)  # reduced: a wall stays (darkest of its block)
    k = -(-max(grid.blocked.shape) // 100)
    assert _grey(reduced).shape == tuple(-(-s // k) for s in grid.blocked.shape)
    assert (_grey(reduced) < 240).mean() >= grid.blocked.mean()
