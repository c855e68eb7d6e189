"""benchmarks/prove_impossible.py on Worlds whose answer is known by geometry: two rooms joined
by a door of width D in a straight wall with square jambs. A disc of radius r passes such a door
exactly when D >= 2 r; the proof must never call a door it passes impossible, must prove every
narrower one, and must name D (within 2 mm) in the door."""

import sys
from pathlib import Path

import pytest
from shapely.geometry import box

from pushtrain.facility.free_space import World

BENCH = Path(__file__).resolve().parents[2] / "benchmarks"
sys.path.insert(0, str(BENCH))

import prove_impossible  # noqa: E402


def _rooms(door: float, wall: float = 0.2, angle_deg: float = 0.0) -> World:
    """Two 3 m x 3 m rooms side by side (x), the wall between them (``wall`` thick, at x = 3 m)
    with a door ``door`` [m] wide centred at y = 1.5 m (none if 0); the whole map turned by
    ``angle_deg`` round (3, 1.5) (so no edge need lie along an axis)."""
    from shapely import affinity

    outline = box(0.0, 0.0, 6.0 + wall, 3.0)
    below = box(3.0, 0.0, 3.0 + wall, 1.5 - 0.5 * door)
    above = box(3.0, 1.5 + 0.5 * door, 3.0 + wall, 3.0)
    parts = [outline, below, above]
    parts = [affinity.rotate(p, angle_deg, origin=(3.0, 1.5)) for p in parts]
    return World(outline=parts[0], obstacles=tuple(parts[1:]))


START, GOAL = (1.5, 1.5), (4.7, 1.5)


@pytest.mark.parametrize("radius", [0.25, 0.35])
@pytest.mark.parametrize("door", [0.30, 0.45, 0.49, 0.51, 0.60, 0.69, 0.70, 0.71, 0.90])
def test_a_door_the_disc_passes_is_never_called_impossible(door, radius):
    proof = prove_impossible.prove(_rooms(door).free, START, GOAL, radius)
    if door >= 2.0 * radius:
        assert proof is None, (door, radius)
    else:  # every narrower door is proven, naming its width
        assert proof is not None, (door, radius)
        assert proof.width == pytest.approx(door, abs=0.002)


@pytest.mark.parametrize("angle_deg", [0.0, 23.0, 45.0])
def test_the_proof_names_the_door_and_its_width(angle_deg):
    """A 0.6 m door, 0.70 m needed (Table 1's trailer and 0.05 m of clearance): proven, the
    width 0.6 m within 2 mm, the place in the door, however the map is turned."""
    from shapely import affinity
    from shapely.geometry import Point

    world = _rooms(0.6, angle_deg=angle_deg)
    start, goal = (affinity.rotate(Point(p), angle_deg, origin=(3.0, 1.5)).coords[0]
                   for p in (START, GOAL))
    proof = prove_impossible.prove(world.free, start, goal, 0.35)
    assert proof is not None and proof.needed == pytest.approx(0.7)
    assert proof.width == pytest.approx(0.6, abs=0.002)
    door_middle = affinity.rotate(Point(3.1, 1.5), angle_deg, origin=(3.0, 1.5))
    assert door_middle.distance(Point(proof.x, proof.y)) < 0.15
    assert "0.600 m" in proof.reason() or "0.599 m" in proof.reason() or "0.601 m" in (
        proof.reason())


def test_rooms_with_no_door_are_separate_parts():
    proof = prove_impossible.prove(_rooms(0.0).free, START, GOAL, 0.35)
    assert proof is not None and proof.width == 0.0


def test_an_end_without_room_for_the_disc_proves_nothing():
    """The start itself in the door: the question is not the way, no proof."""
    assert prove_impossible.prove(_rooms(0.6).free, (3.1, 1.5), GOAL, 0.35) is None


def test_the_disc_is_what_the_planner_asks_of_the_train():
    """The proof's radius is the planner's needed_half_width: for the benchmark's trains and
    for a last trailer shorter than it is wide, its axle off centre (the rectangle's end
    nearer than its side)."""
    import dataclasses

    import bench_facility

    from pushtrain.mission import runner
    from pushtrain.planner.passage import needed_half_width
    from pushtrain.planner.train import BodyFootprint

    mission = next(m for m in bench_facility.load_missions() if "grid" in m)
    train = runner.train_of(bench_facility.scenario_of(mission, None))
    stubby = dataclasses.replace(train, trailers=train.trailers[:-1] + (
        BodyFootprint(0.5, 0.6, 0.1),))
    assert prove_impossible.disc_radius(stubby, 0.0) == pytest.approx(0.15)
    for t in (train, stubby):
        for clearance in (0.0, 0.05, 0.12):
            assert prove_impossible.disc_radius(t, clearance) == pytest.approx(
                needed_half_width(t, clearance))
