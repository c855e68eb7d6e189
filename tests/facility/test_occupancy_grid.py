"""Points on and just past the edges of an occupancy grid (:mod:`pushtrain.facility.
occupancy_grid`): inside is answered by its cell, outside (by less than half a cell, on any
side) is "outside the map", never an IndexError."""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner
from PIL import Image

from pushtrain.cli.main import cli
from pushtrain.facility.map_server import load_map

H = 0.1            # resolution [m]
W, HT = 40, 30     # image width and height [pixels]: 4 m x 3 m from the origin (1, 2)
ORIGIN = (1.0, 2.0)


@pytest.fixture
def site(tmp_path):
    pixels = np.full((HT, W), 254, dtype=np.uint8)  # all free
    Image.fromarray(pixels).save(tmp_path / "site.pgm")
    (tmp_path / "site.yaml").write_text(
        f"image: site.pgm\nresolution: {H}\norigin: [{ORIGIN[0]}, {ORIGIN[1]}, 0.0]\n"
        "negate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n")
    return tmp_path


EDGES = {"right": (ORIGIN[0] + W * H, ORIGIN[1] + 1.5),
         "top": (ORIGIN[0] + 2.0, ORIGIN[1] + HT * H),
         "left": (ORIGIN[0], ORIGIN[1] + 1.5), "bottom": (ORIGIN[0] + 2.0, ORIGIN[1])}
OUTWARD = {"right": (1, 0), "top": (0, 1), "left": (-1, 0), "bottom": (0, -1)}


@pytest.mark.parametrize("side", list(EDGES))
@pytest.mark.parametrize("past", [0.05, 0.3, 0.49, 0.51, 2.0])
def test_a_point_just_past_an_edge_is_outside_the_map(site, side, past):
    grid = load_map(site / "site.yaml")
    (x, y), (dx, dy) = EDGES[side], OUTWARD[side]
    why = grid.why_blocked(x + dx * past * H, y + dy * past * H)
    assert why is not None and "outside the map" in why, why
    inside = grid.why_blocked(x - dx * 0.6 * H, y - dy * 0.6 * H)
    assert inside is None, inside  # within the image: its cell is free


@pytest.mark.parametrize("side", ["right", "top"])
def test_a_start_a_third_of_a_cell_past_the_edge_is_exit_2(site, side):
    (x, y), (dx, dy) = EDGES[side], OUTWARD[side]
    scenario = site / "site.toml"
    scenario.write_text(
        '[mission]\nkind = "plan"\n[train]\nn = 1\n[map]\ngrid = "site.yaml"\n'
        f"[start]\nx = {x + dx * H / 3}\ny = {y + dy * H / 3}\ntheta_deg = 180.0\n"
        f"[goal]\nx = {ORIGIN[0] + 2.0}\ny = {ORIGIN[1] + 1.5}\ntheta_deg = 180.0\n")
    done = CliRunner().invoke(cli, ["validate", str(scenario)])
    assert done.exit_code == 2, (done.output, done.exception)
    assert "outside the map" in done.output and "start" in done.output, done.output


@pytest.mark.parametrize("yaw", [0.0, 0.3, -2.0])
def test_the_image_s_top_rows_are_the_map_s_far_side(tmp_path, yaw):
    """An occupied block in the image's top-left corner (row 0 is the top, as map_server
    reads images) lies at the far end of the map's y axis, whatever the origin's yaw."""
    import math

    pixels = np.full((HT, W), 254, dtype=np.uint8)
    pixels[0:5, 0:5] = 0  # occupied
    Image.fromarray(pixels).save(tmp_path / "site.pgm")
    (tmp_path / "site.yaml").write_text(
        f"image: site.pgm\nresolution: {H}\norigin: [{ORIGIN[0]}, {ORIGIN[1]}, {yaw}]\n"
        "negate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n")
    grid = load_map(tmp_path / "site.yaml")

    def world(row, col):  # the centre of pixel (row, col) [m]
        u, v = (col + 0.5) * H, (HT - row - 0.5) * H
        c, s = math.cos(yaw), math.sin(yaw)
        return ORIGIN[0] + c * u - s * v, ORIGIN[1] + s * u + c * v

    blocked = grid.why_blocked(*world(2, 2))
    assert blocked is not None and "occupied" in blocked, blocked
    assert grid.why_blocked(*world(HT - 3, 2)) is None  # the bottom-left corner is free
    assert grid.why_blocked(*world(2, W - 3)) is None
