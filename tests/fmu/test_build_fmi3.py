"""Building the FMI 3.0 FMU: options, cache, self-contained sources, the CLI, fmpy shapes."""

from __future__ import annotations

import re
import shutil
import subprocess
import zipfile
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from fmpy import extract, read_model_description
from fmpy.fmi3 import FMU3Slave

from pushtrain.cli.main import cli
from pushtrain.errors import FmuInputError
from pushtrain.fmu.build import build_fmu
from pushtrain.fmu.shapes import model_description_for


@pytest.fixture(scope="session")
def fmu3_path():
    return Path(build_fmu(fmi_version=3))


@pytest.mark.parametrize("kwargs, message", [
    (dict(n_trailers=3, fmi_version=3), "n_trailers = 3 with fmi_version = 3: the FMI 3.0 FMU "
                                        "serves every n from 1 to 50"),
    (dict(fmi_version=4), "fmi_version = 4: allowed are 2 and 3"),
    (dict(fmi_version="3"), "fmi_version = '3': allowed are 2 and 3"),
    (dict(fmi_version=2), "n_trailers = None: must be an integer from 1 to 50"),
])
def test_bad_build_options_are_named(kwargs, message):
    with pytest.raises(FmuInputError, match=re.escape(message)):
        build_fmu(**kwargs)


@pytest.mark.slow
def test_one_cached_build_serves_every_n_and_differs_from_the_fmi2_builds(tmp_path, monkeypatch):
    monkeypatch.setenv("PUSHTRAIN_CACHE", str(tmp_path / "cache"))
    first = build_fmu(fmi_version=3, output_path=tmp_path / "a.fmu")
    (cached,) = (tmp_path / "cache" / "fmu").glob("TrailerTrain3-*.fmu")
    mtime = cached.stat().st_mtime_ns
    build_fmu(None, tmp_path / "b.fmu", fmi_version=3)  # cache hit
    assert cached.stat().st_mtime_ns == mtime
    assert first.read_bytes() == (tmp_path / "b.fmu").read_bytes()
    with zipfile.ZipFile(first) as zf:
        assert "binaries/x86_64-linux/TrailerTrain.so" in zf.namelist()
        assert b'fmiVersion="3.0"' in zf.read("modelDescription.xml")


def test_sources_rebuild_from_the_build_description(fmu3_path, tmp_path):
    """Another importer compiles ``sources/`` (FMI 3.0: listed in sources/buildDescription.xml)
    with only the FMI headers; the rebuilt library runs exactly like the shipped one."""
    import fmpy

    compiler = shutil.which("cc") or shutil.which("gcc")
    if compiler is None:
        pytest.fail("a C compiler (cc) is required to rebuild the FMU from its sources")
    shipped = Path(extract(str(fmu3_path), unzipdir=str(tmp_path / "shipped")))
    copy = Path(shutil.copytree(shipped, tmp_path / "copy"))
    library = copy / "binaries" / "x86_64-linux" / "TrailerTrain.so"
    library.unlink()
    md = read_model_description(str(fmu3_path))
    (config,) = md.buildConfigurations  # from sources/buildDescription.xml
    (files,) = config.sourceFileSets
    assert files.language == "C99" and "fmi3.c" in files.sourceFiles
    headers = Path(fmpy.__file__).parent / "c-code"
    subprocess.run([compiler, "-std=c99", "-O2", "-shared", "-fPIC", "-fvisibility=hidden",
                    f"-I{headers}", f"-I{copy / 'sources'}",
                    *[str(copy / "sources" / name) for name in files.sourceFiles],
                    "-o", str(library), "-lm"], check=True, capture_output=True, text=True)
    vr = {v.name: v.valueReference for v in md.modelVariables}

    def run(directory: Path) -> np.ndarray:
        fmu = FMU3Slave(guid=md.guid, unzipDirectory=str(directory),
                        modelIdentifier="TrailerTrain", instanceName=directory.name)
        fmu.instantiate()
        fmu.enterConfigurationMode()
        fmu.setUInt64([vr["n"]], [6])
        fmu.exitConfigurationMode()
        fmu.enterInitializationMode(startTime=0.0)
        fmu.setFloat64([vr["v_cmd"], vr["w_cmd"]], [-0.1, 0.2])
        fmu.exitInitializationMode()
        rows = []
        for k in range(100):
            fmu.doStep(k * 0.01, 0.01)
            rows.append(fmu.getFloat64([vr["x"], vr["F_lat"]], nValues=13))
        fmu.terminate()
        fmu.freeInstance()
        return np.array(rows)

    rebuilt = run(copy)
    assert np.all(np.isfinite(rebuilt)) and np.ptp(rebuilt[:, 6]) > 0.05
    np.testing.assert_array_equal(rebuilt, run(shipped))


def test_model_description_for_sizes_fmpys_arrays(fmu3_path, built_fmu):
    md = model_description_for(fmu3_path, 7)
    shapes = {v.name: v.shape for v in md.modelVariables if v.dimensions}
    assert shapes["x"] == (8,) and shapes["front"] == (7,) and shapes["rear"] == (7,)
    assert [v.start for v in md.modelVariables if v.name == "mass"] == [" ".join(["42.1"] * 7)]
    with pytest.raises(FmuInputError, match="n_trailers = 51"):
        model_description_for(fmu3_path, 51)
    with pytest.raises(FmuInputError, match="fmiVersion 2.0"):
        model_description_for(built_fmu(2), 2)


def test_cli_builds_the_fmi3_fmu_without_trailers(tmp_path, fmu3_path):
    runner = CliRunner()
    out = tmp_path / "TrailerTrain3.fmu"
    result = runner.invoke(cli, ["build-fmu", "--fmi-version", "3", "-o", str(out)])
    assert result.exit_code == 0, result.output
    assert result.output.strip() == f"{out} (FMI 3.0, n = 1..50)"
    assert out.read_bytes() == fmu3_path.read_bytes()


@pytest.mark.parametrize("args, message", [
    (["--fmi-version", "3", "--trailers", "2"], "--trailers 2 with --fmi-version 3: the FMI 3.0 "
                                                "FMU serves every n from 1 to 50"),
    ([], "--trailers N is required for --fmi-version 2"),
])
def test_cli_names_a_bad_combination(tmp_path, args, message):
    result = CliRunner().invoke(cli, ["build-fmu", *args, "-o", str(tmp_path / "x.fmu")])
    assert result.exit_code == 2
    assert message in result.output
    assert not (tmp_path / "x.fmu").exists()
