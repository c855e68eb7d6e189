"""Open-loop robot command profiles (no tracking), e.g. the pure rotation of the paper's Sec. 4.4.

A profile is a table of pieces (:class:`Piece`: from a time on, each command channel ramps from
a start value at a rate until a stop value) that the engine evaluates in C
(``core/csrc/openloop.c``, :class:`Profile` is its Python face). The co-simulation master hands
the table to its C step loop once and evaluates it there each step, so an open-loop run makes
no call back into Python. :class:`RotationProfile` and :class:`ConstantCommand` are the
profiles of the scenarios and studies; their readable Python forms are the tests'
(``tests/reference/openloop.py``).
"""

from __future__ import annotations

import ctypes
import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property
from typing import NamedTuple

from . import native

__all__ = ["Piece", "Profile", "RotationProfile", "ConstantCommand"]


class Piece(NamedTuple):
    """One piece of a :class:`Profile`, from time ``t`` [s] (within the period) on: the robot
    command starts at ``(v, w)`` [m/s, rad/s] and ramps at ``(v_rate, w_rate)`` [m/s^2,
    rad/s^2] until it reaches ``(v_stop, w_stop)``, where it holds (None: never)."""

    t: float
    v: float = 0.0
    w: float = 0.0
    v_rate: float = 0.0
    w_rate: float = 0.0
    v_stop: float | None = None
    w_stop: float | None = None


class Profile:
    """A robot command given as a function of time alone: the C table ``PtProfile``.

    Parameters
    ----------
    pieces : sequence of Piece
        Increasing start times; before the first one the command is zero.
    period : float
        > 0: the pieces repeat every ``period`` [s] from t = 0 (zero command before t = 0);
        0: they run once.
    flip_v, flip_w : bool
        Negate that channel in every odd period (a swing back and forth).
    """

    def __init__(self, pieces: Sequence[Piece], period: float = 0.0, *, flip_v: bool = False,
                 flip_w: bool = False):
        pieces = [Piece(*p) for p in pieces]
        if not pieces:
            raise ValueError("pieces = []: a profile needs at least one piece")
        for i, piece in enumerate(pieces):
            _check_piece(i, piece, pieces[i - 1] if i else None)
        if not (math.isfinite(period) and period >= 0.0):
            raise ValueError(f"period = {period!r} s: must be finite and >= 0")
        self.pieces, self.period = tuple(pieces), float(period)
        self.flip_v, self.flip_w = bool(flip_v), bool(flip_w)
        self._pieces = (native.PtProfilePiece * len(pieces))(*(
            native.PtProfilePiece(p.t, (p.v, p.w), (p.v_rate, p.w_rate),
                                  (_stop(p.v_rate, p.v_stop), _stop(p.w_rate, p.w_stop)))
            for p in pieces))
        self.struct = native.PtProfile(len(pieces), self._pieces, self.period,
                                       (1 if flip_v else 0) | (2 if flip_w else 0))
        """The ``PtProfile`` the C reads (its pieces kept alive by this object)."""
        self._lib = native.load()
        self._cmd = (ctypes.c_double * 2)()

    def command_at(self, t: float) -> tuple[float, float]:
        """The command ``(v0 [m/s], w0 [rad/s])`` at ``t`` [s]."""
        status = self._lib.pt_profile_command(ctypes.byref(self.struct), t, self._cmd)
        if status:
            raise ValueError(f"the profile refused t = {t!r} s: "
                             f"{native.STATUS.get(status, status)}")
        return self._cmd[0], self._cmd[1]


def _check_piece(i: int, piece: Piece, before: Piece | None) -> None:
    """Raise ValueError naming the field of ``pieces[i]`` that the C cannot take: a start time
    that is NaN, decreases or is infinite (only the first may be -inf), a value or rate that is
    not finite, a NaN stop."""
    for name, value in piece._asdict().items():
        if name.endswith("_stop"):
            bad = value is not None and math.isnan(value)
        elif name == "t":
            bad = not (math.isfinite(value) or (before is None and value == -math.inf))
        else:
            bad = not math.isfinite(value)
        if bad:
            raise ValueError(f"pieces[{i}].{name} = {value!r}: must be finite (a stop may be "
                             "infinite, the first start -inf)")
    if before is not None and piece.t < before.t:
        raise ValueError(f"pieces[{i}].t = {piece.t!r} s: the start times must not decrease "
                         f"(pieces[{i - 1}].t = {before.t!r} s)")


def _stop(rate: float, stop: float | None) -> float:
    """The C's stop value: infinite in the ramp's direction for None."""
    if stop is not None:
        return float(stop)
    return math.inf if rate >= 0 else -math.inf


@dataclass(frozen=True)
class RotationProfile:
    """Periodic pure rotation of the robot (Fig. 15): v0 = 0 and a trapezoidal yaw rate.

    Each half period the yaw rate ramps with angular acceleration ``alpha`` [rad/s^2] to
    ``+w_max`` [rad/s], holds for ``hold`` [s] and ramps back to 0; the next half period does the
    same with ``-w_max``, so the robot swings back and forth. Has the controller interface the
    master expects (``n``, ``guide_geometry``, ``command``) and the :attr:`profile` its C loop
    runs.
    """

    n: int
    w_max: float
    alpha: float
    hold: float = 0.0
    guide_geometry: None = None

    def __post_init__(self):
        for name in ("w_max", "alpha"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} = {value!r}: must be finite and > 0")
        if not (math.isfinite(self.hold) and self.hold >= 0):
            raise ValueError(f"hold = {self.hold!r} s: must be finite and >= 0")

    @property
    def half_period(self) -> float:
        """Duration [s] of one swing: ramp up, hold, ramp down."""
        return 2.0 * self.w_max / self.alpha + self.hold

    @cached_property
    def profile(self) -> Profile:
        """The swing as a :class:`Profile`: ramp up from 0, hold, ramp down to 0 (held there),
        the yaw rate negated every other half period."""
        ramp = self.w_max / self.alpha
        return Profile([Piece(0.0, w_rate=self.alpha), Piece(ramp, w=self.w_max),
                        Piece(ramp + self.hold, w=self.w_max, w_rate=-self.alpha, w_stop=0.0)],
                       self.half_period, flip_w=True)

    def yaw_rate(self, t: float) -> float:
        """Commanded yaw rate [rad/s] at time ``t`` [s] (0 before t = 0)."""
        return self.profile.command_at(t)[1]

    def command(self, t, measurement, ref, leader=None):
        return (*self.profile.command_at(t), None)


@dataclass(frozen=True)
class ConstantCommand:
    """The robot drives with a fixed (v0 [m/s], w0 [rad/s]): open-loop pushing or holding still.

    Has the controller interface the master expects (``n``, ``guide_geometry``, ``command``) and
    the :attr:`profile` its C loop runs.
    """

    n: int
    v0: float = 0.0
    w0: float = 0.0
    guide_geometry: None = None

    def __post_init__(self):
        for name in ("v0", "w0"):
            value = getattr(self, name)
            if not math.isfinite(value):
                raise ValueError(f"{name} = {value!r}: must be finite")

    @cached_property
    def profile(self) -> Profile:
        """The command as a :class:`Profile` of one piece that holds from the start of time."""
        return Profile([Piece(-math.inf, self.v0, self.w0)])

    def command(self, t, measurement, ref, leader=None):
        return (*self.profile.command_at(t), None)
