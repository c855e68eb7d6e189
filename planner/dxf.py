"""DXF floor plans (CAD drawings): the walls and obstacles on named layers as shapely polygons.

Reading needs the optional package ``ezdxf`` (``pip install 'pushtrain[cad]'``). What becomes what,
for the model-space entities on the named layers (layer names compare case-insensitively, as in
CAD programs):

- **Closed shapes are solid obstacles**: closed LWPOLYLINE and POLYLINE, CIRCLE, closed SPLINE
  and ELLIPSE, SOLID, TRACE and 3DFACE (columns, racks, machines drawn as outlines).
- **Open curves are thin walls**: LINE, open polylines, ARC, open SPLINE and ELLIPSE, each grown
  by half of ``line_thickness`` (default 5 cm) to either side, with square ends so that lines
  meeting at a corner close it. A drawn line is a wall's face or centre line; the thickness only
  gives it area, so set it to the real wall thickness if the plan draws centre lines.
- **Block references** (INSERT) are expanded; an entity inside a block on layer ``0`` takes the
  reference's layer, as CAD programs draw it.
- Everything else (text, dimensions, hatches, points, images) is ignored.

Curves are flattened to within 2 mm (chords inside an arc). **Units**: the drawing's
``$INSUNITS`` header is honoured (inches, feet, millimetres, centimetres, metres, ...); a drawing
without units (``$INSUNITS`` 0 or missing) is read as metres unless ``units`` says otherwise.
Coordinates are taken as they are (no ``$INSBASE`` shift), so the scenario's poses are in the
drawing's own coordinates, in metres.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from pathlib import Path

import shapely
from shapely.geometry import LineString, Polygon

from pushtrain.errors import MapError

__all__ = ["UNITS", "DEFAULT_LINE_THICKNESS", "FloorPlan", "read_dxf"]

log = logging.getLogger(__name__)

UNITS = {"m": 1.0, "dm": 0.1, "cm": 0.01, "mm": 0.001, "in": 0.0254, "ft": 0.3048}
"""Unit names accepted by ``units`` and their size [m]."""

DEFAULT_LINE_THICKNESS = 0.05
"""Thickness [m] given to an open line or curve (a wall drawn as a line has no area)."""

_FLATTEN = 0.002
"""Largest deviation [m] of a flattened curve from the drawn one."""

_CLOSED_TYPES = {"SOLID", "TRACE", "3DFACE", "CIRCLE"}
_CURVE_TYPES = {"LINE", "LWPOLYLINE", "POLYLINE", "ARC", "SPLINE", "ELLIPSE"} | _CLOSED_TYPES


@dataclass(frozen=True)
class FloorPlan:
    """What :func:`read_dxf` found.

    Attributes
    ----------
    obstacles : tuple of shapely Polygon
        Solid shapes and thickened lines [m].
    bounds : (xmin, ymin, xmax, ymax)
        Extent of the obstacles [m].
    counts : dict
        Entities used per layer (as the drawing spells it).
    scale : float
        Size of one drawing unit [m].
    """

    obstacles: tuple
    bounds: tuple
    counts: dict
    scale: float


def _ezdxf(path: Path):
    try:
        import ezdxf
    except ImportError:
        raise MapError(str(path), [("dxf", str(path), "reading a DXF floor plan needs the optional "
                                    "package ezdxf: pip install 'pushtrain[cad]'")]) from None
    return ezdxf


def _scale(doc, path: Path, units: str | None) -> float:
    """Size of one drawing unit [m]: ``units`` if given, else from ``$INSUNITS``."""
    from ezdxf import units as dxf_units

    if units is not None:
        if units not in UNITS:
            raise MapError(str(path), [("dxf_units", units, f"one of {', '.join(UNITS)}")])
        return UNITS[units]
    code = int(doc.header.get("$INSUNITS", 0) or 0)
    if code == 0:
        log.warning("%s declares no units ($INSUNITS = 0): read as metres (set map.dxf_units "
                    "if it is in another unit)", path.name)
        return 1.0
    try:
        return float(dxf_units.conversion_factor(code, dxf_units.M))
    except (KeyError, IndexError, ValueError, TypeError):
        raise MapError(str(path), [("$INSUNITS", code, "a known DXF length unit; set "
                                    f"map.dxf_units to one of {', '.join(UNITS)}")]) from None


def _entities(layout, wanted: set[str], depth: int = 0, layer: str | None = None):
    """(entity, layer) of every curve on a wanted layer, block references expanded."""
    for entity in layout:
        kind = entity.dxftype()
        own = entity.dxf.get("layer", "0")
        effective = layer if (layer is not None and own == "0") else own
        if kind == "INSERT" and depth < 16:
            try:
                inner = list(entity.virtual_entities())
            except Exception as exc:  # a broken block must not hide the rest of the plan
                log.warning("block reference %s on layer %s skipped: %s",
                            entity.dxf.get("name", "?"), effective, exc)
                continue
            yield from _entities(inner, wanted, depth + 1, effective)
        elif kind in _CURVE_TYPES and effective.casefold() in wanted:
            yield entity, effective


def _shape(entity, scale: float, thickness: float):
    """The obstacle polygon [m] of one entity (solid if closed, a thickened line if open), or
    None if it is degenerate."""
    from ezdxf import path as dxf_path

    curve = dxf_path.make_path(entity)
    points = [(p.x * scale, p.y * scale) for p in curve.flattening(_FLATTEN / scale)]
    if len(points) < 2:
        return None
    closed = (entity.dxftype() in _CLOSED_TYPES or curve.is_closed
              or getattr(entity, "closed", False) or getattr(entity, "is_closed", False))
    if closed and len(points) >= 3:
        poly = Polygon(points)
        if not poly.is_valid:
            poly = shapely.make_valid(poly)
        if poly.area > 0.0:
            return poly
    line = LineString(points)
    if line.length <= 0.0:
        return None
    return line.buffer(0.5 * thickness, cap_style="square", join_style="mitre")


def read_dxf(path, layers, line_thickness: float = DEFAULT_LINE_THICKNESS,
             units: str | None = None) -> FloorPlan:
    """The obstacles [m] on ``layers`` of the DXF file at ``path`` (see the module docstring).

    Raises
    ------
    MapError
        ezdxf missing, the file unreadable or not a DXF, a layer the drawing does not have, a
        layer with nothing to use on it, unknown units, a bad ``line_thickness``.
    """
    path = Path(path)
    ezdxf = _ezdxf(path)
    if not (math.isfinite(line_thickness) and line_thickness > 0.0):
        raise MapError(str(path), [("line_thickness", line_thickness, "a number > 0 (m)")])
    names = [str(name) for name in layers]
    if not names:
        raise MapError(str(path), [("layers", [], "at least one layer name")])
    try:
        doc = ezdxf.readfile(path)
    except OSError as exc:
        raise MapError(str(path), [("dxf", str(path), "cannot be read: "
                                    f"{exc.strerror or exc}")]) from None
    except ezdxf.DXFError as exc:
        raise MapError(str(path), [("dxf", str(path), f"not a readable DXF file: {exc}")]) from None
    scale = _scale(doc, path, units)
    present = {layer.dxf.name.casefold(): layer.dxf.name for layer in doc.layers}
    msp = doc.modelspace()
    for entity in msp:
        name = entity.dxf.get("layer", "0")
        present.setdefault(name.casefold(), name)
    missing = [n for n in names if n.casefold() not in present]
    if missing:
        raise MapError(str(path), [("layers", missing, "layers the drawing has: "
                                    + ", ".join(sorted(present.values())))])
    obstacles, counts = [], {present[n.casefold()]: 0 for n in names}
    for entity, layer in _entities(msp, {n.casefold() for n in names}):
        try:
            shape = _shape(entity, scale, line_thickness)
        except (TypeError, ValueError) as exc:  # e.g. a polyface mesh: no outline to take
            log.warning("%s on layer %s skipped: %s", entity.dxftype(), layer, exc)
            continue
        if shape is None:
            continue
        parts = [g for g in getattr(shape, "geoms", [shape]) if isinstance(g, Polygon)]
        obstacles += [g for g in parts if not g.is_empty]
        key = present.get(layer.casefold(), layer)
        counts[key] = counts.get(key, 0) + 1
    empty = [n for n, c in counts.items() if c == 0]
    if empty:
        raise MapError(str(path), [("layers", empty, "each named layer must hold a line, "
                                    "polyline, circle, arc, spline or block reference")])
    bounds = shapely.total_bounds(obstacles)
    log.info("floor plan %s: %s; %.1f m x %.1f m", path.name,
             ", ".join(f"{n}: {c} shapes" for n, c in counts.items()),
             bounds[2] - bounds[0], bounds[3] - bounds[1])
    return FloorPlan(tuple(obstacles), tuple(float(b) for b in bounds), counts, scale)
