"""benchmarks/prove_impossible.py on grids whose answer is known by geometry: two rooms joined by
a door k cells wide in a straight wall. A disc of radius r passes such a door exactly when
k h >= 2 r; the proof must never call a door it passes impossible, and must prove the doors
narrower by more than its slack (0.207 of a cell on the radius, rounded to whole cells)."""

import sys
from pathlib import Path

import numpy as np
import pytest

from pushtrain.facility.occupancy_grid import OccupancyGrid

BENCH = Path(__file__).resolve().parents[2] / "benchmarks"
sys.path.insert(0, str(BENCH))

import prove_impossible  # noqa: E402

H = 0.1


def _rooms(door_cells: int, wall_cells: int = 2) -> OccupancyGrid:
    """Two 3 m x 3 m rooms side by side (x), 10 cm cells, the wall between them with a door
    ``door_cells`` wide in its middle (none if 0)."""
    blocked = np.zeros((30, 62), dtype=bool)
    blocked[:, 30:30 + wall_cells] = True
    lo = 15 - door_cells // 2
    blocked[lo:lo + door_cells, 30:30 + wall_cells] = False
    return OccupancyGrid(blocked, 0.5 * H, 0.5 * H, H)


START, GOAL = (1.5, 1.5), (4.7, 1.5)


@pytest.mark.parametrize("radius", [0.25, 0.30, 0.35, 0.40])
@pytest.mark.parametrize("door_cells", range(3, 11))
def test_a_door_the_disc_passes_is_never_called_impossible(door_cells, radius):
    proof = prove_impossible.prove(_rooms(door_cells), START, GOAL, radius)
    if door_cells * H >= 2.0 * radius - 1e-9:
        assert proof is None, (door_cells, radius)
    if door_cells * H < 2.0 * (radius - 0.207 * H) - H:  # a whole cell below the slack
        assert proof is not None, (door_cells, radius)


def test_the_proof_names_the_door_and_its_width():
    """A 0.6 m door, 0.70 m needed (Table 1's trailer and 0.05 m of clearance): proven, the
    width within half a cell of 0.6 m, the place in the door."""
    proof = prove_impossible.prove(_rooms(6), START, GOAL, 0.35)
    assert proof is not None and proof.needed == pytest.approx(0.7)
    assert proof.width == pytest.approx(0.6, abs=0.5 * H)
    assert 3.0 <= proof.x <= 3.2 and 1.2 <= proof.y <= 1.8
    assert "0.50-0.60 m wide wall to wall" in proof.reason()


def test_rooms_with_no_door_are_separate_parts():
    proof = prove_impossible.prove(_rooms(0), START, GOAL, 0.35)
    assert proof is not None and proof.width == 0.0


def test_an_end_without_room_for_the_disc_proves_nothing():
    """The start itself in the door: the question is not the way, no proof."""
    assert prove_impossible.prove(_rooms(6), (3.05, 1.5), GOAL, 0.35) is None
