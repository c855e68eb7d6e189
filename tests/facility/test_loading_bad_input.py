"""Bad map inputs (issue #29, round 3): each one is refused with exit 2 and a short message
naming the file or field, the value and what is allowed, fast, or warned about; never a
traceback.

Grids: an image whose header claims 20000 x 20000 pixels, a resolution of 1e-9 m, an origin
beyond 100 km, a YAML "billion laughs", a YAML file over 1 MiB, a huge quoted value. DXF floor
plans: files cut short, a line 1e12 m long, NaN and infinite coordinates, a room drawn as one
closed outline around the start, millimetres declared and inches asked for. Polygons: a
self-crossing free-space outline.
"""

from __future__ import annotations

import logging
import time
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from PIL import Image

from pushtrain.cli.main import cli
from pushtrain.errors import MapError, PlanningInputError
from pushtrain.facility.free_space import World, polygon_from_points
from pushtrain.facility.map_server import load_map, read_map_yaml

MAX_MESSAGE = 4000
"""Longest error output [characters] a bad map may give ("a few kB")."""


def _invoke(args) -> tuple[int, str]:
    result = CliRunner().invoke(cli, args)
    assert result.exception is None or isinstance(result.exception, SystemExit), (
        result.output, result.exception)
    assert "Traceback" not in result.output
    assert len(result.output) < MAX_MESSAGE, len(result.output)
    return result.exit_code, result.output


# ------------------------------------------------------------------------------ grids
def _grid_scenario(folder: Path, yaml_text: str, start=(1.0, 1.0), goal=(3.0, 1.0)) -> Path:
    (folder / "site.yaml").write_text(yaml_text)
    path = folder / "site.toml"
    path.write_text(f'[mission]\nkind = "plan"\n[train]\nn = 1\n[map]\ngrid = "site.yaml"\n'
                    f"[start]\nx = {start[0]}\ny = {start[1]}\ntheta_deg = 180.0\n"
                    f"[goal]\nx = {goal[0]}\ny = {goal[1]}\ntheta_deg = 180.0\n")
    return path


MAP_FIELDS = ("resolution: 0.05\norigin: [0.0, 0.0, 0.0]\nnegate: 0\noccupied_thresh: 0.65\n"
              "free_thresh: 0.196\n")


@pytest.mark.parametrize("width, height, body", [
    (20000, 20000, b"\0" * 1000),     # Pillow's own limit (179 M pixels) refuses it: a traceback
    (20000, 20000, b""),              # the header alone
    (6000, 5000, b"\0" * 1000),       # under Pillow's limits, over ours: refused before decoding
])
def test_an_image_too_large_is_refused_from_its_header(tmp_path, width, height, body):
    (tmp_path / "big.pgm").write_bytes(f"P5\n{width} {height}\n255\n".encode() + body)
    path = _grid_scenario(tmp_path, "image: big.pgm\n" + MAP_FIELDS)
    started = time.perf_counter()
    code, output = _invoke(["validate", str(path)])
    assert time.perf_counter() - started < 5.0
    assert code == 2, output
    assert "map.grid (site.yaml) image" in output and "big.pgm" in output
    size = f"{width} x {height} pixels" if width * height < 178956970 else \
        f"{width * height} pixels"
    assert size in output and "at most 25000000 pixels" in output, output


def test_a_resolution_of_a_nanometre_is_named(tmp_path):
    pixels = np.full((40, 80), 254, np.uint8)
    Image.fromarray(pixels).save(tmp_path / "room.pgm")
    path = _grid_scenario(tmp_path, "image: room.pgm\n" + MAP_FIELDS.replace("0.05", "1.0e-9"))
    code, output = _invoke(["validate", str(path)])
    assert code == 2, output
    assert "map.grid (site.yaml) resolution = 1e-09" in output, output
    assert "from 0.001 to 10 m per pixel" in output and "outside" not in output
    path = _grid_scenario(tmp_path, "image: room.pgm\n" + MAP_FIELDS.replace(
        "[0.0, 0.0, 0.0]", "[1.0e+12, 0.0, 0.0]"))
    code, output = _invoke(["validate", str(path)])
    assert code == 2 and "origin" in output and "from -100000 to 100000 m" in output, output


def _laughs(levels: int) -> str:
    """A YAML "billion laughs": each level a list of nine aliases of the level below."""
    lines = ['a0: &a0 ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]']
    for k in range(1, levels):
        lines.append(f"a{k}: &a{k} [" + ", ".join([f"*a{k - 1}"] * 9) + "]")
    return "\n".join(lines) + f"\nimage: *a{levels - 1}\n" + MAP_FIELDS


def test_yaml_aliases_are_refused_fast(tmp_path):
    """Seven levels (4.8 M strings: seconds and a 35 MB message before the fix; nine levels
    took 35 s and 312 MB) are refused at the first alias."""
    path = tmp_path / "laughs.yaml"
    path.write_text(_laughs(7))
    started = time.perf_counter()
    with pytest.raises(MapError) as info:
        read_map_yaml(path)
    assert time.perf_counter() - started < 1.0
    assert len(str(info.value)) < MAX_MESSAGE
    assert "an alias (*a0): aliases are not allowed in a map file" in str(info.value)
    assert info.value.errors[0][0] == "(syntax) line 2"
    scenario = _grid_scenario(tmp_path, _laughs(9))
    code, output = _invoke(["validate", str(scenario)])
    assert code == 2 and "map.grid (site.yaml) (syntax) line 2" in output, output


def test_yaml_nested_too_deeply_is_refused(tmp_path):
    """Found by tests/facility/test_loading_fuzz.py: PyYAML's composer recursed into a
    RecursionError."""
    path = tmp_path / "deep.yaml"
    path.write_text("image: " + "[" * 5000 + "]" * 5000 + "\n")
    with pytest.raises(MapError, match="not valid YAML: nested too deeply"):
        read_map_yaml(path)


@pytest.mark.slow
def test_large_yaml_files_and_values_give_short_messages(tmp_path):
    path = tmp_path / "large.yaml"
    path.write_text("image: map.pgm\n" + MAP_FIELDS + "comment: " + "x" * (1 << 20) + "\n")
    with pytest.raises(MapError, match=r"bytes: a map_server YAML file has at most 1048576"):
        read_map_yaml(path)
    path.write_text(MAP_FIELDS + "image: [" + ", ".join(["lol"] * 100_000) + "]\n")
    with pytest.raises(MapError) as info:
        read_map_yaml(path)
    text = str(info.value)
    assert len(text) < MAX_MESSAGE and "image = ['lol', 'lol'," in text
    assert "more characters)" in text


# ------------------------------------------------------------------------------ DXF
ezdxf = pytest.importorskip("ezdxf")


def _dxf_scenario(folder: Path, draw, units: int = 6, extra: str = "") -> Path:
    """A 10 m x 5 m hall walled by four lines on WALLS (a LINE, an open polyline), an inner
    wall, whatever ``draw(msp)`` adds, and a scenario from (3, 1) to (6, 1)."""
    doc = ezdxf.new(units=units)
    doc.layers.add("WALLS")
    msp = doc.modelspace()
    k = {6: 1.0, 4: 1000.0}[units]
    on = {"layer": "WALLS"}
    msp.add_lwpolyline([(0, 0), (10 * k, 0), (10 * k, 5 * k), (0, 5 * k)], dxfattribs=on)
    msp.add_line((0, 5 * k), (0, 0), dxfattribs=on)
    msp.add_line((2 * k, 2 * k), (4 * k, 2 * k), dxfattribs=on)
    draw(msp)
    doc.saveas(folder / "plan.dxf")
    path = folder / "plan.toml"
    path.write_text(f'[mission]\nkind = "plan"\n[train]\nn = 1\n[map]\ndxf = "plan.dxf"\n'
                    f'layers = ["WALLS"]\n{extra}\n[start]\nx = 3.0\ny = 1.0\ntheta_deg = 180.0\n'
                    "[goal]\nx = 6.0\ny = 1.0\ntheta_deg = 180.0\n")
    return path


def test_the_hall_itself_is_fine(tmp_path):
    assert _invoke(["validate", str(_dxf_scenario(tmp_path, lambda msp: None))])[0] == 0


def test_a_dxf_cut_short_names_the_file(tmp_path):
    """Every cut of the hall's file is a MapError (StopIteration, ValueError, IndexError
    tracebacks before the fix), and the CLI exits 2."""
    from pushtrain.facility.dxf import read_dxf

    path = _dxf_scenario(tmp_path, lambda msp: None)
    whole = (tmp_path / "plan.dxf").read_bytes()
    cut = tmp_path / "cut.dxf"
    for end in range(0, len(whole) - 20, 37):
        cut.write_bytes(whole[:end])
        with pytest.raises(MapError) as info:
            read_dxf(cut, ["WALLS"])
        (where, value, allowed), = info.value.errors
        assert where == "dxf" and value == str(cut), (end, info.value)
    (tmp_path / "plan.dxf").write_bytes(whole[:97])
    code, output = _invoke(["validate", str(path)])
    assert code == 2, output
    assert "plan.dxf" in output and "not a readable DXF file: cut short or damaged" in output


@pytest.mark.parametrize("what, draw, needles", [
    ("a line 1e12 m long", lambda msp: msp.add_line((0, 4), (1e12, 4), dxfattribs={
        "layer": "WALLS"}), ["LINE (handle", "on layer WALLS", "x from 0 to 1e+12 m",
                             "coordinates from -100000 to 100000 m"]),
    ("a NaN end", lambda msp: msp.add_line((0, 4), (float("nan"), 4), dxfattribs={
        "layer": "WALLS"}), ["LINE (handle", "on layer WALLS", "end = (nan, 4.0, 0.0)",
                             "finite numbers"]),
    ("an infinite end", lambda msp: msp.add_line((0, 4), (float("inf"), 4), dxfattribs={
        "layer": "WALLS"}), ["LINE (handle", "end = (inf, 4.0, 0.0)", "finite numbers"]),
    ("a NaN polyline point (a GEOS traceback before)", lambda msp: msp.add_lwpolyline(
        [(5, 3), (float("nan"), 3), (6, 4)], close=True, dxfattribs={"layer": "WALLS"}),
     ["LWPOLYLINE (handle", "a point at (nan, 3.0)", "finite coordinates"]),
    ("a NaN radius", lambda msp: msp.add_circle((5, 3), float("nan"), dxfattribs={
        "layer": "WALLS"}), ["CIRCLE (handle", "radius = nan", "finite numbers"]),
    ("a circle 2e6 km across (5 s to flatten before)", lambda msp: msp.add_circle(
        (5, 3), 1e9, dxfattribs={"layer": "WALLS"}), ["CIRCLE (handle", "x from -1e+09"]),
])
def test_non_finite_and_far_coordinates_are_named(tmp_path, what, draw, needles):
    path = _dxf_scenario(tmp_path, draw)
    started = time.perf_counter()
    code, output = _invoke(["validate", str(path)])
    assert time.perf_counter() - started < 5.0, what
    assert code == 2, (what, output)
    assert "map.dxf (plan.dxf)" in output, output
    for needle in needles:
        assert needle in output, (what, needle, output)


def test_a_room_drawn_closed_around_the_start_says_so(tmp_path):
    path = _dxf_scenario(tmp_path, lambda msp: msp.add_lwpolyline(
        [(1, 0.5), (8, 0.5), (8, 1.8), (1, 1.8)], close=True, dxfattribs={"layer": "WALLS"}))
    code, output = _invoke(["validate", str(path)])
    assert code == 2, output
    assert "start = '(3.0, 1.0)': must lie in the map's free space: (3, 1) m lies inside the " \
           "closed LWPOLYLINE (handle" in output, output
    assert "on layer WALLS of plan.dxf" in output
    assert "free space is the extent of plan.dxf minus what layers WALLS hold: closed shapes " \
           "(polylines, circles, ...) are solid" in output, output
    # outside the drawing's extent
    text = path.read_text().replace("x = 6.0", "x = 60.0")
    path.write_text(text)
    code, output = _invoke(["validate", str(path)])
    assert code == 2 and "(60, 1) m lies outside the extent of plan.dxf" in output, output


def test_units_declared_and_asked_for_differ_warns_naming_both(tmp_path, caplog):
    from pushtrain.facility.dxf import read_dxf

    _dxf_scenario(tmp_path, lambda msp: None, units=4)       # millimetres, 10 000 x 5 000
    with caplog.at_level(logging.WARNING, logger="pushtrain.facility.dxf"):
        plan = read_dxf(tmp_path / "plan.dxf", ["WALLS"], units="in")
    assert plan.scale == 0.0254
    (record,) = [r for r in caplog.records if "declares" in r.getMessage()]
    text = record.getMessage()
    assert "plan.dxf declares millimetres ($INSUNITS = 4)" in text, text
    assert "map.dxf_units = 'in' (inches): read as inches" in text, text
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="pushtrain.facility.dxf"):
        read_dxf(tmp_path / "plan.dxf", ["WALLS"], units="mm")
        read_dxf(tmp_path / "plan.dxf", ["WALLS"])
    assert not [r for r in caplog.records if "declares" in r.getMessage()]


# ------------------------------------------------------------------------------ polygons
BOWTIE = [[0.0, 0.0], [12.0, 0.0], [12.0, 3.0], [7.0, 3.0], [7.0, -1.0], [6.0, -1.0],
          [6.0, 3.0], [0.0, 3.0]]


def test_a_self_crossing_free_outline_is_refused_saying_where(tmp_path):
    path = tmp_path / "bow.toml"
    path.write_text(f'[mission]\nkind = "plan"\n[train]\nn = 1\n[map]\nfree = {BOWTIE}\n'
                    "[start]\nx = 2.0\ny = 1.0\ntheta_deg = 180.0\n"
                    "[goal]\nx = 10.0\ny = 1.0\ntheta_deg = 180.0\n")
    for command in (["validate", str(path)], ["plan", str(path)]):
        code, output = _invoke(command)
        assert code == 2, output
        assert "map.free = [[0.0, 0.0], [12.0, 0.0]," in output, output
        assert ": not a simple polygon (self-intersection at (7, 0) m): the outline of the free " \
               "space must not cross or touch itself" in output, output
    with pytest.raises(PlanningInputError, match=r"map.free is not a simple polygon "
                                                 r"\(self-intersection at \(7, 0\) m\)"):
        polygon_from_points(BOWTIE, "map.free", outline=True)
    # the planner's own worlds (World.from_dict) and obstacles are still repaired, with a warning
    world = World.from_dict({"bounds": [-1, -2, 13, 4], "obstacles": [BOWTIE]})
    assert world.free_area < 14 * 6
    assert World.from_dict({"free": BOWTIE}).free_area == pytest.approx(34.0)   # 3 parts


def test_load_map_still_reads_a_good_grid(tmp_path):
    pixels = np.full((40, 80), 254, np.uint8)
    Image.fromarray(pixels).save(tmp_path / "room.pgm")
    (tmp_path / "room.yaml").write_text("image: room.pgm\n" + MAP_FIELDS)
    assert load_map(tmp_path / "room.yaml").shape == (40, 80)


def test_a_spline_through_one_repeated_point_is_skipped_with_a_warning(tmp_path, caplog):
    """Found by tests/facility/test_loading_fuzz.py: ezdxf's path of such a spline raised
    IndexError."""
    path = _dxf_scenario(tmp_path, lambda msp: msp.add_spline([(5, 3)] * 4, dxfattribs={
        "layer": "WALLS"}))
    code, output = _invoke(["validate", str(path)])
    assert code == 0, output
    assert "SPLINE (handle" in caplog.text and "on layer WALLS skipped" in caplog.text


def test_a_drawing_with_thousands_of_layers_gives_a_short_message(tmp_path):
    def layers(msp):
        for k in range(3000):
            msp.doc.layers.add(f"LAYER_WITH_A_LONG_NAME_{k:05d}")

    path = _dxf_scenario(tmp_path, layers)
    path.write_text(path.read_text().replace('["WALLS"]', '["DOORS"]'))
    code, output = _invoke(["validate", str(path)])
    assert code == 2 and "map.layers = ['DOORS']: layers the drawing has: " in output, output
    assert "more characters)" in output


@pytest.mark.parametrize("which", ["yaml", "image", "dxf"])
def test_a_fifo_in_place_of_a_map_file_is_refused_not_waited_on(tmp_path, which):
    import os
    import signal

    def too_long(signum, frame):
        raise TimeoutError("waited on the FIFO")

    if which == "dxf":
        path = _dxf_scenario(tmp_path, lambda msp: None)
        (tmp_path / "plan.dxf").unlink()
        os.mkfifo(tmp_path / "plan.dxf")
    else:
        path = _grid_scenario(tmp_path, "image: room.pgm\n" + MAP_FIELDS)
        if which == "yaml":
            (tmp_path / "site.yaml").unlink()
            os.mkfifo(tmp_path / "site.yaml")
        else:
            os.mkfifo(tmp_path / "room.pgm")
    old = signal.signal(signal.SIGALRM, too_long)
    signal.alarm(5)
    try:
        code, output = _invoke(["validate", str(path)])
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)
    assert code == 2 and "not a regular file" in output, output
