"""The facility map: where the train may be.

The free space (:class:`~.free_space.World`: polygons, or the free cells of a grid), loaded from
a scenario's map (:mod:`.loading`): occupancy grids in the ROS map_server format
(:mod:`.occupancy_grid`), DXF floor plans (:mod:`.dxf`), polygons drawn on top; the signed
distance field that collisions are tested on (:mod:`.distance_field`), the tracing between grids
and polygons (:mod:`.raster`), and example layouts as plain data (:mod:`.example_layouts`).

Stands on the core and pushtrain's own infrastructure only; the planner, the missions, the
reports, the studies and the command line read it.
"""

__all__: list[str] = []
