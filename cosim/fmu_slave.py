"""A thin, fast wrapper around fmpy's ``FMU2Slave`` or ``FMU3Slave`` for the TrailerTrain FMU.

One wrapper, two thin backends: the FMI 2.0 FMU (one build per n) has a scalar per element,
``x[2]``; the FMI 3.0 FMU (one build for every n) has array variables, ``x`` holding x[0] .. x[n],
and its n is set before initialization. Callers use the contract's element names (``x[2]``,
``slide[1]``) with either; the wrapper maps them onto value references looked up by name from
the model description. Per-step calls go straight to the FMU's C functions (bare ctypes, no fmpy
wrapper, no argument conversion) with preallocated value-reference and value arrays, and can
write into a caller's array (the recorder's row); fmpy loads, extracts and reads the model
description, once per FMU file and process. FMU log messages go to :mod:`logging` and the last
ones are kept for error messages.
"""

from __future__ import annotations

import atexit
import ctypes
import logging
import re
import shutil
import tempfile
import threading
from collections import deque
from pathlib import Path
from typing import NamedTuple

import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException

from pushtrain.errors import CosimError, CosimInputError
from pushtrain.fmu.variables import ARRAYS, MAX_TRAILERS

__all__ = ["TrailerTrainSlave"]

log = logging.getLogger(__name__)
_STATUS = ["OK", "WARNING", "DISCARD", "ERROR", "FATAL", "PENDING"]
_WARNING = 1  # a status above fmi2Warning / fmi3Warning is a failure (as fmpy treats it)
_ELEMENT = re.compile(r"(\w+)\[(\d+)\]")
_BLOCKS = {block.name: block for block in ARRAYS}  # first body index and length of each array


class _FmuLog:
    """Receives the FMU's log messages: forwards them to logging and keeps the last few."""

    def __init__(self, name: str):
        self.name = name
        self.recent: deque[str] = deque(maxlen=20)

    def record(self, status: int, message) -> None:
        text = message.decode("utf-8", "replace") if isinstance(message, bytes) else str(message)
        label = _STATUS[status] if 0 <= status < len(_STATUS) else str(status)
        self.recent.append(f"[{label}] {text}")
        level = logging.ERROR if status >= 3 else logging.WARNING if status == 1 else logging.DEBUG
        log.log(level, "FMU %s: %s", self.name, text)


class _Unpacked(NamedTuple):
    """An FMU file read and extracted once per process: its model description, its variables
    by name, the type of each value reference, the folder it is extracted to."""

    md: object
    variables: dict
    types: dict
    folder: str


_UNPACKED: dict[tuple, _Unpacked] = {}
_UNPACKED_LOCK = threading.Lock()


def _unpacked(path: Path) -> _Unpacked:
    """``path`` read (fmpy's model-description reader) and extracted (fmpy's ``extract``), or the
    copy this process already has of the same file (same path, size and modification time).

    Reading the XML costs about 0.1 s at n = 50 and extracting several ms, per run of a sweep;
    several instances may load the one extracted library (the FMU keeps no global state).
    The folders are removed when the process exits."""
    stat = path.stat()
    key = (str(path.resolve()), stat.st_size, stat.st_mtime_ns)
    with _UNPACKED_LOCK:
        found = _UNPACKED.get(key)
        if found is not None and Path(found.folder).is_dir():
            return found
        md = read_model_description(str(path))
        folder = tempfile.mkdtemp(prefix="pushtrain-fmu-")
        if not _UNPACKED:
            atexit.register(_remove_unpacked)
        try:
            extract(str(path), folder)
        except Exception:
            shutil.rmtree(folder, ignore_errors=True)
            raise
        variables = {v.name: v for v in md.modelVariables}
        types = {v.valueReference: v.type for v in md.modelVariables}
        _UNPACKED[key] = found = _Unpacked(md, variables, types, folder)
        return found


def _remove_unpacked() -> None:
    """Remove the folders of :func:`_unpacked` (at exit)."""
    with _UNPACKED_LOCK:
        for unpacked in _UNPACKED.values():
            shutil.rmtree(unpacked.folder, ignore_errors=True)
        _UNPACKED.clear()


class _Fmi2:
    """FMI 2.0 backend: every name is a scalar variable with one value."""

    def __init__(self, md, unzipdir: str, instance_name: str, fmu_log: _FmuLog):
        from fmpy import calloc, free
        from fmpy.fmi2 import (
            FMU2Slave,
            fmi2CallbackAllocateMemoryTYPE,
            fmi2CallbackFreeMemoryTYPE,
            fmi2CallbackFunctions,
            fmi2CallbackLoggerTYPE,
        )
        from fmpy.logging import addLoggerProxy

        self.slave = FMU2Slave(guid=md.guid, unzipDirectory=unzipdir,
                               modelIdentifier=md.coSimulation.modelIdentifier,
                               instanceName=instance_name)
        self.callbacks = fmi2CallbackFunctions()
        self.callbacks.logger = fmi2CallbackLoggerTYPE(
            lambda env, name, status, category, message: fmu_log.record(status, message))
        self.callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        self.callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        addLoggerProxy(ctypes.byref(self.callbacks))
        self.real_type, self.bool_type = ctypes.c_double, ctypes.c_int  # fmi2Real, fmi2Boolean
        self.vr_type = ctypes.c_uint
        self.get_real, self.set_real = "fmi2GetReal", "fmi2SetReal"
        self.get_bool, self.do_step = "fmi2GetBoolean", "fmi2DoStep"
        self.step_tail = (1,)  # noSetFMUStatePriorToCurrentPoint
        self.step_types = (ctypes.c_int,)

    def instantiate(self, n: int) -> None:
        self.slave.instantiate(callbacks=self.callbacks, loggingOn=False)

    def enter_initialization(self, t0: float) -> None:
        self.slave.setupExperiment(startTime=t0)
        self.slave.enterInitializationMode()

    def set(self, kind: str, refs: list[int], values: list) -> None:
        {"Real": self.slave.setReal, "Integer": self.slave.setInteger,
         "Boolean": self.slave.setBoolean}[kind](refs, values)

    def arguments(self, refs, nvr: int, buffer, count: int) -> tuple:
        """The arguments of an fmi2 get/set call (no nValues)."""
        return (ctypes.c_void_p(self.slave.component), refs, ctypes.c_size_t(nvr), buffer)

    def get_reals(self, refs: list[int], count: int) -> list[float]:
        return self.slave.getReal(refs)


class _Fmi3:
    """FMI 3.0 backend: arrays are one variable; n is set in Configuration Mode."""

    def __init__(self, md, unzipdir: str, instance_name: str, fmu_log: _FmuLog):
        from fmpy.fmi3 import FMU3Slave

        self.slave = FMU3Slave(guid=md.guid, unzipDirectory=unzipdir,
                               modelIdentifier=md.coSimulation.modelIdentifier,
                               instanceName=instance_name)
        self.log_message = lambda env, status, category, message: fmu_log.record(status, message)
        self.n_ref = next(v.valueReference for v in md.modelVariables if v.name == "n")
        self.real_type, self.bool_type = ctypes.c_double, ctypes.c_bool  # fmi3Float64, Boolean
        self.vr_type = ctypes.c_uint32
        self.get_real, self.set_real = "fmi3GetFloat64", "fmi3SetFloat64"
        self.get_bool, self.do_step = "fmi3GetBoolean", "fmi3DoStep"
        # noSetFMUStatePriorToCurrentPoint, then eventHandlingNeeded, terminateSimulation,
        # earlyReturn and lastSuccessfulTime (outputs the TrailerTrain FMU sets but never needs)
        self._step_out = [ctypes.c_bool(), ctypes.c_bool(), ctypes.c_bool(), ctypes.c_double()]
        self.step_tail = (True, *(ctypes.byref(value) for value in self._step_out))
        self.step_types = (ctypes.c_bool,
                           *(ctypes.POINTER(type(value)) for value in self._step_out))

    def instantiate(self, n: int) -> None:
        self.slave.instantiate(loggingOn=False, logMessage=self.log_message)
        self.slave.enterConfigurationMode()
        self.slave.setUInt64([self.n_ref], [n])
        self.slave.exitConfigurationMode()

    def enter_initialization(self, t0: float) -> None:
        self.slave.enterInitializationMode(startTime=t0)

    def set(self, kind: str, refs: list[int], values: list) -> None:
        {"Float64": self.slave.setFloat64, "Int32": self.slave.setInt32,
         "Boolean": self.slave.setBoolean, "UInt64": self.slave.setUInt64}[kind](refs, values)

    def arguments(self, refs, nvr: int, buffer, count: int) -> tuple:
        """The arguments of an fmi3 get/set call."""
        return (ctypes.c_void_p(self.slave.component), refs, ctypes.c_size_t(nvr), buffer,
                ctypes.c_size_t(count))

    def get_reals(self, refs: list[int], count: int) -> list[float]:
        return self.slave.getFloat64(refs, nValues=count)


class _Plan:
    """How to move the values of ``names`` in one call: the distinct value references (in order
    of first use) with the position and number of their values, and where each name's value is.
    """

    def __init__(self, slave: "TrailerTrainSlave", names):
        self.refs: list[int] = []
        self.spans: list[tuple[int, int, int]] = []  # (ref, start, size)
        self.index: list[int] = []
        starts: dict[int, int] = {}
        self.count = 0
        for name in names:
            ref, offset, size = slave._locate(name)
            if ref not in starts:
                starts[ref] = self.count
                self.refs.append(ref)
                self.spans.append((ref, self.count, size))
                self.count += size
            self.index.append(starts[ref] + offset)
        self.identity = self.index == list(range(self.count))  # FMI 2.0: no gather needed


class TrailerTrainSlave:
    """One instance of a TrailerTrain FMU (FMI 2.0 or 3.0), ready to step.

    Parameters
    ----------
    fmu_path : path-like
        The ``.fmu`` file.
    instance_name : str
        Name passed to the FMU's instantiate function.
    n_trailers : int, optional
        FMI 3.0: the number of trailers to configure (default: the FMU's start value of ``n``).
        FMI 2.0: ignored; the build fixed n (compare :attr:`n`).
    """

    def __init__(self, fmu_path, instance_name: str = "train", n_trailers: int | None = None):
        self.fmu_path = Path(fmu_path)
        if not self.fmu_path.is_file():
            raise CosimInputError(f"FMU file {str(self.fmu_path)!r} does not exist")
        unpacked = _unpacked(self.fmu_path)
        self.md, self._vars, self._types = unpacked.md, unpacked.variables, unpacked.types
        if self.md.coSimulation is None:
            raise CosimInputError(f"{self.fmu_path} has no Co-Simulation interface")
        n_var = self._vars.get("n")
        if n_var is None:
            raise CosimInputError(f"{self.fmu_path} is not a TrailerTrain FMU (no variable 'n')")
        self.fmi_version = int(self.md.fmiVersion.split(".")[0])
        self.n = int(n_var.start)
        if self.fmi_version == 3 and n_trailers is not None:
            if isinstance(n_trailers, bool) or not (isinstance(n_trailers, int)
                                                    and 1 <= n_trailers <= MAX_TRAILERS):
                raise CosimInputError(f"n_trailers = {n_trailers!r}: this FMU takes n from 1 "
                                      f"to {MAX_TRAILERS}")
            self.n = n_trailers
        self.vr = {name: var.valueReference for name, var in self._vars.items()}
        self._unzipdir = unpacked.folder
        self._log = _FmuLog(instance_name)
        backend = {2: _Fmi2, 3: _Fmi3}.get(self.fmi_version)
        if backend is None:
            raise CosimInputError(f"{self.fmu_path}: FMI {self.md.fmiVersion}; allowed are 2.0 "
                                  "and 3.0")
        self._fmu = backend(self.md, self._unzipdir, instance_name, self._log)
        self.slave = self._fmu.slave
        self._inputs: dict[int, np.ndarray] = {}  # FMI 3.0 input arrays as last set
        self._instantiated = False
        self._step = None
        self.time = 0.0

    # -------------------------------------------------------------- names
    def names(self, base: str, first: int, last: int) -> list[str]:
        """``[f"{base}[{i}]" for i in first..last]``."""
        return [f"{base}[{i}]" for i in range(first, last + 1)]

    def _size(self, var) -> int:
        """Number of values of variable ``var`` at this instance's n."""
        return _BLOCKS[var.name].count(self.n) if var.dimensions else 1

    def _locate(self, name: str) -> tuple[int, int, int]:
        """(value reference, offset of the value, values of that reference) of ``name``."""
        var = self._vars.get(name)
        if var is not None and not var.dimensions:
            return var.valueReference, 0, 1
        match = _ELEMENT.fullmatch(name)
        var = self._vars.get(match.group(1)) if match and self.fmi_version == 3 else None
        if var is not None and var.dimensions:
            offset = int(match.group(2)) - _BLOCKS[var.name].first
            if 0 <= offset < self._size(var):
                return var.valueReference, offset, self._size(var)
        raise CosimError(f"FMU {self.fmu_path.name} (n = {self.n}) has no variable {name!r}")

    def _refs(self, names) -> list[int]:
        return [self._locate(name)[0] for name in names]

    def _type(self, name: str) -> str:
        """The FMI type of the variable that holds ``name``."""
        return self._types[self._locate(name)[0]]

    # -------------------------------------------------------------- set-up
    def start(self, start_values: dict, t0: float = 0.0) -> None:
        """Instantiate (FMI 3.0: with n trailers), set parameters and start values, and
        initialize at ``t0`` [s]."""
        try:
            self._fmu.instantiate(self.n)
            self._instantiated = True
            self._component = ctypes.c_void_p(self.slave.component)
            name = self._fmu.do_step
            address = ctypes.cast(getattr(self.slave.dll, name), ctypes.c_void_p).value
            self._step = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_double,
                                          ctypes.c_double, *self._fmu.step_types)(address)
            self._set_values(start_values)
            self._fmu.enter_initialization(t0)
            self.slave.exitInitializationMode()
        except FMICallException as exc:
            raise CosimError(f"FMU initialization failed: {self.last_messages() or exc}") from exc
        self.time = t0

    def _set_values(self, values: dict) -> None:
        groups: dict[str, dict[str, object]] = {}
        for name, value in values.items():
            groups.setdefault(self._type(name), {})[name] = value
        for kind, group in groups.items():
            convert = {"Boolean": bool, "Integer": int, "Int32": int,
                       "UInt64": int}.get(kind, float)
            given = [convert(v) for v in group.values()]
            plan = _Plan(self, group)
            if plan.identity:
                self._fmu.set(kind, plan.refs, given)
                continue
            # FMI 3.0 arrays are set whole: the elements not given keep their current values
            current = np.array(self._fmu.get_reals(plan.refs, plan.count))
            current[plan.index] = given
            self._fmu.set(kind, plan.refs, [float(v) for v in current])

    def last_messages(self) -> str:
        """The FMU's last log messages, one per line."""
        return "\n".join(self._log.recent)

    def _why(self, status: int) -> str:
        """The FMU's last messages, or the status of a failed call that logged none."""
        label = _STATUS[status] if 0 <= status < len(_STATUS) else str(status)
        return self.last_messages() or f"status {label}"

    # -------------------------------------------------------------- fast per-step access
    def _function(self, name: str):
        """The FMU's C function ``name`` as a bare ctypes function returning its status: called
        with ready ctypes arguments, no conversion and no fmpy wrapper in between."""
        address = ctypes.cast(getattr(self.slave.dll, name), ctypes.c_void_p).value
        return ctypes.CFUNCTYPE(ctypes.c_int)(address)

    def _buffers(self, plan: _Plan, value_type):
        refs = (self._fmu.vr_type * len(plan.refs))(*plan.refs)
        buffer = (value_type * max(plan.count, 1))()
        return refs, buffer, np.ctypeslib.as_array(buffer)[: plan.count]

    def real_reader(self, names, out: np.ndarray | None = None):
        """A function returning the current values of ``names`` as a (reused) numpy array.

        With ``out`` (a float64 array of len(names)) the values land there and ``out`` is
        returned; for FMI 2.0 and a C-contiguous ``out`` the FMU writes into it directly."""
        return self._reader(names, self._fmu.real_type, self._function(self._fmu.get_real), out)

    def bool_reader(self, names, out: np.ndarray | None = None):
        """A function returning the current values of the Booleans ``names`` as a (reused)
        numpy array (0/1 for FMI 2.0's fmi2Boolean, bools for FMI 3.0), or copied into ``out``
        (cast to its dtype) and ``out`` returned."""
        return self._reader(names, self._fmu.bool_type, self._function(self._fmu.get_bool), out)

    def _reader(self, names, ctype, call, out=None):
        """One ``call`` of the FMU's getter (fmi2GetReal, fmi3GetFloat64, ...) per read into a
        preallocated buffer; for FMI 3.0 arrays, then one gather of the named elements."""
        plan = _Plan(self, names)
        refs, buffer, values = self._buffers(plan, ctype)
        if out is not None and out.shape != (len(plan.index),):
            raise CosimInputError(f"out has shape {out.shape}; {len(plan.index)} names to read")
        direct = (out is not None and plan.identity and out.dtype == values.dtype
                  and out.flags.c_contiguous and out.flags.writeable)
        if direct:  # the FMU writes straight into ``out``
            buffer = (ctype * len(out)).from_buffer(out)
        args = self._fmu.arguments(refs, len(plan.refs), buffer, plan.count)
        index = np.array(plan.index)
        result = out
        if out is None:
            result = values if plan.identity else np.empty(len(index), dtype=values.dtype)
        if direct or (out is None and plan.identity):
            finish = None  # the values are where they are returned
        elif plan.identity:
            def finish():
                result[...] = values
        elif result.dtype == values.dtype:
            def finish():
                np.take(values, index, out=result)
        else:
            def finish():
                np.copyto(result, values[index], casting="unsafe")

        def read() -> np.ndarray:
            status = call(*args)
            if status > _WARNING:
                raise self.read_error(names, status)
            if finish is not None:
                finish()
            return result

        return read

    def real_writer(self, names):
        """A function ``write(values)`` setting ``names`` (in order) from a sequence of floats.

        FMI 3.0 sets whole arrays: the elements not named keep the values last set through any
        writer of this instance."""
        plan = _Plan(self, names)
        refs, buffer, values = self._buffers(plan, self._fmu.real_type)
        set_real = self._function(self._fmu.set_real)
        args = self._fmu.arguments(refs, len(plan.refs), buffer, plan.count)
        index = np.array(plan.index)
        spans = [(self._last_set(ref, size), start, size) for ref, start, size in plan.spans]

        def write(new_values) -> None:
            if plan.identity:
                buffer[:] = new_values  # ctypes: no numpy call per step
            else:
                for last, start, size in spans:
                    values[start:start + size] = last
                values[index] = new_values
            status = set_real(*args)
            if status > _WARNING:
                raise self.write_error(names, new_values, status)
            if not plan.identity:
                for last, start, size in spans:
                    last[:] = values[start:start + size]

        return write

    def _last_set(self, ref: int, size: int) -> np.ndarray:
        """The values last set of the input with value reference ``ref`` (shared by writers)."""
        if ref not in self._inputs:
            self._inputs[ref] = np.array(self._fmu.get_reals([ref], size), dtype=float)
        return self._inputs[ref]

    def get_reals(self, names) -> np.ndarray:
        """The current values of the Reals ``names`` (a new array; for set-up, not per step)."""
        return np.array(self.real_reader(names)(), dtype=float)

    def do_step(self, t: float, h: float) -> None:
        """One communication step from ``t`` to ``t + h`` [s]; raises CosimError on failure."""
        status = self._step(self._component, t, h, *self._fmu.step_tail)
        if status > _WARNING:
            raise self.step_error(t, h, status)
        self.time = t + h

    # -------------------------------------------------------------- errors of per-step calls
    def read_error(self, names, status: int) -> CosimError:
        """The error of a failed read of ``names`` with FMI status ``status``."""
        return CosimError(f"reading {names[0]} .. {names[-1]} failed at "
                          f"t = {self.time:.6f} s: {self._why(status)}")

    def write_error(self, names, values, status: int) -> CosimError:
        """The error of a failed write of ``values`` to ``names``."""
        return CosimError(f"setting {list(names)} = {list(values)} failed at "
                          f"t = {self.time:.6f} s: {self._why(status)}")

    def step_error(self, t: float, h: float, status: int) -> CosimError:
        """The error of a failed doStep from ``t`` over ``h`` [s]."""
        return CosimError(f"fmi{self.fmi_version}DoStep failed at t = {t:.6f} s (h = {h} s): "
                          f"{self._why(status)}")

    def fmi_functions(self) -> dict[str, int]:
        """Addresses of this instance's per-step FMI functions (for compiled code that calls
        them): ``"get_real"``, ``"set_real"``, ``"get_boolean"``, ``"do_step"`` (fmi2GetReal ..
        fmi2DoStep, or fmi3GetFloat64 .. fmi3DoStep) and ``"component"`` (the instance); after
        :meth:`start`."""
        if not self._instantiated:
            raise CosimError("fmi_functions: needs a started instance")
        fmu = self._fmu
        out = {role: ctypes.cast(getattr(self.slave.dll, name), ctypes.c_void_p).value
               for role, name in (("get_real", fmu.get_real), ("set_real", fmu.set_real),
                                  ("get_boolean", fmu.get_bool), ("do_step", fmu.do_step))}
        out["component"] = self.slave.component
        return out

    def read_plan(self, names) -> tuple[list[int], int, list[int] | None]:
        """How one call reads ``names``: the value references, the number of values they hold,
        and where each name's value is among them (None: in order, one value per reference)."""
        plan = _Plan(self, names)
        return plan.refs, plan.count, None if plan.identity else plan.index

    # -------------------------------------------------------------- life cycle
    def close(self) -> None:
        """Terminate and free the instance (the extracted files stay for the next instance of
        this FMU in the process; they are removed when it exits)."""
        if self._instantiated:
            try:
                self.slave.terminate()
            except FMICallException:
                pass
            self.slave.freeInstance()
            self._instantiated = False

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
