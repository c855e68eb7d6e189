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
without units (``$INSUNITS`` 0 or missing) is read as metres. ``units`` (the scenario's
``map.dxf_units``) overrides the header, with a warning naming both when they differ.
Coordinates are taken as they are (no ``$INSBASE`` shift), so the scenario's poses are in the
drawing's own coordinates, in metres.

**Free space.** Without a grid or an outline of its own, the map is the drawing's extent (the
bounding box of what the layers hold) minus the obstacles: a room drawn as one *closed* outline
is a solid obstacle, and a pose inside it is not free (draw walls as lines or open polylines, or
give ``map.free``). :attr:`FloorPlan.sources` names each obstacle's entity and layer, for
messages.

**Refused** (:class:`~pushtrain.errors.MapError` naming the file, entity and layer): a file cut
short or damaged, an entity with a non-finite number, a coordinate beyond
``SCENARIO_BOUNDS["map.coordinate"]`` (100 km; checked on the curve's control points, before it
is flattened), more than :data:`MAX_ENTITIES` entities with the block references expanded.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import shapely
from shapely.geometry import LineString, Polygon
from shapely.validation import explain_validity

from pushtrain.errors import MapError
from pushtrain.limits import SCENARIO_BOUNDS
from pushtrain.validation import clip_text, clipped

__all__ = ["UNITS", "DEFAULT_LINE_THICKNESS", "MAX_ENTITIES", "FloorPlan", "read_dxf"]

log = logging.getLogger(__name__)

UNITS = {"m": 1.0, "dm": 0.1, "cm": 0.01, "mm": 0.001, "in": 0.0254, "ft": 0.3048}
"""Unit names accepted by ``units`` and their size [m]."""

DEFAULT_LINE_THICKNESS = 0.05
"""Thickness [m] given to an open line or curve (a wall drawn as a line has no area)."""

_FLATTEN = 0.002
"""Largest deviation [m] of a flattened curve from the drawn one."""

MAX_ENTITIES = 250_000
"""Most entities read on the named layers, block references expanded (nested blocks multiply:
ten references to a block of ten references, 16 deep, would be 1e16)."""

_MAX_REPORTED = 10
"""Most bad entities a MapError lists (the rest are counted)."""

_UNIT_NAMES = {"m": "metres", "dm": "decimetres", "cm": "centimetres", "mm": "millimetres",
               "in": "inches", "ft": "feet"}

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
    sources : tuple of str
        What each obstacle was drawn as, e.g. ``"a closed LWPOLYLINE (handle 2F) on layer
        WALLS"``, in the order of ``obstacles``.
    """

    obstacles: tuple
    bounds: tuple
    counts: dict
    scale: float
    sources: tuple = ()


def _ezdxf(path: Path):
    try:
        import ezdxf
    except ImportError:
        raise MapError(str(path), [("dxf", str(path), "reading a DXF floor plan needs the optional "
                                    "package ezdxf: pip install 'pushtrain[cad]'")]) from None
    return ezdxf


def _scale(doc, path: Path, units: str | None) -> float:
    """Size of one drawing unit [m]: ``units`` if given (a warning if ``$INSUNITS`` declares
    another), else from ``$INSUNITS``."""
    from ezdxf import units as dxf_units

    raw = doc.header.get("$INSUNITS", 0)
    try:
        code = int(raw or 0)
    except (TypeError, ValueError, OverflowError):
        code = None
    declared = None
    if code:
        try:
            declared = float(dxf_units.conversion_factor(code, dxf_units.M))
        except (KeyError, IndexError, ValueError, TypeError):
            declared = None
    if units is not None:
        if units not in UNITS:
            raise MapError(str(path), [("dxf_units", units, f"one of {', '.join(UNITS)}")])
        if declared is not None and not math.isclose(declared, UNITS[units], rel_tol=1e-9):
            named = [_UNIT_NAMES[u] for u, size in UNITS.items()
                     if math.isclose(size, declared, rel_tol=1e-9)]
            log.warning("%s declares %s ($INSUNITS = %d) but map.dxf_units = %r (%s): read as "
                        "%s, as the scenario says; remove map.dxf_units to use the drawing's "
                        "units", path.name, named[0] if named else dxf_units.unit_name(code),
                        code, units, _UNIT_NAMES[units], _UNIT_NAMES[units])
        return UNITS[units]
    if code == 0:
        log.warning("%s declares no units ($INSUNITS = 0): read as metres (set map.dxf_units "
                    "if it is in another unit)", path.name)
        return 1.0
    if declared is None:
        raise MapError(str(path), [("$INSUNITS", clip_text(raw, 40), "a known DXF length unit; "
                                    f"set map.dxf_units to one of {', '.join(UNITS)}")])
    return declared


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


def _name(entity, layer: str) -> str:
    """``"LINE (handle 2A) on layer WALLS"``."""
    handle = entity.dxf.get("handle", None)
    own = f" (handle {handle})" if handle else ""
    return f"{entity.dxftype()}{own} on layer {layer}"


def _bad_number(entity, curve, scale: float) -> tuple[object, str] | None:
    """(value, what is allowed) for an entity with a non-finite number or a coordinate beyond
    the map's bound, else None; checked on the attributes and the curve's control points (a
    curve lies in their hull), before anything is flattened."""
    for key, value in entity.dxfattribs().items():
        numbers = np.asarray(value if isinstance(value, (tuple, list)) else [value])
        if numbers.dtype.kind == "f" and not np.all(np.isfinite(numbers)):
            return f"{key} = {value}", "finite numbers"
    coordinate = SCENARIO_BOUNDS["map.coordinate"]
    xy = np.array([(v.x, v.y) for v in curve.control_vertices()], dtype=float).reshape(-1, 2)
    if not xy.size:
        return None
    if not np.all(np.isfinite(xy)):
        k = int(np.flatnonzero(~np.all(np.isfinite(xy), axis=1))[0])
        return f"a point at {tuple(xy[k].tolist())}", "finite coordinates"
    xy = xy * scale
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    if lo.min() < coordinate.lo or hi.max() > coordinate.hi:
        return (f"x from {lo[0]:.6g} to {hi[0]:.6g} m, y from {lo[1]:.6g} to {hi[1]:.6g} m",
                f"coordinates from {coordinate.lo:g} to {coordinate.hi:g} m "
                f"({coordinate.reason})")
    return None


def _shape(entity, curve, scale: float, thickness: float, name: str):
    """The obstacle polygon [m] of one entity (solid if closed, a thickened line if open) and
    whether it was closed, or (None, False) if it is degenerate."""
    points = [(p.x * scale, p.y * scale) for p in curve.flattening(_FLATTEN / scale)]
    if len(points) < 2:
        return None, False
    closed = (entity.dxftype() in _CLOSED_TYPES or curve.is_closed
              or getattr(entity, "closed", False) or getattr(entity, "is_closed", False))
    if closed and len(points) >= 3:
        poly = Polygon(points)
        if not poly.is_valid:
            log.warning("the closed %s crosses itself (%s): taken as the areas it encloses",
                        name, explain_validity(poly))
            poly = shapely.make_valid(poly)
        if poly.area > 0.0:
            return poly, True
    line = LineString(points)
    if line.length <= 0.0:
        return None, False
    return line.buffer(0.5 * thickness, cap_style="square", join_style="mitre"), False


_NOT_COUNTED = {b"VERTEX", b"SEQEND", b"ATTRIB"}
"""Sub-entities of an entity (a POLYLINE's vertices, an INSERT's attributes): not counted."""


def _count_entities(path: Path, limit: int) -> int:
    """The entities of the ENTITIES section of the ASCII DXF at ``path``, counted from its
    group codes without reading the drawing (stops once past ``limit``; 0 for a binary DXF,
    left to ezdxf). Seconds for a file ezdxf takes minutes to read."""
    with open(path, "rb") as f:
        if f.read(18) == b"AutoCAD Binary DXF":
            return 0
        f.seek(0)
        lines = iter(f)
        inside, count = False, 0
        for code in lines:
            value = next(lines, b"").strip()
            if code.strip() != b"0":
                continue
            if value == b"SECTION":
                next(lines, None)  # group code 2
                inside = next(lines, b"").strip() == b"ENTITIES"
            elif value == b"ENDSEC":
                inside = False
            elif inside and value not in _NOT_COUNTED:
                count += 1
                if count > limit:
                    break
    return count


def read_dxf(path, layers, line_thickness: float = DEFAULT_LINE_THICKNESS,
             units: str | None = None) -> FloorPlan:
    """The obstacles [m] on ``layers`` of the DXF file at ``path`` (see the module docstring).

    Raises
    ------
    MapError
        ezdxf missing, the file unreadable, cut short or not a DXF, a layer the drawing does not
        have, a layer with nothing to use on it, unknown units, a bad ``line_thickness``, an
        entity with a non-finite number or a coordinate beyond 100 km, too many entities.
    """
    path = Path(path)
    ezdxf = _ezdxf(path)
    if not (math.isfinite(line_thickness) and line_thickness > 0.0):
        raise MapError(str(path), [("line_thickness", line_thickness, "a number > 0 (m)")])
    names = [str(name) for name in layers]
    if not names:
        raise MapError(str(path), [("layers", [], "at least one layer name")])
    if path.exists() and not path.is_file():  # a folder, a FIFO, a device
        raise MapError(str(path), [("dxf", str(path), "not a regular file")])
    try:
        counted = _count_entities(path, MAX_ENTITIES)
    except OSError as exc:
        raise MapError(str(path), [("dxf", str(path), "cannot be read: "
                                    f"{clip_text(exc.strerror or exc)}")]) from None
    if counted > MAX_ENTITIES:
        raise MapError(str(path), [("dxf", str(path), f"more than {MAX_ENTITIES} entities in "
                                    f"its ENTITIES section: at most {MAX_ENTITIES} (counted "
                                    "before reading the drawing)")])
    try:
        doc = ezdxf.readfile(path)
    except OSError as exc:
        raise MapError(str(path), [("dxf", str(path), "cannot be read: "
                                    f"{clip_text(exc.strerror or exc)}")]) from None
    except ezdxf.DXFError as exc:
        raise MapError(str(path), [("dxf", str(path), "not a readable DXF file: "
                                    f"{clip_text(exc)}")]) from None
    except (StopIteration, EOFError, ValueError, IndexError, KeyError, ArithmeticError) as exc:
        # what ezdxf's tag reader raises on a file cut short or damaged inside a section
        why = f"{type(exc).__name__}: {clip_text(exc)}" if str(exc) else type(exc).__name__
        raise MapError(str(path), [("dxf", str(path), "not a readable DXF file: cut short or "
                                    f"damaged ({why})")]) from None
    scale = _scale(doc, path, units)
    present = {layer.dxf.name.casefold(): layer.dxf.name for layer in doc.layers}
    msp = doc.modelspace()
    for entity in msp:
        name = entity.dxf.get("layer", "0")
        present.setdefault(name.casefold(), name)
    missing = [n for n in names if n.casefold() not in present]
    if missing:
        raise MapError(str(path), [("layers", clipped(missing), "layers the drawing has: "
                                    + clip_text(", ".join(sorted(present.values())), 1000))])
    from ezdxf import path as dxf_path

    obstacles, sources, counts = [], [], {present[n.casefold()]: 0 for n in names}
    bad = []
    for k, (entity, layer) in enumerate(_entities(msp, {n.casefold() for n in names})):
        if k >= MAX_ENTITIES:
            raise MapError(str(path), [("layers", names, f"more than {MAX_ENTITIES} entities "
                                        "with the block references expanded: at most "
                                        f"{MAX_ENTITIES}")])
        name = _name(entity, layer)
        try:
            curve = dxf_path.make_path(entity)
            problem = _bad_number(entity, curve, scale)
            if problem is not None:
                bad.append((name, *problem))
                continue
            shape, closed = _shape(entity, curve, scale, line_thickness, name)
        except (ezdxf.DXFError, TypeError, ValueError, ArithmeticError, IndexError) as exc:
            # e.g. a polyface mesh (no outline to take), an arc of zero sweep, a spline through
            # fewer fit points than its degree needs
            log.warning("%s skipped: %s", name, clip_text(exc))
            continue
        if shape is None:
            continue
        parts = [g for g in getattr(shape, "geoms", [shape]) if isinstance(g, Polygon)]
        parts = [g for g in parts if not g.is_empty]
        obstacles += parts
        what = (f"the closed {name}" if closed else
                f"the {name} (a wall {line_thickness:g} m thick)")
        sources += [what] * len(parts)
        key = present.get(layer.casefold(), layer)
        counts[key] = counts.get(key, 0) + 1
    if bad:
        more = ([(f"and {len(bad) - _MAX_REPORTED} more entities", "", "the same")]
                if len(bad) > _MAX_REPORTED else [])
        raise MapError(str(path), bad[:_MAX_REPORTED] + more)
    empty = [n for n, c in counts.items() if c == 0]
    if empty:
        raise MapError(str(path), [("layers", empty, "each named layer must hold a line, "
                                    "polyline, circle, arc, spline or block reference")])
    bounds = shapely.total_bounds(obstacles)
    log.info("floor plan %s: %s; %.1f m x %.1f m", path.name,
             ", ".join(f"{n}: {c} shapes" for n, c in counts.items()),
             bounds[2] - bounds[0], bounds[3] - bounds[1])
    return FloorPlan(tuple(obstacles), tuple(float(b) for b in bounds), counts, scale,
                     tuple(sources))
