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


@pytest.mark.slow
def test_strict_build_with_werror_packages_sources_and_binary(tmp_path, monkeypatch):
    monkeypatch.setenv("PUSHTRAIN_CACHE", str(tmp_path / "cache"))
    out = build_fmu(2, tmp_path / "TT2.fmu", strict=True)
    with zipfile.ZipFile(out) as zf:
        names = set(zf.namelist())
    assert "modelDescription.xml" in names
    assert "binaries/linux64/TrailerTrain.so" in names
    for src in ("sources/model.c", "sources/start.c", "sources/variables.c", "sources/chain.c",
                "sources/forces.c",
                "sources/slip.c", "sources/slip_solver.c", "sources/fmi2.c", "sources/model.h",
                "sources/build_config.h",
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



FMU_ROOT = Path(__file__).resolve().parents[2] / "fmu"
MAX_C_LINES = 800  # issue 25: a C file longer than this holds two things
C_DEFINITION = re.compile(
    r"^(?:static\s+)?(?:inline\s+)?[A-Za-z_][\w\s*]*?\b(\w+)\s*\([^;{]*\)\s*\{", re.MULTILINE)


def test_no_c_file_of_the_fmus_is_over_800_lines():
    files = sorted(FMU_ROOT.glob("*/*.[ch]"))
    assert {path.parent.name for path in files} >= {"src", "controller_src"}, files
    long = {path.name: n for path in files
            if (n := len(path.read_text().splitlines())) > MAX_C_LINES}
    assert not long, f"over {MAX_C_LINES} lines: {long}"


def _plant_files(fmi_version):
    from pushtrain.fmu.render import HEADER_FILES, source_files

    return [FMU_ROOT / "src" / name for name in source_files(fmi_version) + HEADER_FILES]


def _controller_files():
    """The controller's C files under fmu/ (its control law is core's, not counted here)."""
    from pushtrain.fmu.controller import GLUE_FILES
    from pushtrain.fmu.controller_variables import CONTROLLER_HEADERS, CONTROLLER_SOURCES

    return [FMU_ROOT / ("src" if name in GLUE_FILES else "controller_src") / name
            for name in CONTROLLER_SOURCES + CONTROLLER_HEADERS]


@pytest.mark.parametrize("build", ["plant FMI 2.0", "plant FMI 3.0", "controller"])
def test_each_c_function_of_an_fmu_is_defined_once(build):
    """A function is defined (``type name(args) {`` at the start of a line) in one of the files
    compiled into the FMU only: no second solver or glue under a compile-time switch, no glue
    of its own for the controller."""
    files = {"plant FMI 2.0": lambda: _plant_files(2), "plant FMI 3.0": lambda: _plant_files(3),
             "controller": _controller_files}[build]()
    seen: dict[str, list[str]] = {}
    for path in files:
        for function in C_DEFINITION.findall(path.read_text()):
            seen.setdefault(function, []).append(path.name)
    assert {"instance_new", "model_set_defaults", "model_do_step"} <= set(seen)  # found
    twice = {function: where for function, where in seen.items() if len(where) > 1}
    assert not twice, f"defined more than once: {twice}"


def test_both_fmus_stand_on_one_glue():
    """The controller compiles the plant's glue files, and no FMI function of its own."""
    glue = {path.name for path in _plant_files(2)} & {path.name for path in _controller_files()}
    assert {"instance.c", "fmi2.c", "fmu_model.h", "instance.h"} <= glue
    own = [path for path in _controller_files() if path.parent.name == "controller_src"]
    assert own and not any("fmi2" in name for path in own
                           for name in C_DEFINITION.findall(path.read_text()))


def test_the_c_start_values_are_rendered_from_the_variable_table_and_table_1():
    """start_values.h holds every parameter's and input's start (Table 1's from
    pushtrain.table1); no C file of the FMUs types a Table 1 number itself."""
    from pushtrain import table1
    from pushtrain.fmu.render import render_start_values_header
    from pushtrain.fmu.variables import ARRAYS, SCALARS

    header = render_start_values_header()
    starts = dict(re.findall(r"#define START_(\w+) (\S+)", header))
    assert starts["mass"] == repr(table1.TRAILER_MASS)
    assert starts["inertia"] == repr(table1.TRAILER_INERTIA)
    assert starts["mu"] == repr(table1.MU)
    assert starts["front"] == starts["rear"] == repr(table1.LINK)
    for row in (*SCALARS, *ARRAYS):
        if row.causality in ("parameter", "input") and row.type in ("Real", "Integer"):
            assert float(starts[row.name]) == row.start, row.name
    literals = [repr(v) for v in (table1.TRAILER_MASS, table1.TRAILER_INERTIA, table1.MU,
                                  table1.LINK)]
    start_c = (FMU_ROOT / "src" / "start.c").read_text()
    assert "START_mass" in start_c  # start.c reads the header
    for path in sorted(FMU_ROOT.glob("*/*.[ch]")):
        text = path.read_text()
        assert not [v for v in literals if re.search(rf"(?<![\w.]){re.escape(v)}(?![\w.])",
                                                     text)], path.name
