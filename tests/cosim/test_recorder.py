"""Tests of the co-simulation recorder (pushtrain.cosim.recorder)."""

import numpy as np
import pytest

from pushtrain.cosim.recorder import Recorder
from pushtrain.errors import CosimInputError

BLOCKS = [("t", ["t"]), ("pose", ["x", "y", "theta"]), ("flags", ["slipping", "jackknifed"])]


def test_rows_grow_past_the_capacity_and_are_trimmed():
    rec = Recorder(BLOCKS, order=["t", "x", "slipping", "y", "theta", "jackknifed"], capacity=3)
    buffer = np.zeros(3)
    for k in range(1000):
        buffer[:] = (k, -k, 0.5 * k)  # a reused buffer, as the FMU reader hands out
        rec.append(t=0.01 * k, pose=buffer, flags=[k % 2, False])
    data = rec.to_array()
    assert data.dtype.names == ("t", "x", "slipping", "y", "theta", "jackknifed")
    assert len(data) == rec.rows == 1000
    k = np.arange(1000)
    assert np.array_equal(data["t"], 0.01 * k) and np.array_equal(data["x"], k)
    assert np.array_equal(data["y"], -k) and np.array_equal(data["theta"], 0.5 * k)
    assert np.array_equal(data["slipping"], k % 2) and not data["jackknifed"].any()
    assert rec.last("theta") == 499.5 and np.array_equal(rec.column("y"), -k)


def test_a_block_not_given_stays_nan():
    rec = Recorder(BLOCKS)
    rec.append(t=1.0, pose=(1.0, 2.0, 3.0))
    rec.append(t=2.0, flags=(1, 0))
    data = rec.to_array()
    assert np.isnan(data["slipping"][0]) and np.isnan(data["x"][1])
    assert list(data[1]) == pytest.approx([2.0, np.nan, np.nan, np.nan, 1.0, 0.0], nan_ok=True)


def test_declarations_must_name_every_column_once():
    with pytest.raises(CosimInputError, match="twice"):
        Recorder([("a", ["x"]), ("b", ["x"])])
    with pytest.raises(CosimInputError, match="missing"):
        Recorder(BLOCKS, order=["t", "x", "y", "theta", "slipping"])
    with pytest.raises(CosimInputError, match="unknown"):
        Recorder(BLOCKS, order=["t", "x", "y", "theta", "slipping", "jackknifed", "z"])
    with pytest.raises(IndexError):
        Recorder(BLOCKS).last("t")


def test_rows_filled_through_views_are_committed_in_one_copy():
    rec = Recorder(BLOCKS, order=["jackknifed", "t", "x", "y", "theta", "slipping"], capacity=2)
    pose, flags = rec.view("pose"), rec.view("flags")
    assert np.shares_memory(pose, rec.row) and pose.flags.c_contiguous
    flags[:] = (0, 1)  # set once: kept in every later row
    for k in range(5):
        rec.view("t")[0] = 0.5 * k
        pose[:] = (k, 2 * k, 3 * k)
        rec.commit()
    pose[:] = -1.0  # after the last commit: not recorded
    data = rec.to_array()
    assert data.dtype.names == ("jackknifed", "t", "x", "y", "theta", "slipping")
    assert np.array_equal(data["t"], 0.5 * np.arange(5))
    assert np.array_equal(data["theta"], 3 * np.arange(5))
    assert np.array_equal(data["slipping"], np.zeros(5)) and data["jackknifed"].all()
    assert rec.last("y") == 8.0 and rec.rows == 5


def test_an_empty_recorder_gives_an_empty_table():
    data = Recorder(BLOCKS).to_array()
    assert len(data) == 0 and data.dtype.names == ("t", "x", "y", "theta", "slipping", "jackknifed")


def test_advance_refuses_more_rows_than_are_free():
    rec = Recorder(BLOCKS, capacity=4)
    free = rec.free_rows()
    free[:2] = np.arange(2 * free.shape[1]).reshape(2, -1)
    rec.advance(2)
    assert rec.rows == 2
    with pytest.raises(ValueError, match=r"advance\(3\): 2 rows are free"):
        rec.advance(3)
    with pytest.raises(ValueError):
        rec.advance(-1)
    assert rec.rows == 2
