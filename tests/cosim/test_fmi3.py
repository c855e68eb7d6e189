"""The Python master on the FMI 3.0 FMU: the slave wrapper's FMI 3.0 backend, ``simulate`` and
``plan-and-run`` with ``[fmu] fmi_version = 3`` give what the FMI 2.0 FMU of that n gives, with no
per-n build."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from pushtrain.cli.main import cli
from pushtrain.core.controller import ControllerConfig
from pushtrain.core.reference import Reference
from pushtrain.core.segment import Segment
from pushtrain.cosim.events import Push, Slide
from pushtrain.cosim.fmu_slave import TrailerTrainSlave
from pushtrain.cosim.master import simulate
from pushtrain.cosim.plant import InitialState, PlantConfig
from pushtrain.errors import CosimError
from pushtrain.fmu.build import build_fmu

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def fmu3_path():
    return Path(build_fmu(fmi_version=3))


def _drive(slave: TrailerTrainSlave, n: int, steps: int = 300):
    """The master's access pattern: readers over element names, one writer for the commands
    and one per slide element; returns every value read."""
    slave.start({"slip_mode": 0, "front[2]": 0.6, "rear[0]": 0.45, "payload[1]": 12.0,
                 "theta_start[1]": 0.05, "x0_start": 0.3})
    read = slave.real_reader(slave.names("x", 0, n) + slave.names("theta", 0, n)
                             + ["v_cmd"] + slave.names("phi", 1, n) + slave.names("F_lat", 1, n))
    flags = slave.bool_reader(slave.names("slipping", 1, n) + ["jackknifed"])
    write_cmd = slave.real_writer(["v_cmd", "w_cmd", "push_x", "push_y"])
    slides = {i: slave.real_writer([f"slide[{i}]"]) for i in (2, n)}
    rows = []
    for k in range(steps):
        t = k * 0.005
        write_cmd((-0.1, 0.3 * math.sin(t), 20.0, -5.0))
        if k == 50:
            slides[2]((0.02,))
        if k == 100:
            slides[n]((-0.01,))  # the element written earlier through another writer stays
        rows.append(np.concatenate([read(), flags().astype(float)]))
        slave.do_step(t, 0.005)
    return np.array(rows)


def test_the_slave_wrapper_reads_and_writes_fmi3_arrays_like_fmi2_scalars(fmu3_path, built_fmu):
    n = 4
    with TrailerTrainSlave(fmu3_path, n_trailers=n) as slave3:
        assert (slave3.fmi_version, slave3.n) == (3, n)
        rows3 = _drive(slave3, n)
        assert slave3.get_reals(["slide[2]", "slide[4]", "slide_speed[2]"]).tolist() == [
            0.02, -0.01, 0.02]
    with TrailerTrainSlave(built_fmu(n), n_trailers=n) as slave2:
        assert (slave2.fmi_version, slave2.n) == (2, n)
        rows2 = _drive(slave2, n)
    np.testing.assert_allclose(rows3, rows2, rtol=1e-12, atol=1e-12)
    assert np.ptp(rows3[:, 1]) > 0.01  # the train moved


def test_the_wrapper_names_unknown_elements_and_refuses_n_out_of_range(fmu3_path):
    with TrailerTrainSlave(fmu3_path, n_trailers=2) as slave:
        with pytest.raises(CosimError, match=r"\(n = 2\) has no variable 'x\[3\]'"):
            slave.real_reader(["x[3]"])
        with pytest.raises(CosimError, match=r"has no variable 'front\[0\]'"):
            slave.real_reader(["front[0]"])
    with pytest.raises(CosimError, match="n_trailers = 51: this FMU takes n from 1 to 50"):
        TrailerTrainSlave(fmu3_path, n_trailers=51)


def test_simulate_on_the_fmi3_fmu_equals_the_fmi2_fmu_of_that_n(fmu3_path, built_fmu):
    n = 2
    ref = Reference.from_segments((0.0, 0.0, math.pi), [Segment("line", 1.0),
                                                         Segment("arc", 0.8, 1.0 / 2.5)],
                                  speed=0.08)
    plant = PlantConfig(n_trailers=n, mass=[40.0, 45.0], slip_mode=0)
    initial = InitialState.behind_reference(ref, plant.geometry(), lateral_offset=0.05)
    events = [Slide(3.0, 1.0, 0.03), Push(6.0, 2.0, lateral=15.0)]
    runs = [simulate(fmu, ref, ControllerConfig.uniform(n), events=events, plant=plant,
                     initial=initial, horizon=12.0, check_goal=False)
            for fmu in (fmu3_path, built_fmu(n))]
    assert runs[0].status == runs[1].status == "completed"
    assert runs[0].data.dtype.names == runs[1].data.dtype.names
    for name in runs[0].data.dtype.names:
        np.testing.assert_allclose(runs[0].data[name], runs[1].data[name], rtol=1e-12,
                                   atol=1e-12, err_msg=name)


@pytest.mark.slow
def test_plan_and_run_with_fmi_version_3_needs_no_build_per_n(tmp_path, monkeypatch):
    """``[fmu] fmi_version = 3``: one FMU for n = 3 and n = 2 (no FMI 2.0 build), and the run
    equals the FMI 2.0 run of the same scenario."""
    monkeypatch.setenv("PUSHTRAIN_CACHE", str(tmp_path / "cache"))
    text = (ROOT / "examples" / "straight_push.toml").read_text()
    text = text.replace("settle_time = 5.0", "settle_time = 5.0\nhorizon = 30.0")
    runner = CliRunner()
    results = {}
    for version, trailers in ((3, 3), (3, 2), (2, 3)):
        scenario = tmp_path / f"fmi{version}.toml"
        scenario.write_text(text + f"\n[fmu]\nfmi_version = {version}\n")
        out = tmp_path / f"out{version}_{trailers}"
        result = runner.invoke(cli, ["plan-and-run", str(scenario), "--trailers", str(trailers),
                                     "--no-plots", "--out", str(out)])
        assert result.exit_code in (0, 1), result.output  # 1: the 30 s horizon ends first
        results[version, trailers] = np.load(out / "results.npz")
        if version == 3:
            built = sorted(p.name for p in (tmp_path / "cache" / "fmu").glob("*.fmu"))
            assert len(built) == 1 and built[0].startswith("TrailerTrain3-"), built
    assert results[3, 2]["x2"].size > 100 and "x3" not in results[3, 2].files
    a, b = results[3, 3], results[2, 3]
    assert sorted(a.files) == sorted(b.files)
    for name in a.files:
        np.testing.assert_allclose(a[name], b[name], rtol=1e-12, atol=1e-12, err_msg=name)
