"""The route the search follows, kept off the corners the train cannot turn on the planner's
arcs (:func:`turnable_route`): :func:`~pushtrain.planner.route.find_route`'s route, each corner
:func:`~pushtrain.planner.passage.tight_corners` finds too tight closed and the route found
again."""

from __future__ import annotations

import logging
import math

from .config import turning_radius_from_joint_limit
from .passage import swept_band, tight_corners
from .route import find_route
from .train import Train

__all__ = ["turnable_route", "turning_bands"]

log = logging.getLogger(__name__)


def turning_bands(train: Train, config, margins):
    """The bands the train sweeps turning steadily (:func:`~pushtrain.planner.passage.
    swept_band`): on the planner's radius, and on the tightest radius its joints allow
    (``config``'s joint margin kept), each body keeping ``margins`` [m]."""
    band = swept_band(train, config.radius_for(train), margins)
    tightest = swept_band(train, turning_radius_from_joint_limit(
        train.phi_max - config.joint_margin, train.max_link(), 0.0), margins)
    return band, tightest


def turnable_route(field, train: Train, start, goal, half_width: float, config, margins,
                   tries: int = 3, longest: float = 2.5):
    """The route of the last trailer (:func:`~pushtrain.planner.route.find_route`), kept off
    the corners the train cannot turn on the planner's arcs (:func:`~pushtrain.planner.
    passage.tight_corners`: the corridor there narrower than the band the train sweeps). Each
    such corner (too tight by more than a cell of the map) is closed (a disc as wide as the
    corridor there) and the route found again,
    ``tries`` times at most; a way round is taken if it turns with a wider margin and is at
    most ``longest`` times as long, else the first route stays (it may be the only way in)."""
    route = find_route(field, start, goal, half_width)
    if route is None:
        return None
    band, tightest = turning_bands(train, config, margins)

    def worst(r):
        # too tight by more than a cell of the map (what the widths' measure may be off by)
        corners = tight_corners(r, field, band, tightest, only_too_tight=True)
        if corners and corners[0].width < corners[0].needed - field.resolution:
            return corners[0]
        return None

    corner = worst(route)
    avoid = []
    for _ in range(tries):
        if corner is None:
            break
        radius = max(corner.width, half_width)
        if min(math.hypot(corner.x - p[0], corner.y - p[1]) for p in (start, goal)) <= radius:
            break  # the corner is at an end: no way round it
        avoid.append((corner.x, corner.y, radius))
        other = find_route(field, start, goal, half_width, avoid=tuple(avoid))
        if other is None or other.length > longest * route.length:
            break
        other_corner = worst(other)
        if other_corner is not None and (other_corner.width - other_corner.needed
                                         <= corner.width - corner.needed):
            corner = other_corner  # no better this way: try round its worst corner too
            continue
        log.info("the route avoids a corner the train cannot turn at (%.2f, %.2f): %.1f m "
                 "instead of %.1f m", avoid[-1][0], avoid[-1][1], other.length, route.length)
        route, corner = other, other_corner
    return route
