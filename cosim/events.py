"""Scheduled disturbances of a co-simulation run and what of them applies at each step.

:class:`Push` (a force on the last trailer), :class:`Slide` (an imposed lateral slide of a
trailer's wheel) and :class:`SetBias` (a joint-angle sensor bias switched on) are given to
:func:`pushtrain.cosim.master.simulate`; its :class:`EventSchedule` answers, at each
communication point ``t``, which biases switch now, which push force acts and which slide speeds
change. An event is active on ``t0 <= t < t0 + duration`` (1e-12 s tolerance on both ends), so a
push of ``duration`` d starting on a communication point acts on exactly d / h steps.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

from pushtrain.errors import CosimInputError

__all__ = ["EVENT_TOLERANCE", "EventSchedule", "Push", "SetBias", "Slide", "positive_number"]

log = logging.getLogger(__name__)

EVENT_TOLERANCE = 1e-12
"""[s] Tolerance of event times against communication points."""


def positive_number(name: str, value, allow_zero: bool = False) -> float:
    """``value`` as a float; CosimInputError unless finite and > 0 (>= 0 with ``allow_zero``)."""
    ok = isinstance(value, (int, float)) and math.isfinite(value)
    ok = ok and (value >= 0 if allow_zero else value > 0)
    if not ok:
        raise CosimInputError(
            f"{name} = {value!r}: must be a finite number {'>= 0' if allow_zero else '> 0'}"
        )
    return float(value)


@dataclass(frozen=True)
class Push:
    """External force on the last trailer's axle midpoint from ``t`` for ``duration`` [s].

    ``lateral`` [N] acts along the last trailer's *current* left normal (positive: to its left
    as seen facing the robot): the direction is taken from the trailer's heading at every
    communication point and held over the step, so the force turns with the trailer. That is
    what a lateral push means on a vehicle: a hand or a bumper pressing on the trailer's side
    stays perpendicular to it, and the rolling model's wheel force ``F_lat`` along that same
    normal takes exactly ``-lateral`` while the push lasts, whatever the trailer does. A force
    of fixed direction is what ``fx``, ``fy`` [N] are for: they add a world-frame force. In the
    rolling model (slip_mode 0) a push changes the wheel and hitch forces only.
    """

    t: float
    duration: float
    lateral: float = 0.0
    fx: float = 0.0
    fy: float = 0.0


@dataclass(frozen=True)
class Slide:
    """Imposed lateral slide of trailer ``trailer``'s wheel: ``distance`` [m] along its left
    normal over ``duration`` [s] from ``t`` (a kinematic disturbance: the paper's hand push,
    Fig. 9(b), in the rolling model). ``trailer`` None means the last trailer."""

    t: float
    duration: float
    distance: float
    trailer: int | None = None


@dataclass(frozen=True)
class SetBias:
    """Switch the measurement bias of joint ``joint`` (1..n) to ``bias`` [rad] at ``t``."""

    t: float
    joint: int
    bias: float


def _active(event, t: float) -> bool:
    return event.t - EVENT_TOLERANCE <= t < event.t + event.duration - EVENT_TOLERANCE


class EventSchedule:
    """The events of one run, checked, and what of them applies at each communication point.

    Parameters
    ----------
    events : sequence of Push, Slide, SetBias
    n : int
        Number of trailers (joints and slides are numbered 1..n).
    t_end : float
        End of the run [s]; later events are kept but logged as a warning.

    Raises
    ------
    CosimInputError
        For an unknown event, a duration <= 0, a negative or non-finite time, a joint or trailer
        outside 1..n.
    """

    def __init__(self, events, n: int, t_end: float):
        self.n = n
        self.pushes: list[Push] = []
        self.slides: list[Slide] = []
        biases: list[SetBias] = []
        for k, ev in enumerate(events):
            where = f"events[{k}]"
            if isinstance(ev, Push):
                positive_number(f"{where}.duration", ev.duration)
                self.pushes.append(ev)
            elif isinstance(ev, Slide):
                positive_number(f"{where}.duration", ev.duration)
                trailer = n if ev.trailer is None else ev.trailer
                if not (isinstance(trailer, int) and 1 <= trailer <= n):
                    raise CosimInputError(f"{where}.trailer = {ev.trailer!r}: allowed are 1..{n}")
                self.slides.append(ev)
            elif isinstance(ev, SetBias):
                if not (isinstance(ev.joint, int) and 1 <= ev.joint <= n):
                    raise CosimInputError(f"{where}.joint = {ev.joint!r}: allowed are 1..{n}")
                biases.append(ev)
            else:
                raise CosimInputError(
                    f"{where} = {ev!r}: allowed are Push, Slide and SetBias events"
                )
            if not (isinstance(ev.t, (int, float)) and math.isfinite(ev.t) and ev.t >= 0):
                raise CosimInputError(f"{where}.t = {ev.t!r} s: must be finite and >= 0")
            if ev.t > t_end:
                log.warning("%s at t = %.3f s is after the end of the run (%.3f s)",
                            where, ev.t, t_end)
        self.biases = sorted(biases, key=lambda e: e.t)
        self._next_bias = 0
        self._slide_speed: dict[int, float] = {}  # trailer -> slide speed [m/s] set in the FMU

    def biases_due(self, t: float) -> list[SetBias]:
        """The bias switches not yet returned whose time has come at ``t`` [s], in time order."""
        start = k = self._next_bias
        while k < len(self.biases) and self.biases[k].t <= t + EVENT_TOLERANCE:
            k += 1
        self._next_bias = k
        return self.biases[start:k]

    @property
    def next_bias_time(self) -> float:
        """Time [s] of the first bias switch not yet returned by :meth:`biases_due` (inf if
        none)."""
        k = self._next_bias
        return self.biases[k].t if k < len(self.biases) else math.inf

    def switch_times(self) -> list[float]:
        """The instants [s] (less :data:`EVENT_TOLERANCE`) at which a push or slide starts or
        ends, ascending, each once: between two of them the active pushes and slides stay."""
        return sorted({b for ev in (*self.pushes, *self.slides)
                       for b in (ev.t - EVENT_TOLERANCE, ev.t + ev.duration - EVENT_TOLERANCE)})

    def active_pushes(self, t: float) -> list[Push]:
        """The pushes acting at ``t`` [s]."""
        return [p for p in self.pushes if _active(p, t)]

    def push_force(self, t: float, theta_n: float) -> tuple[float, float]:
        """World-frame force (push_x, push_y) [N] on the last trailer at ``t`` [s] when its
        heading is ``theta_n`` [rad]: the sum of the active pushes (zero outside them)."""
        push_x = push_y = 0.0
        for p in self.pushes:
            if _active(p, t):
                push_x += p.fx - math.sin(theta_n) * p.lateral
                push_y += p.fy + math.cos(theta_n) * p.lateral
        return push_x, push_y

    def slide_changes(self, t: float) -> list[tuple[int, float]]:
        """``(trailer, speed)`` for every trailer whose imposed slide speed [m/s] (the sum of
        its active slides, distance / duration) differs at ``t`` [s] from the one set before;
        the new speeds become the ones set."""
        if not self.slides:
            return []
        speeds = dict.fromkeys(self._slide_speed, 0.0)
        for ev in self.slides:
            if _active(ev, t):
                i = self.n if ev.trailer is None else ev.trailer
                speeds[i] = speeds.get(i, 0.0) + ev.distance / ev.duration
        changes = [(i, v) for i, v in speeds.items() if self._slide_speed.get(i, 0.0) != v]
        self._slide_speed.update(changes)
        return changes

    def slide_speed(self, trailer: int) -> float:
        """The slide speed [m/s] of ``trailer`` (1..n) set by the last :meth:`slide_changes`."""
        return self._slide_speed.get(trailer, 0.0)
