"""DXF floor plans: closed shapes and thickened lines on the named layers, units, block
references, the errors (missing layers, missing ezdxf) and the bundled floor plan."""

from __future__ import annotations

import math
import os
import sys
import time
from pathlib import Path

import pytest
from click.testing import CliRunner
from shapely.geometry import Point

from pushtrain.cli.main import cli
from pushtrain.errors import MapError
from pushtrain.facility.dxf import read_dxf
from pushtrain.facility.loading import map_world

ezdxf = pytest.importorskip("ezdxf")  # the test extras install it (pip install -e ".[test]")

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def write_plan(path: Path, units: int = 4, scale: float = 1000.0) -> Path:
    """A plan in drawing units (``scale`` per metre, $INSUNITS ``units``): a LINE wall 10 m long
    on WALLS, a closed 2 m x 1 m rack on Racks, a column block (0.4 m square, drawn on layer 0)
    placed on RACKS at (6, 3), a circle r = 0.5 m on RACKS, and a line on NOTES."""
    doc = ezdxf.new(units=units)
    for name in ("WALLS", "Racks", "NOTES"):
        doc.layers.add(name)
    msp = doc.modelspace()

    def u(x, y):
        return (x * scale, y * scale)

    msp.add_line(u(0, 0), u(10, 0), dxfattribs={"layer": "WALLS"})
    msp.add_lwpolyline([u(2, 2), u(4, 2), u(4, 3), u(2, 3)], close=True,
                       dxfattribs={"layer": "Racks"})
    block = doc.blocks.new("COLUMN")
    block.add_lwpolyline([u(-0.2, -0.2), u(0.2, -0.2), u(0.2, 0.2), u(-0.2, 0.2)], close=True)
    msp.add_blockref("COLUMN", u(6, 3), dxfattribs={"layer": "RACKS"})
    msp.add_circle(u(8, 4), 0.5 * scale, dxfattribs={"layer": "RACKS"})
    msp.add_line(u(0, 5), u(10, 5), dxfattribs={"layer": "NOTES"})
    if units == 0:
        doc.header["$INSUNITS"] = 0
    doc.saveas(path)
    return path


def _areas(plan):
    return sorted(round(p.area, 4) for p in plan.obstacles)


@pytest.mark.parametrize("units, scale", [(4, 1000.0), (1, 1 / 0.0254), (6, 1.0)])
def test_shapes_layers_and_units(tmp_path, units, scale):
    path = write_plan(tmp_path / "plan.dxf", units, scale)
    plan = read_dxf(path, ["walls", "RACKS"], line_thickness=0.1)
    # wall: 10 m x 0.1 m with square ends (0.05 m beyond each end); rack 2 m2; column 0.16 m2;
    # circle pi 0.25 m2, flattened within 2 mm: at most its perimeter x 2 mm less
    wall = (10.0 + 0.1) * 0.1
    areas = _areas(plan)
    assert [areas[0], areas[2], areas[3]] == pytest.approx([0.16, wall, 2.0], abs=1e-4)
    assert math.pi * 0.25 - math.pi * 0.002 <= areas[1] <= math.pi * 0.25
    assert plan.counts == {"WALLS": 1, "Racks": 3}
    assert plan.scale == pytest.approx({4: 0.001, 1: 0.0254, 6: 1.0}[units])
    world = map_world(dxf=str(path), layers=["WALLS", "RACKS"], line_thickness=0.1)
    free = world.free
    assert not free.contains(Point(3.0, 2.5)) and not free.contains(Point(6.1, 3.1))
    assert not free.contains(Point(8.0, 4.0)) and free.contains(Point(5.0, 1.0))
    assert free.contains(Point(5.0, 4.45))             # the NOTES line is not read
    assert world.outline.bounds == pytest.approx((-0.05, -0.05, 10.05, 4.5), abs=1e-6)


def test_unitless_drawings_are_metres_unless_told(tmp_path):
    path = write_plan(tmp_path / "plan.dxf", units=0, scale=100.0)   # drawn in cm, says nothing
    assert read_dxf(path, ["RACKS"]).bounds[2] == pytest.approx(850.0, rel=1e-3)
    plan = read_dxf(path, ["RACKS"], units="cm")
    assert plan.bounds == pytest.approx((2.0, 2.0, 8.5, 4.5), abs=1e-3)


def test_missing_layers_and_empty_layers_are_named(tmp_path):
    path = write_plan(tmp_path / "plan.dxf")
    with pytest.raises(MapError) as info:
        read_dxf(path, ["WALLS", "DOORS"])
    (where, value, allowed), = info.value.errors
    assert where == "layers" and value == ["DOORS"] and "WALLS" in allowed and "Racks" in allowed
    doc = ezdxf.readfile(path)
    doc.layers.add("EMPTY")
    doc.saveas(path)
    with pytest.raises(MapError, match="must hold a line"):
        read_dxf(path, ["EMPTY"])
    (tmp_path / "junk.dxf").write_text("not a drawing\n")
    with pytest.raises(MapError, match="junk.dxf"):
        read_dxf(tmp_path / "junk.dxf", ["WALLS"])


def _dxf_scenario(folder: Path, layers='["WALLS", "RACKS"]') -> Path:
    write_plan(folder / "plan.dxf")
    text = (f'[mission]\nkind = "plan"\n[train]\nn = 1\n[map]\ndxf = "plan.dxf"\n'
            f"layers = {layers}\n[start]\nx = 3.0\ny = 1.0\ntheta_deg = 180.0\n"
            "[goal]\nx = 5.0\ny = 1.0\ntheta_deg = 180.0\n")
    path = folder / "floor.toml"
    path.write_text(text)
    return path


def test_a_dxf_without_the_named_layers_exits_2(tmp_path):
    path = _dxf_scenario(tmp_path, '["WALLS", "DOORS"]')
    result = CliRunner().invoke(cli, ["validate", str(path)])
    assert result.exit_code == 2, result.output
    assert "map.layers" in result.output and "DOORS" in result.output
    assert "layers the drawing has" in result.output


def test_missing_ezdxf_names_the_extra(tmp_path, monkeypatch):
    path = _dxf_scenario(tmp_path)
    assert CliRunner().invoke(cli, ["validate", str(path)]).exit_code == 0
    monkeypatch.setitem(sys.modules, "ezdxf", None)          # import ezdxf now fails
    from pushtrain.mission import runner

    monkeypatch.setattr(runner, "_WORLDS", {})
    result = CliRunner().invoke(cli, ["validate", str(path)])
    assert result.exit_code == 2, result.output
    assert "map.dxf" in result.output and "pip install 'pushtrain[cad]'" in result.output


def test_the_bundled_floor_plan(tmp_path):
    """The example's drawing: what the script writes has the layers the scenario reads, and the
    doorway is open only because DIMENSIONS is not read."""
    import importlib.util

    spec = importlib.util.spec_from_file_location(
        "make_floor_dxf", EXAMPLES / "maps" / "make_floor_dxf.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    module.main(["--out", str(tmp_path)])
    for path in (tmp_path / "floor.dxf", EXAMPLES / "maps" / "floor.dxf"):
        plan = read_dxf(path, ["WALLS", "RACKS"], line_thickness=0.15)
        assert plan.counts == {"WALLS": 6, "RACKS": 6}
        assert plan.bounds == pytest.approx((-0.075, -0.075, 20.075, 12.075))
        world = map_world(dxf=str(path), layers=["WALLS", "RACKS"], line_thickness=0.15)
        assert world.free.contains(Point(12.0, 6.0))                      # the doorway
        shut = map_world(dxf=str(path), layers=["WALLS", "RACKS", "DIMENSIONS"])
        assert not shut.free.contains(Point(12.0, 6.0))


@pytest.mark.slow
def test_the_floor_plan_script_is_reproducible(tmp_path):
    """Run as the README says, twice a second apart: the same bytes, and the committed
    floor.dxf is what it writes (no dates, random GUIDs or time stamps inside)."""
    import subprocess

    script = EXAMPLES / "maps" / "make_floor_dxf.py"
    for name, seed in (("a", "1"), ("b", "2")):  # a set's order varies with the hash seed
        subprocess.run([sys.executable, str(script), "--out", str(tmp_path / name)], check=True,
                       capture_output=True, timeout=300, env={**os.environ,
                                                              "PYTHONHASHSEED": seed})
        time.sleep(1.1)  # a time stamp to the second would differ
    first = (tmp_path / "a" / "floor.dxf").read_bytes()
    assert first == (tmp_path / "b" / "floor.dxf").read_bytes()
    assert first == (EXAMPLES / "maps" / "floor.dxf").read_bytes()


def _lines_dxf(path: Path, count: int) -> Path:
    """A minimal ASCII DXF (R12 form) of ``count`` LINE entities on layer WALLS."""
    line = "  0\nLINE\n  8\nWALLS\n 10\n0.0\n 20\n0.0\n 30\n0.0\n 11\n1.0\n 21\n1.0\n 31\n0.0\n"
    with open(path, "w") as f:
        f.write("  0\nSECTION\n  2\nENTITIES\n")
        for _ in range(count):
            f.write(line)
        f.write("  0\nENDSEC\n  0\nEOF\n")
    return path


def test_too_many_entities_are_refused_from_their_count_within_seconds(tmp_path):
    """300,000 entities: ezdxf took 57-123 s to read them before the count refused them; the
    group codes are counted first (a bound against minutes, not a timing)."""
    from pushtrain.facility.dxf import MAX_ENTITIES

    path = _lines_dxf(tmp_path / "huge.dxf", 300_000)
    t0 = time.process_time()
    with pytest.raises(MapError) as info:
        read_dxf(path, ["WALLS"])
    assert time.process_time() - t0 < 15.0
    assert f"more than {MAX_ENTITIES} entities" in str(info.value)
    assert "huge.dxf" in str(info.value)


def test_the_entity_count_agrees_with_ezdxf(tmp_path):
    """The pre-count is the number of model-space entities ezdxf reads (sub-entities such as a
    polyline's vertices not counted), for the bundled plan and a small line file."""
    from pushtrain.facility.dxf import _count_entities

    for path in (EXAMPLES / "maps" / "floor.dxf", _lines_dxf(tmp_path / "few.dxf", 7)):
        doc = ezdxf.readfile(path)
        want = len(doc.modelspace()) + len(doc.paperspace())
        assert _count_entities(path, 10**6) == want, path
    doc = ezdxf.new("R12")
    doc.modelspace().add_polyline2d([(0, 0), (1, 0), (1, 1)])  # POLYLINE, 3 VERTEX, SEQEND
    doc.saveas(tmp_path / "poly.dxf")
    assert _count_entities(tmp_path / "poly.dxf", 10**6) == 1
