"""Occupancy grids in the ROS map_server format: pixel values, thresholds, negate, modes, origin
and row order, rotated origins, polygons burned in, and the files' error messages."""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely
from PIL import Image
from shapely.affinity import rotate
from shapely.geometry import Point, box

from pushtrain.errors import MapError
from pushtrain.facility.loading import grid_world
from pushtrain.facility.map_server import load_map, occupancy_values, read_map_yaml

MAP_SAVER = {"resolution": 0.05, "origin": [0.0, 0.0, 0.0], "negate": 0,
             "occupied_thresh": 0.65, "free_thresh": 0.196}


def write_map(folder, pixels, name="map", image_name=None, **fields) -> str:
    """A map_server map in ``folder``: ``pixels`` (uint8, row 0 at the top; (H, W, C) for
    colour) saved as PGM/PNG, and the YAML with MAP_SAVER's fields updated by ``fields``."""
    image_name = image_name or f"{name}.pgm"
    Image.fromarray(np.asarray(pixels, dtype=np.uint8)).save(folder / image_name)
    data = {"image": image_name, **MAP_SAVER, **fields}
    lines = []
    for key, value in data.items():
        if value is not None:
            lines.append(f"{key}: {value}")
    path = folder / f"{name}.yaml"
    path.write_text("\n".join(lines) + "\n")
    return str(path)


# grey value -> what map_server makes of it with 0.65 / 0.196, by p = (255 - x) / 255 worked out
# by hand: 89 -> p = 0.6510 (> 0.65), 90 -> 0.6471, 205 -> 0.19608 (not < 0.196), 206 -> 0.1922
TRINARY = {0: 100, 50: 100, 89: 100, 90: -1, 127: -1, 204: -1, 205: -1, 206: 0, 254: 0, 255: 0}
# negate: p = x / 255: 166 -> 0.6510, 165 -> 0.6471, 50 -> 0.19608, 49 -> 0.1922
NEGATED = {0: 0, 49: 0, 50: -1, 165: -1, 166: 100, 255: 100}


@pytest.mark.parametrize("negate, expected", [(0, TRINARY), (1, NEGATED)])
def test_trinary_values_thresholds_and_negate(tmp_path, negate, expected):
    grey = np.array([list(expected)] * 2, dtype=np.uint8)   # two equal rows: at least 2 x 2
    path = write_map(tmp_path, grey, negate=negate)
    grid = load_map(path)
    values = grid.image.values[0].tolist()
    assert values == list(expected.values())
    # known free only: the grid's single row is the image's single row
    assert (~grid.blocked[0]).tolist() == [v == 0 for v in expected.values()]


def test_thresholds_are_read_from_the_file(tmp_path):
    grey = np.array([[100, 130, 160]] * 2, dtype=np.uint8)  # p = 0.608, 0.490, 0.373
    grid = load_map(write_map(tmp_path, grey, occupied_thresh=0.5, free_thresh=0.4))
    assert grid.image.values[0].tolist() == [100, -1, 0]


def test_scale_and_raw_modes_and_transparency():
    grey = np.array([[0.0, 128.0, 128.0, 250.0]])
    alpha = np.array([[255, 255, 0, 255]])
    values, free = occupancy_values(grey, alpha, False, 0.65, 0.196, "scale")
    # 128: p = 127/255 = 0.49804 -> 99 (0.49804 - 0.196) / (0.65 - 0.196) = 65.86 -> 66
    assert values[0].tolist() == [100, 66, -1, 0]
    assert free[0].tolist() == [False, False, False, True]
    raw, raw_free = occupancy_values(np.array([[0.0, 10.0, 20.0, 100.0, 255.0]]), None, False,
                                     0.65, 0.196, "raw")
    assert raw[0].tolist() == [0, 10, 20, 100, -1]  # above 100 is unknown
    assert raw_free[0].tolist() == [True, True, False, False, False]  # x / 100 < 0.196


def test_colour_images_are_averaged_without_alpha(tmp_path):
    rgba = np.zeros((2, 3, 4), dtype=np.uint8)
    rgba[:, 0] = (0, 255, 255, 10)      # mean 170: p = 0.333, unknown (alpha left out)
    rgba[:, 1] = (255, 255, 240, 255)   # mean 250: free
    rgba[:, 2] = (30, 30, 30, 255)      # occupied
    grid = load_map(write_map(tmp_path, rgba, image_name="map.png"))
    assert grid.image.values[0].tolist() == [-1, 0, 100]


def asymmetric_image():
    """A 4-row x 6-column map: free, with an L of occupied pixels in the top-left corner and an
    unknown pixel at the bottom right."""
    pixels = np.full((4, 6), 254, dtype=np.uint8)
    pixels[0, 0:3] = 0
    pixels[1, 0] = 0
    pixels[3, 5] = 205
    return pixels


def test_origin_resolution_and_row_0_is_the_top(tmp_path):
    h, ox, oy = 0.5, 10.0, -2.0
    grid = load_map(write_map(tmp_path, asymmetric_image(), resolution=h, origin=[ox, oy, 0.0]))
    # pixel (row r, column c) of a 4-row image: centre (ox + (c + .5) h, oy + (4 - r - .5) h)
    def centre(r, c):
        return ox + (c + 0.5) * h, oy + (4 - r - 0.5) * h

    assert grid.why_blocked(*centre(0, 0)) is not None       # top-left: occupied
    assert grid.why_blocked(*centre(1, 0)) is not None
    assert grid.why_blocked(*centre(3, 0)) is None            # bottom-left: free
    assert "unknown" in grid.why_blocked(*centre(3, 5))
    assert "outside the map image" in grid.why_blocked(ox - 0.1, oy + 1.0)
    assert grid.bounds == pytest.approx((ox, oy, ox + 6 * h, oy + 4 * h))
    # the distance field: the nearest blocked cell to pixel (1, 3) is the L's end (0, 2), one
    # cell up and one across: sqrt(2) cells between centres, less half a cell to its edge
    field = grid_world(grid).distance_field()
    assert field.at(*centre(1, 3)) == pytest.approx((math.sqrt(2.0) - 0.5) * h)
    assert field.at(*centre(0, 1)) < 0.0


def test_a_map_rotated_by_90_deg_gives_the_rotated_world(tmp_path):
    h, ox, oy = 0.5, 3.0, 1.0
    pixels = asymmetric_image()
    flat = grid_world(load_map(write_map(tmp_path, pixels, "flat", resolution=h,
                                         origin=[ox, oy, 0.0])))
    turned = grid_world(load_map(write_map(tmp_path, pixels, "turned", resolution=h,
                                           origin=[ox, oy, math.pi / 2])))
    # a point (u, v) of the map frame is (ox + u, oy + v) in the flat world and, turned by
    # 90 deg counter-clockwise about the origin, (ox - v, oy + u) in the turned one
    height, width = pixels.shape
    for r in range(height):
        for c in range(width):
            u, v = (c + 0.5) * h, (height - r - 0.5) * h
            a = flat.occupancy.why_blocked(ox + u, oy + v)
            b = turned.occupancy.why_blocked(ox - v, oy + u)
            assert (a is None) == (b is None) == (pixels[r, c] == 254), (r, c)
            assert turned.distance_field().at(ox - v, oy + u) == pytest.approx(
                flat.distance_field().at(ox + u, oy + v))
    expected = rotate(flat.free, 90.0, origin=(ox, oy))
    assert turned.free.symmetric_difference(expected).area < 1e-6
    corners = turned.occupancy.image.corners()
    assert corners[1] == pytest.approx([ox, oy + width * h])   # lower-right -> up the y axis


def test_a_map_at_any_yaw_is_resampled_by_nearest_neighbour(tmp_path):
    h, yaw = 0.1, 0.5
    pixels = np.full((30, 40), 254, dtype=np.uint8)
    pixels[10:14, 5:30] = 0                                   # a wall across the middle
    grid = load_map(write_map(tmp_path, pixels, resolution=h, origin=[1.0, 2.0, yaw]))
    # every new cell takes the pixel under its centre (worked out here with the rotation)
    xs, ys = grid.centres()
    X, Y = np.broadcast_arrays(xs, ys)
    c, s = math.cos(yaw), math.sin(yaw)
    u = c * (X - 1.0) + s * (Y - 2.0)
    v = -s * (X - 1.0) + c * (Y - 2.0)
    col, row = np.floor(u / h).astype(int), 29 - np.floor(v / h).astype(int)
    inside = (col >= 0) & (col < 40) & (row >= 0) & (row < 30)
    under = np.where(inside, pixels[row.clip(0, 29), col.clip(0, 39)] == 254, False)
    assert np.array_equal(~grid.blocked, under)
    # the world's outline is the rotated image, the wall is where it was drawn
    world = grid_world(grid)
    footprint = rotate(box(1.0, 2.0, 5.0, 5.0), yaw, origin=(1.0, 2.0), use_radians=True)
    assert world.outline.symmetric_difference(footprint).area < 1e-9
    wall = rotate(box(1.5, 3.6, 4.0, 4.0), yaw, origin=(1.0, 2.0), use_radians=True)
    assert not world.free.intersects(wall.buffer(-h))         # within the resampling error


def test_traced_polygons_keep_every_cell_on_its_side(tmp_path):
    rng = np.random.default_rng(3)
    pixels = np.where(rng.random((60, 80)) < 0.3, 0, 254).astype(np.uint8)   # noise
    pixels[20:40, 30:50] = 254
    grid = load_map(write_map(tmp_path, pixels, resolution=0.05, origin=[-1.0, 0.5, 0.0]))
    world = grid_world(grid)
    xs, ys = grid.centres()
    inside = shapely.contains_xy(world.free, xs, ys)
    assert np.array_equal(inside, ~grid.blocked)


def test_eroded_grid_world_is_the_distance_level_set(tmp_path):
    pixels = np.full((80, 120), 254, dtype=np.uint8)
    pixels[:, :10] = 0
    pixels[30:50, 60:70] = 205                                 # an unknown block
    world = grid_world(load_map(write_map(tmp_path, pixels, resolution=0.05)))
    region = world.eroded(0.4)
    # the wall's face is at x = 0.5 m, the block spans x 3.0..3.5, y 1.5..2.5 (row 0 top)
    assert not region.contains(Point(0.85, 2.0)) and region.contains(Point(0.95, 2.0))
    assert not region.contains(Point(3.85, 2.0)) and region.contains(Point(3.95, 2.0))
    assert region.contains(Point(3.25, 2.95)) and not region.contains(Point(3.25, 2.85))
    assert world.eroded(0.4) is region                         # cached


def test_burned_polygons_reach_the_distance_field(tmp_path):
    pixels = np.full((40, 60), 254, dtype=np.uint8)
    grid = load_map(write_map(tmp_path, pixels, resolution=0.05))   # 3 m x 2 m, all free
    thin = box(1.0, 0.0, 1.01, 2.0)                                    # a 1 cm wall
    world = grid_world(grid, [thin], keep_in=box(0.0, 0.0, 2.5, 2.0))
    field = world.distance_field()
    assert field.at(1.005, 1.0) < 0.0                                  # never lost
    assert field.at(2.75, 1.0) < 0.0                                   # outside keep_in
    assert field.at(0.5, 1.0) > 0.3
    assert world.free.intersection(thin).area == 0.0
    # a copy with more obstacles (the planner's blocked regions) keeps the grid and burns them
    more = world.with_obstacles([box(0.2, 0.2, 0.4, 0.4)])
    assert more.occupancy is not None and more.distance_field().at(0.3, 0.3) < 0.0
    assert world.distance_field().at(0.3, 0.3) > 0.0


def test_warehouse_files_are_what_the_script_writes(tmp_path):
    import importlib.util
    from pathlib import Path

    folder = Path(__file__).resolve().parents[2] / "examples" / "maps"
    spec = importlib.util.spec_from_file_location("make_warehouse", folder / "make_warehouse.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    module.main(["--out", str(tmp_path)])
    for name in ("warehouse.pgm", "warehouse.yaml"):
        assert (tmp_path / name).read_bytes() == (folder / name).read_bytes(), name
    grid = load_map(folder / "warehouse.yaml")
    values = grid.image.values
    assert grid.shape == (340, 500) and grid.resolution == 0.05
    assert {0, 100, -1} == set(np.unique(values).tolist())       # free, occupied, unknown


# ------------------------------------------------------------------------------ bad files
BAD_YAML = {
    "resolution_zero": ({"resolution": 0}, "resolution", "from 0.001 to 10 m"),
    "resolution_negative": ({"resolution": -0.05}, "resolution", "from 0.001 to 10 m"),
    "resolution_text": ({"resolution": "fine"}, "resolution", "from 0.001 to 10 m"),
    "occupied_above_1": ({"occupied_thresh": 1.5}, "occupied_thresh", "from 0 to 1"),
    "free_below_0": ({"free_thresh": -0.1}, "free_thresh", "from 0 to 1"),
    "free_not_below_occupied": ({"free_thresh": 0.7}, "free_thresh", "less than occupied_thresh"),
    "origin_short": ({"origin": "[1.0, 2.0]"}, "origin", "[x, y, yaw]"),
    "negate_2": ({"negate": 2}, "negate", "0 or 1"),
    "mode": ({"mode": "binary"}, "mode", "trinary"),
    "no_image": ({"image": None}, "image", "image file"),
}


@pytest.mark.parametrize("case", sorted(BAD_YAML))
def test_bad_yaml_fields_are_named(tmp_path, case):
    fields, where, allowed = BAD_YAML[case]
    path = write_map(tmp_path, np.full((4, 4), 254, np.uint8), **fields)
    if fields.get("image", "") is None:  # write_map leaves out None fields
        path_text = (tmp_path / "map.yaml").read_text()
        assert "image" not in path_text
    with pytest.raises(MapError) as info:
        read_map_yaml(path)
    (problem,) = [p for p in info.value.errors if p[0] == where]
    assert allowed in problem[2]


def test_missing_and_unreadable_images(tmp_path):
    path = write_map(tmp_path, np.full((4, 4), 254, np.uint8))
    (tmp_path / "map.pgm").write_bytes(b"P5\nthis is not an image")
    with pytest.raises(MapError, match="cannot be read as an image"):
        load_map(path)
    (tmp_path / "map.pgm").unlink()
    with pytest.raises(MapError, match="no such file") as info:
        load_map(path)
    assert info.value.errors[0][0] == "image"
    with pytest.raises(MapError, match="cannot be read"):
        load_map(tmp_path / "nothere.yaml")
    (tmp_path / "broken.yaml").write_text("image: [unclosed\n")
    with pytest.raises(MapError, match="not valid YAML"):
        load_map(tmp_path / "broken.yaml")
