"""Open-loop profiles (core/openloop.py, their C in core/csrc/openloop.c): the C table against
the readable profile of tests/reference/openloop.py bit for bit, the swing's closed-form angle,
and the bad input the table refuses."""

import math
import re
import struct

import numpy as np
import pytest
from reference.openloop import rotation_yaw_rate

from pushtrain.core.openloop import ConstantCommand, Piece, Profile, RotationProfile


def _bits(x: float) -> bytes:
    return struct.pack("<d", x)


@pytest.mark.parametrize("w_max_deg, alpha_deg, hold", [(10.0, 5.0, 0.0), (20.0, 60.0, 0.0),
                                                        (7.0, 3.3, 1.7), (10.0, 5.0, 0.35)])
def test_the_rotation_profile_equals_the_readable_one_bit_for_bit(w_max_deg, alpha_deg, hold):
    """Every 5 ms over 40 half periods (and at the pieces' edges): the same float, signed zeros
    included."""
    w_max, alpha = math.radians(w_max_deg), math.radians(alpha_deg)
    profile = RotationProfile(3, w_max, alpha, hold)
    half = profile.half_period
    times = [k * 0.005 for k in range(-20, int(40 * half / 0.005))]
    times += [j * half + e for j in range(40) for e in (0.0, w_max / alpha, w_max / alpha + hold)]
    wrong = [t for t in times
             if _bits(profile.yaw_rate(t)) != _bits(rotation_yaw_rate(t, w_max, alpha, hold))]
    assert not wrong, wrong[:5]
    assert {_bits(profile.command(t, None, None)[0]) for t in times} == {_bits(0.0)}


@pytest.mark.parametrize("hold", [0.0, 1.5])
def test_each_swing_turns_the_robot_by_the_closed_form_angle(hold):
    """The yaw rate integrated over a half period is w_max^2 / alpha + w_max hold, with sign
    +, -, +, ...; it peaks at w_max and never leaves [-w_max, w_max]."""
    w_max, alpha = math.radians(10.0), math.radians(5.0)
    profile = RotationProfile(3, w_max, alpha, hold)
    half, dt = profile.half_period, 1e-4
    for j in range(4):
        t = j * half + (np.arange(round(half / dt)) + 0.5) * dt  # midpoint rule
        rates = np.array([profile.yaw_rate(x) for x in t])
        assert rates.sum() * dt == pytest.approx((-1) ** j * (w_max**2 / alpha + w_max * hold),
                                                 rel=1e-6)
        assert np.abs(rates).max() == pytest.approx(w_max, rel=1e-3)
        assert np.abs(rates).max() <= w_max
    assert profile.yaw_rate(-1.0) == 0.0


def test_a_constant_command_holds_at_every_time():
    command = ConstantCommand(2, -0.05, 0.01)
    for t in (-1e9, -0.0, 0.0, 3.0, 1e12):
        assert command.command(t, None, None) == (-0.05, 0.01, None)
    assert _bits(ConstantCommand(2, -0.0).command(1.0, None, None)[0]) == _bits(-0.0)


def test_a_table_ramps_holds_at_its_stop_and_repeats():
    """A once-only table: zero before its first piece, a ramp held at its stop, a hold; a
    periodic one flips only the channel asked for."""
    once = Profile([Piece(1.0, v=-0.1, v_rate=-0.05, v_stop=-0.2), Piece(5.0, w=0.3)])
    assert once.command_at(0.5) == (0.0, 0.0)
    assert once.command_at(2.0) == pytest.approx((-0.15, 0.0))
    assert once.command_at(4.0) == (-0.2, 0.0)  # held at its stop
    assert once.command_at(7.0) == (0.0, 0.3)
    swing = Profile([Piece(0.0, v=0.1, w=0.2)], period=2.0, flip_w=True)
    assert [swing.command_at(t) for t in (0.5, 2.5, 4.5, -0.5)] == [
        (0.1, 0.2), (0.1, -0.2), (0.1, 0.2), (0.0, 0.0)]


@pytest.mark.parametrize("pieces, period, field", [
    ([], 0.0, "pieces"),
    ([Piece(0.0, v=math.nan)], 0.0, "pieces[0].v"),
    ([Piece(0.0, w_rate=math.inf)], 0.0, "pieces[0].w_rate"),
    ([Piece(0.0), Piece(-math.inf)], 0.0, "pieces[1].t"),
    ([Piece(1.0), Piece(0.5)], 0.0, "pieces[1].t"),
    ([Piece(0.0, v_stop=math.nan)], 0.0, "pieces[0].v_stop"),
    ([Piece(0.0)], -1.0, "period"),
    ([Piece(0.0)], math.inf, "period"),
])
def test_a_table_the_c_cannot_take_is_refused_naming_the_field(pieces, period, field):
    with pytest.raises(ValueError, match=re.escape(field)):
        Profile(pieces, period)



@pytest.mark.parametrize("make, field", [
    (lambda: ConstantCommand(2, math.nan), "v0"), (lambda: ConstantCommand(2, 0.0, math.inf), "w0"),
    (lambda: RotationProfile(2, 0.0, 1.0), "w_max"), (lambda: RotationProfile(2, 1.0, math.nan),
                                                      "alpha"),
    (lambda: RotationProfile(2, 1.0, 1.0, -1.0), "hold"),
])
def test_bad_profile_settings_are_refused_naming_the_field(make, field):
    with pytest.raises(ValueError, match=f"^{field} = "):
        make()
