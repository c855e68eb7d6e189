"""One control instant of a controller written in Python (or called from Python).

At every control instant ``t``: sample the last trailer's reference at ``t`` (a rest sample
during cusp dwells, before the start and after the goal), while pulling also the robot's own
reference from the :class:`~pushtrain.core.pulling.PullGuide` built with the controller's chain
model (``controller.guide_geometry``), and ask the controller for the robot command. The
co-simulation master calls it back for a law written in Python (the compiled law, with its slip
governor, and open-loop profiles run in its C loop); with the compiled law
(:class:`~pushtrain.core.controller.Controller`) the whole instant is one C call
(``pt_track``), which the engine (``core/csrc``) also runs inside its loops. The tests' reference
closed loop (``tests/reference/closed_loop.py``) steps it with the readable reference law
(``tests/reference/controller.py``).
"""

from __future__ import annotations

import math

from .pulling import PullGuide
from .reference import ReferenceSample
from .segment import PULL, REST

__all__ = ["TrackingLoop"]

_NO_REFERENCE = ReferenceSample(math.nan, math.nan, math.nan, 0.0, 0.0, REST)


def _no_reference(t: float) -> ReferenceSample:
    """The sample of an open-loop run without a reference: at rest, pose unknown."""
    return _NO_REFERENCE


class TrackingLoop:
    """Reference sampling, pull guide and controller call of one control instant.

    Parameters
    ----------
    controller
        A :class:`~pushtrain.core.controller.Controller`, or anything with its
        ``command(t, measurement, ref, leader)`` (the slip governor, open-loop profiles). Its
        ``guide_geometry`` (None for open-loop profiles, which ignore the reference) is the chain
        model of the pull guide.
    reference : Reference, SampledReference or None
        The last trailer's reference; None (open loop) hands the controller a resting sample
        with a NaN pose.
    info : bool
        False lets a compiled controller skip building its ``ControlInfo`` each call (the
        co-simulation master does not record it): :meth:`command` may then return None in its
        place.
    """

    def __init__(self, controller, reference, info: bool = True):
        self.controller = controller
        self.reference = reference
        geometry = getattr(controller, "guide_geometry", None)
        self.guide = None
        if reference is not None and geometry is not None and reference.pull_intervals():
            self.guide = PullGuide(reference, geometry)
        self.reference_at = _no_reference if reference is None else reference.sample_at
        """``reference_at(t)``: the last trailer's :class:`ReferenceSample` at ``t`` [s]."""
        make_tracker = getattr(controller, "tracker", None)
        self.tracker = None
        """The compiled instant (a :class:`~pushtrain.core.controller.Tracker`) when the
        controller is the compiled law and the reference one it can copy, else None."""
        if make_tracker is not None and reference is not None:
            self.tracker = make_tracker(reference, self.guide, info)
        if self.tracker is not None:
            self.command = self.tracker.command  # the whole instant in compiled code

    def command(self, t: float, measurement):
        """The controller's command at ``t`` [s] for ``measurement``.

        With a controller that has a ``tracker(reference, guide, info)`` method
        (:class:`~pushtrain.core.controller.Controller`) this method is the
        :attr:`tracker`'s ``command``, which does the same in one call.

        Returns ``(v0, w0, info, ref)``: the robot command [m/s, rad/s], the controller's
        diagnostics and the reference sample it tracked.
        """
        ref = self.reference_at(t)
        leader = None
        if ref.direction == PULL and self.guide is not None:
            leader = self.guide.sample_at(t)
        v0, w0, info = self.controller.command(t, measurement, ref, leader)
        return v0, w0, info, ref
