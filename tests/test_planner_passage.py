"""The widest way's narrowest passage against an independent distance transform of the same
public maps, and "impossible here" said before any search (issue 34 item 3)."""

import math
from pathlib import Path

import numpy as np
import pytest
from scipy import ndimage
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import breadth_first_order, minimum_spanning_tree

from pushtrain.errors import PlanningError
from pushtrain.facility.loading import map_world
from pushtrain.planner.config import PlannerConfig
from pushtrain.planner.passage import passable, widest_gap
from pushtrain.planner.planner import plan
from pushtrain.planner.train import Train

PUBLIC = Path(__file__).resolve().parents[1] / "examples" / "maps" / "public"
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
    2m - 1 cells wide wall to wall), within one map cell; and the place named is that narrow."""
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
        expected = (2 * m - 1) * h
        assert gap.width == pytest.approx(expected, abs=h), (name, a, b, cell)
        # the place named lies on a passage that narrow (the test's own transform there)
        i, j = round((gap.y - grid.y0) / h), round((gap.x - grid.x0) / h)
        assert (2 * edt[i, j] - 1) * h == pytest.approx(gap.width, abs=h)
        # one labelling says the same as the bisection, either side of the width
        assert passable(field, pa, pb, 0.5 * expected - h)
        assert not passable(field, pa, pb, 0.5 * expected + 1.5 * h)
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
    assert b["width"] == pytest.approx((2 * m - 1) * h, abs=h)
    assert f"narrows to {b['width']:.2f} m" in str(err)
