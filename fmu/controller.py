"""Build the BackwardController FMU: pushtrain's control law as an FMI 2.0 Co-Simulation FMU.

The FMU compiles the engine's control instant, the files ``core/csrc`` declares for it
(:func:`pushtrain.core.native.engine_files` ``("instant")``: the one control law, reference and
pull guide of ``control.c``, held equal to the tests' readable ``tests/reference/``, the
speed governor ``governor.c``, the open-loop profiles ``openloop.c``, the sensor model
``sensors.c`` and the step's tracking errors ``step.c``; this module's one
dependency on core, with :class:`~pushtrain.core.segment.Segment`), with the plant's FMI glue
(``fmu/src``: ``instance.c`` under ``fmi2.c``, see ``fmu_model.h``), the controller's model in
``fmu/controller_src`` (its variables, the mission table) and the files rendered from
:mod:`.controller_variables`. The mission is data: the last
trailer's line/arc segments and the robot's pull-guide rows, written as a small text table into
the FMU's ``resources/`` (:func:`render_table`), so one compiled binary (cached by a hash of its
sources, like the plant) serves every mission with the same n.

:mod:`pushtrain.mission.ssp` turns a planned or scripted
:class:`~pushtrain.core.reference.Reference` and its :class:`~pushtrain.core.pulling.PullGuide`
into a :class:`ControllerTable`.
"""

from __future__ import annotations

import hashlib
import logging
import math
import shutil
import uuid
import zipfile
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import numpy as np

from pushtrain.core.native import engine_files
from pushtrain.core.segment import Segment
from pushtrain.errors import FmuInputError
from pushtrain.files import atomic_write

from .build import cache_dir, package_fmu, ready_cache_dir, usable_cached
from .controller_variables import (
    CONTROLLER_HEADERS,
    CONTROLLER_IDENTIFIER,
    CONTROLLER_SOURCES,
    TABLE_FILE,
    render_controller_build_config,
    render_controller_description,
    render_controller_header,
)
from .render import check_n

__all__ = ["GLUE_FILES", "ControllerTable", "build_controller_fmu", "render_table"]

log = logging.getLogger(__name__)

BUILD_FORMAT = "1"  # bump when the rendering or packaging of the controller changes
TABLE_FORMAT = 1
GLUE_FILES = ("instance.c", "fmi2.c", "fmu_model.h", "instance.h")  # the FMI glue, from fmu/src
EXPORTS_MAP = "ctrl_exports.map"
EXPORTS = "{\n  global: fmi2*;\n  local: *;\n};\n"
"""Linker version script: the FMU exports its fmi2 functions only (control.h marks the law's
pt_* functions visible, for core/native.py's shared library)."""


@dataclass(frozen=True)
class ControllerTable:
    """The mission of a controller FMU: what its ``resources/reference.txt`` holds.

    ``start`` (x, y, theta) [m, m, rad] of the last trailer at ``t0`` [s], the default
    ``speed`` [m/s], the ``cusp_dwell`` [s] at every direction change, the ``segments`` and, for
    every pulling run, the robot's reference rows ``(t, x, y, theta, v, w)`` (K, 6) computed by
    the pull guide (``leader_runs``, in time order).
    """

    start: tuple[float, float, float]
    segments: tuple[Segment, ...]
    speed: float
    cusp_dwell: float
    t0: float = 0.0
    leader_runs: tuple[np.ndarray, ...] = field(default=())

    def __post_init__(self):
        values = [*self.start, self.speed, self.cusp_dwell, self.t0]
        if len(self.start) != 3 or not all(math.isfinite(float(v)) for v in values):
            raise FmuInputError(f"table start = {self.start!r}, speed = {self.speed!r}, "
                                f"cusp_dwell = {self.cusp_dwell!r}: need finite numbers")
        if not self.segments:
            raise FmuInputError("a controller table needs at least one segment")
        for k, run in enumerate(self.leader_runs):
            run = np.asarray(run, dtype=float)
            if run.ndim != 2 or run.shape[1] != 6 or run.shape[0] < 2:
                raise FmuInputError(f"leader run {k}: shape {run.shape}; need (K >= 2, 6) "
                                    "rows t, x, y, theta, v, w")
            if not np.all(np.isfinite(run)):
                raise FmuInputError(f"leader run {k}: non-finite values")


def _number(value: float) -> str:
    """Shortest text that reads back as the same double (``repr``)."""
    return repr(float(value))


def render_table(table: ControllerTable) -> str:
    """The text of ``resources/reference.txt`` (format described in ``ctrl_table.h``)."""
    lines = [
        "# pushtrain BackwardController mission table (written by pushtrain export-ssp)",
        "# SI units, radians; segments: kind length curvature direction speed (0: default)",
        f"pushtrain-reference {TABLE_FORMAT}",
        "start " + " ".join(_number(v) for v in table.start),
        f"t0 {_number(table.t0)}",
        f"speed {_number(table.speed)}",
        f"cusp_dwell {_number(table.cusp_dwell)}",
        f"segments {len(table.segments)}",
    ]
    for seg in table.segments:
        if seg.kind not in ("line", "arc") or seg.direction not in (1, -1):
            raise FmuInputError(f"segment {seg!r}: kind must be 'line' or 'arc', direction +1 "
                                "(push) or -1 (pull)")
        direction = "push" if seg.direction == 1 else "pull"
        speed = 0.0 if seg.speed is None else seg.speed
        lines.append(f"{seg.kind} {_number(seg.length)} {_number(seg.curvature)} {direction} "
                     f"{_number(speed)}")
    lines.append(f"leader_runs {len(table.leader_runs)}")
    lines.append("# each run: rows of t x y theta v w (the robot's reference while pulling)")
    for run in table.leader_runs:
        run = np.asarray(run, dtype=float)
        lines.append(f"run {run.shape[0]}")
        lines += [" ".join(_number(v) for v in row) for row in run]
    return "\n".join(lines) + "\n"


def _model_dir():
    return resources.files("pushtrain.fmu") / "controller_src"


def _glue_dir():
    return resources.files("pushtrain.fmu") / "src"


def _files(n: int, guid: str, generated: str | None = None) -> dict[str, bytes]:
    """The archive files of a controller build for ``n`` trailers (no resources yet)."""
    engine = engine_files("instant")
    files = {f"sources/{name}": resource.read_bytes() for name, resource in engine.items()}
    files.update({f"sources/{name}": (_glue_dir() if name in GLUE_FILES else _model_dir())
                  .joinpath(name).read_bytes()
                  for name in CONTROLLER_SOURCES + CONTROLLER_HEADERS})
    files["sources/ctrl_variables.h"] = render_controller_header(n, guid).encode()
    files["sources/build_config.h"] = render_controller_build_config(guid).encode()
    files[f"sources/{EXPORTS_MAP}"] = EXPORTS.encode()
    sources = tuple(name for name in engine if name.endswith(".c")) + CONTROLLER_SOURCES
    files["modelDescription.xml"] = render_controller_description(n, guid, generated, sources)
    return files


def _cached_build(n: int, strict: bool, force: bool) -> Path:
    digest = hashlib.sha256(f"format={BUILD_FORMAT};n={n};strict={strict}".encode())
    for path, data in sorted(_files(n, "{guid}", "{date}").items()):
        digest.update(path.encode())
        digest.update(data)
    fingerprint = digest.hexdigest()
    cached = cache_dir() / f"{CONTROLLER_IDENTIFIER}-n{n}-{fingerprint[:16]}.fmu"
    if force or not usable_cached(cached):
        ready_cache_dir()
        guid = "{" + str(uuid.UUID(fingerprint[:32])) + "}"
        log.info("building %s (FMI 2.0, n = %d) into %s", CONTROLLER_IDENTIFIER, n, cached)
        package_fmu(_files(n, guid), CONTROLLER_IDENTIFIER, 2, cached, strict,
                    version_script=f"sources/{EXPORTS_MAP}")
    else:
        log.debug("using cached %s", cached)
    return cached


def build_controller_fmu(n_trailers: int, table: ControllerTable, output_path, *,
                         strict: bool = False, force: bool = False) -> Path:
    """Write a BackwardController FMU for ``n_trailers`` with the mission ``table``.

    The compiled FMU (without a mission) is cached like the plant; the file written at
    ``output_path`` (atomically) is that FMU plus ``resources/reference.txt``.

    Raises
    ------
    FmuInputError
        ``n_trailers`` out of range or a malformed table.
    FmuBuildError
        cmake missing, or the compiler failed.
    """
    n = check_n(n_trailers)
    if not isinstance(table, ControllerTable):
        raise FmuInputError(f"table = {table!r}: must be a ControllerTable")
    text = render_table(table)
    cached = _cached_build(n, strict, force)
    out = Path(output_path)

    def write(partial: Path) -> None:
        shutil.copyfile(cached, partial)
        with zipfile.ZipFile(partial, "a", zipfile.ZIP_DEFLATED) as zf:
            zf.writestr(f"resources/{TABLE_FILE}", text)

    out.parent.mkdir(parents=True, exist_ok=True)
    return atomic_write(out, write)
