"""Reading a facility's map in the ROS ``map_server`` format into an
:class:`~pushtrain.facility.occupancy_grid.OccupancyGrid`.

The format (ROS 1 ``map_server``, ROS 2 ``nav2_map_server``; what ``map_saver`` writes) is a
YAML file naming an image::

    image: warehouse.pgm          # PGM, PNG, ... (Pillow); absolute or relative to the YAML file
    resolution: 0.05              # m per pixel, > 0
    origin: [-0.5, -0.5, 0.0]     # pose (x [m], y [m], yaw [rad]) of the lower-left pixel
    negate: 0                     # 1: white is occupied, black free
    occupied_thresh: 0.65         # p above it: occupied
    free_thresh: 0.196            # p below it: free
    mode: trinary                 # optional: trinary (default), scale or raw

A pixel of grey value x (0..255; a colour pixel's channels are averaged, alpha left out) has the
occupancy probability p = (255 - x) / 255, or x / 255 with ``negate``. ``trinary``: p >
``occupied_thresh`` is occupied (100), p < ``free_thresh`` free (0), anything else unknown (-1).
``scale``: the same, but a value in between is 99 (p - free) / (occupied - free), and a pixel with
any transparency (alpha < 255) is unknown. ``raw``: the value is x itself (after ``negate``, as
map_server does), 0..100 a percentage and anything above unknown. The thresholds compare strictly
(``>``, ``<``), as map_server does; with map_saver's 0.196 its unknown grey 205 (p = 0.19608)
is unknown, not free.

**Free is only what is known free.** pushtrain's bodies may only stand on cells whose p <
``free_thresh`` (raw: x / 100 < ``free_thresh``): occupied, unknown and in-between cells are all
blocked, and so is everything outside the image.

Worlds are made of grids in :mod:`pushtrain.facility.loading`.
"""

from __future__ import annotations

import logging
import math
import re
import stat
from pathlib import Path

import numpy as np

from pushtrain.errors import MapError
from pushtrain.limits import MAP_BOUNDS, MAP_YAML_BYTES, SCENARIO_BOUNDS
from pushtrain.validation import clip_text, clipped

from .distance_field import MAX_CELLS
from .occupancy_grid import UNKNOWN, MapImage, OccupancyGrid

__all__ = ["MAP_MODES", "read_map_yaml", "occupancy_values", "load_map"]

log = logging.getLogger(__name__)

MAP_MODES = ("trinary", "scale", "raw")
"""The ``mode`` values of the map_server format."""


def _number(data: dict, key: str, problems: list, allowed: str, lo=None, hi=None):
    """``data[key]`` as a finite float within [lo, hi] (inclusive), or None with a problem."""
    value = data.get(key)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        problems.append((key, value, allowed))
        return None
    if (lo is not None and value < lo) or (hi is not None and value > hi):
        problems.append((key, value, allowed))
        return None
    return float(value)


def _yaml_loader():
    """A safe YAML loader that refuses aliases (``*name``): a map_server file needs none, and
    nested aliases expand exponentially (a "billion laughs" of a few hundred bytes); and a key
    given twice in a mapping (the last would win silently)."""
    import yaml

    class NoAliasLoader(yaml.SafeLoader):
        def compose_node(self, parent, index):
            if self.check_event(yaml.AliasEvent):
                event = self.peek_event()
                raise yaml.composer.ComposerError(
                    None, None, f"an alias (*{clip_text(event.anchor, 40)}): aliases are not "
                    "allowed in a map file", event.start_mark)
            return super().compose_node(parent, index)

        def construct_mapping(self, node, deep=False):
            # a key given twice: YAML 1.2 forbids it, PyYAML keeps the last one silently
            seen = {}
            for key_node, _ in node.value:
                key = self.construct_object(key_node, deep=deep)
                try:
                    first = seen.setdefault(key, key_node)
                except TypeError:  # an unhashable key: the base class says so
                    continue
                if first is not key_node:
                    raise yaml.constructor.ConstructorError(
                        None, None, f"the key {clip_text(repr(key), 40)} is given twice (first "
                        f"on line {first.start_mark.line + 1}): each key once",
                        key_node.start_mark)
            return super().construct_mapping(node, deep=deep)

    return NoAliasLoader


def read_map_yaml(path) -> dict:
    """The validated fields of a map_server YAML file: ``image`` (a Path, resolved against the
    YAML's folder), ``resolution`` [m], ``origin`` (x, y, yaw) [m, m, rad], ``negate`` (bool),
    ``occupied_thresh``, ``free_thresh`` and ``mode``. Raises :class:`MapError` naming every
    bad field. Keys the format does not define are ignored (tools add their own).

    Bounds: the file at most :data:`~pushtrain.limits.MAP_YAML_BYTES`, no YAML aliases,
    ``resolution`` within ``MAP_BOUNDS["resolution"]``, the origin's x and y within
    ``SCENARIO_BOUNDS["map.coordinate"]``; values quoted in messages are clipped."""
    import yaml

    path = Path(path)
    source = str(path)

    def fail(problems):
        return MapError(source, [(where, clipped(value), allowed)
                                 for where, value, allowed in problems])

    try:
        info = path.stat()
        if not stat.S_ISREG(info.st_mode):   # a FIFO or a device would block or never end
            raise fail([("(file)", source, "not a regular file")])
        size = info.st_size
        if size > MAP_YAML_BYTES:
            raise fail([("(file)", source, f"{size} bytes: a map_server YAML file has at most "
                                           f"{MAP_YAML_BYTES} (map_saver writes about 150)")])
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise fail([("(file)", source, f"cannot be read: {exc.strerror or exc}")]) from None
    except UnicodeDecodeError:
        raise fail([("(file)", source, "must be UTF-8 YAML text")]) from None
    try:
        data = yaml.load(text, Loader=_yaml_loader())  # a SafeLoader without aliases
    except yaml.YAMLError as exc:
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        mark = getattr(exc, "problem_mark", None)
        where = f"(syntax) line {mark.line + 1}" if mark is not None else "(syntax)"
        raise fail([(where, None, f"not valid YAML: {clip_text(problem)}")]) from None
    except RecursionError:
        raise fail([("(syntax)", None, "not valid YAML: nested too deeply")]) from None
    if not isinstance(data, dict):
        raise fail([("(top level)", data, "a YAML mapping with image, resolution, origin, "
                                          "occupied_thresh and free_thresh")])
    problems = []
    image = data.get("image")
    if not isinstance(image, str) or not image.strip():
        problems.append(("image", image, "the image file (PGM, PNG, ...), absolute or relative "
                                         "to the YAML file"))
    res = MAP_BOUNDS["resolution"]
    resolution = _number(data, "resolution", problems, f"a number from {res.lo:g} to {res.hi:g} "
                         f"{res.unit} per pixel ({res.reason})", res.lo, res.hi)
    origin = data.get("origin")
    coordinate = SCENARIO_BOUNDS["map.coordinate"]
    if (not isinstance(origin, (list, tuple)) or len(origin) != 3
            or not all(isinstance(v, (int, float)) and not isinstance(v, bool)
                       and math.isfinite(v) for v in origin)):
        problems.append(("origin", origin, "[x, y, yaw]: the pose of the lower-left pixel "
                                           "(m, m, rad)"))
    elif not all(coordinate.contains(v) for v in origin[:2]):
        problems.append(("origin", origin, f"[x, y, yaw] with x and y from {coordinate.lo:g} to "
                                           f"{coordinate.hi:g} m ({coordinate.reason})"))
    occupied = _number(data, "occupied_thresh", problems, "a number from 0 to 1", 0.0, 1.0)
    free = _number(data, "free_thresh", problems, "a number from 0 to 1", 0.0, 1.0)
    if occupied is not None and free is not None and free >= occupied:
        problems.append(("free_thresh", free, f"less than occupied_thresh = {occupied:g} (a "
                                              "pixel cannot be both free and occupied)"))
    negate = data.get("negate", 0)
    if negate not in (0, 1) or isinstance(negate, float):
        problems.append(("negate", negate, "0 or 1 (true or false)"))
    mode = data.get("mode", "trinary")
    if not isinstance(mode, str) or mode not in MAP_MODES:
        problems.append(("mode", mode, f"one of {', '.join(MAP_MODES)}"))
    if problems:
        raise fail(problems)
    image_path = Path(image.strip()).expanduser()
    if not image_path.is_absolute():
        image_path = path.parent / image_path
    return {"image": image_path, "resolution": resolution,
            "origin": tuple(float(v) for v in origin), "negate": bool(negate),
            "occupied_thresh": occupied, "free_thresh": free, "mode": mode}


def _read_pixels(image_path: Path, source: str) -> tuple[np.ndarray, np.ndarray | None]:
    """Grey levels (H, W) in 0..255 (colour channels averaged) and the alpha channel (or None)
    of an image file; MapError ``image`` if it is missing, cannot be decoded, or has more than
    :data:`~pushtrain.facility.distance_field.MAX_CELLS` pixels (read from its header, before
    any pixel is decoded)."""
    import warnings

    from PIL import Image, UnidentifiedImageError

    name = str(image_path)
    too_many = f"at most {MAX_CELLS} pixels (5000 x 5000: the distance field's cell limit)"
    if image_path.exists() and not image_path.is_file():  # a folder, a FIFO, a device
        raise MapError(source, [("image", name, "not a regular file")])
    try:
        with warnings.catch_warnings():
            # Pillow's own limit (89 M pixels, 179 M refused) is above ours, checked below
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)
            im = Image.open(image_path)
        with im:
            width, height = im.size
            if width * height > MAX_CELLS:
                raise MapError(source, [("image", name, f"{width} x {height} pixels (its "
                                                        f"header says): {too_many}")])
            im.load()
            mode = im.mode
            if mode in ("P", "PA"):
                im = im.convert("RGBA")
                mode = "RGBA"
            elif mode == "1":
                im = im.convert("L")
                mode = "L"
            pixels = np.asarray(im)
    except MapError:
        raise
    except Image.DecompressionBombError as exc:  # its header: more than 179 M pixels
        size = re.search(r"\((\d+) pixels\)", str(exc))
        size = f"{size.group(1)} pixels" if size else "more than 179 M pixels"
        raise MapError(source, [("image", name, f"{size} (its header says): "
                                                f"{too_many}")]) from None
    except FileNotFoundError:
        raise MapError(source, [("image", name, "no such file (a relative image path is "
                                                "relative to the YAML file)")]) from None
    except (UnidentifiedImageError, OSError, ValueError, SyntaxError, EOFError) as exc:
        why = clip_text(getattr(exc, "strerror", None) or exc)
        raise MapError(source, [("image", name, f"cannot be read as an image: {why}")]) from None
    pixels = np.asarray(pixels, dtype=float)
    if mode in ("I;16", "I;16B", "I;16L", "I"):
        return pixels * (255.0 / 65535.0), None
    if mode == "L":
        return pixels, None
    if mode == "LA":
        return pixels[..., 0], pixels[..., 1]
    if mode in ("RGB", "RGBA"):
        alpha = pixels[..., 3] if mode == "RGBA" else None
        return pixels[..., :3].mean(axis=-1), alpha
    raise MapError(source, [("image", name, f"pixel mode {mode!r}: a grey, grey + alpha, RGB, "
                                            "RGBA or palette image")])


def occupancy_values(grey, alpha, negate: bool, occupied_thresh: float, free_thresh: float,
                     mode: str = "trinary") -> tuple[np.ndarray, np.ndarray]:
    """The map server's occupancy values (int16) and the known-free mask of grey levels x
    (0..255) with an optional alpha channel, as the module docstring defines them."""
    x = np.asarray(grey, dtype=float)
    if negate:
        x = 255.0 - x
    if mode == "raw":
        values = np.rint(x).astype(np.int16)
        known = values <= 100
        return np.where(known, values, UNKNOWN).astype(np.int16), known & (
            values / 100.0 < free_thresh)
    p = (255.0 - x) / 255.0
    occupied = p > occupied_thresh
    free = p < free_thresh
    if mode == "scale":
        between = np.rint(99.0 * (p - free_thresh) / (occupied_thresh - free_thresh))
        values = np.where(occupied, 100, np.where(free, 0, between))
        if alpha is not None:
            transparent = np.asarray(alpha) < 255
            values = np.where(transparent, UNKNOWN, values)
            free = free & ~transparent
    else:
        values = np.where(occupied, 100, np.where(free, 0, UNKNOWN))
    return values.astype(np.int16), free


def load_map(path) -> OccupancyGrid:
    """The axis-aligned :class:`OccupancyGrid` of a map_server YAML file [m]; MapError names
    the bad field (file, image, resolution, origin, thresholds, negate, mode)."""
    path = Path(path)
    meta = read_map_yaml(path)
    grey, alpha = _read_pixels(meta["image"], str(path))
    values, free = occupancy_values(grey, alpha, meta["negate"], meta["occupied_thresh"],
                                    meta["free_thresh"], meta["mode"])
    image = MapImage(values, free, meta["resolution"], meta["origin"], str(path),
                     str(meta["image"]))
    grid = OccupancyGrid.from_image(image)
    if not free.any():
        raise MapError(str(path), [("image", str(meta["image"]),
                                    "has no free pixel (p < free_thresh): check negate and "
                                    "the thresholds")])
    log.info("map %s: %d x %d pixels at %g m (%s, %.0f %% free)", path.name, free.shape[1],
             free.shape[0], meta["resolution"], meta["mode"], 100.0 * free.mean())
    return grid
