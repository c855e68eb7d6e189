"""The prepared-map cache (facility/map_cache.py, issue 34 item 6): a second load of the same
map reads its traced polygons and distance field from disk; a changed map is prepared again;
a damaged file is said to be damaged, prepared again and rewritten."""

import logging

import numpy as np
import pytest
import shapely
from PIL import Image

from pushtrain.facility.distance_field import DistanceField
from pushtrain.facility.loading import grid_world
from pushtrain.facility.map_server import load_map
from pushtrain.facility.raster import blocked_polygons


@pytest.fixture
def cache(tmp_path, monkeypatch):
    folder = tmp_path / "cache"
    monkeypatch.setenv("PUSHTRAIN_CACHE", str(folder))
    return folder / "maps"


@pytest.fixture
def builds(monkeypatch):
    """How many times the map was traced and its distance field computed."""
    count = {"traced": 0, "field": 0}
    trace, field = blocked_polygons, DistanceField.from_occupancy

    def traced(*args, **kwargs):
        count["traced"] += 1
        return trace(*args, **kwargs)

    def computed(*args, **kwargs):
        count["field"] += 1
        return field(*args, **kwargs)

    monkeypatch.setattr("pushtrain.facility.loading.blocked_polygons", traced)
    monkeypatch.setattr(DistanceField, "from_occupancy", computed)
    return count


def _room(folder, wall_at: int = 30, name: str = "room"):
    """A 4 m x 3 m room at 5 cm with a wall stub (rows 0..29 of column ``wall_at``)."""
    pixels = np.full((60, 80), 254, dtype=np.uint8)
    pixels[[0, -1], :] = 0
    pixels[:, [0, -1]] = 0
    pixels[:30, wall_at] = 0
    Image.fromarray(pixels).save(folder / f"{name}.pgm")
    yaml = folder / f"{name}.yaml"
    yaml.write_text(f"image: {name}.pgm\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\n"
                    "negate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n")
    return yaml


def test_the_second_load_of_a_map_reads_the_cache(tmp_path, cache, builds):
    yaml = _room(tmp_path)
    first = grid_world(load_map(yaml))
    assert builds == {"traced": 1, "field": 1}
    assert len(list(cache.glob("*.npz"))) == 1
    second = grid_world(load_map(yaml))
    assert builds == {"traced": 1, "field": 1}  # nothing prepared again
    # the same map to the bit: the same plans
    assert np.array_equal(first.distance_field().values, second.distance_field().values)
    assert first.free.equals(second.free) and first.obstacles[0].equals(second.obstacles[0])
    # the file's name and place are no part of the key: a copy elsewhere is the same map
    copy = tmp_path / "copy"
    copy.mkdir()
    for f in tmp_path.glob("room.*"):
        (copy / f.name).write_bytes(f.read_bytes())
    grid_world(load_map(copy / "room.yaml"))
    assert builds == {"traced": 1, "field": 1}
    # and without the cache, all is prepared
    grid_world(load_map(yaml), cache=False)
    assert builds == {"traced": 2, "field": 2}


def test_a_changed_map_is_prepared_again(tmp_path, cache, builds):
    yaml = _room(tmp_path)
    before = grid_world(load_map(yaml)).distance_field()
    _room(tmp_path, wall_at=50)  # the wall stub moved
    after = grid_world(load_map(yaml)).distance_field()
    assert builds == {"traced": 2, "field": 2}
    assert len(list(cache.glob("*.npz"))) == 2
    assert not np.array_equal(before.values, after.values)
    # a scenario's polygon burned in is another map too
    from shapely.geometry import box

    grid_world(load_map(yaml), [box(1.0, 1.0, 1.5, 1.5)])
    assert builds == {"traced": 3, "field": 3}


def test_a_polygon_as_an_obstacle_and_as_the_keep_in_outline_are_two_maps(tmp_path, cache,
                                                                          builds):
    """The same box drawn on the room once as an obstacle (the room without it) and once as
    the keep-in outline (only the box): two cache entries, and each loads its own free space
    (they shared one key: the second read the first's). Areas against the room's own: 4 x 3 m
    less its border and wall stub, less or only the 1.5 m x 1 m box."""
    from shapely.geometry import box

    yaml = _room(tmp_path)
    piece = box(1.0, 1.0, 2.5, 2.0)
    for _ in range(2):  # built, then read back from the cache: the same answers
        without = grid_world(load_map(yaml), [piece])
        only = grid_world(load_map(yaml), keep_in=piece)
        assert without.cache_key != only.cache_key
        assert only.free_area == pytest.approx(piece.area, abs=0.05)
        assert without.free_area > 6.0  # the room (about 7.3 m2) less the box
        assert without.free.intersection(piece).area < 1e-9
        assert only.distance_field().at(1.75, 1.5) > 0.0
        assert without.distance_field().at(1.75, 1.5) < 0.0
    assert builds == {"traced": 2, "field": 2}
    assert len(list(cache.glob("*.npz"))) == 2


@pytest.mark.parametrize("damage", ["truncate", "flip", "garbage", "other map"])
def test_a_damaged_cache_is_rebuilt_and_says_so(tmp_path, cache, builds, caplog, damage):
    yaml = _room(tmp_path)
    good = grid_world(load_map(yaml)).distance_field().values.copy()
    (path,) = cache.glob("*.npz")
    data = bytearray(path.read_bytes())
    if damage == "truncate":
        data = data[: len(data) // 2]
    elif damage == "flip":  # a byte inside the field's values: only the CRC sees it
        data[len(data) // 2] ^= 0xFF
    elif damage == "garbage":
        data = bytearray(b"not a zip at all")
    else:  # a whole file of another map under this map's name
        other = _room(tmp_path, wall_at=60, name="other")
        grid_world(load_map(other))
        (path_other,) = set(cache.glob("*.npz")) - {path}
        data = bytearray(path_other.read_bytes())
    path.write_bytes(bytes(data))
    before = dict(builds)
    with caplog.at_level(logging.WARNING, logger="pushtrain.facility.map_cache"):
        again = grid_world(load_map(yaml)).distance_field().values
    assert builds["field"] == before["field"] + 1 and builds["traced"] == before["traced"] + 1
    assert np.array_equal(again, good)
    assert any("damaged" in r.getMessage() and path.name in r.getMessage()
               for r in caplog.records), caplog.text
    # rewritten whole: the next load is a hit
    grid_world(load_map(yaml))
    assert builds["field"] == before["field"] + 1


def test_a_cache_folder_that_cannot_be_written_leaves_the_map_in_memory(tmp_path, monkeypatch,
                                                                       caplog):
    blocker = tmp_path / "a file"
    blocker.write_text("x")
    monkeypatch.setenv("PUSHTRAIN_CACHE", str(blocker))
    with caplog.at_level(logging.WARNING, logger="pushtrain.facility.map_cache"):
        world = grid_world(load_map(_room(tmp_path)))
    assert world.distance_field().values.shape == (60, 80)
    assert "cannot be cached" in caplog.text


@pytest.fixture
def erosions(monkeypatch):
    """How many times a grid world's free space was eroded (traced at a margin)."""
    from pushtrain.facility import raster

    count = {"eroded": 0}
    clear_region = raster.clear_region

    def traced(*args, **kwargs):
        count["eroded"] += 1
        return clear_region(*args, **kwargs)

    monkeypatch.setattr(raster, "clear_region", traced)
    return count


def test_the_eroded_free_space_is_cached_with_the_map(tmp_path, cache, erosions):
    yaml = _room(tmp_path)
    built = grid_world(load_map(yaml)).eroded(0.1)
    assert erosions["eroded"] == 1
    (path,) = (cache / "eroded").glob("*.npz")
    again = grid_world(load_map(yaml))
    read = again.eroded(0.1)
    assert erosions["eroded"] == 1  # read back, not traced again
    # the same geometry to the bit, so the exact test decides the same
    assert shapely.to_wkb(read) == shapely.to_wkb(built)
    assert read.area < again.free.area  # and it is an erosion of the free space
    # another margin, or the map without the cache, is traced
    again.eroded(0.2)
    grid_world(load_map(yaml), cache=False).eroded(0.1)
    assert erosions["eroded"] == 3
    assert len(list((cache / "eroded").glob("*.npz"))) == 2
    # a changed map is another key
    _room(tmp_path, wall_at=50)
    moved = grid_world(load_map(yaml)).eroded(0.1)
    assert erosions["eroded"] == 4 and not moved.equals(built)


@pytest.mark.parametrize("damage", ["truncate", "garbage", "other margin"])
def test_a_damaged_eroded_cache_is_rebuilt_and_says_so(tmp_path, cache, erosions, caplog,
                                                       damage):
    yaml = _room(tmp_path)
    good = shapely.to_wkb(grid_world(load_map(yaml)).eroded(0.1))
    (path,) = (cache / "eroded").glob("*.npz")
    data = path.read_bytes()
    if damage == "truncate":
        data = data[: len(data) // 2]
    elif damage == "garbage":
        data = b"not a zip at all"
    else:  # the file of another margin under this margin's name
        grid_world(load_map(yaml)).eroded(0.2)
        (other,) = set((cache / "eroded").glob("*.npz")) - {path}
        data = other.read_bytes()
    path.write_bytes(data)
    before = erosions["eroded"]
    with caplog.at_level(logging.WARNING, logger="pushtrain.facility.map_cache"):
        again = grid_world(load_map(yaml)).eroded(0.1)
    assert erosions["eroded"] == before + 1
    assert shapely.to_wkb(again) == good
    assert any("damaged" in r.getMessage() and path.name in r.getMessage()
               for r in caplog.records), caplog.text
    grid_world(load_map(yaml)).eroded(0.1)  # rewritten whole: a hit
    assert erosions["eroded"] == before + 1
