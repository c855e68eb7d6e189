"""The planner's signed distance field against shapely's exact distances (an independent
computation) and against hand-made occupancy grids."""

import math

import numpy as np
import pytest
import shapely

from pushtrain.errors import PlanningInputError
from pushtrain.facility import example_layouts
from pushtrain.facility.distance_field import DistanceField
from pushtrain.facility.free_space import World


def _exact_signed(world: World, x, y):
    pts = shapely.points(x, y)
    d = shapely.distance(world.free.boundary, pts)
    return np.where(shapely.contains_xy(world.free, x, y), d, -d)


@pytest.mark.parametrize("make", [example_layouts.l_corridor, example_layouts.bay])
def test_polygon_field_is_exact_near_walls(make):
    world = World.from_dict(make()["world"])
    field = world.distance_field(0.02)
    rng = np.random.default_rng(3)
    xmin, ymin, xmax, ymax = world.outline.bounds
    x = rng.uniform(xmin, xmax, 4000)
    y = rng.uniform(ymin, ymax, 4000)
    exact = _exact_signed(world, x, y)
    near = np.abs(exact) < 0.9
    err = np.abs(field.at(x, y) - exact)[near]
    # bilinear interpolation of exact node values of a 1-Lipschitz function: < h / sqrt(2)
    assert err.max() < 0.02 / math.sqrt(2.0) + 1e-9
    # and along straight walls, away from corners, it is exact
    assert np.median(err) < 1e-9


def test_polygon_nodes_are_exact_within_band():
    world = World.from_dict(example_layouts.bay()["world"])
    field = DistanceField.from_world(world, 0.05, band=0.5)
    ny, nx = field.shape
    xs = field.x0 + 0.05 * np.arange(nx)
    ys = field.y0 + 0.05 * np.arange(ny)
    gx, gy = np.meshgrid(xs, ys)
    exact = _exact_signed(world, gx, gy)
    near = np.abs(exact) < 0.5
    assert np.allclose(field.values[near], exact[near], atol=1e-12)
    # far from walls the distance transform stays within a cell of the truth
    assert np.abs(field.values - exact)[~near].max() < 0.05


def test_occupancy_field_distances_and_outside():
    blocked = np.zeros((40, 60), dtype=bool)
    blocked[:, :5] = True  # a wall in the first 5 columns: its face at x = 4.5 cells
    field = DistanceField.from_occupancy(blocked, x0=1.0, y0=2.0, resolution=0.1)
    # a free cell centre at column 20: 15.5 cells from the wall's face
    assert field.at(1.0 + 2.0, 2.0 + 2.0) == pytest.approx(1.55)
    assert field.at(1.0 + 0.2, 2.0 + 2.0) < 0.0  # inside the wall
    assert field.at(-5.0, 2.0) == -np.inf  # outside the grid counts as blocked
    # the grid's own edge bounds the world: half a cell beyond the last row's centre
    assert field.at(1.0 + 3.0, 2.0 + 3.9) == pytest.approx(0.05)
    assert field.clear(1.0 + 3.0, 2.0 + 2.0, 0.5)
    assert not field.clear(1.0 + 0.6, 2.0 + 2.0, 0.5)


def test_world_caches_its_field_and_prefers_occupancy():
    world = World.from_dict(example_layouts.bay()["world"])
    assert world.distance_field() is world.distance_field()

    class Grid:
        blocked = np.zeros((10, 10), dtype=bool)
        x0, y0, resolution = 0.0, 0.0, 0.5

    gridded = World(world.outline, world.obstacles, occupancy=Grid())
    assert gridded.distance_field().resolution == 0.5


@pytest.mark.parametrize("bad", [0.0, -0.1, math.nan])
def test_bad_resolution_is_refused(bad):
    world = World.from_dict(example_layouts.bay()["world"])
    with pytest.raises(PlanningInputError, match="resolution"):
        DistanceField.from_world(world, bad)


def test_lookup_is_bilinear_between_nodes_and_minus_infinity_outside():
    """at() against scipy's own bilinear interpolation (map_coordinates, order 1) at random
    points, the grid's corners and edges, and points outside it or not numbers (-inf)."""
    from scipy.ndimage import map_coordinates

    rng = np.random.default_rng(5)
    values = rng.normal(size=(37, 53))
    field = DistanceField(values, -2.0, 1.5, 0.05)
    x0, y0, x1, y1 = field.bounds
    x = np.concatenate([rng.uniform(x0, x1, 2034), [x0, x1, x0, x1, x0, 0.5 * (x0 + x1)]])
    y = np.concatenate([rng.uniform(y0, y1, 2034), [y0, y0, y1, y1, 0.5 * (y0 + y1), y1]])
    x[-6:] = np.clip(x[-6:], x0, x1 - 1e-12)  # the far edges, just inside
    y[-6:] = np.clip(y[-6:], y0, y1 - 1e-12)
    u, v = (x - x0) / field.resolution, (y - y0) / field.resolution
    expected = map_coordinates(values, [v, u], order=1, mode="nearest")
    got = field.at(x.reshape(40, 51), y.reshape(40, 51)).reshape(-1)
    assert np.allclose(got, expected, rtol=0.0, atol=1e-12)
    assert float(field.at(x0 + 0.01, y0 + 0.02)) == pytest.approx(
        float(map_coordinates(values, [[0.4], [0.2]], order=1)[0]), abs=1e-12)
    outside = field.at(np.array([x0 - 0.01, x1 + 0.01, 0.0, np.nan, np.inf]),
                       np.array([0.0, 0.0, y1 + 0.01, 0.0, 0.0]))
    assert np.all(outside == -np.inf)


def test_lookup_equals_the_readable_reference_bit_for_bit():
    """The C lookup against tests/reference/field_lookup.py, point by point, to the bit: random
    points (some outside), the nodes themselves, the four edges and corners exactly, the
    smallest steps outside them, NaN and infinities; scalar, broadcast and strided inputs keep
    their shapes."""
    from tests.reference.field_lookup import field_at

    rng = np.random.default_rng(11)
    values = rng.normal(size=(23, 31))
    field = DistanceField(values, -1.25, 0.75, 0.037)
    x0, y0, x1, y1 = field.bounds
    xs = list(rng.uniform(x0 - 0.1, x1 + 0.1, 3000))
    ys = list(rng.uniform(y0 - 0.1, y1 + 0.1, 3000))
    edges_x = [x0, x1, np.nextafter(x0, -np.inf), np.nextafter(x1, np.inf),
               np.nextafter(x1, -np.inf), 0.5 * (x0 + x1)]
    edges_y = [y0, y1, np.nextafter(y0, -np.inf), np.nextafter(y1, np.inf),
               np.nextafter(y1, -np.inf), 0.5 * (y0 + y1)]
    for ex in edges_x:
        for ey in edges_y:
            xs.append(ex)
            ys.append(ey)
    nodes_x = x0 + field.resolution * np.arange(31)
    nodes_y = y0 + field.resolution * np.arange(23)
    xs += list(np.repeat(nodes_x, 23))
    ys += list(np.tile(nodes_y, 31))
    xs += [np.nan, 0.0, np.inf, -np.inf]
    ys += [0.0, np.nan, 0.0, 0.0]
    x, y = np.array(xs), np.array(ys)
    got = field.at(x, y)
    want = np.array([field_at(values, x0, y0, field.resolution, a, b)
                     for a, b in zip(xs, ys, strict=True)])
    assert got.shape == x.shape
    assert np.array_equal(got.view(np.int64), want.view(np.int64))  # the same bits
    assert (got == -np.inf).sum() > 900  # the points outside (and NaN) were tried
    # shapes: a scalar gives a 0-d array, broadcast and strided inputs their broadcast shape
    assert field.at(0.0, 1.0).shape == ()
    assert float(field.at(0.0, 1.0)) == field_at(values, x0, y0, field.resolution, 0.0, 1.0)
    grid = field.at(nodes_x[None, :-1:2], nodes_y[:-1, None])  # (the far edge may round out)
    assert grid.shape == (22, 15)
    assert np.allclose(grid, values[:-1, :-1:2], rtol=0.0, atol=1e-12)
    assert np.array_equal(field.at(x[::3], y[::3]), got[::3])
