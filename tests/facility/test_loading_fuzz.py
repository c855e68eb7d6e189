"""Property-based tests of map files: random image headers and pixels (PGM, PNG), map_server YAML
fields and text, and DXF entities (with extreme and non-finite coordinates, units, block
references, files cut short or damaged), each planned with ``pushtrain plan``.

Every example must end in a plan (exit 0), no plan (exit 1) or refused input (exit 2), never a
traceback, with an output of at most :data:`MAX_OUTPUT` characters. Each CLI call runs in a
forked child whose address space may grow by at most :data:`MEMORY_CAP` bytes and which is
killed after :data:`TIME_CAP` seconds, so that a map that eats the memory or hangs is a red test,
not a dead CI. The maps are a few metres across and the planner's budget 0.3 s: 0.1 to 1 s an
example, 30 examples a test (set ``PUSHTRAIN_MAP_FUZZ_EXAMPLES`` to search longer, and
``PUSHTRAIN_MAP_FUZZ_EVENTS=1`` with ``--hypothesis-show-statistics`` to see what the calls
said).
"""

from __future__ import annotations

import math
import multiprocessing
import os
import struct
import sys
import traceback
import zlib
from pathlib import Path

import numpy as np
import pytest
import yaml
from click.testing import CliRunner
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from pushtrain.cli.main import cli

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"),
                                reason="the caps use fork and /proc (Linux)")

MEMORY_CAP = 1536 << 20
"""Address space [bytes] a CLI call may add to the test process's (a plan on a small map needs
some 300 MB; decoding a 20000 x 20000 image as float64 would need 3.2 GB)."""

TIME_CAP = 60.0
"""Wall time [s] a CLI call may take (a plan of 0.3 s budget on a small map takes about 1 s)."""

MAX_OUTPUT = 4096
"""Longest output [characters] of one call: every message under a few kB."""

EXAMPLES = int(os.environ.get("PUSHTRAIN_MAP_FUZZ_EXAMPLES", "30"))
"""Examples per test (0.1 to 1 s each)."""

SETTINGS = settings(max_examples=EXAMPLES, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


# ------------------------------------------------------------------------ the capped call
def _address_space() -> int:
    """The process's virtual memory size [bytes] (VmSize)."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmSize:"):
            return int(line.split()[1]) * 1024
    raise RuntimeError("no VmSize in /proc/self/status")


def _child(args, conn, limit: int) -> None:
    import resource

    try:
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
        result = CliRunner().invoke(cli, args)
        exc = result.exception
        crash = (None if exc is None or isinstance(exc, SystemExit) else
                 "".join(traceback.format_exception(exc))[-4000:])
        conn.send((result.exit_code, result.output[:2 * MAX_OUTPUT], len(result.output), crash))
    except BaseException as exc:  # noqa: B036 (reported to the parent, whatever it is)
        conn.send((None, "", 0, "".join(traceback.format_exception(exc))[-4000:]))
    finally:
        conn.close()


def run_capped(args) -> tuple[int, str]:
    """(exit code, output) of ``pushtrain ARGS`` in a forked child capped in memory and time;
    fails the test on a traceback, a crash, a time-out, another exit code or a long output."""
    ctx = multiprocessing.get_context("fork")
    receive, send = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=_child, args=(args, send, _address_space() + MEMORY_CAP),
                       daemon=True)
    proc.start()
    send.close()
    try:
        if not receive.poll(TIME_CAP):
            pytest.fail(f"pushtrain {' '.join(args)} took over {TIME_CAP} s")
        try:
            code, output, length, crash = receive.recv()
        except EOFError:
            proc.join(5.0)
            pytest.fail(f"pushtrain {' '.join(args)} died (exit code {proc.exitcode})")
    finally:
        if proc.is_alive():
            proc.kill()
        proc.join()
        receive.close()
    assert crash is None, crash
    assert "Traceback" not in output, output
    assert code in (0, 1, 2), (code, output)
    assert length <= MAX_OUTPUT, (length, output[:MAX_OUTPUT])
    event(f"exit {code}")
    if os.environ.get("PUSHTRAIN_MAP_FUZZ_EVENTS"):  # what the refusals say, to tune the search
        event(" ".join(output.split())[:90])
    return code, output


def _scenario(folder: Path, map_lines: str, start, goal) -> Path:
    """A plan mission of one trailer pushed from ``start`` to ``goal`` (x, y) [m] (the robot
    1 m behind, at -x) on the map ``map_lines``, with 0.3 s of planning."""
    path = folder / "fuzz.toml"
    path.write_text(f'[mission]\nkind = "plan"\n[train]\nn = 1\n[map]\n{map_lines}\n'
                    f"[start]\nx = {start[0]}\ny = {start[1]}\ntheta_deg = 180.0\n"
                    f"[goal]\nx = {goal[0]}\ny = {goal[1]}\ntheta_deg = 180.0\n"
                    "[planner]\ntime_budget = 0.3\n")
    return path


def _plan(path: Path) -> tuple[int, str]:
    return run_capped(["plan", str(path)])


# ------------------------------------------------------------------------------- images
SIZES = st.one_of(st.integers(0, 120), st.sampled_from([-3, 5001, 20000, 65536, 10**9, 2**31]))
BYTES = st.binary(max_size=300)


@st.composite
def pixels(draw) -> np.ndarray:
    """A small grey image (row 0 at the top): mostly free (254) with blocks of other values."""
    if draw(st.booleans()):                        # big enough for the mission: 3.5 m x 1.5 m
        height, width = draw(st.integers(30, 60)), draw(st.integers(70, 100))
    else:
        height, width = draw(st.integers(1, 100)), draw(st.integers(1, 120))
    grey = np.full((height, width), draw(st.sampled_from([254, 254, 255, 205, 0, 128])),
                   dtype=np.uint8)
    for _ in range(draw(st.integers(0, 4))):
        r, c = draw(st.integers(0, height - 1)), draw(st.integers(0, width - 1))
        grey[r:r + draw(st.integers(1, 30)), c:c + draw(st.integers(1, 30))] = draw(
            st.integers(0, 255))
    return grey


def _png_chunk(kind: bytes, data: bytes) -> bytes:
    return (struct.pack(">I", len(data)) + kind + data
            + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF))


@st.composite
def image_files(draw) -> tuple[str, bytes]:
    """(file name, bytes) of an image: a PGM header with any size and maximum and any body, a
    PNG header with any size, an image Pillow writes in some mode, or bytes."""
    kind = draw(st.sampled_from(["pgm_header", "png_header", "pillow", "pillow", "pillow",
                                 "bytes"]))
    event(f"image: {kind}")
    if kind == "pgm_header":
        width, height = draw(SIZES), draw(SIZES)
        maxval = draw(st.sampled_from([255, 255, 1, 0, 65535, 65536, 300]))
        magic = draw(st.sampled_from(["P5", "P5", "P2", "P4", "P6"]))
        header = f"{magic}\n{width} {height}\n{maxval}\n".encode()
        if magic == "P5" and maxval == 255 and 0 < width * height <= 12000 and draw(
                st.booleans()):
            body = np.full(width * height, 254, np.uint8).tobytes()   # a whole free image
        else:
            body = draw(BYTES)
        return "map.pgm", header + body
    if kind == "png_header":
        ihdr = struct.pack(">IIBBBBB", draw(SIZES) % 2**32, draw(SIZES) % 2**32,
                           draw(st.sampled_from([8, 1, 16, 3])), draw(st.sampled_from([0, 2, 4,
                                                                                        6, 3])),
                           0, 0, 0)
        body = draw(st.one_of(st.just(b""), BYTES.map(lambda b: _png_chunk(b"IDAT", b))))
        return "map.png", b"\x89PNG\r\n\x1a\n" + _png_chunk(b"IHDR", ihdr) + body
    if kind == "pillow":
        from io import BytesIO

        from PIL import Image

        grey = draw(pixels())
        mode = draw(st.sampled_from(["L", "LA", "RGB", "RGBA", "P", "1", "I;16"]))
        image = Image.fromarray(grey).convert(mode) if mode != "I;16" else Image.fromarray(
            grey.astype(np.uint16) * 257)
        fmt = "PNG" if mode not in ("L", "1") or draw(st.booleans()) else "PPM"
        out = BytesIO()
        image.save(out, format=fmt)
        data = out.getvalue()
        if draw(st.integers(0, 3)) == 0:                            # cut short
            data = data[:draw(st.integers(0, len(data)))]
        return ("map.png" if fmt == "PNG" else "map.pgm"), data
    return draw(st.sampled_from(["map.pgm", "map.png", "map.jpg"])), draw(BYTES)


# ------------------------------------------------------------------------------- YAML
FIELD_VALUES = {
    "resolution": [0.05, 0.05, 0.1, 1e-9, 1e-3, 0, -0.05, 1e9, math.nan, math.inf, "fine", None,
                   True, [0.05]],
    "origin": [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [-0.5, -0.5, 0.4], [1e12, 0.0, 0.0],
               [math.nan, 0.0, 0.0], [0.0, 0.0, math.inf], [0.0, 0.0], "here", None,
               [0.0, 0.0, 1e300]],
    "negate": [0, 0, 1, 2, 0.5, True, "yes", None],
    "occupied_thresh": [0.65, 0.65, 1.5, -1, math.nan, 0.1, "high"],
    "free_thresh": [0.196, 0.196, 0.9, -0.1, math.nan, 0.0, 1.0],
    "mode": ["trinary", "trinary", "scale", "raw", "binary", 3, None, ["scale"]],
}
NASTY_YAML = [
    "a: &a [x, x, x, x, x, x, x, x, x]\nb: &b [*a, *a, *a, *a, *a, *a, *a, *a, *a]\n"
    "c: &c [*b, *b, *b, *b, *b, *b, *b, *b, *b]\nimage: *c\n",
    "[" * 5000 + "]" * 5000 + "\n",
    "{" * 3000 + "\n",
    "image: !!python/object/apply:os.system [echo hi]\n",
    "image: map.pgm\n\tresolution: 0.05\n",
    "- image\n- map.pgm\n",
    "",
    "image: " + "x" * 100_000 + "\n",
    "image: map.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n" + "k: v\n" * 20_000,
    "\xff\xfe binary",
]


@st.composite
def yaml_texts(draw, image: str) -> str:
    """A map_server YAML naming ``image``: fields replaced by wrong or extreme values, left out,
    other keys added, or a nasty text (aliases, deep nesting, tags, tabs, huge values)."""
    if draw(st.integers(0, 7)) == 0:
        event("yaml: nasty text")
        return draw(st.sampled_from(NASTY_YAML))
    data = {"image": draw(st.sampled_from(["missing.pgm", "", ".", "/", None, "fuzz.yaml", 7]))
            if draw(st.integers(0, 7)) == 0 else image}
    for key, values in FIELD_VALUES.items():
        value = draw(st.sampled_from(values)) if draw(st.integers(0, 3)) == 0 else values[0]
        if value is not None or draw(st.booleans()):
            data[key] = value
    if draw(st.booleans()):
        data[draw(st.text(min_size=1, max_size=8))] = draw(st.one_of(st.integers(),
                                                                     st.text(max_size=20)))
    return yaml.safe_dump(data, allow_unicode=True)


def _room() -> bytes:
    """A 5 m x 2.5 m room at 5 cm a pixel, walls 10 cm thick, as a PGM: the mission fits."""
    from io import BytesIO

    from PIL import Image

    grey = np.full((50, 100), 254, np.uint8)
    grey[:2], grey[-2:], grey[:, :2], grey[:, -2:] = 0, 0, 0, 0
    out = BytesIO()
    Image.fromarray(grey).save(out, format="PPM")
    return out.getvalue()


@pytest.mark.slow
@SETTINGS
@given(focus=st.sampled_from(["image", "yaml", "both"]), data=st.data())
def test_random_grid_maps_plan_or_exit_1_or_2(tmp_path_factory, focus, data):
    """A random image with good fields, a good room with random fields, or both random."""
    folder = tmp_path_factory.mktemp("grid")
    name, raw = data.draw(image_files()) if focus != "yaml" else ("map.pgm", _room())
    (folder / name).write_bytes(raw)
    text = (data.draw(yaml_texts(name)) if focus != "image" else
            yaml.safe_dump({"image": name, **{k: v[0] for k, v in FIELD_VALUES.items()}}))
    (folder / "fuzz.yaml").write_bytes(text.encode("utf-8", "surrogatepass"))
    _plan(_scenario(folder, 'grid = "fuzz.yaml"', start=(2.0, 1.2), goal=(3.5, 1.2)))


# ------------------------------------------------------------------------------- DXF
NUMBERS = st.one_of(st.floats(-1.0, 12.0), st.floats(-1.0, 12.0), st.floats(-1.0, 12.0),
                    st.sampled_from([math.nan, math.inf, -math.inf, 1e12, -1e6, 1e5, 0.0, 1e-300,
                                     1e300]))
POINTS = st.tuples(NUMBERS, NUMBERS)
"""Coordinates: mostly in and around the hall, sometimes extreme or not finite."""
LAYERS = st.sampled_from(["WALLS", "WALLS", "WALLS", "OTHER", "0"])


@st.composite
def entities(draw):
    """(kind, arguments) of one entity to add to the model space."""
    kind = draw(st.sampled_from(["LINE", "LWPOLYLINE", "CIRCLE", "ARC", "ELLIPSE", "SPLINE",
                                 "INSERT", "TEXT", "POLYLINE"]))
    layer = draw(LAYERS)
    if kind == "LINE":
        args = (draw(POINTS), draw(POINTS))
    elif kind in ("LWPOLYLINE", "POLYLINE"):
        points = draw(st.lists(POINTS, min_size=0, max_size=6))
        bulges = draw(st.lists(st.sampled_from([0.0, 0.0, 0.5, -1.0, 1e6, math.nan]),
                               min_size=len(points), max_size=len(points)))
        args = (points, bulges, draw(st.booleans()))
    elif kind == "CIRCLE":
        args = (draw(POINTS), draw(NUMBERS))
    elif kind == "ARC":
        args = (draw(POINTS), draw(NUMBERS), draw(NUMBERS) * 30, draw(NUMBERS) * 30)
    elif kind == "ELLIPSE":
        # ezdxf refuses to write a ratio outside [1e-10, 1]; the major axis may be anything
        args = (draw(POINTS), draw(POINTS), draw(st.sampled_from([0.5, 1.0, 1e-9])))
    elif kind == "SPLINE":
        args = (draw(st.lists(POINTS, min_size=0, max_size=6)), draw(st.booleans()))
    elif kind == "INSERT":
        args = (draw(POINTS), draw(st.sampled_from([1.0, 1.0, 0.001, 1e9, 0.0, -1.0, math.nan])),
                draw(NUMBERS) * 30, draw(st.integers(0, 3)))
    else:
        args = (draw(POINTS),)
    return kind, layer, args


def _add(doc, msp, kind: str, layer: str, args) -> None:
    on = {"layer": layer}
    if kind == "LINE":
        msp.add_line((*args[0], 0.0), (*args[1], 0.0), dxfattribs=on)
    elif kind == "LWPOLYLINE":
        points, bulges, closed = args
        msp.add_lwpolyline([(x, y, 0.0, 0.0, b) for (x, y), b in zip(points, bulges,
                                                                     strict=True)],
                           format="xyseb", close=closed, dxfattribs=on)
    elif kind == "POLYLINE":
        points, _, closed = args
        msp.add_polyline2d(points, close=closed, dxfattribs=on)
    elif kind == "CIRCLE":
        msp.add_circle(args[0], args[1], dxfattribs=on)
    elif kind == "ARC":
        msp.add_arc(*args, dxfattribs=on)
    elif kind == "ELLIPSE":
        centre, major, ratio = args
        msp.add_ellipse(centre, (*major, 0.0), ratio, dxfattribs=on)
    elif kind == "SPLINE":
        points, closed = args
        msp.add_spline(points, dxfattribs=on).closed = closed
    elif kind == "INSERT":
        point, scale, angle, depth = args
        name = f"B{depth}"
        if name not in doc.blocks:
            for k in range(depth + 1):      # B0 a column; Bk ten references to B(k-1)
                block = doc.blocks.new(f"B{k}") if f"B{k}" not in doc.blocks else None
                if block is None:
                    continue
                if k == 0:
                    block.add_lwpolyline([(0, 0), (0.3, 0), (0.3, 0.3), (0, 0.3)], close=True)
                else:
                    for j in range(10):
                        block.add_blockref(f"B{k - 1}", (0.4 * j, 0.0))
        msp.add_blockref(name, point, dxfattribs={**on, "xscale": scale, "yscale": scale,
                                                  "rotation": angle})
    else:
        msp.add_text("note", dxfattribs=on).set_placement(args[0])


@st.composite
def dxf_files(draw) -> tuple[bytes, str]:
    """(bytes of a DXF, the scenario's [map] lines): a 6 m x 3 m hall (walls drawn as lines,
    in the declared units) or none, random entities, random $INSUNITS, dxf_units, layers and
    line_thickness, and the file maybe cut short or damaged."""
    import io

    import ezdxf

    insunits = draw(st.sampled_from([6, 6, 0, 4, 1, 5, 21, 99]))
    doc = ezdxf.new(units=6)
    doc.header["$INSUNITS"] = insunits
    doc.layers.add("WALLS")
    doc.layers.add("OTHER")
    msp = doc.modelspace()
    if draw(st.integers(0, 4)) > 0:
        k = {4: 1000.0, 1: 1 / 0.0254, 5: 100.0}.get(insunits, 1.0)
        corners = [(0, 0), (6 * k, 0), (6 * k, 3 * k), (0, 3 * k), (0, 0)]
        for a, b in zip(corners, corners[1:], strict=False):
            msp.add_line(a, b, dxfattribs={"layer": "WALLS"})
    for kind, layer, args in draw(st.lists(entities(), max_size=draw(st.sampled_from([0, 2, 5])))):
        try:
            _add(doc, msp, kind, layer, args)
        except (ezdxf.DXFError, ValueError, TypeError, ZeroDivisionError, IndexError):
            event(f"dxf: ezdxf refused to write a {kind}")
    out = io.StringIO()
    doc.write(out)
    raw = out.getvalue().encode("utf-8", "surrogateescape")
    damage = draw(st.sampled_from(["none", "none", "none", "none", "cut", "byte"]))
    event(f"dxf damage: {damage}")
    where = draw(st.floats(0.0, 1.0))   # a fraction: the file's length varies (its GUIDs, dates)
    if damage == "cut":
        raw = raw[:int(where * len(raw))]
    elif damage == "byte":
        at = min(int(where * len(raw)), len(raw) - 1)
        raw = raw[:at] + draw(st.sampled_from([b"\xff", b"\n", b"nan", b"-", b"9"])) + raw[at + 1:]
    lines = ['dxf = "fuzz.dxf"',
             "layers = " + draw(st.sampled_from(['["WALLS"]', '["WALLS"]', '["WALLS", "OTHER"]',
                                                 '["MISSING"]', '["walls", "0"]']))]
    units = draw(st.sampled_from([None, None, None, "m", "mm", "in"]))
    if units:
        lines.append(f'dxf_units = "{units}"')
    thickness = draw(st.sampled_from([None, None, 0.15, 1e-9, 50.0]))
    if thickness:
        lines.append(f"line_thickness = {thickness}")
    return raw, "\n".join(lines)


@pytest.mark.slow
@SETTINGS
@given(case=dxf_files())
def test_random_floor_plans_plan_or_exit_1_or_2(tmp_path_factory, case):
    pytest.importorskip("ezdxf")
    raw, map_lines = case
    folder = tmp_path_factory.mktemp("dxf")
    (folder / "fuzz.dxf").write_bytes(raw)
    _plan(_scenario(folder, map_lines, start=(1.5, 1.5), goal=(4.0, 1.5)))


def _runaway(monkeypatch, folder: Path, read_pixels) -> Path:
    """A small grid scenario whose image reading is ``read_pixels`` (in the child only)."""
    from PIL import Image

    from pushtrain.facility import map_server

    monkeypatch.setattr(map_server, "_read_pixels", read_pixels)
    Image.fromarray(np.full((20, 20), 254, np.uint8)).save(folder / "map.pgm")
    (folder / "fuzz.yaml").write_text("image: map.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n"
                                      "negate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n")
    return _scenario(folder, 'grid = "fuzz.yaml"', start=(0.5, 0.5), goal=(0.6, 0.5))


def test_the_caps_turn_a_runaway_call_into_a_red_test(tmp_path, monkeypatch):
    """An allocation beyond the memory cap and a call beyond the time cap fail the test (the
    test process itself is untouched)."""
    import time

    def greedy(*args, **kwargs):
        return np.ones(MEMORY_CAP // 4, dtype=np.float64)     # twice the cap

    def sleepy(*args, **kwargs):
        time.sleep(60.0)

    with pytest.raises(AssertionError, match="MemoryError"):
        _plan(_runaway(monkeypatch, tmp_path, greedy))
    monkeypatch.setattr(sys.modules[__name__], "TIME_CAP", 1.0)
    started = time.perf_counter()
    with pytest.raises(pytest.fail.Exception, match="took over 1.0 s"):
        _plan(_runaway(monkeypatch, tmp_path, sleepy))
    assert time.perf_counter() - started < 10.0
