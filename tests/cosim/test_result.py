"""The summary of a run (:func:`pushtrain.cosim.result.summarize`) against numbers worked out
by hand from a small table: force ratios, slip events and time slipping, errors."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pushtrain.cosim.result import summarize

STEP = 0.01


def _table():
    """Eight rows of a two-trailer run: trailer 1 slips on rows 2-3 and 6, trailer 2 never."""
    names = ["t", "e_lat", "e_theta", "e_lon"] + [f"{k}{i}" for i in (1, 2) for k in
                                                    ("phi", "F_lat", "F_lat_max", "slipping")]
    data = np.zeros(8, dtype=[(name, float) for name in names])
    data["t"] = STEP * np.arange(8)
    data["e_lat"] = [0.0, 0.01, -0.03, 0.02, 0.0, 0.0, 0.0, 0.005]
    data["e_theta"] = np.radians([0, 1, -2, 0, 0, 0, 0, 0])
    data["phi1"] = np.radians([0, 5, 10, -20, 0, 0, 0, 0])
    data["phi2"] = np.radians([0, 1, 2, 3, 4, 5, 6, 7])
    data["F_lat1"] = [10.0, -40.0, 120.0, -150.0, 30.0, 20.0, 110.0, 0.0]
    data["F_lat2"] = [1.0, 2.0, -3.0, 4.0, 5.0, 6.0, 7.0, 8.0]
    data["F_lat_max1"] = 100.0
    data["F_lat_max2"] = 50.0
    data["slipping1"] = [0, 0, 1, 1, 0, 0, 1, 0]
    return data


def test_force_ratios_slips_and_errors_are_summarised():
    s = summarize(_table(), 2, "goal_reached", "ok", wall=0.5, step=STEP)
    assert s["max_F_lat_ratio"] == pytest.approx([150.0 / 100.0, 8.0 / 50.0])
    one, two = s["slip"]
    assert one["events"] == 2 and one["first_t"] == pytest.approx(0.02)
    assert one["time_slipping_s"] == pytest.approx(3 * STEP)
    assert two == {"trailer": 2, "events": 0, "first_t": None, "time_slipping_s": 0.0}
    assert s["max_abs_phi_deg"] == pytest.approx([20.0, 7.0])
    assert s["lateral_error_m"]["max"] == pytest.approx(0.03)
    assert s["lateral_error_m"]["final"] == pytest.approx(0.005)
    rms = math.sqrt((0.01**2 + 0.03**2 + 0.02**2 + 0.005**2) / 8)
    assert s["lateral_error_m"]["rms"] == pytest.approx(rms)
    assert s["t_final"] == pytest.approx(0.07) and s["steps"] == 7


def test_a_run_slipping_from_its_first_row_counts_that_event():
    data = _table()
    data["slipping2"] = [1, 1, 0, 0, 0, 0, 0, 0]
    two = summarize(data, 2, "goal_reached", "ok", wall=0.5, step=STEP)["slip"][1]
    assert two["events"] == 1 and two["first_t"] == 0.0
