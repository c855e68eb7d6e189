"""The widest way's narrowest passage against an independent distance transform of the same
public maps, and "impossible here" said before any search (issue 34 item 3)."""

import math
from pathlib import Path

import numpy as np
import pytest
from reference.chords import chord as reference_chord
from reference.chords import shortest_chord as reference_shortest_chord
from scipy import ndimage
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import breadth_first_order, minimum_spanning_tree

from pushtrain.errors import PlanningError
from pushtrain.facility.loading import map_world
from pushtrain.planner.config import PlannerConfig
from pushtrain.planner.passage import passable, widest_gap
from pushtrain.planner.planner import plan
from pushtrain.planner.train import Train

PUBLIC = Path(__file__).resolve().parents[2] / "examples" / "maps" / "public"
MAPS = ["aws_bookstore", "aws_small_warehouse", "willow_garage"]


class _WidestTree:
    """Independent maximin: the path between two cells in a maximum spanning tree of the
    8-connected free cells (edge weight: the smaller distance of its two cells) has the
    largest smallest distance of all paths (scipy's minimum_spanning_tree of top - weight)."""

    def __init__(self, edt: np.ndarray):
        ny, nx = edt.shape
        free = edt > 0
        self.edt, self.index = edt, np.full(edt.shape, -1)
        ii, jj = np.nonzero(free)
        self.ii, self.jj = ii, jj
        self.index[ii, jj] = np.arange(ii.size)
        rows, cols, weights = [], [], []
        top = edt.max() + 1.0
        for di, dj in ((0, 1), (1, 0), (1, 1), (1, -1)):
            i2, j2 = ii + di, jj + dj
            ok = (i2 < ny) & (j2 >= 0) & (j2 < nx)
            ok[ok] &= free[i2[ok], j2[ok]]
            rows.append(self.index[ii[ok], jj[ok]])
            cols.append(self.index[i2[ok], j2[ok]])
            weights.append(top - np.minimum(edt[ii[ok], jj[ok]], edt[i2[ok], j2[ok]]))
        m = ii.size
        graph = csr_matrix((np.concatenate(weights), (np.concatenate(rows),
                                                      np.concatenate(cols))), shape=(m, m))
        self.tree = minimum_spanning_tree(graph)

    def maximin(self, a: tuple[int, int], b: tuple[int, int]):
        """(the largest smallest distance [cells] of a way from cell ``a`` to ``b``, its
        cell); (None, None) if none."""
        _, pred = breadth_first_order(self.tree, int(self.index[a]), directed=False,
                                      return_predecessors=True)
        node, best, where = int(self.index[b]), math.inf, None
        if pred[node] < 0:
            return None, None
        while node != self.index[a]:
            cell = (self.ii[node], self.jj[node])
            if self.edt[cell] < best:
                best, where = self.edt[cell], cell
            node = int(pred[node])
        return best, where


def _transform(world):
    """The test's own distance transform of the world's occupancy grid [cells from the
    nearest blocked cell's centre; outside the grid is blocked], and the cells of its largest
    free piece."""
    edt = ndimage.distance_transform_edt(np.pad(~world.occupancy.blocked, 1))[1:-1, 1:-1]
    labels, _ = ndimage.label(edt > 0, structure=np.ones((3, 3), bool))
    largest = np.argmax(np.bincount(labels.ravel())[1:]) + 1
    return edt, labels == largest


@pytest.mark.parametrize("name", MAPS)
def test_the_widest_way_agrees_with_scipys_distance_transform(name):
    """On each public map, between cells in its rooms: our widest way's narrowest width
    against the test's own maximin over scipy's distance_transform_edt of the same occupancy
    grid (a passage whose best cell lies m cells from the nearest blocked cell's centre is
    2m - 1 or 2m cells wide wall to wall), within one map cell; and the place named is that
    narrow."""
    world = map_world(grid=str(PUBLIC / f"{name}.yaml"))
    grid = world.occupancy
    h = grid.resolution
    edt, piece = _transform(world)
    tree = _WidestTree(edt)
    field = world.distance_field()
    rng = np.random.default_rng(34)
    roomy = np.argwhere(piece & (edt >= 1.0 / h))
    checked = 0
    for _ in range(200):
        a, b = (tuple(roomy[k]) for k in rng.choice(len(roomy), 2, replace=False))
        m, cell = tree.maximin(a, b)
        if m is None or min(edt[a], edt[b]) < m + 3:
            continue  # the ends themselves would be the narrowest: our ends are always open
        pa = (grid.x0 + h * a[1], grid.y0 + h * a[0])
        pb = (grid.x0 + h * b[1], grid.y0 + h * b[0])
        gap = widest_gap(field, pa, pb, 0.35)
        expected = (2 * m - 0.5) * h  # 2m - 1 or 2m cells wall to wall
        assert gap.width == pytest.approx(expected, abs=h), (name, a, b, cell)
        # the place named lies on a passage that narrow (the test's own transform there)
        i, j = round((gap.y - grid.y0) / h), round((gap.x - grid.x0) / h)
        assert (2 * edt[i, j] - 0.5) * h == pytest.approx(gap.width, abs=h)
        # one labelling says the same as the bisection, either side of the width
        assert passable(field, pa, pb, (m - 1) * h)
        assert not passable(field, pa, pb, (m + 0.5) * h)
        checked += 1
        if checked == 4:
            break
    assert checked >= 3


def _explode(*_args, **_kwargs):
    raise AssertionError("the search (or its heuristic) ran for an impossible mission")


@pytest.mark.parametrize("name", ["aws_bookstore", "willow_garage"])
def test_a_train_wider_than_every_way_is_impossible_before_any_search(monkeypatch, name):
    """One trailer that asks 0.45 m of clearance (1.5 m passages), between two roomy places
    of a public map whose widest way (by the test's own maximin over scipy's transform)
    narrows below that: "impossible here" with the widest way's narrowest place, and neither
    the heuristic's grid search nor the search is started (both would raise here)."""
    import pushtrain.planner.whole_train as whole_train

    world = map_world(grid=str(PUBLIC / f"{name}.yaml"))
    grid, h = world.occupancy, world.occupancy.resolution
    edt, piece = _transform(world)
    tree = _WidestTree(edt)
    roomy = np.argwhere(piece & (edt >= 1.1 / h))
    rng = np.random.default_rng(7)
    needed = 2 * (0.3 + 0.45)
    for _ in range(100):
        a, b = (tuple(roomy[k]) for k in rng.choice(len(roomy), 2, replace=False))
        m, _ = tree.maximin(a, b)
        if m is not None and (2 * m - 1) * h < needed - 2 * h:
            break
    else:
        pytest.fail(f"no two roomy places of {name} with a way narrower than {needed} m")

    def pose(cell):  # the train straight, its robot (1.04 m ahead) toward the most room
        best = max(np.linspace(-math.pi, math.pi, 16, endpoint=False),
                   key=lambda th: edt[min(max(round(cell[0] + 1.04 / h * math.sin(th)), 0),
                                          edt.shape[0] - 1),
                                      min(max(round(cell[1] + 1.04 / h * math.cos(th)), 0),
                                          edt.shape[1] - 1)])
        return (grid.x0 + h * cell[1], grid.y0 + h * cell[0], float(best))

    start, goal = pose(a), pose(b)
    monkeypatch.setattr(whole_train, "Heuristic", _explode)
    monkeypatch.setattr(whole_train, "Search", _explode)
    with pytest.raises(PlanningError) as info:
        plan(world, start, goal, Train.uniform(1), PlannerConfig(clearance=[0.05, 0.45]))
    err = info.value
    assert err.reason == "unreachable", str(err)
    assert err.details["impossible"] and "impossible here" in str(err)
    b = err.details["bottleneck"]
    assert b["needed"] == pytest.approx(needed)
    assert b["width"] == pytest.approx((2 * m - 0.5) * h, abs=h)
    assert f"narrows to {b['width']:.2f} m" in str(err)


# ---------------------------------------------------------------------- turning
def _steady_bodies(train, rho):
    """The test's own steady arc: the last trailer's axle midpoint at (rho, 0) on a circle
    round the origin, heading tangent (CCW travel, chain heading theta = travel + pi); each
    body ahead from P_{i-1} = P_i + F_i e_i + R_{i-1} e_{i-1} with the joint angle that keeps
    it on its circle (found by bisection, not by a formula)."""
    import shapely

    front, rear = train.geometry.front, train.geometry.rear
    poses = [(rho, 0.0, -0.5 * math.pi)]  # travel +y at (rho, 0); theta points back to robot
    for i in range(train.n, 0, -1):
        x, y, th = poses[-1]
        hx, hy = x + front[i - 1] * math.cos(th), y + front[i - 1] * math.sin(th)

        def tangency(phi, hx=hx, hy=hy, th=th, i=i):  # body ahead's heading tangent: 0
            th0 = th + phi
            px, py = hx + rear[i - 1] * math.cos(th0), hy + rear[i - 1] * math.sin(th0)
            return px * math.cos(th0) + py * math.sin(th0)  # radial part of its heading

        lo, hi = -0.5 * math.pi, 0.0
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            if tangency(lo) * tangency(mid) <= 0.0:
                hi = mid
            else:
                lo = mid
        th0 = th + 0.5 * (lo + hi)
        poses.append((hx + rear[i - 1] * math.cos(th0), hy + rear[i - 1] * math.sin(th0), th0))
    poses.reverse()  # robot first
    return [shapely.Polygon(body.corners(*pose)) for body, pose in zip(train.bodies, poses,
                                                                      strict=True)]


@pytest.mark.parametrize("n, rho, link, offset", [(1, 0.97, 0.52, 0.0), (3, 0.97, 0.52, 0.0),
                                                  (5, 2.5, 0.52, 0.0), (3, 1.5, 0.4, 0.0),
                                                  (2, 1.2, 0.52, 0.15)])
def test_the_swept_band_is_the_ring_the_steady_train_covers(n, rho, link, offset):
    """The band (r_in, r_out) of the train on a steady arc against the test's own placement
    of every body (0.6 x 0.8 m trailers, their centres ``offset`` ahead of the axle, the
    0.5 x 0.6 m robot, links ``link``) and shapely's distances from the arc's centre, 0.05 m
    clearance added."""
    from shapely.geometry import Point

    from pushtrain.planner.passage import swept_band
    from pushtrain.planner.train import BodyFootprint

    train = Train.uniform(n, link=link, trailer=BodyFootprint(0.8, 0.6, offset))
    margins = [0.05] * (n + 1)
    polys = _steady_bodies(train, rho)
    centre = Point(0.0, 0.0)
    r_in = min(centre.distance(p) for p in polys) - 0.05
    r_out = max(max(math.hypot(x, y) for x, y in p.exterior.coords) for p in polys) + 0.05
    band = swept_band(train, rho, margins)
    assert band.r_in == pytest.approx(r_in, abs=1e-6)
    assert band.r_out == pytest.approx(r_out, abs=1e-6)


@pytest.mark.parametrize("rho", [0.97, 1.5])
def test_a_right_angle_corner_needs_what_the_formula_says(rho):
    """An L of two corridors of width W: the ring's quarter, centred on the inside corner's
    diagonal behind it, fits (shapely) for W just above corner_need and nowhere along that
    diagonal just below."""
    from shapely.geometry import Polygon, box
    from shapely.ops import unary_union

    from pushtrain.planner.passage import corner_need, swept_band

    band = swept_band(Train.uniform(3), rho, [0.05] * 4)
    need = corner_need(band, 0.5 * math.pi)
    angles = np.linspace(0.0, 0.5 * math.pi, 91)

    def fits(width):
        # the L: inside corner at the origin (blocked x < 0 and y < 0), legs W wide
        free = unary_union([box(0.0, -5.0, width, width), box(-5.0, 0.0, width, width)])
        free = free.buffer(1e-9)
        for u in np.linspace(0.0, band.r_in, 200):  # centre u behind the corner, diagonally
            c = -u / math.sqrt(2.0)
            outer = [(c + band.r_out * math.cos(a), c + band.r_out * math.sin(a)) for a in angles]
            inner = [(c + band.r_in * math.cos(a), c + band.r_in * math.sin(a))
                     for a in angles[::-1]]
            if free.contains(Polygon(outer + inner)):
                return True
        return False

    assert fits(need + 0.01)
    assert not fits(need - 0.01)


def _office_door(corridor: float = 0.8):
    """A corridor along x ``corridor`` m wide and a room below it through a 0.9 m door in a
    0.1 m wall: three trailers pushed along the corridor and down through the door; the
    door's middle."""
    from shapely.geometry import box
    from shapely.ops import unary_union

    from pushtrain.facility.free_space import World

    free = unary_union([box(0.0, 5.0, 16.0, 5.0 + corridor), box(8.0, 0.0, 13.0, 4.9),
                        box(10.0, 4.85, 10.9, 5.05)])
    world = World(free.envelope, (free.envelope.difference(free),))
    return (world, (4.5, 5.0 + 0.5 * corridor, math.pi), (10.45, 2.0, 0.5 * math.pi),
            (10.45, 4.95))


def _l_09():
    from pushtrain.facility import example_layouts
    from pushtrain.facility.free_space import World

    case = example_layouts.l_corridor(0.9)
    return World.from_dict(case["world"]), case["start"], case["goal"], (8.1, 0.9)


def test_a_corner_too_tight_for_the_train_is_named_with_its_numbers():
    """Three trailers round a 0.9 m L (the last trailer alone needs 0.70 m: the way is wide
    enough): the answer names the corner, the swept band and the width the corner needs (the
    test's own steady placement and the corner rule) against the 0.90 m the map has, and no
    width it names is below it."""
    import re

    world, start, goal, inside_corner = _l_09()
    train = Train.uniform(3)
    config = PlannerConfig()
    with pytest.raises(PlanningError) as info:
        plan(world, start, goal, train, config)
    err = info.value
    corner = err.details["corner"]
    assert corner is not None, str(err)
    assert err.where == (corner["x"], corner["y"])  # the mark on planning_failure.png
    assert math.dist((corner["x"], corner["y"]), inside_corner) < 1.0
    assert corner["turn_deg"] == pytest.approx(90.0, abs=10.0)
    assert corner["width"] == pytest.approx(0.9, abs=0.02) and "door" not in corner
    rho = config.radius_for(train)
    polys = _steady_bodies(train, rho)
    r_in = min(shapely_point_distance(p) for p in polys) - 0.05
    r_out = max(max(math.hypot(x, y) for x, y in p.exterior.coords) for p in polys) + 0.05
    turn = math.radians(corner["turn_deg"])
    assert corner["needed"] == pytest.approx(r_out - r_in * math.cos(0.5 * turn), abs=1e-6)
    assert corner["needed"] > 0.9 + 0.02
    text = str(err)
    assert "cannot turn" in text and f"needs {corner['needed']:.2f} m of corridor" in text
    assert f"sweeps a {r_out - r_in:.2f} m band" in text
    for width in re.findall(r"(\d+\.\d+) m wide", text):
        assert float(width) >= 0.9 - 1e-9
    # the page's marker (report.html's payload and planning_failure.png): the corner, labelled
    from pushtrain.report.html import failure_payload

    b = failure_payload(3, err.details, world=world, start=start, goal=goal)["bottleneck"]
    assert (b["x"], b["y"]) == (corner["x"], corner["y"]) and "corner too tight" in b["what"]
    assert b["width"] == corner["width"] and b["needed"] == corner["needed"]


def shapely_point_distance(poly) -> float:
    from shapely.geometry import Point

    return Point(0.0, 0.0).distance(poly)


def test_no_failure_names_a_passage_narrower_than_the_maps(monkeypatch):
    """A search that fails in a 2 m L (joints limited to 25 deg: the train cannot bend round
    the corner). Its route keeps near the inside corner (the corridor is wider than the
    centring band), where twice the route's distance from the wall is well under 2 m; every
    width the message names is at least the widest way's, by the test's own maximin over
    scipy's distance transform of the map rasterized at 2 cm, less one cell."""
    import re

    import shapely

    import pushtrain.planner.budget as budget
    from pushtrain.facility import example_layouts
    from pushtrain.facility.free_space import World

    monkeypatch.setattr(budget, "STEPS_PER_SECOND", 20_000)
    case = example_layouts.l_corridor(2.0)
    world = World.from_dict(case["world"])
    with pytest.raises(PlanningError) as info:
        plan(world, case["start"], case["goal"], Train.uniform(3, phi_max=math.radians(25.0)),
             PlannerConfig(time_budget=3.0, joint_margin=math.radians(2.0)))
    text = str(info.value)
    h = 0.02
    xs, ys = np.arange(-0.5, 9.5, h), np.arange(-0.5, 9.5, h)
    free = shapely.contains_xy(world.free, xs[None, :], ys[:, None])
    edt = ndimage.distance_transform_edt(free)
    def cell(p):
        return round((p[1] + 0.5) / h), round((p[0] + 0.5) / h)

    m, _ = _WidestTree(edt).maximin(cell(case["start"]), cell(case["goal"]))
    widest = (2 * m - 0.5) * h
    named = [float(w) for w in re.findall(r"(\d+\.\d+) m wide", text)]
    assert named, text
    assert min(named) >= widest - h, (named, widest, text)


@pytest.mark.parametrize("name", MAPS)
def test_chords_are_the_walk_out_from_the_point_of_the_scalar_reference(name):
    """chords (all points and directions at once), width_across and shortest_chord(s) against
    tests/reference/chords.py (one chord at a time: walk out sample by sample until the field
    is <= 0, the zero crossing interpolated), at points of a public map in rooms, corridors,
    doors, walls and outside it, for short and long reaches."""
    from pushtrain.planner.passage import (
        CHORD_DIRECTIONS,
        chords,
        shortest_chord,
        shortest_chords,
        width_across,
    )

    field = map_world(grid=str(PUBLIC / f"{name}.yaml")).distance_field()
    x0, y0, x1, y1 = field.bounds
    rng = np.random.default_rng(7)
    xs, ys = rng.uniform(x0 - 1.0, x1 + 1.0, 40), rng.uniform(y0 - 1.0, y1 + 1.0, 40)
    positive = 0
    for reach in (0.3, 2.5):
        every = chords(field, xs, ys, CHORD_DIRECTIONS, reach)
        shortest = shortest_chords(field, xs, ys, reach)
        for p, (x, y) in enumerate(zip(xs, ys, strict=True)):
            expected = [reference_chord(field, x, y, th, reach) for th in CHORD_DIRECTIONS]
            np.testing.assert_allclose(every[p], expected, rtol=0.0, atol=1e-12)
            th = CHORD_DIRECTIONS[p % CHORD_DIRECTIONS.size]
            assert width_across(field, x, y, th, reach) == pytest.approx(
                reference_chord(field, x, y, th, reach), rel=0.0, abs=1e-12)
            narrowest = reference_shortest_chord(field, x, y, reach)
            assert shortest[p] == pytest.approx(narrowest, rel=0.0, abs=1e-12)
            assert shortest_chord(field, x, y, reach) == pytest.approx(narrowest, rel=0.0,
                                                                       abs=1e-12)
            positive += narrowest > 0.0
    assert positive > 10  # not only walls and outside


# ---------------------------------------------------------------------- lining up with a door
def _fits_door(band, corridor: float, door: float, wall: float) -> bool:
    """Whether a steady right-angle turn on ``band`` from a corridor (``0 <= y <= corridor``)
    into a door (``0 <= x <= door`` through the wall ``-wall <= y <= 0``) and a room below
    fits (shapely): some ring centre, on a 2.5 mm grid, whose quarter ring, the straight
    train along the corridor before it and down through the door after it, lie in the free
    space."""
    import shapely
    from shapely.geometry import box
    from shapely.ops import unary_union

    free = unary_union([box(-5.0, 0.0, 5.0, corridor), box(0.0, -wall - 0.01, door, 0.01),
                        box(-5.0, -5.0, 5.0, -wall)]).buffer(1e-9)
    shapely.prepare(free)
    r, big, rho, a = band.r_in, band.r_out, band.radius, band.half_straight
    angles = np.linspace(0.0, 0.5 * math.pi, 46)
    ring = np.r_[np.c_[big * np.cos(angles), big * np.sin(angles)],
                 np.c_[r * np.cos(angles), r * np.sin(angles)][::-1]]
    cx = np.arange(-1.5, door, 0.0025)
    for cy in np.arange(-r - wall - 0.2, corridor - big + 0.0025, 0.0025):
        centres = np.stack([cx, np.full_like(cx, cy)], axis=1)
        rings = shapely.polygons(ring[None, :, :] + centres[:, None, :])
        before = shapely.box(cx - 4.0, cy + rho - a, cx, cy + rho + a)
        after = shapely.box(cx + rho - a, cy - 4.0, cx + rho + a, cy)
        if np.any(shapely.contains(free, rings) & shapely.contains(free, before)
                  & shapely.contains(free, after)):
            return True
    return False


@pytest.mark.parametrize("radius, door, wall", [(0.973, 0.9, 0.1), (0.567, 0.9, 0.1),
                                                (0.973, 1.2, 0.05), (0.567, 1.0, 0.15),
                                                (0.567, 0.8, 0.2)])
def test_door_need_is_the_corridor_a_steady_turn_into_the_door_needs(radius, door, wall):
    """door_need against the test's own search of ring centres (shapely containment of the
    quarter ring and the straight train before and after it): a corridor 1.5 cm wider fits,
    one 1.5 cm narrower does not."""
    from pushtrain.planner.passage import door_need, swept_band

    band = swept_band(Train.uniform(3), radius, [0.05] * 4)
    need = door_need(band, door, wall)
    assert math.isfinite(need) and need > band.width - 1e-9
    assert _fits_door(band, need + 0.015, door, wall)
    assert not _fits_door(band, need - 0.015, door, wall)


def test_no_steady_turn_goes_through_a_door_narrower_than_the_straight_train():
    """A 0.68 m door (the trailers need 0.70 m straight): inf, and no corridor however wide
    lets a steady turn in (the test's own search, a 2 m corridor)."""
    from pushtrain.planner.passage import door_need, swept_band

    band = swept_band(Train.uniform(3), 0.567, [0.05] * 4)
    assert door_need(band, 0.68, 0.1) == math.inf
    assert not _fits_door(band, 2.0, 0.68, 0.1)


def test_a_door_the_train_cannot_line_up_with_is_named_with_its_numbers():
    """Three trailers along a 0.8 m corridor (the last trailer needs 0.70 m: the way is wide
    enough), then right through a 0.9 m door in a 0.1 m wall: the answer names the door
    (where, its width and wall), the corridor's width in front of it and what a steady turn
    into it needs at the planner's radius and at the tightest the joints allow (door_need,
    checked above), and no width it names is below the corridor's; the page's marker is the
    door."""
    import re

    from pushtrain.planner.config import turning_radius_from_joint_limit
    from pushtrain.planner.passage import door_need, swept_band
    from pushtrain.report.html import failure_payload

    world, start, goal, door_middle = _office_door(0.8)
    train, config = Train.uniform(3), PlannerConfig()
    with pytest.raises(PlanningError) as info:
        plan(world, start, goal, train, config)
    err = info.value
    corner = err.details["corner"]
    assert corner is not None and corner.get("door"), str(err)
    door = corner["door"]
    assert err.where == (corner["x"], corner["y"]) == (door["x"], door["y"])
    assert math.dist(err.where, door_middle) < 0.3
    assert door["width"] == pytest.approx(0.9, abs=0.02)
    assert door["wall"] == pytest.approx(0.1, abs=0.06)
    assert corner["width"] == door["corridor"] == pytest.approx(0.8, abs=0.02)
    margins = config.margins(train)
    tightest = turning_radius_from_joint_limit(train.phi_max - config.joint_margin,
                                               train.max_link(), 0.0)
    for key, radius in (("needed", config.radius_for(train)), ("needed_tightest", tightest)):
        want = door_need(swept_band(train, radius, margins), door["width"], door["wall"])
        assert corner[key] == pytest.approx(want, abs=1e-9)
    assert corner["needed_tightest"] > corner["width"]  # even at the tightest radius
    text = str(err)
    assert "cannot turn on the planner's arcs: to line up with the door" in text, text
    assert f"corridor {corner['width']:.2f} m wide" in text
    assert f"needs {corner['needed']:.2f} m of corridor in front of it" in text
    assert f"({tightest:.2f} m) {corner['needed_tightest']:.2f} m of corridor" in text
    for width in re.findall(r"(\d+\.\d+) m wide", text):
        assert float(width) >= 0.8 - 0.02
    b = failure_payload(3, err.details, world=world, start=start, goal=goal)["bottleneck"]
    assert (b["x"], b["y"]) == err.where
    assert b["what"].startswith("door the train cannot line up with (0.90 m door")


def test_a_door_off_a_wide_corridor_is_measured_and_not_too_tight():
    """The same door off a 2 m corridor: the route's corner is the door, measured (0.9 m in a
    0.1 m wall, the corridor 2 m), and a steady turn fits there."""
    from pushtrain.planner.config import turning_radius_from_joint_limit
    from pushtrain.planner.passage import swept_band, tight_corners
    from pushtrain.planner.route import find_route

    world, start, goal, door_middle = _office_door(2.0)
    train, config = Train.uniform(3), PlannerConfig()
    field = world.distance_field()
    route = find_route(field, start[:2], goal[:2], 0.35)
    margins = config.margins(train)
    tightest = turning_radius_from_joint_limit(train.phi_max - config.joint_margin,
                                               train.max_link(), 0.0)
    corners = tight_corners(route, field, swept_band(train, config.radius_for(train), margins),
                            swept_band(train, tightest, margins))
    door = [c for c in corners if c.door is not None]
    assert len(door) == 1 and math.dist((door[0].x, door[0].y), door_middle) < 0.3
    assert door[0].door.width == pytest.approx(0.9, abs=0.02)
    assert door[0].width == pytest.approx(2.0, abs=0.02) and not door[0].too_tight


def test_the_quick_screen_keeps_a_door_too_tight_at_a_wide_radius_as_the_full_measure_does():
    """A 1.3 m corridor, the room below it through a 1.1 m door in a 0.4 m wall, the goal down
    and to the right: the route turns about 72 deg into the door. On arcs of 3 m the steady
    turn (corner_need) fits the corridor, lining up with the door (door_need) does not: the
    quick path turnable_route uses (only_too_tight) keeps that corner with the full measure's
    numbers (it measured the door on chords within 20 deg of the legs' normals, and missed
    it: the corner came back as a plain one, needing only corner_need)."""
    from shapely.geometry import box
    from shapely.ops import unary_union

    from pushtrain.facility.free_space import World
    from pushtrain.planner.passage import corner_need, door_need, swept_band, tight_corners
    from pushtrain.planner.route import find_route

    free = unary_union([box(0.0, 5.0, 16.0, 6.3), box(8.0, 0.0, 16.0, 4.6),
                        box(10.0, 4.55, 11.1, 5.05)])
    world = World(free.envelope, (free.envelope.difference(free),))
    field = world.distance_field()
    train, config = Train.uniform(3), PlannerConfig()
    margins = config.margins(train)
    route = find_route(field, (4.5, 5.65), (14.0, 3.0), 0.35)
    band = swept_band(train, 3.0, margins)
    doors = [c for c in tight_corners(route, field, band, band)
             if c.door is not None and math.radians(60.0) <= c.turn <= math.radians(80.0)]
    assert doors and doors[0].too_tight
    corner = doors[0]
    assert corner.door.width == pytest.approx(1.1, abs=0.02)
    assert corner.door.wall == pytest.approx(0.4, abs=0.06)
    assert corner.width == pytest.approx(1.3, abs=0.02)
    assert corner_need(band, corner.turn) < 1.3 - 0.05 and door_need(band, 1.1, 0.4) > 1.3 + 0.2
    quick = tight_corners(route, field, band, band, only_too_tight=True)
    assert corner in quick


def test_a_door_on_a_public_map_is_never_named_narrower_than_the_way_through_it():
    """The office's door at (7.7, 42.0) off the west corridor, in a ragged 0.3 m wall: a chord
    through a route point near its jamb is 0.70 m, but the widest way through it is wider.
    The door named is the widest way's through it: within one cell of the test's own maximin
    over scipy's transform of the grid (0.70-0.80 m), and never narrower than the widest
    way's narrowest place the same failure names (the way from start to goal passes it)."""
    from pushtrain.planner.config import turning_radius_from_joint_limit
    from pushtrain.planner.passage import swept_band, tight_corners
    from pushtrain.planner.route import find_route

    world = map_world(grid=str(PUBLIC / "willow_garage.yaml"))
    grid, h = world.occupancy, world.occupancy.resolution
    start, goal = (7.2, 39.7), (9.5, 42.65)
    edt, _ = _transform(world)

    def cell(p):
        return round((p[1] - grid.y0) / h), round((p[0] - grid.x0) / h)

    m, _ = _WidestTree(edt).maximin(cell(start), cell(goal))
    field = world.distance_field()
    train, config = Train.uniform(1), PlannerConfig()
    margins = config.margins(train)
    tightest = turning_radius_from_joint_limit(train.phi_max - config.joint_margin,
                                               train.max_link(), 0.0)
    corners = tight_corners(find_route(field, start, goal, 0.35), field,
                            swept_band(train, config.radius_for(train), margins),
                            swept_band(train, tightest, margins))
    doors = [c.door for c in corners if c.door is not None]
    assert doors and math.dist((doors[0].x, doors[0].y), (7.7, 42.0)) < 0.5
    assert doors[0].width == pytest.approx((2 * m - 0.5) * h, abs=h)
    assert doors[0].width >= widest_gap(field, start, goal, 0.35).width - 1e-9
