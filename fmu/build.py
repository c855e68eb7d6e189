"""Build the TrailerTrain FMU for a given number of trailers from the C sources in ``fmu/src``.

The build renders ``modelDescription.xml``, a ``build_config.h`` (FMI version, n, GUID) for that n and
``variables.h`` (value references, names, types and causalities of the variable table, so the C
code never retypes them), lets fmpy's build helper write the CMake cache for its own ``CMakeLists.txt`` (the FMI 2.0 headers
come from the installed fmpy), compiles, and zips a self-contained ``.fmu`` with
``binaries/linux64/TrailerTrain.so`` and ``sources/`` so other tools can rebuild it. Builds are
cached by a hash of the sources, n and the build options.
"""

from __future__ import annotations

import hashlib
import logging
import os
import shutil
import subprocess
import sys
import tempfile
import uuid
import xml.etree.ElementTree as ET
import zipfile
from datetime import UTC, datetime
from importlib import resources
from pathlib import Path

from pushtrain import __version__
from pushtrain.errors import FmuBuildError, FmuInputError
from pushtrain.files import atomic_write
from pushtrain.limits import BOUNDS

from .variables import ARRAYS, MAX_TRAILERS, SCALARS, VR_STRIDE, variables_for

__all__ = [
    "MODEL_IDENTIFIER",
    "FmuBuildError",
    "build_fmu",
    "cache_dir",
    "render_model_description",
    "render_variables_header",
]

log = logging.getLogger(__name__)

MODEL_IDENTIFIER = "TrailerTrain"
SOURCE_FILES = ("model.c", "variables.c", "chain.c", "forces.c", "slip.c", "fmi2.c")
HEADER_FILES = ("model.h",)
DEFAULT_STEP = 0.005
BUILD_FORMAT = "2"  # bump when the rendering or packaging changes

UNITS = ("m", "m/s", "m/s2", "rad", "rad/s", "rad/s2", "N", "kg", "kg.m2", "s")
_BASE_UNITS = {
    "m": {"m": "1"},
    "m/s": {"m": "1", "s": "-1"},
    "m/s2": {"m": "1", "s": "-2"},
    "rad": {"rad": "1"},
    "rad/s": {"rad": "1", "s": "-1"},
    "rad/s2": {"rad": "1", "s": "-2"},
    "N": {"kg": "1", "m": "1", "s": "-2"},
    "kg": {"kg": "1"},
    "kg.m2": {"kg": "1", "m": "2"},
    "s": {"s": "1"},
}


def cache_dir() -> Path:
    """Folder of cached FMUs: ``$PUSHTRAIN_CACHE`` or ``~/.cache/pushtrain/fmu``."""
    root = os.environ.get("PUSHTRAIN_CACHE")
    base = Path(root) if root else Path.home() / ".cache" / "pushtrain"
    return base / "fmu"


def _source_dir():
    return resources.files("pushtrain.fmu") / "src"


def _check_n(n_trailers) -> int:
    if isinstance(n_trailers, bool) or not isinstance(n_trailers, (int,)) and not (
        hasattr(n_trailers, "__index__")
    ):
        raise FmuInputError(
            f"n_trailers = {n_trailers!r}: must be an integer from 1 to {MAX_TRAILERS}"
        )
    n = int(n_trailers)
    if not 1 <= n <= MAX_TRAILERS:
        raise FmuInputError(f"n_trailers = {n}: must be from 1 to {MAX_TRAILERS}")
    return n


def _fingerprint(n: int, strict: bool) -> str:
    digest = hashlib.sha256()
    digest.update(f"format={BUILD_FORMAT};n={n};strict={strict}".encode())
    src = _source_dir()
    for name in SOURCE_FILES + HEADER_FILES:
        digest.update(name.encode())
        digest.update((src / name).read_bytes())
    # what the tables render to (variables.py and everything it reads), not the date of a build
    digest.update(render_model_description(n, "{guid}", generated="{date}"))
    digest.update(render_variables_header().encode())
    return digest.hexdigest()


def _fmt(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return repr(value)
    return str(value)


def generation_time() -> str:
    """When this build is made, ISO 8601 UTC (``$SOURCE_DATE_EPOCH`` if set, for reproducible
    builds). It is written into the XML only: the cache key does not depend on it."""
    epoch = os.environ.get("SOURCE_DATE_EPOCH")
    moment = (datetime.fromtimestamp(int(epoch), UTC) if epoch
              else datetime.now(UTC))
    return moment.strftime("%Y-%m-%dT%H:%M:%SZ")


def render_model_description(n_trailers: int, guid: str, generated: str | None = None) -> bytes:
    """The ``modelDescription.xml`` of a TrailerTrain FMU with ``n_trailers`` trailers.

    ``generated`` is its generationDateAndTime (default: :func:`generation_time`).
    """
    n = _check_n(n_trailers)
    root = ET.Element(
        "fmiModelDescription",
        {
            "fmiVersion": "2.0",
            "modelName": MODEL_IDENTIFIER,
            "guid": guid,
            "description": f"Holonomic robot pushing or pulling {n} passive off-hooked trailers "
            "(chain kinematics, robot velocity loop, lateral wheel forces)",
            "generationTool": f"pushtrain {__version__}",
            "generationDateAndTime": generated or generation_time(),
            "variableNamingConvention": "structured",
            "numberOfEventIndicators": "0",
        },
    )
    cs = ET.SubElement(
        root,
        "CoSimulation",
        {
            "modelIdentifier": MODEL_IDENTIFIER,
            "canHandleVariableCommunicationStepSize": "true",
            "canGetAndSetFMUstate": "true",
            "canSerializeFMUstate": "true",
            "canNotUseMemoryManagementFunctions": "true",
            "canBeInstantiatedOnlyOncePerProcess": "false",
            "providesDirectionalDerivative": "false",
        },
    )
    files = ET.SubElement(cs, "SourceFiles")
    for name in SOURCE_FILES:
        ET.SubElement(files, "File", {"name": name})

    units = ET.SubElement(root, "UnitDefinitions")
    for name in UNITS:
        unit = ET.SubElement(units, "Unit", {"name": name})
        ET.SubElement(unit, "BaseUnit", _BASE_UNITS[name])

    categories = ET.SubElement(root, "LogCategories")
    for name, text in (
        ("logStatusError", "Errors: bad parameters, refused calls, non-finite states"),
        ("logStatusWarning", "Warnings"),
        ("logDebug", "One message per communication step (off unless asked for)"),
    ):
        ET.SubElement(categories, "Category", {"name": name, "description": text})

    ET.SubElement(
        root,
        "DefaultExperiment",
        {"startTime": "0.0", "stopTime": "10.0", "stepSize": _fmt(DEFAULT_STEP)},
    )

    variables = variables_for(n)
    model_vars = ET.SubElement(root, "ModelVariables")
    for var in variables:
        attrs = {
            "name": var.name,
            "valueReference": str(var.vr),
            "description": var.description,
            "causality": var.causality,
            "variability": var.variability,
        }
        if var.initial is not None:
            attrs["initial"] = var.initial
        sv = ET.SubElement(model_vars, "ScalarVariable", attrs)
        type_attrs = {}
        if var.unit:
            type_attrs["unit"] = var.unit
        if var.min is not None:
            type_attrs["min"] = _fmt(var.min)
        if var.max is not None:
            type_attrs["max"] = _fmt(var.max)
        if var.name == "n":
            type_attrs["start"] = str(n)
        elif var.start is not None:
            type_attrs["start"] = _fmt(var.start)
        ET.SubElement(sv, var.type, type_attrs)

    index = {var.name: k + 1 for k, var in enumerate(variables)}
    structure = ET.SubElement(root, "ModelStructure")
    outputs = ET.SubElement(structure, "Outputs")
    for var in variables:
        if var.causality != "output":
            continue
        # the inputs it depends on directly (the variable table's feedthrough); "" = state only
        refs = sorted(index[name] for name in var.depends_on)
        attrs = {"index": str(index[var.name]), "dependencies": " ".join(map(str, refs))}
        if refs:
            attrs["dependenciesKind"] = " ".join("dependent" for _ in refs)
        ET.SubElement(outputs, "Unknown", attrs)
    initial = ET.SubElement(structure, "InitialUnknowns")
    for var in variables:
        if (var.causality == "output" and var.initial in ("approx", "calculated")) or (
            var.causality == "calculatedParameter"
        ):
            ET.SubElement(initial, "Unknown", {"index": str(index[var.name])})

    ET.indent(root, space="  ")
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="utf-8")


def _render_build_config(n: int, guid: str) -> str:
    return (
        "/* Generated by pushtrain.fmu.build for this FMU: do not edit. */\n"
        "#ifndef TRAILERTRAIN_BUILD_CONFIG_H\n#define TRAILERTRAIN_BUILD_CONFIG_H\n"
        "#define FMI_VERSION 2\n"
        f"#define MAX_TRAILERS {n} /* n is fixed by the build */\n"
        f"#define DEFAULT_TRAILERS {n}\n"
        f'#define MODEL_GUID "{guid}"\n'
        "#endif\n"
    )


_C_TYPES = {"Real": "var_real", "Integer": "var_integer", "Boolean": "var_boolean"}
_C_CAUSALITIES = {
    "input": "var_input",
    "output": "var_output",
    "parameter": "var_parameter",
    "calculatedParameter": "var_calculated_parameter",
    "local": "var_local",
}


def render_variables_header() -> str:
    """``variables.h``: the C view of :mod:`pushtrain.fmu.variables` (the same for every n).

    Value-reference enums (``vr_<scalar>``, ``blk_<block>``) and one ``VarInfo`` table per kind,
    indexed by them. Only ``variables.c`` includes it; the rest of the C code asks that file.
    """
    lines = [
        "/* Generated by pushtrain.fmu.build from fmu/variables.py: do not edit.",
        " * Scalar s has value reference vr_s (< VR_STRIDE); element i of array block b has",
        " * VR_STRIDE * blk_b + i, for i from first to n + last_offset. */",
        "#ifndef TRAILERTRAIN_VARIABLES_H",
        "#define TRAILERTRAIN_VARIABLES_H",
        "",
        f"#define VR_STRIDE {VR_STRIDE}",
        "",
        "enum ScalarVr {",
        ",\n".join(f"    vr_{v.name} = {v.vr}" for v in SCALARS),
        "};",
        f"#define SCALAR_VR_END {max(v.vr for v in SCALARS) + 1}",
        "",
        "enum Block {",
        ",\n".join(f"    blk_{b.name} = {b.block}" for b in ARRAYS),
        "};",
        f"#define BLOCK_END {max(b.block for b in ARRAYS) + 1}",
        "",
        "typedef enum { var_real, var_integer, var_boolean } VarType;",
        "typedef enum {",
        "    var_input, var_output, var_parameter, var_calculated_parameter, var_local",
        "} VarCausality;",
        "",
        "typedef struct {",
        "    const char *name; /* NULL: no variable has this number */",
        "    VarType type;",
        "    VarCausality causality;",
        "    int first, last_offset; /* array blocks: i runs from first to n + last_offset */",
        "    int bounded;            /* parameters: min <= value <= max is checked */",
        "    double min, max;",
        "    const char *unit, *reason; /* for the message when a value is out of range */",
        "} VarInfo;",
        "",
        "static const VarInfo scalar_info[SCALAR_VR_END] = {",
    ]
    lines += [f"    [vr_{v.name}] = {_var_info(v, 0, 0)}," for v in SCALARS]
    lines += ["};", "", "static const VarInfo block_info[BLOCK_END] = {"]
    lines += [
        f"    [blk_{b.name}] = {_var_info(b, b.first, -1 if b.to_n_minus_1 else 0)},"
        for b in ARRAYS
    ]
    lines += ["};", "", "#endif", ""]
    return "\n".join(lines)


def _c_string(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def _var_info(row, first: int, last_offset: int) -> str:
    """One VarInfo initializer; bounds and their reason from the table (pushtrain.limits)."""
    fields = [_c_string(row.name), _C_TYPES[row.type], _C_CAUSALITIES[row.causality],
              str(first), str(last_offset)]
    if row.min is None:
        fields += ["0", "0.0", "0.0", "NULL", "NULL"]
    else:
        bound = BOUNDS.get(row.name)
        reason = bound.reason if bound is not None else row.description
        unit = bound.unit if bound is not None else (row.unit or "")
        fields += ["1", repr(float(row.min)), repr(float(row.max)), _c_string(unit),
                   _c_string(reason)]
    return "{" + ", ".join(fields) + "}"


def _cmake_env() -> dict:
    """Environment whose PATH finds cmake: the ``cmake`` wheel (comes with fmpy) first."""
    env = dict(os.environ)
    dirs = []
    try:
        import cmake  # the PyPI wheel

        dirs.append(cmake.CMAKE_BIN_DIR)
    except (ImportError, AttributeError):
        pass
    dirs.append(str(Path(sys.executable).parent))
    env["PATH"] = os.pathsep.join(dirs + [env.get("PATH", "")])
    if shutil.which("cmake", path=env["PATH"]) is None:
        raise FmuBuildError(
            "cmake not found: install the 'cmake' wheel (pip install cmake) or a system cmake"
        )
    return env


def _compile(unzipdir: Path, build_dir: Path, strict: bool) -> None:
    import fmpy
    from fmpy.build import create_cmake_settings

    options = {
        "CMAKE_C_STANDARD:STRING": "99",
        "CMAKE_C_STANDARD_LIBRARIES:STRING": "-lm",
        "CMAKE_C_VISIBILITY_PRESET:STRING": "hidden",
    }
    if strict:
        options["CMAKE_C_FLAGS:STRING"] = "-Werror"
    create_cmake_settings(unzipdir, build_dir, all_warnings=True, cmake_options=options)
    source_dir = Path(fmpy.__file__).parent / "c-code"
    env = _cmake_env()
    for command in (
        ["cmake", "-S", str(source_dir), "-B", str(build_dir)],
        ["cmake", "--build", str(build_dir), "--target", "install", "--config", "Release"],
    ):
        done = subprocess.run(command, env=env, capture_output=True, text=True)
        if done.returncode != 0:
            tail = "\n".join((done.stdout + done.stderr).strip().splitlines()[-40:])
            raise FmuBuildError(f"{' '.join(command[:2])} failed (exit {done.returncode}):\n{tail}")
        warnings = [line for line in done.stderr.splitlines() if "warning:" in line]
        for line in warnings:
            log.warning("compiler: %s", line)


def _build_into(n: int, target: Path, strict: bool, guid: str) -> None:
    import fmpy

    with tempfile.TemporaryDirectory(prefix="pushtrain-fmu-") as tmp:
        unzipdir = Path(tmp) / "fmu"
        sources = unzipdir / "sources"
        sources.mkdir(parents=True)
        src = _source_dir()
        for name in SOURCE_FILES + HEADER_FILES:
            (sources / name).write_bytes((src / name).read_bytes())
        (sources / "build_config.h").write_text(_render_build_config(n, guid))
        (sources / "variables.h").write_text(render_variables_header())
        (unzipdir / "modelDescription.xml").write_bytes(render_model_description(n, guid))
        build_dir = Path(tmp) / "build"
        build_dir.mkdir()
        _compile(unzipdir, build_dir, strict)
        binary = unzipdir / "binaries" / fmpy.platform / f"{MODEL_IDENTIFIER}{fmpy.sharedLibraryExtension}"
        if not binary.is_file():
            raise FmuBuildError(f"the build produced no {binary.relative_to(unzipdir)}")
        def write_zip(partial: Path) -> None:
            with zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as zf:
                for path in sorted(unzipdir.rglob("*")):
                    if path.is_file():
                        zf.write(path, path.relative_to(unzipdir).as_posix())

        atomic_write(target, write_zip)


def build_fmu(n_trailers: int, output_path=None, *, strict: bool = False, force: bool = False) -> Path:
    """Build (or take from the cache) the TrailerTrain FMU for ``n_trailers`` trailers.

    Parameters
    ----------
    n_trailers : int
        Number of trailers, 1 to 50.
    output_path : path-like, optional
        Where to write the ``.fmu``; by default the cached file itself is returned.
    strict : bool
        Compile with ``-Werror`` (development builds).
    force : bool
        Rebuild even if the cache has this build.

    Returns
    -------
    pathlib.Path
        The ``.fmu`` file.

    Raises
    ------
    FmuBuildError
        ``n_trailers`` out of range, cmake missing, or the compiler failed.
    """
    n = _check_n(n_trailers)
    fingerprint = _fingerprint(n, strict)
    cached = cache_dir() / f"{MODEL_IDENTIFIER}-n{n}-{fingerprint[:16]}.fmu"
    if force or not cached.is_file():
        cached.parent.mkdir(parents=True, exist_ok=True)
        guid = "{" + str(uuid.UUID(fingerprint[:32])) + "}"
        log.info("building %s for n = %d into %s", MODEL_IDENTIFIER, n, cached)
        _build_into(n, cached, strict, guid)
    else:
        log.debug("using cached %s", cached)
    if output_path is None:
        return cached
    out = Path(output_path)
    if out.is_dir():
        out = out / f"{MODEL_IDENTIFIER}.fmu"
    out.parent.mkdir(parents=True, exist_ok=True)
    return atomic_write(out, lambda partial: shutil.copyfile(cached, partial))
