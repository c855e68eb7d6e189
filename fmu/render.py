"""Render the TrailerTrain FMU's generated files from the variable table (:mod:`.variables`).

- ``modelDescription.xml``: FMI 2.0 for one n (scalars ``x[0]``, ``x[1]``, ...) or FMI 3.0 for
  every n (arrays ``x`` with a ``<Dimension>`` on the structural parameter ``n`` or ``n_bodies``);
- ``sources/buildDescription.xml`` (FMI 3.0 keeps the source file list there);
- ``variables.h``: value-reference enums, names, types, causalities and bounds for the C code;
- ``build_config.h``: FMI version, the array capacity, the default n and the GUID.

Pure functions of their arguments (and of ``generationDateAndTime``), so the builder can hash
what they render.
"""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from datetime import UTC, datetime

from pushtrain import __version__
from pushtrain.errors import FmuInputError
from pushtrain.limits import BOUNDS
from pushtrain.table1 import SAMPLING_TIME

from .variables import (
    ARRAYS,
    DEFAULT_TRAILERS,
    MAX_TRAILERS,
    SCALARS,
    VR_STRIDE,
    direct_inputs,
    scalars_for,
    variables_for,
)

__all__ = [
    "BASE_UNITS",
    "MODEL_IDENTIFIER",
    "xml_bytes",
    "xml_number",
    "source_files",
    "check_n",
    "generation_time",
    "render_model_description",
    "render_model_description3",
    "render_build_description",
    "render_variables_header",
    "render_start_values_header",
    "render_build_config",
]

MODEL_IDENTIFIER = "TrailerTrain"
MODEL_SOURCES = ("model.c", "start.c", "variables.c", "chain.c", "forces.c", "slip.c",
                 "slip_solver.c", "instance.c")
HEADER_FILES = ("model.h", "fmu_model.h", "instance.h")
DEFAULT_STEP = SAMPLING_TIME  # the modelDescription's DefaultExperiment stepSize [s]

UNITS = ("m", "m/s", "m/s2", "rad", "rad/s", "rad/s2", "N", "kg", "kg.m2", "s")
BASE_UNITS = {  # each unit of UNITS in SI base units (the modelDescription's UnitDefinitions)
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
_FMI3_TYPES = {"Real": "Float64", "Integer": "Int32", "Boolean": "Boolean", "UInt64": "UInt64"}


def source_files(fmi_version: int) -> tuple[str, ...]:
    """The C files compiled into the FMU: the model, the shared glue and the version's glue."""
    if fmi_version not in (2, 3):
        raise FmuInputError(f"fmi_version = {fmi_version!r}: allowed are 2 and 3")
    return MODEL_SOURCES + (f"fmi{fmi_version}.c",)


def check_n(n_trailers) -> int:
    """``n_trailers`` as an int from 1 to MAX_TRAILERS, else FmuInputError naming the value."""
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


def xml_number(value) -> str:
    """``value`` as a modelDescription attribute: booleans as true/false, floats by ``repr``
    (the shortest text that reads back as the same double)."""
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


def _root(attrs: dict) -> ET.Element:
    return ET.Element("fmiModelDescription", attrs)


def _common_sections(root: ET.Element) -> None:
    """UnitDefinitions, LogCategories and DefaultExperiment (the same in FMI 2.0 and 3.0)."""
    units = ET.SubElement(root, "UnitDefinitions")
    for name in UNITS:
        unit = ET.SubElement(units, "Unit", {"name": name})
        ET.SubElement(unit, "BaseUnit", BASE_UNITS[name])

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
        {"startTime": "0.0", "stopTime": "10.0", "stepSize": xml_number(DEFAULT_STEP)},
    )


def xml_bytes(root: ET.Element) -> bytes:
    """The indented UTF-8 document of ``root`` with its XML declaration."""
    ET.indent(root, space="  ")
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="utf-8")


def _is_initial_unknown(var) -> bool:
    return (var.causality == "output" and var.initial in ("approx", "calculated")) or (
        var.causality == "calculatedParameter"
    )


def render_model_description(n_trailers: int, guid: str, generated: str | None = None) -> bytes:
    """The FMI 2.0 ``modelDescription.xml`` of a TrailerTrain FMU with ``n_trailers`` trailers.

    ``generated`` is its generationDateAndTime (default: :func:`generation_time`).
    """
    n = check_n(n_trailers)
    root = _root({
        "fmiVersion": "2.0",
        "modelName": MODEL_IDENTIFIER,
        "guid": guid,
        "description": f"Holonomic robot pushing or pulling {n} passive off-hooked trailers "
        "(chain kinematics, robot velocity loop, lateral wheel forces)",
        "generationTool": f"pushtrain {__version__}",
        "generationDateAndTime": generated or generation_time(),
        "variableNamingConvention": "structured",
        "numberOfEventIndicators": "0",
    })
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
    for name in source_files(2):
        ET.SubElement(files, "File", {"name": name})
    _common_sections(root)

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
            type_attrs["min"] = xml_number(var.min)
        if var.max is not None:
            type_attrs["max"] = xml_number(var.max)
        if var.name == "n":
            type_attrs["start"] = str(n)
        elif var.start is not None:
            type_attrs["start"] = xml_number(var.start)
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
        if _is_initial_unknown(var):
            ET.SubElement(initial, "Unknown", {"index": str(index[var.name])})
    return xml_bytes(root)


def describe_array(block) -> str:
    """The FMI 3.0 description of array ``block``: its template for element i, with the range."""
    last = "n - 1" if block.to_n_minus_1 else "n"
    text = block.description.format(
        i="i", prev="i-1", body="body i", prev_body="body i-1",
        point="body i (the robot's centre, a trailer's axle midpoint)",
    )
    return f"{text}; elements i = {block.first}..{last} (body 0 is the robot)"


def _array_dependencies(block, vr_of: dict[str, int]) -> list[int]:
    """Value references of the whole variables an output array depends on directly (the union
    over its elements for the largest train, so it holds for every n)."""
    names = set()
    for i in range(block.first, block.count(MAX_TRAILERS) + block.first):
        names.update(name.split("[", 1)[0] for name in
                     direct_inputs(block.feedthrough, i, MAX_TRAILERS))
    return sorted(vr_of[name] for name in names)


def _fmi3_attrs(row, description: str, vr: int) -> dict:
    attrs = {
        "name": row.name,
        "valueReference": str(vr),
        "description": description,
        "causality": row.causality,
        "variability": row.variability,
    }
    if row.initial is not None:
        attrs["initial"] = row.initial
    if row.unit:
        attrs["unit"] = row.unit
    if row.min is not None:
        attrs["min"] = xml_number(row.min)
    if row.max is not None:
        attrs["max"] = xml_number(row.max)
    return attrs


def render_model_description3(guid: str, generated: str | None = None) -> bytes:
    """The FMI 3.0 ``modelDescription.xml``: one FMU for every n from 1 to MAX_TRAILERS.

    ``n`` is a structural parameter (start ``DEFAULT_TRAILERS``) and every per-body quantity an
    array whose ``<Dimension>`` references ``n`` or ``n_bodies`` (see :mod:`.variables`).
    """
    root = _root({
        "fmiVersion": "3.0",
        "modelName": MODEL_IDENTIFIER,
        "instantiationToken": guid,
        "description": f"Holonomic robot pushing or pulling n = 1..{MAX_TRAILERS} passive "
        "off-hooked trailers (chain kinematics, robot velocity loop, lateral wheel forces); "
        "n is a structural parameter",
        "generationTool": f"pushtrain {__version__}",
        "generationDateAndTime": generated or generation_time(),
        "variableNamingConvention": "structured",
    })
    ET.SubElement(root, "CoSimulation", {
        "modelIdentifier": MODEL_IDENTIFIER,
        "canGetAndSetFMUState": "true",
        "canSerializeFMUState": "true",
        "canHandleVariableCommunicationStepSize": "true",
        "canBeInstantiatedOnlyOncePerProcess": "false",
        "providesDirectionalDerivatives": "false",
        "hasEventMode": "false",
    })
    _common_sections(root)

    scalars = scalars_for(3)
    vr_of = {var.name: var.vr for var in scalars}
    vr_of.update({block.name: VR_STRIDE * block.block for block in ARRAYS})
    model_vars = ET.SubElement(root, "ModelVariables")
    for var in scalars:
        attrs = _fmi3_attrs(var, var.description, var.vr)
        if var.start is not None:
            attrs["start"] = xml_number(var.start)
        ET.SubElement(model_vars, _FMI3_TYPES[var.type], attrs)
    for block in ARRAYS:
        attrs = _fmi3_attrs(block, describe_array(block), vr_of[block.name])
        if block.start is not None:
            attrs["start"] = " ".join([xml_number(block.start)] * block.count(DEFAULT_TRAILERS))
        element = ET.SubElement(model_vars, _FMI3_TYPES[block.type], attrs)
        ET.SubElement(element, "Dimension", {"valueReference": str(vr_of[block.size_variable])})

    structure = ET.SubElement(root, "ModelStructure")
    for var in scalars:
        if var.causality == "output":
            refs = sorted(vr_of[name.split("[", 1)[0]] for name in var.depends_on)
            _fmi3_unknown(structure, "Output", var.vr, refs)
    for block in ARRAYS:
        if block.causality == "output":
            _fmi3_unknown(structure, "Output", vr_of[block.name],
                          _array_dependencies(block, vr_of))
    for row in [*scalars, *ARRAYS]:
        if _is_initial_unknown(row):
            ET.SubElement(structure, "InitialUnknown", {"valueReference": str(vr_of[row.name])})
    return xml_bytes(root)


def _fmi3_unknown(structure: ET.Element, tag: str, vr: int, refs: list[int]) -> None:
    attrs = {"valueReference": str(vr), "dependencies": " ".join(map(str, refs))}
    if refs:
        attrs["dependenciesKind"] = " ".join("dependent" for _ in refs)
    ET.SubElement(structure, tag, attrs)


def render_build_description() -> bytes:
    """FMI 3.0 ``sources/buildDescription.xml``: the C99 sources of the FMI 3.0 FMU."""
    root = ET.Element("fmiBuildDescription", {"fmiVersion": "3.0"})
    config = ET.SubElement(root, "BuildConfiguration", {"modelIdentifier": MODEL_IDENTIFIER})
    files = ET.SubElement(config, "SourceFileSet", {"language": "C99"})
    for name in source_files(3):
        ET.SubElement(files, "SourceFile", {"name": name})
    return xml_bytes(root)


def render_build_config(fmi_version: int, n_trailers: int | None, guid: str) -> str:
    """``build_config.h``: FMI 2.0 fixes n (arrays sized for it); FMI 3.0 sizes the arrays for
    MAX_TRAILERS and starts with n = DEFAULT_TRAILERS."""
    source_files(fmi_version)  # checks the version
    if fmi_version == 2:
        n = check_n(n_trailers)
        capacity = f"#define MAX_TRAILERS {n} /* n is fixed by the build */\n"
        default = f"#define DEFAULT_TRAILERS {n}\n"
    else:
        capacity = f"#define MAX_TRAILERS {MAX_TRAILERS} /* n is a structural parameter */\n"
        default = f"#define DEFAULT_TRAILERS {DEFAULT_TRAILERS}\n"
    return (
        "/* Generated by pushtrain.fmu.build for this FMU: do not edit. */\n"
        "#ifndef TRAILERTRAIN_BUILD_CONFIG_H\n#define TRAILERTRAIN_BUILD_CONFIG_H\n"
        f"#define FMI_VERSION {fmi_version}\n"
        f'#define MODEL_IDENTIFIER "{MODEL_IDENTIFIER}"\n'
        '#define MODEL_HEADER "model.h" /* the model behind the glue (fmu_model.h) */\n'
        + capacity + default +
        f'#define MODEL_GUID "{guid}"\n'
        "#endif\n"
    )


_STRUCTURAL_REASONS = {
    "n": f"the FMU's arrays hold 1 to {MAX_TRAILERS} trailers",
    "n_bodies": "the robot and n trailers",
}
_C_TYPES = {"Real": "var_real", "Integer": "var_integer", "Boolean": "var_boolean",
            "UInt64": "var_uint64"}
_C_CAUSALITIES = {
    "input": "var_input",
    "output": "var_output",
    "parameter": "var_parameter",
    "calculatedParameter": "var_calculated_parameter",
    "local": "var_local",
    "structuralParameter": "var_structural_parameter",
    "independent": "var_independent",
}


def render_variables_header(fmi_version: int = 2) -> str:
    """``variables.h``: the C view of :mod:`pushtrain.fmu.variables` for one FMI version (the
    same for every n).

    Value-reference enums (``vr_<scalar>`` for this version's scalars, ``blk_<block>``) and one
    ``VarInfo`` table per kind, indexed by them. Only ``variables.c`` includes it; the rest of
    the C code asks that file.
    """
    present = {var.vr: var for var in scalars_for(fmi_version)}
    arrays = ("one array variable (vr = VR_STRIDE * blk_b)" if fmi_version == 3
              else "one scalar per element (vr = VR_STRIDE * blk_b + i)")
    lines = [
        "/* Generated by pushtrain.fmu.build from fmu/variables.py: do not edit.",
        f" * FMI {fmi_version}.0: scalar s has value reference vr_s (< VR_STRIDE); array block b "
        "is",
        f" * {arrays}, for i from first to n + last_offset. */",
        "#ifndef TRAILERTRAIN_VARIABLES_H",
        "#define TRAILERTRAIN_VARIABLES_H",
        "",
        f"#define VR_STRIDE {VR_STRIDE}",
        "",
        "enum ScalarVr {",
        ",\n".join(f"    vr_{present[vr].name} = {vr}" for vr in sorted(present)),
        "};",
        f"#define SCALAR_VR_END {max(present) + 1}",
        "",
        "enum Block {",
        ",\n".join(f"    blk_{b.name} = {b.block}" for b in ARRAYS),
        "};",
        f"#define BLOCK_END {max(b.block for b in ARRAYS) + 1}",
        "",
        "typedef enum { var_real, var_integer, var_boolean, var_uint64 } VarType;",
        "typedef enum {",
        "    var_input, var_output, var_parameter, var_calculated_parameter, var_local,",
        "    var_structural_parameter, var_independent",
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
    lines += [f"    [vr_{v.name}] = {_var_info(v, 0, 0)}," for _, v in sorted(present.items())]
    lines += ["};", "", "static const VarInfo block_info[BLOCK_END] = {"]
    lines += [
        f"    [blk_{b.name}] = {_var_info(b, b.first, -1 if b.to_n_minus_1 else 0)},"
        for b in ARRAYS
    ]
    lines += ["};", "", "#endif", ""]
    return "\n".join(lines)


def render_start_values_header() -> str:
    """``start_values.h``: ``START_<name>``, the start value of every parameter and input that
    has one (for an array block, of each of its elements), as the model description states it,
    for ``start.c``'s ``model_set_defaults``. The same for both FMI versions; the structural
    parameter n starts at ``DEFAULT_TRAILERS`` of ``build_config.h``."""
    rows = [row for row in (*SCALARS, *ARRAYS)
            if row.start is not None and row.type in ("Real", "Integer")
            and row.causality in ("parameter", "input")]
    lines = [
        "/* Generated by pushtrain.fmu.build from fmu/variables.py: do not edit.",
        " * START_<name>: the start value of every parameter and input (of each element of an",
        " * array block), as modelDescription.xml states it. Only start.c includes it. */",
        "#ifndef TRAILERTRAIN_START_VALUES_H",
        "#define TRAILERTRAIN_START_VALUES_H",
        "",
    ]
    for row in rows:
        value = repr(float(row.start)) if row.type == "Real" else str(int(row.start))
        lines.append(f"#define START_{row.name} {value}" + (f" /* {row.unit} */" if row.unit
                                                           else ""))
    lines += ["", "#endif", ""]
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
        reason = (bound.reason if bound is not None
                  else _STRUCTURAL_REASONS.get(row.name, row.description))
        unit = bound.unit if bound is not None else (row.unit or "")
        fields += ["1", repr(float(row.min)), repr(float(row.max)), _c_string(unit),
                   _c_string(reason)]
    return "{" + ", ".join(fields) + "}"
