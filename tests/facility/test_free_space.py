"""Grid worlds against polygon worlds (plans and collision verdicts), the scenario's [map] with
a grid, the CLI's exit 2 for every bad map, and the grid image in the plots."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import shapely
from click.testing import CliRunner
from PIL import Image
from shapely.geometry import box

from pushtrain.cli.main import cli
from pushtrain.facility import example_layouts
from pushtrain.facility.free_space import World
from pushtrain.facility.loading import grid_world
from pushtrain.facility.map_server import load_map
from pushtrain.planner.config import PlannerConfig
from pushtrain.planner.planner import plan
from pushtrain.planner.train import BodyFootprint, Train

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
H = 0.05


def render(world: World, folder: Path, name: str = "corridor", pad: float = 0.5) -> Path:
    """``world`` as a SLAM tool would save it: a pixel free if its centre is in the free space,
    occupied within 10 cm of it, unknown beyond; origin at the outline's corner less ``pad``."""
    xmin, ymin, xmax, ymax = world.outline.bounds
    x0, y0 = xmin - pad, ymin - pad
    width = int(round((xmax - xmin + 2 * pad) / H))
    height = int(round((ymax - ymin + 2 * pad) / H))
    xs = x0 + (np.arange(width) + 0.5) * H
    ys = y0 + (height - np.arange(height) - 0.5) * H                 # row 0 at the top
    free = shapely.contains_xy(world.free, xs[None, :], ys[:, None])
    near = shapely.contains_xy(world.free.buffer(0.1), xs[None, :], ys[:, None])
    pixels = np.where(free, 254, np.where(near, 0, 205)).astype(np.uint8)
    Image.fromarray(pixels).save(folder / f"{name}.pgm")
    yaml = folder / f"{name}.yaml"
    yaml.write_text(f"image: {name}.pgm\nresolution: {H}\norigin: [{x0}, {y0}, 0.0]\n"
                    "negate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n")
    return yaml


@pytest.fixture(scope="module")
def l_worlds(tmp_path_factory):
    case = example_layouts.l_corridor(2.0)
    polygons = World.from_dict(case["world"])
    gridded = grid_world(load_map(render(polygons, tmp_path_factory.mktemp("l"))))
    return case, polygons, gridded


def test_the_l_corridor_as_a_grid_plans_the_same_length(l_worlds):
    case, polygons, gridded = l_worlds
    cfg = PlannerConfig(planner="restarts", time_budget=3.0, seed=1)
    a = plan(polygons, case["start"], case["goal"], Train.uniform(3), cfg)
    b = plan(gridded, case["start"], case["goal"], Train.uniform(3), cfg)
    assert b.length == pytest.approx(a.length, rel=0.05)


def _footprint_samples(body: BodyFootprint, pose, step: float = 0.025) -> np.ndarray:
    """Points (k, 2) [m] covering the body's rectangle at ``pose``, ``step`` apart, edges
    included."""
    along = np.linspace(-0.5 * body.length, 0.5 * body.length,
                        int(math.ceil(body.length / step)) + 1) + body.offset
    across = np.linspace(-0.5 * body.width, 0.5 * body.width,
                         int(math.ceil(body.width / step)) + 1)
    a, c = (m.ravel() for m in np.meshgrid(along, across))
    x, y, th = pose
    return np.column_stack([x + a * math.cos(th) - c * math.sin(th),
                            y + a * math.sin(th) + c * math.cos(th)])


def test_grid_and_polygons_give_the_same_collision_verdicts(l_worlds):
    """Poses clearly in (clearance >= margin + 10 cm, measured exactly on the polygons) or clearly
    out (the footprint reaches 10 cm into a wall): the grid world says the same, through its
    traced regions and through its distance field."""
    _, polygons, gridded = l_worlds
    body, margin = BodyFootprint(), 0.05
    walls = box(-1.0, -1.0, 10.0, 10.0).difference(polygons.free)
    deep = walls.buffer(-0.1)
    field = gridded.distance_field()
    verdicts = {True: 0, False: 0}
    for x in np.arange(0.3, 9.0, 0.37):
        for y in np.arange(0.3, 9.0, 0.37):
            for theta in np.radians([0.0, 30.0, 90.0, 135.0]):
                poly = body.polygons(x, y, theta)
                inside = polygons.free.contains(poly)
                clear = inside and poly.distance(polygons.free.boundary) >= margin + 0.1
                out = poly.intersects(deep)
                if not (clear or out):
                    continue
                assert gridded.eroded(margin).contains(poly) == clear, (x, y, theta)
                by_field = bool(np.min(field.at(*_footprint_samples(body, (x, y, theta)).T))
                                >= margin)
                assert by_field == clear, (x, y, theta)
                verdicts[clear] += 1
    assert verdicts[True] > 50 and verdicts[False] > 500


# ------------------------------------------------------------------------------ scenarios
def write_grid_scenario(folder: Path, yaml_name: str = "maps/room.yaml", start=(1.0, 1.0),
                        goal=(3.0, 1.0), extra: str = "") -> Path:
    text = (f'name = "room"\n[mission]\nkind = "plan"\n[train]\nn = 1\n[map]\n'
            f'grid = "{yaml_name}"\n{extra}\n'
            f"[start]\nx = {start[0]}\ny = {start[1]}\ntheta_deg = 180.0\n"
            f"[goal]\nx = {goal[0]}\ny = {goal[1]}\ntheta_deg = 180.0\n")
    path = folder / "room.toml"
    path.write_text(text)
    return path


def write_room(folder: Path, **fields) -> Path:
    """A 4 m x 2 m room (5 cm pixels, origin 0, 0) with 10 cm walls and a pillar (occupied) at
    x 2.0..2.2 m, y 1.5..1.7 m; YAML fields overridden by ``fields``."""
    folder.mkdir(parents=True, exist_ok=True)
    pixels = np.full((40, 80), 254, dtype=np.uint8)
    pixels[:2, :] = pixels[-2:, :] = 0
    pixels[:, :2] = pixels[:, -2:] = 0
    pixels[6:10, 40:44] = 0          # rows from the top: y from 2 - 10 * 0.05 = 1.5 to 1.7
    Image.fromarray(pixels).save(folder / "room.pgm")
    data = {"image": "room.pgm", "resolution": 0.05, "origin": "[0.0, 0.0, 0.0]", "negate": 0,
            "occupied_thresh": 0.65, "free_thresh": 0.196, **fields}
    (folder / "room.yaml").write_text("".join(f"{k}: {v}\n" for k, v in data.items()
                                              if v is not None))
    return folder / "room.yaml"


def test_grid_paths_are_relative_to_the_scenario_and_polygons_are_burned_in(tmp_path):
    from pushtrain.mission.runner import world_of
    from pushtrain.mission.scenario import load_scenario

    write_room(tmp_path / "site" / "maps")
    path = write_grid_scenario(tmp_path / "site", extra=(
        "obstacles = [[[3.0, 0.2], [3.2, 0.2], [3.2, 0.6], [3.0, 0.6]]]\n"
        "bounds = [0.0, 0.0, 3.6, 2.0]"))
    sc = load_scenario(path)
    assert sc.map.grid == str(tmp_path / "site" / "maps" / "room.yaml")
    world = world_of(sc)
    assert world is world_of(sc)                         # read and traced once
    field = world.distance_field()
    assert field.at(2.1, 1.6) < 0.0                      # the pillar of the image
    assert field.at(3.1, 0.4) < 0.0                      # the polygon drawn on top
    assert field.at(3.8, 1.0) < 0.0                      # outside bounds
    assert field.at(1.0, 1.0) == pytest.approx(0.9, abs=H)   # 0.9 m from the wall face at x=0.1
    assert not world.free.contains(shapely.Point(3.1, 0.4))


def test_the_old_polygon_map_is_unchanged():
    from pushtrain.mission.runner import world_of
    from pushtrain.mission.scenario import load_scenario

    sc = load_scenario(EXAMPLES / "bay.toml")
    world = world_of(sc)
    expected = World.from_dict(example_layouts.bay()["world"])
    assert world.occupancy is None
    assert world.free.symmetric_difference(expected.free).area == 0.0


@pytest.fixture
def runner():
    return CliRunner()


# case -> (yaml fields, start, goal, what the message must name)
BAD_MAPS = {
    "missing_image": ({"image": "nothere.pgm"}, None, None,
                      ["map.grid (room.yaml) image", "nothere.pgm", "no such file"]),
    "resolution_zero": ({"resolution": 0}, None, None,
                        ["map.grid (room.yaml) resolution", "0", "from 0.001 to 10 m"]),
    "resolution_negative": ({"resolution": -0.05}, None, None, ["resolution", "-0.05"]),
    "occupied_thresh": ({"occupied_thresh": 1.2}, None, None,
                        ["occupied_thresh", "1.2", "from 0 to 1"]),
    "free_thresh": ({"free_thresh": -0.5}, None, None, ["free_thresh", "-0.5", "from 0 to 1"]),
    "free_not_below_occupied": ({"free_thresh": 0.8}, None, None,
                                ["free_thresh", "0.8", "less than occupied_thresh"]),
    "start_outside": ({}, (5.0, 1.0), None, ["start", "outside the map image", "room.pgm"]),
    "goal_occupied": ({}, None, (2.12, 1.62), ["goal", "occupied", "row 7, column 42"]),
    "start_on_wall": ({}, (0.02, 1.0), None, ["start", "occupied"]),
}


@pytest.mark.parametrize("case", sorted(BAD_MAPS))
def test_bad_maps_exit_2_naming_the_field(runner, tmp_path, case):
    fields, start, goal, needles = BAD_MAPS[case]
    write_room(tmp_path / "maps", **fields)
    path = write_grid_scenario(tmp_path, start=start or (1.0, 1.0), goal=goal or (3.0, 1.0))
    out = tmp_path / "out"
    for command in (["validate", str(path)], ["plan-and-run", str(path), "--out", str(out)]):
        result = runner.invoke(cli, command)
        assert result.exit_code == 2, result.output
        assert "Traceback" not in result.output
        for needle in needles:
            assert needle in result.output, (needle, result.output)
    assert not out.exists()


def test_unreadable_image_and_missing_yaml_exit_2(runner, tmp_path):
    yaml = write_room(tmp_path / "maps")
    (yaml.parent / "room.pgm").write_bytes(b"\x89PNG but not really")
    path = write_grid_scenario(tmp_path)
    result = runner.invoke(cli, ["validate", str(path)])
    assert result.exit_code == 2 and "cannot be read as an image" in result.output
    path = write_grid_scenario(tmp_path, yaml_name="maps/other.yaml")
    result = runner.invoke(cli, ["validate", str(path)])
    assert result.exit_code == 2, result.output
    assert "map.grid" in result.output and "other.yaml" in result.output


def test_map_fields_that_need_a_dxf_and_a_map_without_any_source(runner, tmp_path):
    write_room(tmp_path / "maps")
    path = write_grid_scenario(tmp_path, extra='layers = ["WALLS"]')
    result = runner.invoke(cli, ["validate", str(path)])
    assert result.exit_code == 2 and "map.layers" in result.output and "map.dxf" in result.output
    path.write_text(path.read_text().replace('grid = "maps/room.yaml"\nlayers = ["WALLS"]', ""))
    result = runner.invoke(cli, ["validate", str(path)])
    assert result.exit_code == 2 and "grid" in result.output and "dxf" in result.output


def test_a_grid_scenario_validates_and_plans(runner, tmp_path):
    write_room(tmp_path / "maps")
    path = write_grid_scenario(tmp_path, start=(2.0, 0.8), goal=(3.3, 0.8))
    result = runner.invoke(cli, ["validate", str(path)])
    assert result.exit_code == 0, result.output
    result = runner.invoke(cli, ["plan", str(path), "--plot", str(tmp_path / "plan.png")])
    assert result.exit_code == 0, result.output
    assert (tmp_path / "plan.png").stat().st_size > 10_000


# ------------------------------------------------------------------------------ drawing
def test_the_grid_image_is_drawn_where_the_map_lies(tmp_path):
    """The image's corners land on the rotated footprint; the failure picture draws it too."""
    from matplotlib.figure import Figure

    from pushtrain.planner.diagnostic import save_diagnostic

    yaml = write_room(tmp_path, origin="[1.0, -2.0, 0.6]")
    world = grid_world(load_map(yaml))
    fig = Figure()
    ax = fig.add_subplot()
    world.plot(ax)
    (image,) = ax.get_images()
    to_data = image.get_transform() - ax.transData
    corners = to_data.transform([[0.0, 0.0], [4.0, 0.0], [4.0, 2.0]])
    c, s = math.cos(0.6), math.sin(0.6)
    assert corners[0] == pytest.approx([1.0, -2.0])
    assert corners[1] == pytest.approx([1.0 + 4 * c, -2.0 + 4 * s])
    assert corners[2] == pytest.approx([1.0 + 4 * c - 2 * s, -2.0 + 4 * s + 2 * c])
    assert image.get_extent() == pytest.approx([0.0, 4.0, 0.0, 2.0])
    # the free pixels are drawn light, the occupied ones dark (row 0 at the top)
    shade = image.get_array()
    assert shade[20, 20] > 0.9 and shade[7, 41] < 0.3 and shade[0, 10] < 0.3
    png = tmp_path / "planning_failure.png"
    save_diagnostic(png, world, start=(2.0, -0.5, 0.6), goal=(3.0, 0.0, 0.6))
    assert png.stat().st_size > 10_000


def test_map_png_of_a_run_draws_the_grid(tmp_path):
    from pushtrain.report.mapview import map_figure

    world = grid_world(load_map(write_room(tmp_path)))
    n, t = 1, np.linspace(0.0, 10.0, 50)
    cols = {"t": t, "x_d": 1.5 + 0.1 * t, "y_d": np.full_like(t, 1.0),
            "theta_d": np.full_like(t, math.pi)}
    for i in range(n + 1):
        cols[f"x{i}"] = 1.5 + 0.1 * t - 1.04 * (n - i)
        cols[f"y{i}"] = np.full_like(t, 1.0)
        cols[f"theta{i}"] = np.full_like(t, math.pi)
    data = np.rec.fromarrays(list(cols.values()), names=list(cols))
    fig = map_figure(data, n, world=world)
    (image,) = fig.axes[0].get_images()
    assert image.get_array().shape == (40, 80)


def test_the_walls_are_cut_into_pieces_that_cover_every_ring_in_order():
    """The wall distance's pieces (free_space._boundary_pieces): each ring of a map with holes
    and rings of every length cut into line strings of at most 16 edges, each starting where
    the one before ended, together exactly the ring's points."""
    import shapely
    from shapely.geometry import Point, Polygon, box

    from pushtrain.facility.free_space import _boundary_pieces

    outline = Point(0.0, 0.0).buffer(20.0, quad_segs=40)  # 161 points: 10 pieces
    holes = [box(-1, -1, 1, 1), Point(5.0, 5.0).buffer(1.0, quad_segs=4),  # 17 points: 1 piece
             Point(-8.0, 0.0).buffer(2.0, quad_segs=8)]  # 33 points: 2 pieces
    free = outline.difference(shapely.union_all(holes)).union(box(30, 0, 31, 1))
    pieces = _boundary_pieces(free)
    rings = shapely.get_parts(shapely.get_rings(shapely.get_parts(free)))
    k = 0
    for ring in rings:
        xy = shapely.get_coordinates(ring)
        got = []
        while len(got) < len(xy) - 1:
            part = shapely.get_coordinates(pieces[k])
            assert 2 <= len(part) <= 17
            if got:
                assert np.array_equal(part[0], got[-1])  # starts where the last ended
                got.extend(part[1:].tolist())
            else:
                got.extend(part.tolist())
            k += 1
        assert np.array_equal(np.array(got), xy)
    assert k == len(pieces)
    assert isinstance(free, shapely.MultiPolygon) and not isinstance(free, Polygon)


def test_a_point_off_an_l_shaped_outline_is_told_where_the_free_space_is():
    """Inside the L's bounding box but off its polygon, the bounds would not say why (the
    point lies within them): the answer names the nearest free point and its distance,
    computed here from the L's two arms. Outside the bounds, the bounds are named."""
    world = World.from_dict({"free": [[0, 0], [9, 0], [9, 9], [7, 9], [7, 2], [0, 2]]})
    said = world.why_not_free(3.0, 5.0)
    # the arms are y <= 2 (x <= 9) and x >= 7: the nearest free point of (3, 5) is (3, 2)
    assert "within its bounds but off its polygon" in said
    assert "(3.00, 2.00) m, 3.00 m away" in said
    assert "x from" not in said
    far = world.why_not_free(12.0, 5.0)
    assert "x from 0 to 9 m, y from 0 to 9 m" in far
    assert world.why_not_free(8.0, 5.0) is None
