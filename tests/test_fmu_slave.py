"""Tests of the TrailerTrain FMU wrapper (pushtrain.cosim.fmu_slave)."""

import numpy as np
import pytest
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import fmi2Real

from pushtrain.cosim.fmu_slave import TrailerTrainSlave
from pushtrain.errors import CosimError


def test_readers_and_writers_by_name(fmu3):
    with TrailerTrainSlave(fmu3) as slave:
        slave.start({"theta_start[0]": 0.3, "theta_start[1]": 0.1})
        read = slave.real_reader(["theta[0]", "phi[1]", "x[0]"])
        flags = slave.bool_reader(["slipping[1]", "jackknifed"])
        assert read() == pytest.approx([0.3, 0.2, 0.0])
        assert flags().tolist() == [0, 0]
        slave.real_writer(["v_cmd"])([0.05])
        slave.do_step(0.0, 0.5)
        assert read()[2] > 0.0  # the robot moved along +x (heading 0.3 rad)
        np.testing.assert_allclose(slave.get_reals(["F_lat_max[1]"]), [0.09 * 42.1 * 9.81])


def test_a_failing_read_says_when_and_what(fmu3):
    def failing_get(*_args):
        raise FMICallException(function="fmi2GetReal", status=3)

    with TrailerTrainSlave(fmu3) as slave:
        slave.start({})
        slave.time = 1.25
        read = slave._reader(["x[0]", "y[0]"], fmi2Real, failing_get)
        with pytest.raises(CosimError,
                           match=r"reading x\[0\] \.\. y\[0\] failed at t = 1.250000 s"):
            read()
