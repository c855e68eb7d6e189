"""Export a mission as an SSP 1.0 package: the plant FMU, the controller FMU, their connections
and parameters, so the closed loop runs in any FMI/SSP tool (libcosim, ecos, fmpy, ...).

The package (a zip, written atomically)::

    SystemStructure.ssd            the system: components "train" (TrailerTrain) and
                                   "controller" (BackwardController), every connection between
                                   them, DefaultExperiment (start, stop) with the step size in
                                   OSP's annotation (libcosim reads it)
    resources/TrailerTrain.fmu     the plant, FMI 2.0 for the scenario's n
    resources/BackwardController.fmu   pushtrain's control law, with the mission table
    resources/train.ssv            the plant's parameters (the scenario's train, robot, start)
    resources/controller.ssv       the controller's parameters (gains, limits, its chain model,
                                   the joint sensor model, the goal tolerances)
    OspSystemStructure.xml         (optional) the same system in libcosim's own format

Timing. pushtrain's master does, at every t_k: read the plant, compute the command from that
measurement, set it, step. The controller FMU computes its outputs at t from the inputs it holds
at t (lazily, at the read), on the grid t_0 + k h of the master's step, and its step commits the
memory (rate limits, backlash, done) of the first command read at t. So:

- a master that sets the controller's inputs from the plant's outputs at t_k and then reads the
  command (a Gauss-Seidel order: plant outputs -> controller -> plant inputs) reproduces
  pushtrain's loop exactly (to the rounding of C against Python);
- a Jacobi master (the fixed-step algorithms of libcosim and ecos, fmpy's SSP loop: step
  everything, then transfer every output) hands the controller the plant's outputs one step
  late: the command applied over [t_k, t_k+1] is the law at t_k (reference and rate limits at
  t_k) of the measurement at t_k-1 (at t_0: of the measurement at t_0, which libcosim and ecos
  propagate during initialization). That is pushtrain's loop with a one-step measurement delay,
  exactly (tests: libcosim and ecos equal it to 1e-9 m); at 5 ms and 0.08 m/s the last trailer's
  path moves by 0.4 mm on the bundled missions, under the 1 mm bar.
"""

from __future__ import annotations

import logging
import math
import stat
import tempfile
import xml.etree.ElementTree as ET
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pushtrain.core.controller import ControllerConfig
from pushtrain.core.pulling import PullGuide
from pushtrain.core.reference import Reference
from pushtrain.cosim.plant import InitialState
from pushtrain.errors import InputError, ScenarioError
from pushtrain.files import atomic_write
from pushtrain.fmu.build import build_fmu
from pushtrain.fmu.controller import ControllerTable, build_controller_fmu
from pushtrain.fmu.controller_variables import CONTROLLER_IDENTIFIER
from pushtrain.fmu.render import MODEL_IDENTIFIER

from .runner import controller_of, geometry_of, initial_of, plant_of, sensors_of
from .scenario import Scenario

__all__ = ["CONTROLLER", "PARAMETER_SET", "PLANT", "SSP_TARGETS", "SspExport",
           "check_ssp_target", "controller_parameters", "controller_table", "export_ssp",
           "horizon_of", "plant_parameters", "ssp_target_problem"]

log = logging.getLogger(__name__)

PLANT, CONTROLLER = "train", "controller"
"""The component names in the SSD."""
PARAMETER_SET = "mission"
"""The name of both components' parameter sets (ecos applies a named set to every component
that has one: ``EcosSimulation.init(parameter_set="mission")``; libcosim applies each
component's first set by default)."""

NS = {
    "ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
    "ssc": "http://ssp-standard.org/SSP1/SystemStructureCommon",
    "ssv": "http://ssp-standard.org/SSP1/SystemStructureParameterValues",
    "osp": "http://opensimulationplatform.com/SSP/OSPAnnotations",
}
OSP_CONFIG_NS = "http://opensimulationplatform.com/MSMI/OSPSystemStructure"


@dataclass
class SspExport:
    """What :func:`export_ssp` wrote: the package, its step and stop time [s], the connections
    (plant output or controller output, input) and what the package leaves out."""

    path: Path
    step: float
    start_time: float
    stop_time: float
    connections: list[tuple[str, str]]
    warnings: list[str] = field(default_factory=list)


def controller_table(reference: Reference, config: ControllerConfig) -> ControllerTable:
    """The controller FMU's mission table for ``reference``: its segments and, for every pulling
    run, the robot's reference that the pull guide computes with the controller's chain model
    (what :class:`~pushtrain.core.tracking.TrackingLoop` samples)."""
    if not isinstance(reference, Reference):
        raise ScenarioError("reference", [("reference", type(reference).__name__,
                                           "a line/arc Reference (planned or scripted)")])
    runs = ()
    if reference.pull_intervals():
        guide = PullGuide(reference, config.geometry)
        runs = tuple(np.column_stack([r.t, r.x, r.y, r.theta, r.v, r.w]) for r in guide.runs)
    return ControllerTable(tuple(reference.start), reference.segments,
                           reference.speed, reference.cusp_dwell, reference.t0, runs)


def controller_parameters(sc: Scenario, initial: InitialState, step: float) -> dict:
    """Start values of the controller FMU for ``sc``: gains, limits, its chain model, the joint
    sensor model, the previous command at the start (as the master's reset) and the goal."""
    cfg = controller_of(sc)
    sensors = sensors_of(sc)
    n = sc.train.n
    out = {"k_x": cfg.k_x, "k_y": cfg.k_y, "k_theta": cfg.k_theta, "v_max": cfg.v_max,
           "w_max": cfg.w_max, "acc_max": cfg.acc_max or 0.0,
           "alpha_max": cfg.alpha_max or 0.0, "rest_speed": cfg.rest_speed,
           "measure_last_pose": bool(sensors.measure_last_pose),
           "joint_quantization": sensors.joint_quantization,
           "joint_backlash": sensors.joint_backlash,
           "v_start": initial.v0, "w_start": initial.w0, "dt_start": step,
           "goal_tolerance": sc.sim.goal_tolerance,
           "goal_heading_tolerance": math.radians(sc.sim.goal_heading_tolerance_deg)}
    for i in range(1, n + 1):
        out[f"front[{i}]"] = float(cfg.geometry.front[i - 1])
        out[f"rear[{i - 1}]"] = float(cfg.geometry.rear[i - 1])
        out[f"joint_bias[{i}]"] = float(sensors.bias[i - 1])
    return {k: (v if isinstance(v, bool) else float(v)) for k, v in out.items()}


def plant_parameters(sc: Scenario, initial: InitialState) -> dict:
    """Start values of the plant FMU: the scenario's train and robot and the initial state."""
    values = {**plant_of(sc).start_values(), **initial.start_values()}
    return {k: (int(v) if k == "slip_mode" else float(v)) for k, v in values.items()}


def horizon_of(sc: Scenario, reference: Reference) -> float:
    """The run length [s] of pushtrain's master for ``sc``: ``sim.horizon``, else the
    reference's end plus ``sim.settle_time``, rounded up to whole steps."""
    step = sc.sim.step
    if sc.sim.horizon is not None:
        return float(sc.sim.horizon)
    horizon = float(reference.t_end) - float(reference.t0) + sc.sim.settle_time
    return step * math.ceil(horizon / step - 1e-9)


def _connections(n: int) -> list[tuple[str, str, str, str]]:
    """Every connection: (start element, start connector, end element, end connector)."""
    out = [(PLANT, "x[0]", CONTROLLER, "x0"), (PLANT, "y[0]", CONTROLLER, "y0"),
           (PLANT, "theta[0]", CONTROLLER, "theta0")]
    out += [(PLANT, f"phi[{i}]", CONTROLLER, f"phi[{i}]") for i in range(1, n + 1)]
    out += [(PLANT, f"x[{n}]", CONTROLLER, "x_last"), (PLANT, f"y[{n}]", CONTROLLER, "y_last"),
            (PLANT, f"theta[{n}]", CONTROLLER, "theta_last")]
    out += [(CONTROLLER, "v_cmd", PLANT, "v_cmd"), (CONTROLLER, "w_cmd", PLANT, "w_cmd")]
    return out


_OBSERVED = {  # connectors declared for tools that record connectors (fmpy): name -> type
    CONTROLLER: [("e_lon", "Real"), ("e_lat", "Real"), ("e_theta", "Real"), ("done", "Boolean")],
    PLANT: [("jackknifed", "Boolean")],
}


def _q(prefix: str, tag: str) -> str:
    return f"{{{NS[prefix]}}}{tag}"


def _connectors(component: str, n: int) -> list[tuple[str, str, str]]:
    """(name, kind, type) of a component's connectors: every connected variable, then the
    observed outputs."""
    rows = []
    for start_el, start_c, end_el, end_c in _connections(n):
        if start_el == component:
            rows.append((start_c, "output", "Real"))
        if end_el == component:
            rows.append((end_c, "input", "Real"))
    rows += [(name, "output", kind) for name, kind in _OBSERVED[component]]
    seen, out = set(), []
    for row in rows:
        if row[0] not in seen:
            seen.add(row[0])
            out.append(row)
    return out


def _xml(root: ET.Element) -> bytes:
    ET.indent(root, space="  ")
    return b'<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="utf-8")


def _ssv(name: str, values: dict) -> bytes:
    for prefix in ("ssv", "ssc"):
        ET.register_namespace(prefix, NS[prefix])
    root = ET.Element(_q("ssv", "ParameterSet"), {"version": "1.0", "name": name})
    params = ET.SubElement(root, _q("ssv", "Parameters"))
    for key, value in values.items():
        p = ET.SubElement(params, _q("ssv", "Parameter"), {"name": key})
        if isinstance(value, bool):
            ET.SubElement(p, _q("ssv", "Boolean"), {"value": "true" if value else "false"})
        elif isinstance(value, int):
            ET.SubElement(p, _q("ssv", "Integer"), {"value": str(value)})
        else:
            ET.SubElement(p, _q("ssv", "Real"), {"value": repr(float(value))})
    return _xml(root)


def _ssd(sc: Scenario, n: int, start: float, stop: float, step: float) -> bytes:
    for prefix in ("ssd", "ssc", "osp"):
        ET.register_namespace(prefix, NS[prefix])
    root = ET.Element(_q("ssd", "SystemStructureDescription"), {
        "version": "1.0", "name": sc.name,
        "description": f"pushtrain mission {sc.name}: the robot pushing {n} trailers "
                       "(TrailerTrain) with pushtrain's backward controller (BackwardController)",
        "generationTool": "pushtrain export-ssp"})
    system = ET.SubElement(root, _q("ssd", "System"), {
        "name": "mission", "description": "plant outputs -> controller -> plant inputs"})
    elements = ET.SubElement(system, _q("ssd", "Elements"))
    for name, identifier in ((PLANT, MODEL_IDENTIFIER), (CONTROLLER, CONTROLLER_IDENTIFIER)):
        comp = ET.SubElement(elements, _q("ssd", "Component"), {
            "name": name, "type": "application/x-fmu-sharedlibrary",
            "source": f"resources/{identifier}.fmu"})
        connectors = ET.SubElement(comp, _q("ssd", "Connectors"))
        for cname, kind, ctype in _connectors(name, n):
            c = ET.SubElement(connectors, _q("ssd", "Connector"), {"name": cname, "kind": kind})
            ET.SubElement(c, _q("ssc", ctype))
        bindings = ET.SubElement(comp, _q("ssd", "ParameterBindings"))
        ET.SubElement(bindings, _q("ssd", "ParameterBinding"), {
            "type": "application/x-ssp-parameter-set", "source": f"resources/{name}.ssv"})
    connections = ET.SubElement(system, _q("ssd", "Connections"))
    for start_el, start_c, end_el, end_c in _connections(n):
        ET.SubElement(connections, _q("ssd", "Connection"), {
            "startElement": start_el, "startConnector": start_c,
            "endElement": end_el, "endConnector": end_c})
    experiment = ET.SubElement(root, _q("ssd", "DefaultExperiment"),
                               {"startTime": repr(start), "stopTime": repr(stop)})
    annotations = ET.SubElement(experiment, _q("ssd", "Annotations"))
    annotation = ET.SubElement(annotations, _q("ssc", "Annotation"),
                               {"type": "com.opensimulationplatform"})
    algorithm = ET.SubElement(annotation, _q("osp", "Algorithm"))
    ET.SubElement(algorithm, _q("osp", "FixedStepAlgorithm"), {"baseStepSize": repr(step)})
    return _xml(root)


def _osp_config(n: int, start: float, step: float, parameters: dict) -> bytes:
    """libcosim's OspSystemStructure.xml of the same system (FMUs under resources/)."""
    ET.register_namespace("", OSP_CONFIG_NS)

    def q(tag: str) -> str:
        return f"{{{OSP_CONFIG_NS}}}{tag}"

    root = ET.Element(q("OspSystemStructure"), {"version": "0.1"})
    ET.SubElement(root, q("StartTime")).text = repr(start)
    ET.SubElement(root, q("BaseStepSize")).text = repr(step)
    ET.SubElement(root, q("Algorithm")).text = "fixedStep"
    simulators = ET.SubElement(root, q("Simulators"))
    for name, identifier in ((PLANT, MODEL_IDENTIFIER), (CONTROLLER, CONTROLLER_IDENTIFIER)):
        sim = ET.SubElement(simulators, q("Simulator"), {
            "name": name, "source": f"resources/{identifier}.fmu", "stepSize": repr(step)})
        initial = ET.SubElement(sim, q("InitialValues"))
        for key, value in parameters[name].items():
            iv = ET.SubElement(initial, q("InitialValue"), {"variable": key})
            if isinstance(value, bool):
                ET.SubElement(iv, q("Boolean"), {"value": "true" if value else "false"})
            elif isinstance(value, int):
                ET.SubElement(iv, q("Integer"), {"value": str(value)})
            else:
                ET.SubElement(iv, q("Real"), {"value": repr(float(value))})
    connections = ET.SubElement(root, q("Connections"))
    for start_el, start_c, end_el, end_c in _connections(n):
        vc = ET.SubElement(connections, q("VariableConnection"))
        ET.SubElement(vc, q("Variable"), {"simulator": start_el, "name": start_c})
        ET.SubElement(vc, q("Variable"), {"simulator": end_el, "name": end_c})
    return _xml(root)


def _not_exported(sc: Scenario) -> list[str]:
    """What the package leaves out of the scenario (it still runs, without these)."""
    s = sc.sensors
    out = []
    noise = {"sensors.joint_noise_deg": s.joint_noise_deg,
             "sensors.position_noise": s.position_noise,
             "sensors.heading_noise_deg": s.heading_noise_deg}
    for name, value in noise.items():
        if value > 0.0:
            out.append(f"{name} = {value:g}: random sensor noise is not exported (the "
                       "controller FMU models joint bias, quantization and backlash)")
    if sc.events:
        out.append(f"events: {len(sc.events)} timed disturbance(s) are not exported (apply "
                   "them with your tool's own means on the plant's inputs push_x, push_y, "
                   "slide[i])")
    return out


def _check_exportable(sc: Scenario) -> None:
    if sc.controller.governor:
        raise ScenarioError(sc.name, [("controller.governor", True,
                                       "false for export-ssp (the controller FMU has no slip "
                                       "governor)")])


SSP_TARGETS = ("a new path or an earlier .ssp package (a regular file: a zip holding "
               "SystemStructure.ssd), which is replaced")
"""What :func:`export_ssp` may write to (the text of the refusals' "allowed")."""


def ssp_target_problem(out) -> str | None:
    """Why ``out`` must not be replaced by an SSP package (None: it may): anything but a new
    path or an earlier package, e.g. a file of another kind, a link, a FIFO or a device (as
    root, ``-o /dev/full`` replaced the device with a regular file)."""
    target = Path(out)
    try:
        mode = target.lstat().st_mode
    except FileNotFoundError:
        return None
    except OSError as exc:
        return f"cannot be looked at: {exc.strerror or exc}"
    if stat.S_ISLNK(mode):
        return f"is a symbolic link (to {str(target.readlink())!r})"
    if stat.S_ISDIR(mode):
        return "is a folder"
    if not stat.S_ISREG(mode):
        kind = ("a FIFO" if stat.S_ISFIFO(mode) else "a character device" if stat.S_ISCHR(mode)
                else "a block device" if stat.S_ISBLK(mode) else "a socket"
                if stat.S_ISSOCK(mode) else "a special file")
        return f"is not a regular file ({kind})"
    try:
        with zipfile.ZipFile(target) as zf:
            names = zf.namelist()
    except (zipfile.BadZipFile, OSError, EOFError, ValueError):
        return "is a file but not an SSP package (not a zip)"
    if "SystemStructure.ssd" not in names:
        return "is a zip without SystemStructure.ssd: not an SSP package"
    return None


def check_ssp_target(out) -> Path:
    """``out`` as a Path; raises InputError when it must not be replaced
    (:func:`ssp_target_problem`)."""
    problem = ssp_target_problem(out)
    if problem is not None:
        raise InputError(f"{str(out)!r} {problem}; allowed: {SSP_TARGETS}")
    return Path(out)


def export_ssp(sc: Scenario, reference: Reference, out, *, ospconfig: bool = False,
               initial: InitialState | None = None) -> SspExport:
    """Write the SSP 1.0 package of ``sc`` tracking ``reference`` to ``out`` (atomically: a
    new path or an earlier package, :func:`check_ssp_target`, which is replaced by a rename).

    ``initial`` defaults to the scenario's initial state behind the reference (as
    ``run_scenario``). Raises :class:`ScenarioError` for what the package cannot express (the
    slip governor), InputError for an ``out`` that must not be replaced, and
    :class:`~pushtrain.errors.FmuBuildError` if a build fails.
    """
    check_ssp_target(out)
    _check_exportable(sc)
    n = sc.train.n
    step = float(sc.sim.step)
    if initial is None:
        initial = (initial_of(sc, reference) if sc.mission.kind != "rotation"
                   else InitialState.behind_reference(reference, geometry_of(sc)))
    start = float(reference.t0)
    stop = start + horizon_of(sc, reference)
    parameters = {PLANT: plant_parameters(sc, initial),
                  CONTROLLER: controller_parameters(sc, initial, step)}
    table = controller_table(reference, controller_of(sc))
    plant_fmu = build_fmu(n)
    out = Path(out)
    with tempfile.TemporaryDirectory(prefix="pushtrain-ssp-") as tmp:
        controller_fmu = build_controller_fmu(n, table, Path(tmp) / "controller.fmu")
        members = {
            "SystemStructure.ssd": _ssd(sc, n, start, stop, step),
            f"resources/{PLANT}.ssv": _ssv(PARAMETER_SET, parameters[PLANT]),
            f"resources/{CONTROLLER}.ssv": _ssv(PARAMETER_SET, parameters[CONTROLLER]),
        }
        if ospconfig:
            members["OspSystemStructure.xml"] = _osp_config(n, start, step, parameters)

        def write(partial: Path) -> None:
            with zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as zf:
                for name, data in members.items():
                    zf.writestr(name, data)
                zf.write(plant_fmu, f"resources/{MODEL_IDENTIFIER}.fmu")
                zf.write(controller_fmu, f"resources/{CONTROLLER_IDENTIFIER}.fmu")

        check_ssp_target(out)  # what stands there now, after the builds
        atomic_write(out, write)
    connections = [(f"{a}.{b}", f"{c}.{d}") for a, b, c, d in _connections(n)]
    log.info("wrote %s: %d connections, stop time %.3f s, step %g s", out, len(connections),
             stop, step)
    return SspExport(out, step, start, stop, connections, _not_exported(sc))
