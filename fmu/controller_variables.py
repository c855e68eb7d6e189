"""The BackwardController FMU's variables: the one table that describes them, and what is
rendered from it (``modelDescription.xml``, the C header ``ctrl_variables.h`` and the
``build_config.h`` of the FMI glue in ``fmu/src``, which the controller shares with the plant).

The controller FMU (FMI 2.0 Co-Simulation, one build per n) runs pushtrain's control law
(``core/csrc/control.c``) on the plant's measured outputs. Its variables, in value-reference
order (1, 2, ...; arrays expanded to scalars ``name[i]`` with the body index i of the plant):

- inputs: the measured robot pose ``x0, y0, theta0``, the joint angles ``phi[1..n]`` and the last
  trailer's pose ``x_last, y_last, theta_last`` (used when ``measure_last_pose``);
- parameters: Kanayama's gains, the robot's speed and rate limits, the controller's own chain
  model ``front[1..n]``, ``rear[0..n-1]``, the sensor model (joint bias, quantization,
  backlash), the previous command at the start and the goal tolerances;
- outputs: the command ``v_cmd, w_cmd``, the last trailer's tracking errors, ``done``, the
  controller's mode, the reference sample and the measured joint angles.

The C code reads every value through the generated offsets (``R_k_x``, ``R_phi + i - 1``), so a
variable is added here and used there by name; start values are generated into C from the same
rows, so the XML and the binary agree by construction.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass

from pushtrain import __version__, defaults
from pushtrain.limits import BOUNDS, SCENARIO_BOUNDS
from pushtrain.table1 import LINK, SAMPLING_TIME

from .render import BASE_UNITS, check_n, generation_time, xml_bytes, xml_number

__all__ = [
    "CONTROLLER_IDENTIFIER",
    "CONTROLLER_SOURCES",
    "TABLE_FILE",
    "CtrlVar",
    "controller_variables",
    "render_controller_build_config",
    "render_controller_description",
    "render_controller_header",
]

CONTROLLER_IDENTIFIER = "BackwardController"
CONTROLLER_SOURCES = ("ctrl_table.c", "ctrl_model.c", "ctrl_instance.c", "instance.c", "fmi2.c")
"""The controller FMU's own C sources (``fmu/controller_src`` and the FMI glue of ``fmu/src``);
the engine's come from ``core/csrc`` (:mod:`pushtrain.fmu.controller`)."""
CONTROLLER_HEADERS = ("ctrl_model.h", "ctrl_table.h", "ctrl_instance.h", "fmu_model.h",
                      "instance.h")
TABLE_FILE = "reference.txt"
"""The mission table in the FMU's ``resources/`` (see :mod:`pushtrain.fmu.controller`)."""
DEFAULT_STEP = SAMPLING_TIME  # one communication step [s]


@dataclass(frozen=True)
class CtrlVar:
    """One row: a scalar, or an array ``name[first..first+count-1]`` when ``per`` is set.

    ``per`` is ``"trailer"`` (i = 1..n) or ``"link"`` (i = 0..n-1, the rear links R_0..R_{n-1}).
    ``depends`` names the inputs an output depends on directly: ``"all"``, ``"own_phi"``
    (phi[i] only) or ``""`` (none: the reference, which is a function of time alone).
    """

    name: str
    type: str  # "Real", "Integer", "Boolean"
    causality: str  # "input", "output", "parameter", "calculatedParameter"
    description: str
    start: float | int | bool | None = None
    unit: str | None = None
    per: str | None = None
    depends: str = "all"
    min: float | None = None
    max: float | None = None
    reason: str = ""  # why the range, for the C message

    def variability(self) -> str:
        if self.causality in ("parameter", "calculatedParameter"):
            return "fixed"
        return "discrete" if self.type != "Real" else "continuous"


def _bound(row: CtrlVar, key: str) -> CtrlVar:
    """``row`` with min/max and reason from the project's table of plausible ranges."""
    bound = BOUNDS.get(key) or SCENARIO_BOUNDS[key]
    return CtrlVar(**{**row.__dict__, "min": bound.lo, "max": bound.hi, "reason": bound.reason})


def _nonneg(row: CtrlVar, reason: str) -> CtrlVar:
    return CtrlVar(**{**row.__dict__, "min": 0.0, "max": math.inf, "reason": reason})


_MEASURED = "Measured "
ROWS: tuple[CtrlVar, ...] = (
    CtrlVar("x0", "Real", "input", _MEASURED + "robot x", 0.0, "m"),
    CtrlVar("y0", "Real", "input", _MEASURED + "robot y", 0.0, "m"),
    CtrlVar("theta0", "Real", "input", _MEASURED + "robot heading", 0.0, "rad"),
    CtrlVar("phi", "Real", "input", "Joint angle phi[{i}] = theta[{prev}] - theta[{i}] as the "
            "plant reports it (the sensor model below adds bias, backlash, quantization)",
            0.0, "rad", per="trailer"),
    CtrlVar("x_last", "Real", "input", _MEASURED + "x of the last trailer's axle midpoint "
            "(used if measure_last_pose)", 0.0, "m"),
    CtrlVar("y_last", "Real", "input", _MEASURED + "y of the last trailer's axle midpoint "
            "(used if measure_last_pose)", 0.0, "m"),
    CtrlVar("theta_last", "Real", "input", _MEASURED + "heading of the last trailer (used if "
            "measure_last_pose)", 0.0, "rad"),
    _bound(CtrlVar("k_x", "Real", "parameter", "Along-track gain K_x (Eq. 3)", defaults.K_X,
                   "1/s"), "controller.gain"),
    _bound(CtrlVar("k_y", "Real", "parameter", "Lateral gain K_y (Eq. 4)", defaults.K_Y,
                   "1/m2"), "controller.gain"),
    _bound(CtrlVar("k_theta", "Real", "parameter", "Heading gain K_theta (Eq. 4)",
                   defaults.K_THETA, "1/m"), "controller.gain"),
    _bound(CtrlVar("v_max", "Real", "parameter", "Robot speed limit (common-factor scaling)",
                   defaults.V_MAX, "m/s"), "robot.v_max"),
    _bound(CtrlVar("w_max", "Real", "parameter", "Robot yaw-rate limit (common-factor scaling)",
                   defaults.W_MAX, "rad/s"), "robot.w_max"),
    _nonneg(CtrlVar("acc_max", "Real", "parameter", "Rate limit of the speed command; 0: none",
                    defaults.ACC_MAX, "m/s2"), "0 switches the rate limit off"),
    _nonneg(CtrlVar("alpha_max", "Real", "parameter", "Rate limit of the yaw-rate command; "
                    "0: none", math.radians(defaults.ALPHA_MAX_DEG), "rad/s2"),
            "0 switches the rate limit off"),
    _nonneg(CtrlVar("rest_speed", "Real", "parameter", "|v_d| at or below which the reference "
                    "counts as resting (zero command)", defaults.REST_SPEED, "m/s"),
            "a speed is not negative"),
    _bound(CtrlVar("front", "Real", "parameter", "The controller's model of the front link "
                   "F_{i} of trailer {i}", LINK, "m", per="trailer"), "front"),
    _bound(CtrlVar("rear", "Real", "parameter", "The controller's model of the rear link R_{i} "
                   "of {body}", LINK, "m", per="link"), "rear"),
    CtrlVar("measure_last_pose", "Boolean", "parameter", "true: track the measured last-trailer "
            "pose (x_last, y_last, theta_last); false: estimate it from the robot pose and the "
            "joint angles", False),
    CtrlVar("joint_bias", "Real", "parameter", "Sensor bias added to joint {i}", 0.0, "rad",
            per="trailer"),
    _nonneg(CtrlVar("joint_quantization", "Real", "parameter", "Resolution of the joint "
                    "readings; 0: none", 0.0, "rad"), "0 switches quantization off"),
    _nonneg(CtrlVar("joint_backlash", "Real", "parameter", "Width of the dead band between "
                    "joint and sensor; 0: none", 0.0, "rad"), "0 switches backlash off"),
    CtrlVar("v_start", "Real", "parameter", "The robot's speed command before the start (rate "
            "limits start from it)", 0.0, "m/s"),
    CtrlVar("w_start", "Real", "parameter", "The robot's yaw-rate command before the start",
            0.0, "rad/s"),
    _nonneg(CtrlVar("dt_start", "Real", "parameter", "How long before the start time "
                    "(v_start, w_start) was sent, normally one communication step; 0: the "
                    "first command is not rate limited", DEFAULT_STEP, "s"),
            "a time interval is not negative"),
    CtrlVar("goal_tolerance", "Real", "parameter", "Distance of the last trailer from the goal "
            "at which done turns true (once the reference has ended)", defaults.GOAL_TOLERANCE[0],
            "m",
            min=1e-6, max=100.0, reason="a goal is a point of the map, not a region over 100 m"),
    CtrlVar("goal_heading_tolerance", "Real", "parameter", "Heading error of the last trailer "
            "at the goal at which done turns true", defaults.GOAL_TOLERANCE[1], "rad",
            min=1e-6, max=math.pi, reason="a tolerance above pi accepts any heading"),
    CtrlVar("v_cmd", "Real", "output", "Robot speed command", unit="m/s"),
    CtrlVar("w_cmd", "Real", "output", "Robot yaw-rate command", unit="rad/s"),
    CtrlVar("e_lon", "Real", "output", "Last trailer's along-track error in the reference's "
            "frame (position minus reference)", unit="m"),
    CtrlVar("e_lat", "Real", "output", "Last trailer's lateral error in the reference's frame",
            unit="m"),
    CtrlVar("e_theta", "Real", "output", "Last trailer's heading minus the reference heading, "
            "wrapped", unit="rad"),
    CtrlVar("done", "Boolean", "output", "The reference has ended and the last trailer is "
            "within the goal tolerances (stays true once true)"),
    CtrlVar("mode", "Integer", "output", "0: rest, 1: push (Kanayama on the last trailer + "
            "inverse chain), 2: pull (Kanayama on the robot along the pull guide)"),
    CtrlVar("x_d", "Real", "output", "Reference x of the last trailer", unit="m", depends=""),
    CtrlVar("y_d", "Real", "output", "Reference y of the last trailer", unit="m", depends=""),
    CtrlVar("theta_d", "Real", "output", "Reference heading of the last trailer", unit="rad",
            depends=""),
    CtrlVar("v_d", "Real", "output", "Reference speed of the last trailer (< 0 pushing)",
            unit="m/s", depends=""),
    CtrlVar("w_d", "Real", "output", "Reference yaw rate of the last trailer", unit="rad/s",
            depends=""),
    CtrlVar("direction", "Integer", "output", "Reference direction: 1 push, -1 pull, 0 rest",
            depends=""),
    CtrlVar("x_e", "Real", "output", "Kanayama along-track error of the tracked body", unit="m"),
    CtrlVar("y_e", "Real", "output", "Kanayama lateral error of the tracked body", unit="m"),
    CtrlVar("theta_e", "Real", "output", "Kanayama heading error of the tracked body",
            unit="rad"),
    CtrlVar("phi_meas", "Real", "output", "Joint angle {i} after the sensor model", unit="rad",
            per="trailer", depends="own_phi"),
    CtrlVar("t_end", "Real", "calculatedParameter", "Time at which the reference ends (from "
            "the mission table)", unit="s"),
)

_UNITS = ("m", "m/s", "m/s2", "rad", "rad/s", "rad/s2", "s", "1/s", "1/m", "1/m2")
_EXTRA_UNITS = {"1/s": {"s": "-1"}, "1/m": {"m": "-1"}, "1/m2": {"m": "-2"}}


@dataclass(frozen=True)
class Scalar:
    """One FMI 2.0 scalar variable of a controller built for n: its row, element and vr."""

    row: CtrlVar
    index: int | None  # the body index i of an array element, None for a scalar
    vr: int

    @property
    def name(self) -> str:
        return self.row.name if self.index is None else f"{self.row.name}[{self.index}]"

    @property
    def description(self) -> str:
        if self.index is None:
            return self.row.description
        i = self.index
        body = "the robot" if i == 0 else f"trailer {i}"
        return self.row.description.format(i=i, prev=i - 1, body=body)


def _elements(row: CtrlVar, n: int) -> list[int | None]:
    if row.per == "trailer":
        return list(range(1, n + 1))
    if row.per == "link":
        return list(range(n))
    return [None]


def controller_variables(n_trailers: int) -> list[Scalar]:
    """Every scalar variable of the controller FMU built for ``n_trailers``, by value reference
    (1, 2, ... in the order of the rows, arrays expanded)."""
    n = check_n(n_trailers)
    out = []
    for row in ROWS:
        for i in _elements(row, n):
            out.append(Scalar(row, i, len(out) + 1))
    return out


def _inputs_of(var: Scalar, variables: list[Scalar]) -> list[Scalar]:
    if var.row.depends == "all":
        return [v for v in variables if v.row.causality == "input"]
    if var.row.depends == "own_phi":
        return [v for v in variables if v.row.name == "phi" and v.index == var.index]
    return []


def render_controller_description(n_trailers: int, guid: str, generated: str | None = None,
                                  sources: tuple[str, ...] = CONTROLLER_SOURCES) -> bytes:
    """The FMI 2.0 ``modelDescription.xml`` of the BackwardController FMU for ``n_trailers``
    whose C ``sources`` are those named (the engine's and :data:`CONTROLLER_SOURCES`)."""
    n = check_n(n_trailers)
    variables = controller_variables(n)
    root = ET.Element("fmiModelDescription", {
        "fmiVersion": "2.0",
        "modelName": CONTROLLER_IDENTIFIER,
        "guid": guid,
        "description": f"pushtrain's backward-motion controller for {n} trailers: Kanayama "
        "tracking of the last trailer (pushing) or of the robot along the pull guide (pulling), "
        "inverse chain kinematics, speed and rate limits; the mission's reference is the table "
        f"resources/{TABLE_FILE}",
        "generationTool": f"pushtrain {__version__}",
        "generationDateAndTime": generated or generation_time(),
        "variableNamingConvention": "structured",
        "numberOfEventIndicators": "0",
    })
    cs = ET.SubElement(root, "CoSimulation", {
        "modelIdentifier": CONTROLLER_IDENTIFIER,
        "needsExecutionTool": "false",
        "canHandleVariableCommunicationStepSize": "true",
        "canGetAndSetFMUstate": "false",
        "canSerializeFMUstate": "false",
        "canNotUseMemoryManagementFunctions": "true",
        "canBeInstantiatedOnlyOncePerProcess": "false",
        "providesDirectionalDerivative": "false",
    })
    files = ET.SubElement(cs, "SourceFiles")
    for name in sources:
        ET.SubElement(files, "File", {"name": name})
    units = ET.SubElement(root, "UnitDefinitions")
    for name in _UNITS:
        unit = ET.SubElement(units, "Unit", {"name": name})
        ET.SubElement(unit, "BaseUnit", BASE_UNITS.get(name) or _EXTRA_UNITS[name])
    categories = ET.SubElement(root, "LogCategories")
    for name, text in (("logStatusError", "Errors: bad parameters, refused calls, bad table"),
                       ("logStatusWarning", "Warnings"),
                       ("logDebug", "One message per communication step")):
        ET.SubElement(categories, "Category", {"name": name, "description": text})
    ET.SubElement(root, "DefaultExperiment",
                  {"startTime": "0.0", "stopTime": "10.0", "stepSize": xml_number(DEFAULT_STEP)})

    model_vars = ET.SubElement(root, "ModelVariables")
    for var in variables:
        row = var.row
        attrs = {"name": var.name, "valueReference": str(var.vr),
                 "description": var.description, "causality": row.causality,
                 "variability": row.variability()}
        if row.causality in ("output", "calculatedParameter"):
            attrs["initial"] = "calculated"
        sv = ET.SubElement(model_vars, "ScalarVariable", attrs)
        type_attrs = {}
        if row.unit:
            type_attrs["unit"] = row.unit
        if row.min is not None:
            type_attrs["min"] = xml_number(float(row.min))
            if math.isfinite(row.max):
                type_attrs["max"] = xml_number(float(row.max))
        if row.start is not None:
            type_attrs["start"] = xml_number(row.start)
        ET.SubElement(sv, row.type, type_attrs)

    index = {var.vr: k + 1 for k, var in enumerate(variables)}
    structure = ET.SubElement(root, "ModelStructure")
    outputs = ET.SubElement(structure, "Outputs")
    for var in variables:
        if var.row.causality == "output":
            refs = sorted(index[v.vr] for v in _inputs_of(var, variables))
            attrs = {"index": str(index[var.vr]), "dependencies": " ".join(map(str, refs))}
            if refs:
                attrs["dependenciesKind"] = " ".join("dependent" for _ in refs)
            ET.SubElement(outputs, "Unknown", attrs)
    initial = ET.SubElement(structure, "InitialUnknowns")
    for var in variables:
        if var.row.causality in ("output", "calculatedParameter"):
            ET.SubElement(initial, "Unknown", {"index": str(index[var.vr])})
    return xml_bytes(root)


_C_TYPE = {"Real": "ctrl_real", "Integer": "ctrl_integer", "Boolean": "ctrl_boolean"}
_C_CAUSALITY = {"input": "ctrl_input", "output": "ctrl_output", "parameter": "ctrl_parameter",
                "calculatedParameter": "ctrl_calculated_parameter"}
_PREFIX = {"Real": "R", "Integer": "I", "Boolean": "B"}


def _c_string(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def _c_double(value: float) -> str:
    if value == math.inf:
        return "HUGE_VAL"
    return repr(float(value))


def render_controller_build_config(guid: str) -> str:
    """``build_config.h`` of the controller's build: what the FMI glue of ``fmu/src``
    (``fmu_model.h``) needs to know of the model (FMI 2.0, its identifier, GUID and header)."""
    return (
        "/* Generated by pushtrain.fmu.controller for this FMU: do not edit. */\n"
        "#ifndef PUSHTRAIN_CTRL_BUILD_CONFIG_H\n#define PUSHTRAIN_CTRL_BUILD_CONFIG_H\n"
        "#define FMI_VERSION 2\n"
        f"#define MODEL_IDENTIFIER {_c_string(CONTROLLER_IDENTIFIER)}\n"
        '#define MODEL_HEADER "ctrl_instance.h" /* the model behind the glue */\n'
        f"#define MODEL_GUID {_c_string(guid)}\n"
        "#endif\n"
    )


def render_controller_header(n_trailers: int, guid: str) -> str:
    """``ctrl_variables.h``: n, the storage offsets of every variable (``R_k_x``;
    an array's first element, ``R_phi + i - 1``), the table indexed by value reference and the
    start values."""
    n = check_n(n_trailers)
    variables = controller_variables(n)
    offsets = {"Real": 0, "Integer": 0, "Boolean": 0}
    index_of, enums, starts = {}, {t: [] for t in offsets}, {t: [] for t in offsets}
    for var in variables:
        kind = var.row.type
        index_of[var.vr] = offsets[kind]
        if var.index is None or var.index == _elements(var.row, n)[0]:
            enums[kind].append(f"{_PREFIX[kind]}_{var.row.name} = {offsets[kind]}")
        start = var.row.start if var.row.start is not None else 0
        starts[kind].append(_c_double(start) if kind == "Real" else str(int(start)))
        offsets[kind] += 1
    lines = [
        "/* Generated by pushtrain.fmu.controller from fmu/controller_variables.py: do not edit.",
        " * Storage offsets (R_ reals, I_ integers, B_ booleans; an array names its first "
        "element)",
        " * and the variables by value reference. */",
        "#ifndef PUSHTRAIN_CTRL_VARIABLES_H",
        "#define PUSHTRAIN_CTRL_VARIABLES_H",
        "",
        "#include <math.h>",
        "",
        f"#define CTRL_N {n}",
        f"#define CTRL_TABLE_FILE {_c_string(TABLE_FILE)}",
        f"#define CTRL_N_REALS {offsets['Real']}",
        f"#define CTRL_N_INTEGERS {offsets['Integer']}",
        f"#define CTRL_N_BOOLEANS {offsets['Boolean']}",
        f"#define CTRL_VR_END {len(variables) + 1}",
        "",
    ]
    for kind in ("Real", "Integer", "Boolean"):
        lines += [f"enum Ctrl{kind}Offset {{", ",\n".join("    " + e for e in enums[kind]),
                  "};", ""]
    lines += [
        "typedef enum { ctrl_real, ctrl_integer, ctrl_boolean } CtrlType;",
        "typedef enum {",
        "    ctrl_input, ctrl_output, ctrl_parameter, ctrl_calculated_parameter",
        "} CtrlCausality;",
        "",
        "typedef struct {",
        "    const char *name; /* NULL: no variable has this value reference */",
        "    CtrlType type;",
        "    CtrlCausality causality;",
        "    int offset;  /* into the storage of its type */",
        "    int bounded; /* parameters: min <= value <= max is checked */",
        "    double min, max;",
        "    const char *unit, *reason;",
        "} CtrlVarInfo;",
        "",
        "static const CtrlVarInfo ctrl_vars[CTRL_VR_END] = {",
    ]
    for var in variables:
        row = var.row
        bounded = row.min is not None
        fields = [_c_string(var.name), _C_TYPE[row.type], _C_CAUSALITY[row.causality],
                  str(index_of[var.vr]), "1" if bounded else "0",
                  _c_double(row.min if bounded else 0.0), _c_double(row.max if bounded else 0.0),
                  _c_string(row.unit or ""), _c_string(row.reason)]
        lines.append(f"    [{var.vr}] = {{{', '.join(fields)}}},")
    lines += ["};", ""]
    lines += [f"static const double ctrl_real_start[CTRL_N_REALS] = "
              f"{{{', '.join(starts['Real'])}}};",
              f"static const int ctrl_integer_start[CTRL_N_INTEGERS] = "
              f"{{{', '.join(starts['Integer'])}}};",
              f"static const int ctrl_boolean_start[CTRL_N_BOOLEANS] = "
              f"{{{', '.join(starts['Boolean'])}}};",
              "", "#endif", ""]
    return "\n".join(lines)
