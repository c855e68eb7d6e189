"""A grid map prepared once: its traced polygons and distance field, cached on disk by content.

Preparing an occupancy grid for planning (tracing its blocked cells into polygons, the free
space, the Euclidean distance transforms of the distance field) costs 0.1 to 0.6 s on a
building floor; a study or a user running mission after mission on one map pays it once.

Key
    SHA-256 of the grid as the map file gives it (its blocked cells, shape, origin,
    resolution), the scenario's polygons drawn on it, each with its role (an obstacle, or the
    keep-in outline: the same polygon in either role is another map), and :data:`FORMAT`.
    Any change of the map file's pixels, its YAML (resolution, origin, thresholds) or the
    scenario's polygons is another key; the file's name and date are not part of it.
File
    ``<PUSHTRAIN_CACHE or ~/.cache/pushtrain>/maps/<key>.npz`` (uncompressed NumPy zip): the
    field's values, origin and resolution, and the traced polygons and free space as WKB.
    Written atomically; a zip member's CRC, the key stored inside and the shapes are checked
    on reading. A file that fails any check is **damaged**: a warning names it and why, and
    the map is prepared again and the file rewritten. A cache folder that cannot be written
    is a warning, not an error (the map is prepared in memory).
"""

from __future__ import annotations

import hashlib
import logging
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import shapely

from pushtrain.files import atomic_write

from .distance_field import DistanceField

__all__ = ["FORMAT", "Prepared", "cache_dir", "eroded", "map_key", "prepared"]

log = logging.getLogger(__name__)

FORMAT = "2"
"""Bumped when what is cached or how it is computed changes."""


@dataclass(frozen=True)
class Prepared:
    """A grid map ready to plan on: ``traced`` (the blocked cells' polygons), ``free`` (the
    free space) and ``field`` (its :class:`DistanceField`); ``source`` is ``"cache"``,
    ``"built"`` or ``"rebuilt"`` (the cached file was damaged)."""

    traced: object
    free: object
    field: DistanceField
    source: str = "built"


def cache_dir() -> Path:
    """Folder of prepared maps: ``$PUSHTRAIN_CACHE/maps`` or ``~/.cache/pushtrain/maps``."""
    root = os.environ.get("PUSHTRAIN_CACHE")
    return (Path(root) if root else Path.home() / ".cache" / "pushtrain") / "maps"


def map_key(grid, obstacles=(), keep_in=None) -> str:
    """The cache key of the burned ``grid`` (an
    :class:`~pushtrain.facility.occupancy_grid.OccupancyGrid`) and the polygons drawn on it."""
    blocked = np.ascontiguousarray(grid.blocked, dtype=bool)
    digest = hashlib.sha256()
    digest.update(f"pushtrain map {FORMAT} {blocked.shape} {grid.x0!r} {grid.y0!r} "
                  f"{grid.resolution!r}".encode())
    digest.update(np.packbits(blocked).tobytes())
    # each polygon with its role: the same polygon as an obstacle (blocked) and as the keep-in
    # outline (everything else blocked) are two maps
    obstacles = tuple(obstacles)
    digest.update(f" obstacles {len(obstacles)}".encode())
    for poly in obstacles:
        wkb = shapely.to_wkb(poly)
        digest.update(f" {len(wkb)} ".encode() + wkb)
    if keep_in is None:
        digest.update(b" no keep_in")
    else:
        wkb = shapely.to_wkb(keep_in)
        digest.update(f" keep_in {len(wkb)} ".encode() + wkb)
    return digest.hexdigest()


def prepared(grid, key: str, build: Callable[[], Prepared]) -> Prepared:
    """The prepared map of ``key``: read from the cache if there and whole, else ``build()``
    (and written to the cache); see the module docstring."""
    out, source = _cached(cache_dir() / f"{key}.npz", "map", lambda path: _read(path, key, grid),
                          build, lambda partial, built: _write(partial, key, built))
    if source == "cache":
        return out
    return Prepared(out.traced, out.free, out.field, source)


def eroded(key: str, margin: float, build: Callable[[], object]):
    """The free space of the map ``key`` (:func:`map_key`) shrunk by ``margin`` [m] (a shapely
    geometry, see :meth:`~pushtrain.facility.free_space.World.eroded`): read from
    ``<cache>/eroded/<key>-<margin>.npz`` if there and whole (the same geometry to the bit:
    WKB), else ``build()`` and written there. A damaged file is said to be damaged, built again
    and rewritten, as a prepared map's."""
    margin = float(margin)
    path = cache_dir() / "eroded" / f"{key}-{margin.hex()}.npz"

    def write(partial: Path, geom) -> None:
        with open(partial, "wb") as f:
            np.savez(f, key=np.array(key), margin=np.array(margin),
                     geometry=np.frombuffer(shapely.to_wkb(geom), dtype=np.uint8))

    def read(path: Path):
        with np.load(path, allow_pickle=False) as data:
            stored = (str(data["key"]), float(data["margin"]))
            if stored != (key, margin):
                raise ValueError(f"it holds the map {stored[0][:12]}... eroded by {stored[1]!r} m,"
                                 f" not {key[:12]}... by {margin!r} m")
            return shapely.from_wkb(data["geometry"].tobytes())

    return _cached(path, f"eroded ({margin:g} m) map", read, build, write)[0]


def _cached(path: Path, what: str, read: Callable, build: Callable, write: Callable):
    """(``read(path)``, ``"cache"``) if ``path`` is there and whole, else (``build()``,
    ``"built"`` or ``"rebuilt"``) written to ``path`` atomically (``write(partial, built)``);
    a damaged file is a warning, a folder that cannot be written too."""
    damaged = None
    if path.is_file():
        try:
            out = read(path)
            log.info("%s %s read from the cache", what, path.name)
            return out, "cache"
        except Exception as exc:  # BadZipFile, bad CRC, EOFError, KeyError, ValueError, ...
            damaged = f"{type(exc).__name__}: {exc}"
            log.warning("the map cache %s is damaged (%s): the %s is prepared again and the "
                        "file rewritten", path, damaged, what)
    out = build()
    log.info("%s %s prepared; cached in %s", what, path.stem[:12], path.parent)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write(path, lambda partial: write(partial, out), keep_suffix=True)
    except OSError as exc:  # pushtrain.files.WriteError is one
        log.warning("the prepared %s cannot be cached in %s (%s): it is kept in memory only",
                    what, path.parent, exc)
    return out, "rebuilt" if damaged else "built"


def _write(path: Path, key: str, out: Prepared) -> None:
    field = out.field
    with open(path, "wb") as f:
        np.savez(f, key=np.array(key), values=field.values,
                 frame=np.array([field.x0, field.y0, field.resolution]),
                 traced=np.frombuffer(shapely.to_wkb(out.traced), dtype=np.uint8),
                 free=np.frombuffer(shapely.to_wkb(out.free), dtype=np.uint8))


def _read(path: Path, key: str, grid) -> Prepared:
    with np.load(path, allow_pickle=False) as data:
        stored = str(data["key"])
        if stored != key:
            raise ValueError(f"it holds the map {stored[:12]}..., not {key[:12]}...")
        values = data["values"]
        x0, y0, h = (float(v) for v in data["frame"])
        traced = shapely.from_wkb(data["traced"].tobytes())
        free = shapely.from_wkb(data["free"].tobytes())
    if values.shape != grid.blocked.shape or not np.all(np.isfinite(values)):
        raise ValueError(f"its field has shape {values.shape}, the map {grid.blocked.shape}")
    if (x0, y0, h) != (float(grid.x0), float(grid.y0), float(grid.resolution)):
        raise ValueError(f"its field's frame {(x0, y0, h)} is not the map's")
    return Prepared(traced, free, DistanceField(values, x0, y0, h), "cache")
