"""Tests of the TrailerTrain FMU wrapper (pushtrain.cosim.fmu_slave)."""

import ctypes
import os
import shutil

import numpy as np
import pytest

from pushtrain.cosim import fmu_slave
from pushtrain.cosim.fmu_slave import TrailerTrainSlave
from pushtrain.errors import CosimError, CosimInputError


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


@pytest.mark.parametrize("fmi_version", [2, 3])
def test_readers_write_into_a_given_array(fmi_version, fmu3):
    from pushtrain.fmu.build import build_fmu

    fmu = fmu3 if fmi_version == 2 else build_fmu(fmi_version=3)
    with TrailerTrainSlave(fmu, n_trailers=3) as slave:
        slave.start({"theta_start[0]": 0.3, "theta_start[1]": 0.1, "x0_start": 1.5})
        row = np.full(8, np.nan)
        read = slave.real_reader(["theta[0]", "phi[1]", "x[0]"], out=row[2:5])
        flags = slave.bool_reader(["slipping[1]", "jackknifed"], out=row[5:7])
        assert read() is not None and flags() is not None
        np.testing.assert_allclose(row[2:7], [0.3, 0.2, 1.5, 0.0, 0.0])
        assert np.isnan(row[[0, 1, 7]]).all()  # nothing written outside the view
        slave.real_writer(["v_cmd", "w_cmd"])([0.05, 0.02])
        slave.do_step(0.0, 0.5)
        read()
        assert row[4] > 1.5 and row[2] > 0.3  # moved and turned: the view holds the new values
        with pytest.raises(CosimInputError, match="out has shape"):
            slave.real_reader(["x[0]"], out=row[:2])


def test_a_failing_read_says_when_and_what(fmu3):
    with TrailerTrainSlave(fmu3) as slave:
        slave.start({})
        slave.time = 1.25
        read = slave._reader(["x[0]", "y[0]"], ctypes.c_double, lambda *args: 3)  # fmi2Error
        with pytest.raises(CosimError,
                           match=r"reading x\[0\] \.\. y\[0\] failed at t = 1.250000 s"):
            read()


@pytest.mark.parametrize("fmi_version", [2, 3])
def test_a_failing_step_or_set_raises_with_the_fmu_message(fmi_version, fmu3):
    from pushtrain.fmu.build import build_fmu

    fmu = fmu3 if fmi_version == 2 else build_fmu(fmi_version=3)
    with TrailerTrainSlave(fmu) as slave:
        slave.start({})
        write = slave.real_writer(["v_cmd"])
        with pytest.raises(CosimError, match=rf"fmi{fmi_version}DoStep failed at t = 1.000000 s"
                                             r".*differs from the FMU's time"):
            slave.do_step(1.0, 0.005)  # not the FMU's communication point
        with pytest.raises(CosimError, match=r"(?s)setting \['v_cmd'\] = \[0.1\] failed.*"
                                             r"not allowed in mode Error"):
            write([0.1])


def test_an_fmu_is_read_and_extracted_once_per_process(fmu3, tmp_path):
    with TrailerTrainSlave(fmu3) as first, TrailerTrainSlave(fmu3) as second:
        assert first._unzipdir == second._unzipdir and first.md is second.md
        first.start({"x0_start": 1.0})
        second.start({"x0_start": 2.0})  # two instances of one loaded library, apart
        first.real_writer(["v_cmd"])([0.1])
        first.do_step(0.0, 0.5)
        assert first.get_reals(["x[0]"])[0] > 1.0 and second.get_reals(["x[0]"])[0] == 2.0
    assert os.path.isdir(first._unzipdir)  # kept for the next instance
    copy = tmp_path / "copy.fmu"
    shutil.copy(fmu3, copy)
    with TrailerTrainSlave(copy) as other:
        assert other._unzipdir != first._unzipdir
        os.utime(copy, ns=(0, 0))  # the file changed: read and extracted again
        with TrailerTrainSlave(copy) as again:
            assert again._unzipdir != other._unzipdir
    folders = [u.folder for u in fmu_slave._UNPACKED.values()]
    fmu_slave._remove_unpacked()  # what happens at exit
    assert folders and not any(os.path.exists(f) for f in folders)
    with TrailerTrainSlave(fmu3) as fresh:  # extracted anew
        fresh.start({})
        assert os.path.isdir(fresh._unzipdir)
