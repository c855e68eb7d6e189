"""Build and load the closed-loop engine (``core/csrc``) with ctypes.

The engine's C files (:data:`ENGINE_FILES`: ``control.c``, the law, reference and pull guide,
``ode.h``, the RK4, ``sensors.c``, the sensor model, ``openloop.c``, open-loop command
profiles, ``step.c``, a co-simulation step's closed-loop work, ``rollout.c``, the planner's
closed loop, ``field.c``, the planner's lookups on a distance field) are compiled once per
machine with the system C compiler into a shared library,
``-std=c99 -O2 -fPIC -shared -ffp-contract=off -lm`` (no fused multiply-add, so the C
arithmetic rounds like Python's), and cached under ``$PUSHTRAIN_CACHE/native`` (default
``~/.cache/pushtrain/native``) by a hash of the sources,
the compiler command, its version and the flags. Another room builds its own library on the
engine's files the same way (:func:`load_library`: the co-simulation's step loop), and the
controller FMU compiles :data:`ENGINE_FILES` ``["instant"]`` (:func:`engine_files`): the
engine's C has this one declared list of files. The library is written under a
temporary name and renamed into place, so concurrent processes may build at the same time: each
gets a complete library.

The compiler is ``$CC`` if set, else Python's own (``sysconfig``'s ``CC``), else ``cc``; without
one :class:`~pushtrain.errors.NativeBuildError` says what to install or set.

:func:`load` returns the :class:`ctypes.CDLL` with every prototype declared; the ``Pt*``
structures below mirror the C structs of ``control.h``, ``sensors.h``, ``openloop.h``,
``step.h`` and ``rollout.h`` (their sizes are checked against the library at load time).
"""

from __future__ import annotations

import ctypes
import functools
import hashlib
import logging
import os
import shlex
import shutil
import subprocess
import sys
import sysconfig
import tempfile
import threading
import uuid
from ctypes import POINTER, c_double, c_int, c_size_t
from importlib import resources
from pathlib import Path

from pushtrain.errors import NativeBuildError, NativeCacheError

__all__ = [
    "CFLAGS",
    "PtChain",
    "PtChecks",
    "PtControlInfo",
    "PtControlState",
    "PtController",
    "PtLeader",
    "PtGovernor",
    "PtMeasurement",
    "PtPhase",
    "PtProfile",
    "PtProfilePiece",
    "PtRecord",
    "PtReference",
    "PtRollout",
    "PtSample",
    "PtSegment",
    "PtSensors",
    "PtStep",
    "PtTrack",
    "PtViolation",
    "STATUS",
    "cache_dir",
    "compiler_command",
    "ENGINE_FILES",
    "dptr",
    "engine_files",
    "library_path",
    "load",
    "load_library",
]

log = logging.getLogger(__name__)

ENGINE_FILES = {
    "instant": ("control.c", "control.h", "governor.c", "governor.h", "ode.h", "openloop.c",
                "openloop.h", "sensors.c", "sensors.h", "step.c", "step.h"),
    "rollout": ("rollout.c", "rollout.h", "field.c", "field.h"),
}
"""The engine's C files in ``core/csrc``: one control instant with its sensors and step
(``"instant"``, what the controller FMU compiles) and the planner's rollout and its lookups on
the distance field (``"rollout"``)."""
CFLAGS = ("-std=c99", "-O2", "-fPIC", "-ffp-contract=off")
LDFLAGS = ("-shared",)
LIBS = ("-lm",)
BUILD_FORMAT = "1"  # bump when the build recipe changes

STATUS = {
    0: "ok",
    1: "non-finite measurement",
    2: "non-finite command",
    3: "pulling without the robot's reference (leader)",
    4: "reference direction not +1, -1 or 0",
    5: "bad argument",
    6: "storage too small",
    7: "bad segment",
    8: "time outside every pulling run",
    9: "reference without segments",
}
"""Meaning of the C status codes (``PT_OK``, ``PT_ERR_*`` in ``control.h``)."""

D_PTR = POINTER(c_double)


class PtChain(ctypes.Structure):
    _fields_ = [("n", c_int), ("front", D_PTR), ("rear", D_PTR)]


class PtSample(ctypes.Structure):
    _fields_ = [("x", c_double), ("y", c_double), ("theta", c_double), ("v", c_double),
                ("w", c_double), ("direction", c_int)]


class PtController(ctypes.Structure):
    _fields_ = [("model", PtChain), ("k_x", c_double), ("k_y", c_double), ("k_theta", c_double),
                ("v_max", c_double), ("w_max", c_double), ("acc_max", c_double),
                ("alpha_max", c_double), ("rest_speed", c_double)]


class PtControlState(ctypes.Structure):
    _fields_ = [("v_prev", c_double), ("w_prev", c_double), ("t_prev", c_double),
                ("has_t_prev", c_int)]


class PtMeasurement(ctypes.Structure):
    _fields_ = [("x0", c_double), ("y0", c_double), ("theta0", c_double), ("phi", D_PTR),
                ("has_last", c_int), ("x_n", c_double), ("y_n", c_double), ("theta_n", c_double)]


class PtControlInfo(ctypes.Structure):
    _fields_ = [("mode", c_int)] + [(name, c_double) for name in (
        "x_e", "y_e", "theta_e", "x_n", "y_n", "theta_n", "v_ref", "w_ref", "v_raw", "w_raw",
        "scale")]


class PtSegment(ctypes.Structure):
    _fields_ = [("length", c_double), ("curvature", c_double), ("speed", c_double),
                ("direction", c_int), ("kind", c_int)]


class PtPhase(ctypes.Structure):
    _fields_ = [(name, c_double) for name in ("t", "x", "y", "theta", "sigma", "kappa", "speed")]


class PtReference(ctypes.Structure):
    _fields_ = [("phases", POINTER(PtPhase)), ("capacity", c_int), ("n_phases", c_int),
                ("t0", c_double), ("speed", c_double), ("cusp_dwell", c_double),
                ("t_end", c_double), ("x_end", c_double), ("y_end", c_double),
                ("theta_end", c_double), ("last_direction", c_int)]


class PtLeader(ctypes.Structure):
    _fields_ = [("n_runs", c_int), ("offset", POINTER(c_int))] + [
        (name, D_PTR) for name in ("t", "x", "y", "theta", "v", "w")]


class PtTrack(ctypes.Structure):
    _fields_ = [("controller", POINTER(PtController)), ("state", POINTER(PtControlState)),
                ("reference", POINTER(PtReference)), ("leader", POINTER(PtLeader)),
                ("t", c_double), ("m", PtMeasurement), ("sample", PtSample),
                ("cmd", c_double * 2), ("info", PtControlInfo)]


class PtSensors(ctypes.Structure):
    _fields_ = [("n", c_int), ("bias", D_PTR), ("half_backlash", c_double),
                ("quantization", c_double), ("noise", c_int), ("measure_last_pose", c_int),
                ("play", D_PTR), ("has_play", c_int)]


class PtGovernor(ctypes.Structure):
    _fields_ = [("model", PtChain), ("mass", D_PTR), ("inertia", D_PTR), ("limits", D_PTR),
                ("tau", c_double), ("acc_max", c_double), ("alpha_max", c_double),
                ("dt", c_double), ("v_est", c_double), ("w_est", c_double), ("v_prev", c_double),
                ("w_prev", c_double), ("saturated", ctypes.c_long), ("limited", ctypes.c_long)]


class PtProfilePiece(ctypes.Structure):
    _fields_ = [("t", c_double), ("start", c_double * 2), ("rate", c_double * 2),
                ("stop", c_double * 2)]


class PtProfile(ctypes.Structure):
    _fields_ = [("n_pieces", c_int), ("pieces", POINTER(PtProfilePiece)), ("period", c_double),
                ("flip", c_int)]


class PtStep(ctypes.Structure):
    _fields_ = [("track", POINTER(PtTrack)), ("profile", POINTER(PtProfile)),
                ("sensors", POINTER(PtSensors)), ("n_pushes", c_int), ("pushes", D_PTR),
                ("cmd", c_double * 2), ("sample", PtSample), ("push", c_double * 2),
                ("errors", c_double * 3), ("governor", POINTER(PtGovernor)),
                ("governor_work", D_PTR)]


class PtChecks(ctypes.Structure):
    _fields_ = [("nx", c_int), ("ny", c_int), ("sdf", D_PTR), ("x0", c_double), ("y0", c_double),
                ("h", c_double), ("point_offset", POINTER(c_int)), ("px", D_PTR), ("py", D_PTR),
                ("margin", D_PTR), ("fine_offset", POINTER(c_int)), ("fine_px", D_PTR),
                ("fine_py", D_PTR), ("fine_margin", D_PTR), ("phi_max", c_double),
                ("rect", D_PTR)]


class PtRollout(ctypes.Structure):
    _fields_ = [("plant", POINTER(PtChain)), ("controller", POINTER(PtController)),
                ("reference", POINTER(PtReference)), ("leader", POINTER(PtLeader)),
                ("t_start", c_double), ("step", c_double), ("checks", POINTER(PtChecks))]


class PtViolation(ctypes.Structure):
    _fields_ = [("step", ctypes.c_long), ("body", c_int), ("other", c_int), ("reason", c_int),
                ("x", c_double), ("y", c_double), ("value", c_double)]


class PtRecord(ctypes.Structure):
    _fields_ = [("states", D_PTR), ("commands", D_PTR), ("references", D_PTR),
                ("directions", POINTER(c_int))]


_STRUCTS = (PtChain, PtSample, PtController, PtControlState, PtMeasurement, PtControlInfo,
            PtSegment, PtPhase, PtReference, PtLeader, PtTrack)  # in pt_sizeof's order
_ROLLOUT_STRUCTS = (PtChecks, PtRollout, PtViolation, PtRecord)  # in pt_rollout_sizeof's

P = ctypes.POINTER
_PROTOTYPES = {
    "pt_sizeof": (c_size_t, [c_int]),
    "pt_wrap": (c_double, [c_double]),
    "pt_last_trailer_pose": (None, [P(PtChain), c_double, c_double, c_double, D_PTR, D_PTR]),
    "pt_body_positions": (None, [P(PtChain), ctypes.c_long, D_PTR, D_PTR, D_PTR, c_int, D_PTR,
                                 D_PTR, D_PTR]),
    "pt_robot_velocity_from_last": (None, [P(PtChain), D_PTR, c_double, c_double, D_PTR]),
    "pt_rates_from_last": (None, [P(PtChain), D_PTR, c_double, c_double, D_PTR]),
    "pt_towed_rates": (None, [P(PtChain), D_PTR, c_double, c_double, D_PTR]),
    "pt_kanayama": (None, [P(PtController), c_double, c_double, c_double, c_double, c_double,
                           D_PTR]),
    "pt_control_reset": (None, [P(PtControlState), c_double, c_double, c_double, c_int]),
    "pt_control_sent": (None, [P(PtControlState), c_double, c_double]),
    "pt_command": (c_int, [P(PtController), P(PtControlState), c_double, P(PtMeasurement),
                           P(PtSample), P(PtSample), D_PTR, P(PtControlInfo)]),
    "pt_reference_init": (c_int, [P(PtReference), P(PtPhase), c_int, D_PTR, c_double, c_double,
                                  c_double, c_int]),
    "pt_reference_append": (c_int, [P(PtReference), P(PtSegment)]),
    "pt_reference_sample": (c_int, [P(PtReference), c_double, P(PtSample)]),
    "pt_reference_samples": (c_int, [P(PtReference), D_PTR, c_int, D_PTR, D_PTR, D_PTR, D_PTR,
                                     D_PTR, P(c_int)]),
    "pt_reference_pull_intervals": (c_int, [P(PtReference), D_PTR, D_PTR, c_int]),
    "pt_pull_run_rows": (c_int, [c_double, c_double, c_double]),
    "pt_pull_run_work": (c_int, [c_int]),
    "pt_pull_run": (c_int, [P(PtChain), P(PtReference), c_double, c_double, c_double, D_PTR,
                            D_PTR, D_PTR, D_PTR, D_PTR, D_PTR, D_PTR, D_PTR]),
    "pt_pull_run_sampled": (c_int, [P(PtChain), ctypes.c_void_p, ctypes.c_void_p, c_double,
                                    c_double, c_double, D_PTR, D_PTR, D_PTR, D_PTR, D_PTR, D_PTR,
                                    D_PTR, D_PTR]),
    "pt_leader_sample": (c_int, [P(PtLeader), c_double, P(PtSample)]),
    "pt_instant": (c_int, [P(PtController), P(PtControlState), P(PtReference), P(PtLeader),
                           c_double, P(PtMeasurement), P(PtSample), D_PTR, P(PtControlInfo)]),
    "pt_track": (c_int, [P(PtTrack)]),
    "pt_sensors_sizeof": (c_size_t, []),
    "pt_sensors_noise_count": (c_int, [P(PtSensors)]),
    "pt_measure_joints": (None, [P(PtSensors), D_PTR, D_PTR, D_PTR]),
    "pt_measure": (c_int, [P(PtSensors), D_PTR, D_PTR, D_PTR, P(PtMeasurement)]),
    "pt_step_sizeof": (c_size_t, []),
    "pt_profile_sizeof": (c_size_t, [c_int]),
    "pt_profile_command": (c_int, [P(PtProfile), c_double, D_PTR]),
    "pt_governor_sizeof": (c_size_t, []),
    "pt_governor_work": (c_int, [c_int]),
    "pt_governor_limit": (None, [P(PtGovernor), D_PTR, D_PTR, D_PTR, D_PTR]),
    "pt_step": (c_int, [P(PtStep), c_double, D_PTR, D_PTR, D_PTR]),
    "pt_rollout_sizeof": (c_size_t, [c_int]),
    "pt_rollout_work": (c_int, [c_int]),
    "pt_rollout": (c_int, [P(PtRollout), P(ctypes.c_long), D_PTR, P(PtControlState),
                           ctypes.c_long, D_PTR, P(PtRecord), P(PtViolation)]),
    "pt_check_state": (c_int, [P(PtChain), P(PtChecks), D_PTR, ctypes.c_long, D_PTR,
                               P(PtViolation)]),
    "pt_hold": (c_int, [P(PtChain), D_PTR, c_double, c_double, c_double, c_int, D_PTR, D_PTR]),
    "pt_sdf_at": (c_double, [P(PtChecks), c_double, c_double]),
    "pt_field_at": (None, [ctypes.c_void_p, ctypes.c_long, ctypes.c_long, c_double, c_double,
                           c_double, ctypes.c_long, ctypes.c_void_p, ctypes.c_void_p,
                           ctypes.c_void_p]),
    "pt_sample_count": (ctypes.c_long, [c_int, ctypes.c_void_p, c_double]),
    "pt_sample_segments": (c_int, [ctypes.c_void_p, c_int, ctypes.c_void_p, c_double,
                                   ctypes.c_void_p]),
    "pt_poses_clear": (c_int, [ctypes.c_void_p, ctypes.c_long, ctypes.c_long, c_double, c_double,
                               c_double, ctypes.c_long, ctypes.c_void_p, c_double,
                               ctypes.c_long, ctypes.c_void_p, ctypes.c_void_p,
                               ctypes.c_void_p]),
    "pt_rects_overlap": (c_int, [D_PTR, D_PTR, D_PTR]),
}

_lock = threading.Lock()
_loaded: dict[Path, ctypes.CDLL] = {}
_by_setting: dict[tuple, ctypes.CDLL] = {}  # (stem, CC, PUSHTRAIN_CACHE) -> the library loaded


def cache_dir() -> Path:
    """Folder of the compiled libraries: ``$PUSHTRAIN_CACHE/native`` or
    ``~/.cache/pushtrain/native``."""
    root = os.environ.get("PUSHTRAIN_CACHE")
    base = Path(root) if root else Path.home() / ".cache" / "pushtrain"
    return base / "native"


def compiler_command() -> list[str]:
    """The C compiler as an argument list: ``$CC``, else Python's ``sysconfig`` CC, else ``cc``.

    Raises
    ------
    NativeBuildError
        If that program is not found.
    """
    env = os.environ.get("CC", "").strip()
    if env:
        argv, origin = shlex.split(env), f"CC = {env!r} (environment)"
    else:
        configured = (sysconfig.get_config_var("CC") or "").strip()
        argv = shlex.split(configured) if configured else []
        origin = f"Python's configured CC = {configured!r}"
        if not argv or shutil.which(argv[0]) is None:
            argv, origin = ["cc"], "the default 'cc'"
    if shutil.which(argv[0]) is None:
        raise NativeBuildError(
            f"C compiler not found: {origin} names {argv[0]!r}, which is not an executable on "
            "PATH; pushtrain compiles its control law (core/csrc) on first use: install a C "
            "compiler (e.g. gcc or clang) or set CC to one")
    return argv


def engine_files(*parts: str) -> dict:
    """``{file name: resource}`` of the engine's C files of ``parts`` of :data:`ENGINE_FILES`
    (default: all)."""
    folder = resources.files("pushtrain.core") / "csrc"
    return {name: folder / name for part in (parts or tuple(ENGINE_FILES))
            for name in ENGINE_FILES[part]}


@functools.lru_cache(maxsize=8)
def _compiler_version(argv: tuple[str, ...]) -> str:
    try:
        done = subprocess.run([*argv, "--version"], capture_output=True, text=True, timeout=60)
    except (OSError, subprocess.SubprocessError) as exc:
        raise NativeBuildError(f"C compiler {argv[0]!r} cannot be run: {exc}") from exc
    lines = (done.stdout or done.stderr).strip().splitlines()
    return lines[0] if lines else ""


def _fingerprint(argv: list[str], files: dict) -> str:
    digest = hashlib.sha256()
    digest.update(f"format={BUILD_FORMAT};platform={sys.platform};".encode())
    recipe = [*argv, _compiler_version(tuple(argv)), *CFLAGS, *LDFLAGS, *LIBS]
    digest.update("\0".join(recipe).encode())
    for name in sorted(files):
        digest.update(name.encode() + b"\0")
        digest.update(files[name].read_bytes())
    return digest.hexdigest()


def _suffix() -> str:
    return ".dll" if sys.platform == "win32" else ".dylib" if sys.platform == "darwin" else ".so"


def _compile(argv: list[str], target: Path, files: dict) -> None:
    """Compile ``files`` (``{name: resource}``: its ``.c`` files with its headers beside them)
    into ``target`` through a temporary file renamed into place."""
    partial = target.with_name(f".{target.name}.{os.getpid()}.{uuid.uuid4().hex[:8]}.part")
    with tempfile.TemporaryDirectory(prefix="pushtrain-native-") as tmp:
        for name, resource in files.items():
            (Path(tmp) / name).write_bytes(resource.read_bytes())
        sources = sorted(name for name in files if name.endswith(".c"))
        command = [*argv, *CFLAGS, *LDFLAGS, "-o", str(partial),
                   *(str(Path(tmp) / name) for name in sources), *LIBS]
        try:
            done = subprocess.run(command, capture_output=True, text=True, timeout=600)
        except (OSError, subprocess.SubprocessError) as exc:
            partial.unlink(missing_ok=True)
            raise NativeBuildError(f"C compiler {argv[0]!r} cannot be run: {exc}") from exc
        if done.returncode != 0 or not partial.is_file():
            partial.unlink(missing_ok=True)
            tail = "\n".join((done.stdout + done.stderr).strip().splitlines()[-30:])
            raise NativeBuildError(
                f"compiling {', '.join(sources)} failed (exit {done.returncode}): "
                f"{shlex.join(command)}\n"
                f"{tail}")
        for line in done.stderr.splitlines():
            if "warning:" in line:
                log.warning("compiler: %s", line)
    try:
        os.replace(partial, target)
    finally:
        partial.unlink(missing_ok=True)


ENGINE_STEM = "pushtrain_control"
"""File stem of the engine's compiled library."""


def library_path(rebuild: bool = False, stem: str = ENGINE_STEM,
                 files: dict | None = None) -> Path:
    """The compiled library ``stem`` of ``files`` (default: the engine's) for the current
    sources and compiler, built if not cached.

    Raises
    ------
    NativeBuildError
        No compiler, a failing compiler, or a cache folder that cannot be written.
    """
    files = engine_files() if files is None else files
    argv = compiler_command()
    target = cache_dir() / f"lib{stem}-{_fingerprint(argv, files)[:16]}{_suffix()}"
    if rebuild or not target.is_file():
        try:
            target.parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            root = os.environ.get("PUSHTRAIN_CACHE")
            where = f"PUSHTRAIN_CACHE = {root!r}: " if root else ""
            raise NativeCacheError(f"{where}cache folder {str(target.parent)!r} cannot be "
                                   f"created: {exc.strerror or exc}; allowed: PUSHTRAIN_CACHE "
                                   "naming a folder (made if missing) where files can be "
                                   "written") from exc
        log.info("compiling %s into %s", stem, target)
        _compile(argv, target, files)
    return target


def load_library(stem: str, files: dict, rebuild: bool = False, declare=None) -> ctypes.CDLL:
    """The library ``stem`` compiled from ``files`` (``{name: resource}``; a room's own C with
    the engine's, :func:`engine_files`), built and cached like the engine's, loaded once per
    process and setting of ``CC`` and ``PUSHTRAIN_CACHE``. ``declare(lib, path)``, if given,
    declares its prototypes (and may check it) once, when it is first loaded; otherwise the
    caller declares them.

    Raises
    ------
    NativeBuildError
        As :func:`library_path`, if the library cannot be loaded, or from ``declare``.
    """
    key = (stem, os.environ.get("CC"), os.environ.get("PUSHTRAIN_CACHE"))
    if not rebuild and key in _by_setting:
        return _by_setting[key]
    with _lock:
        path = library_path(rebuild, stem, files)
        lib = _loaded.get(path)
        if lib is None:
            try:
                lib = ctypes.CDLL(str(path))
            except OSError as exc:
                raise NativeBuildError(f"cannot load {str(path)!r}: {exc}") from exc
            if declare is not None:
                declare(lib, path)
            _loaded[path] = lib
        _by_setting[key] = lib
        return lib


def load(rebuild: bool = False) -> ctypes.CDLL:
    """The control-law library (built and cached on first use), prototypes declared.

    Loaded once per process for each setting of ``CC`` and ``PUSHTRAIN_CACHE``; ``rebuild``
    compiles again.

    Raises
    ------
    NativeBuildError
        As :func:`library_path`, or if the library's struct layouts differ from this binding.
    """
    return load_library(ENGINE_STEM, None, rebuild, declare=_declare_engine)


def _declare_engine(lib: ctypes.CDLL, path: Path) -> None:
    """Declare the engine library's prototypes and check its struct sizes against this
    binding's."""
    for name, (restype, argtypes) in _PROTOTYPES.items():
        function = getattr(lib, name)
        function.restype, function.argtypes = restype, argtypes
    sizes = [(lib.pt_sizeof, w, st) for w, st in enumerate(_STRUCTS)]
    sizes += [(lib.pt_rollout_sizeof, w, st) for w, st in enumerate(_ROLLOUT_STRUCTS)]
    sizes.append((lambda _: lib.pt_sensors_sizeof(), 0, PtSensors))
    sizes.append((lambda _: lib.pt_step_sizeof(), 0, PtStep))
    sizes.append((lambda _: lib.pt_governor_sizeof(), 0, PtGovernor))
    sizes += [(lib.pt_profile_sizeof, w, st) for w, st in enumerate((PtProfile, PtProfilePiece))]
    for sizeof, which, struct in sizes:
        size = sizeof(which)
        if size != ctypes.sizeof(struct):
            raise NativeBuildError(
                f"{struct.__name__} is {size} bytes in {str(path)!r} but "
                f"{ctypes.sizeof(struct)} in core/native.py: the binding does not match "
                "its header in core/csrc")


def dptr(array) -> D_PTR:
    """A ``double*`` to a C-contiguous float64 numpy array (kept alive by the caller)."""
    return array.ctypes.data_as(D_PTR)
