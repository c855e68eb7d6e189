"""The FMU builder: strict compile, cache, packaging, generated C tables, rebuild from sources."""

import re
import zipfile
from pathlib import Path

import pytest
from fmpy import read_model_description

from pushtrain.errors import FmuBuildError
from pushtrain.fmu.build import build_fmu
from pushtrain.fmu.render import render_variables_header


def _generated_enums(fmu_path) -> tuple[int, dict[str, int]]:
    """VR_STRIDE and the enumerators of the ``variables.h`` shipped in the FMU's ``sources/``."""
    with zipfile.ZipFile(fmu_path) as zf:
        header = zf.read("sources/variables.h").decode()
    stride = int(re.search(r"#define VR_STRIDE (\d+)", header).group(1))
    values = {}
    for name in ("ScalarVr", "Block"):
        body = re.search(rf"enum {name} \{{(.*?)\}};", header, re.DOTALL).group(1)
        values.update({k: int(v) for k, v in re.findall(r"(\w+)\s*=\s*(\d+)", body)})
    return stride, values


@pytest.mark.parametrize("n_trailers", [1, 3])
def test_xml_value_references_equal_the_generated_c_enums(built_fmu, n_trailers):
    """The C numbering is generated from the same table as the XML: they cannot disagree."""
    path = built_fmu(n_trailers)
    stride, enums = _generated_enums(path)
    md = read_model_description(str(path))
    assert len(md.modelVariables) > 20
    for var in md.modelVariables:
        match = re.fullmatch(r"(\w+)\[(\d+)\]", var.name)
        if match:
            expected = stride * enums[f"blk_{match.group(1)}"] + int(match.group(2))
        else:
            expected = enums[f"vr_{var.name}"]
        assert var.valueReference == expected, var.name
    # and the C side has no variable the XML lacks
    blocks = {k[4:] for k in enums if k.startswith("blk_")}
    scalars = {k[3:] for k in enums if k.startswith("vr_")}
    xml_names = {var.name.split("[")[0] for var in md.modelVariables}
    assert blocks | scalars == xml_names


def test_generated_header_is_deterministic():
    assert render_variables_header() == render_variables_header()
    assert "enum ScalarVr" in render_variables_header()


def test_sources_rebuild_with_another_compiler_call(built_fmu_unzipped, tmp_path):
    """Another importer compiles ``sources/`` (the XML's SourceFiles) with only the FMI headers.

    The rebuilt library must run exactly like the shipped one.
    """
    import shutil
    import subprocess

    import fmpy
    import numpy as np
    from fmpy.fmi2 import FMU2Slave

    compiler = shutil.which("cc") or shutil.which("gcc")
    if compiler is None:
        pytest.fail("a C compiler (cc) is required to rebuild the FMU from its sources")
    unzipdir, md = built_fmu_unzipped(3)
    copy = tmp_path / "fmu"
    shutil.copytree(unzipdir, copy)
    library = copy / "binaries" / "linux64" / "TrailerTrain.so"
    library.unlink()
    headers = Path(fmpy.__file__).parent / "c-code"
    (config,) = md.buildConfigurations  # the XML's <SourceFiles>
    names = [name for files in config.sourceFileSets for name in files.sourceFiles]
    assert "variables.c" in names
    sources = [str(copy / "sources" / name) for name in names]
    subprocess.run([compiler, "-std=c99", "-O2", "-shared", "-fPIC", "-fvisibility=hidden",
                    f"-I{headers}", f"-I{copy / 'sources'}", *sources, "-o", str(library), "-lm"],
                   check=True, capture_output=True, text=True)

    def run(directory):
        vr = {v.name: v.valueReference for v in md.modelVariables}
        slave = FMU2Slave(guid=md.guid, unzipDirectory=str(directory),
                          modelIdentifier="TrailerTrain", instanceName=str(directory))
        slave.instantiate()
        slave.setupExperiment(startTime=0.0)
        slave.enterInitializationMode()
        slave.setReal([vr["theta_start[2]"], vr["v_cmd"], vr["w_cmd"]], [0.3, -0.1, 0.2])
        slave.exitInitializationMode()
        outputs = [v.valueReference for v in md.modelVariables
                   if v.causality == "output" and v.type == "Real"]
        rows = []
        for k in range(100):
            slave.doStep(k * 0.01, 0.01)
            rows.append(slave.getReal(outputs))
        slave.terminate()
        slave.freeInstance()
        return np.array(rows)

    rebuilt = run(copy)
    assert np.all(np.isfinite(rebuilt))
    np.testing.assert_allclose(rebuilt, run(unzipdir), rtol=1e-12, atol=1e-12)


def test_strict_build_with_werror_packages_sources_and_binary(tmp_path, monkeypatch):
    monkeypatch.setenv("PUSHTRAIN_CACHE", str(tmp_path / "cache"))
    out = build_fmu(2, tmp_path / "TT2.fmu", strict=True)
    with zipfile.ZipFile(out) as zf:
        names = set(zf.namelist())
    assert "modelDescription.xml" in names
    assert "binaries/linux64/TrailerTrain.so" in names
    for src in ("sources/model.c", "sources/variables.c", "sources/chain.c", "sources/forces.c",
                "sources/slip.c", "sources/fmi2.c", "sources/model.h", "sources/build_config.h",
                "sources/variables.h"):
        assert src in names
    assert not any(n.startswith("sources/fmi2Function") for n in names), "FMI headers vendored"
    cached = list((tmp_path / "cache" / "fmu").glob("*.fmu"))
    assert len(cached) == 1
    mtime = cached[0].stat().st_mtime_ns
    build_fmu(2, tmp_path / "again.fmu", strict=True)  # cache hit: no rebuild
    assert cached[0].stat().st_mtime_ns == mtime
    assert not list(tmp_path.glob(".*.part")), "partial files left behind"


@pytest.mark.parametrize("bad", [0, 51, -1, 2.5, "3", True])
def test_out_of_range_n_is_refused_with_the_value(bad):
    match = (re.escape(repr(bad)) if not isinstance(bad, int) or isinstance(bad, bool)
             else str(bad))
    with pytest.raises(FmuBuildError, match=match):
        build_fmu(bad)
