"""Loading a scenario's map into a :class:`~pushtrain.facility.free_space.World`: polygons, an
occupancy grid (ROS map_server format, :mod:`pushtrain.facility.occupancy_grid`) and a DXF floor
plan (:mod:`pushtrain.facility.dxf`), in any combination, and the polygons traced from a grid.

A grid world (:func:`grid_world`) is a :class:`~pushtrain.facility.free_space.World` with
``occupancy`` set, so its :meth:`~pushtrain.facility.free_space.World.distance_field` comes from
the grid (exact to the resolution), and polygons for what still works on shapely geometry
(drawing the legacy way, the planner's region tests, the run's clearance check):

- the outline is the image's footprint (a rotated rectangle for a rotated map);
- the obstacles are the blocked cells, traced by marching squares
  (:func:`~pushtrain.facility.raster.blocked_polygons`: within 0.35 cell of the cells' own edges,
  then simplified by a quarter cell, so that cell centres stay on their side), plus the polygons
  drawn on top, exactly;
- :meth:`World.eroded <pushtrain.facility.free_space.World.eroded>` of a grid world is the level
  set {distance >= margin} of its distance field, traced the same way
  (:func:`~pushtrain.facility.raster.clear_region`), not a buffer of the traced polygons: on a map
  with ragged walls the buffer takes seconds (1 s for the bundled 500 x 340 warehouse), the
  level set a fraction of one (0.03 s).

**Why collisions on a grid go through the distance field.** A footprint keeps a margin m from
every wall exactly when every point of it has a signed distance >= m; sampled at a few points
(spacing s, then a sample's value must be >= m + s / sqrt(2)) the test is a handful of bilinear
lookups per footprint. That cost does not grow with the map (2000 x 2000 cells cost what 200 x 200
cost, once the field is built: Euclidean distance transforms, 1 to 2 s at 2000 x 2000) nor with how
ragged the walls are, a margin is a threshold rather than a new geometry, and the answer is exact
to the resolution, which is all a grid knows. The alternatives: testing each footprint against the
cells under it is exact too, but rasterizes every footprint at every check and needs a dilated grid
per margin; shapely on traced polygons costs in proportion to their vertices (30 000 for a ragged
2000 x 2000 map), and each margin is a buffer that takes seconds to a minute there.

Polygons and DXF obstacles combined with a grid are burned into it
(:meth:`~pushtrain.facility.occupancy_grid.OccupancyGrid.burn`), so the distance field sees them.
"""

from __future__ import annotations

from pathlib import Path

from shapely.geometry import Polygon, box
from shapely.ops import unary_union

from pushtrain.errors import MapError, PlanningInputError
from pushtrain.validation import clipped

from .distance_field import DistanceField
from .map_cache import Prepared, map_key, prepared
from .map_server import load_map
from .occupancy_grid import OccupancyGrid
from .raster import blocked_polygons

__all__ = ["grid_world", "map_world"]

def grid_world(grid: OccupancyGrid, obstacles=(), keep_in: Polygon | None = None,
               cache: bool = True):
    """A :class:`~pushtrain.facility.free_space.World` of ``grid`` with ``obstacles`` (polygons [m])
    and, if given, ``keep_in`` (an outline [m]) burned in: ``occupancy`` is the burned grid, the
    outline the map's footprint (cut to ``keep_in``), the obstacles the traced blocked cells of
    the map (one MultiPolygon) and ``obstacles`` themselves, exactly. The traced polygons, the
    free space and the distance field come from the map cache (:mod:`.map_cache`: by the
    content of the grid and the polygons) when ``cache`` and it holds them, and so do the free
    space's erosions (:meth:`~pushtrain.facility.free_space.World.eroded`)."""
    from .free_space import World

    obstacles = tuple(obstacles)
    burned = grid.burn(obstacles, keep_in)
    outline = burned.footprint()

    def build() -> Prepared:
        traced = blocked_polygons(grid)
        free = outline.difference(traced)  # the traced pieces are disjoint: no union needed
        if obstacles:
            free = free.difference(unary_union(list(obstacles)))
        field = DistanceField.from_occupancy(burned.blocked, burned.x0, burned.y0,
                                             burned.resolution)
        return Prepared(traced, free, field)

    key = map_key(grid, obstacles, keep_in) if cache else None
    ready = prepared(burned, key, build) if cache else build()
    world = World(outline, (ready.traced, *obstacles), occupancy=burned, free=ready.free,
                  cache_key=key)
    world.adopt_distance_field(ready.field)
    return world


def _prefixed(exc: MapError, field: str, own: tuple = ()) -> MapError:
    """``exc`` with each problem's field named from the scenario's ``[map]``: a problem of the
    file itself is ``field``'s, one in ``own`` keeps its name (a field of its own), any other is
    ``field (file name) where``."""
    name = Path(exc.source).name
    errors = [(field if where in ("(file)", field) else where if where in own else
               f"{field} ({name}) {where}", value, allowed) for where, value, allowed in exc.errors]
    return MapError(exc.source, errors)


def map_world(*, free=None, bounds=None, obstacles=(), walls=(), grid=None, dxf=None, layers=(),
              line_thickness: float | None = None, dxf_units: str | None = None):
    """A :class:`~pushtrain.facility.free_space.World` from a scenario's map: polygons (``free``,
    ``bounds``, ``obstacles``, ``walls`` as in :meth:`World.from_dict
    <pushtrain.facility.free_space.World.from_dict>`), a map_server YAML file ``grid`` and a DXF
    floor plan ``dxf`` with its ``layers`` (see :mod:`pushtrain.facility.dxf`).

    With a grid, the polygons and the floor plan's obstacles are burned into it and ``free`` or
    ``bounds`` cut it (:func:`grid_world`). Without one, the floor plan's obstacles join the
    polygons, and the outline is ``free``, ``bounds`` or the floor plan's extent.

    Raises
    ------
    MapError
        A file that cannot be used (each problem's field starts with ``grid`` or ``dxf``), or
        a ``free`` outline that crosses or touches itself (field ``free``).
    PlanningInputError
        A malformed polygon.
    """
    from .free_space import World, polygon_from_points

    outline, outline_label = None, ""
    if free is not None:
        try:
            outline, outline_label = polygon_from_points(free, "map.free", outline=True), "map.free"
        except PlanningInputError as exc:
            if "outline_problem" not in exc.details:
                raise
            raise MapError("<map>", [("free", clipped(free),
                                      exc.details["outline_problem"])]) from None
    elif bounds is not None:
        outline, outline_label = World.from_dict({"bounds": bounds}).outline, "map.bounds"
    extra, labels = [], []
    for name, items in (("obstacles", obstacles), ("walls", walls)):
        for k, p in enumerate(items):
            extra.append(polygon_from_points(p, f"map.{name}[{k}]"))
            labels.append(f"map.{name}[{k}]")
    if dxf is not None:
        from .dxf import DEFAULT_LINE_THICKNESS, read_dxf

        thickness = line_thickness or DEFAULT_LINE_THICKNESS
        try:
            plan = read_dxf(dxf, layers, thickness, dxf_units)
        except MapError as exc:
            raise _prefixed(exc, "dxf", ("layers", "line_thickness", "dxf_units")) from None
        extra += plan.obstacles
        name = Path(dxf).name
        if outline is None and grid is None:
            outline, outline_label = box(*plan.bounds), f"the extent of {name}"
        how = (f"free space is {outline_label or 'the map'} minus what layers "
               f"{', '.join(plan.counts)} hold: closed shapes (polylines, circles, ...) are "
               f"solid, lines and open polylines walls {thickness:g} m thick")
        room = ("; draw a room's walls as lines or an open polyline, or put its outline on a "
                "layer map.layers does not name")
        labels += [f"{source} of {name} ({how}{room if source.startswith('the closed') else ''})"
                   for source in plan.sources]
    if grid is not None:
        try:
            occupancy = load_map(grid)
        except MapError as exc:
            raise _prefixed(exc, "grid") from None
        return grid_world(occupancy, extra, outline)
    if outline is None:
        raise MapError("<map>", [("map", None, "give free (an outline), bounds, grid (a "
                                               "map_server YAML) or dxf (a floor plan)")])
    return World(outline, tuple(extra), labels=tuple(labels), outline_label=outline_label)
