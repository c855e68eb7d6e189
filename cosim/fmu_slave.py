"""A thin, fast wrapper around fmpy's ``FMU2Slave`` or ``FMU3Slave`` for the TrailerTrain FMU.

One wrapper, two thin backends: the FMI 2.0 FMU (one build per n) has a scalar per element,
``x[2]``; the FMI 3.0 FMU (one build for every n) has array variables, ``x`` holding x[0] .. x[n],
and its n is set before initialization. Callers use the contract's element names (``x[2]``,
``slide[1]``) with either; the wrapper maps them onto value references looked up by name from
the model description. Per-step calls use preallocated ctypes arrays viewed as numpy arrays, so
stepping costs a few microseconds. FMU log messages go to :mod:`logging` and the last ones are
kept for error messages.
"""

from __future__ import annotations

import ctypes
import logging
import re
import shutil
import tempfile
from collections import deque
from pathlib import Path

import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException

from pushtrain.errors import CosimError, CosimInputError
from pushtrain.fmu.variables import ARRAYS, MAX_TRAILERS

__all__ = ["CosimError", "TrailerTrainSlave"]

log = logging.getLogger(__name__)
_STATUS = ["OK", "WARNING", "DISCARD", "ERROR", "FATAL", "PENDING"]
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
        self.get_real, self.set_real = self.slave.fmi2GetReal, self.slave.fmi2SetReal
        self.get_bool = self.slave.fmi2GetBoolean

    def instantiate(self, n: int) -> None:
        self.slave.instantiate(callbacks=self.callbacks, loggingOn=False)

    def enter_initialization(self, t0: float) -> None:
        self.slave.setupExperiment(startTime=t0)
        self.slave.enterInitializationMode()

    def set(self, kind: str, refs: list[int], values: list) -> None:
        {"Real": self.slave.setReal, "Integer": self.slave.setInteger,
         "Boolean": self.slave.setBoolean}[kind](refs, values)

    def bind(self, function):
        """``call(refs, nvr, buffer, count)`` of an fmi2 get/set function (no nValues)."""
        component = self.slave.component
        return lambda refs, nvr, buffer, count: function(component, refs, nvr, buffer)

    def get_reals(self, refs: list[int], count: int) -> list[float]:
        return self.slave.getReal(refs)

    def do_step_call(self):
        step, component = self.slave.fmi2DoStep, self.slave.component
        return lambda t, h: step(component, t, h, 1)


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
        self.get_real, self.set_real = self.slave.fmi3GetFloat64, self.slave.fmi3SetFloat64
        self.get_bool = self.slave.fmi3GetBoolean
        self._step_out = [ctypes.c_bool(), ctypes.c_bool(), ctypes.c_bool(), ctypes.c_double()]

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

    def bind(self, function):
        """``call(refs, nvr, buffer, count)`` of an fmi3 get/set function."""
        component = self.slave.component
        return lambda refs, nvr, buffer, count: function(component, refs, nvr, buffer, count)

    def get_reals(self, refs: list[int], count: int) -> list[float]:
        return self.slave.getFloat64(refs, nValues=count)

    def do_step_call(self):
        step, component = self.slave.fmi3DoStep, self.slave.component
        out = [ctypes.byref(value) for value in self._step_out]
        return lambda t, h: step(component, t, h, True, *out)


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
        self.md = read_model_description(str(self.fmu_path))
        if self.md.coSimulation is None:
            raise CosimInputError(f"{self.fmu_path} has no Co-Simulation interface")
        self._vars = {v.name: v for v in self.md.modelVariables}
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
        self._unzipdir = tempfile.mkdtemp(prefix="pushtrain-fmu-")
        extract(str(self.fmu_path), self._unzipdir)
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
        ref = self._locate(name)[0]
        return next(v.type for v in self.md.modelVariables if v.valueReference == ref)

    # -------------------------------------------------------------- set-up
    def start(self, start_values: dict, t0: float = 0.0) -> None:
        """Instantiate (FMI 3.0: with n trailers), set parameters and start values, and
        initialize at ``t0`` [s]."""
        try:
            self._fmu.instantiate(self.n)
            self._instantiated = True
            self._step = self._fmu.do_step_call()
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

    # -------------------------------------------------------------- fast per-step access
    def _buffers(self, plan: _Plan, value_type):
        refs = (self._fmu.vr_type * len(plan.refs))(*plan.refs)
        buffer = (value_type * max(plan.count, 1))()
        return refs, buffer, np.ctypeslib.as_array(buffer)[: plan.count]

    def real_reader(self, names):
        """A function returning the current values of ``names`` as a (reused) numpy array."""
        return self._reader(names, self._fmu.real_type, self._fmu.get_real)

    def bool_reader(self, names):
        """A function returning the current values of the Booleans ``names`` as a (reused)
        numpy array (0/1 for FMI 2.0's fmi2Boolean, bools for FMI 3.0)."""
        return self._reader(names, self._fmu.bool_type, self._fmu.get_bool)

    def _reader(self, names, ctype, get):
        """One call of ``get`` (fmi2GetReal, fmi3GetFloat64, ...) per read into a preallocated
        buffer; for FMI 3.0 arrays, then one gather of the named elements."""
        plan = _Plan(self, names)
        refs, buffer, values = self._buffers(plan, ctype)
        call, nvr, count = self._fmu.bind(get), len(plan.refs), plan.count
        index, out = np.array(plan.index), np.empty(len(plan.index), dtype=values.dtype)

        def read() -> np.ndarray:
            try:
                call(refs, nvr, buffer, count)
            except FMICallException as exc:
                raise CosimError(
                    f"reading {names[0]} .. {names[-1]} failed at t = {self.time:.6f} s: "
                    f"{self.last_messages() or exc}"
                ) from exc
            return values if plan.identity else np.take(values, index, out=out)

        return read

    def real_writer(self, names):
        """A function ``write(values)`` setting ``names`` (in order) from a sequence of floats.

        FMI 3.0 sets whole arrays: the elements not named keep the values last set through any
        writer of this instance."""
        plan = _Plan(self, names)
        refs, buffer, values = self._buffers(plan, self._fmu.real_type)
        set_, nvr, count = self._fmu.bind(self._fmu.set_real), len(plan.refs), plan.count
        index = np.array(plan.index)
        spans = [(self._last_set(ref, size), start, size) for ref, start, size in plan.spans]

        def write(new_values) -> None:
            if plan.identity:
                values[:] = new_values
            else:
                for last, start, size in spans:
                    values[start:start + size] = last
                values[index] = new_values
            try:
                set_(refs, nvr, buffer, count)
            except FMICallException as exc:
                raise CosimError(
                    f"setting {list(names)} = {list(new_values)} failed at t = {self.time:.6f} s: "
                    f"{self.last_messages() or exc}"
                ) from exc
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
        try:
            self._step(t, h)
        except FMICallException as exc:
            raise CosimError(
                f"fmi{self.fmi_version}DoStep failed at t = {t:.6f} s (h = {h} s): "
                f"{self.last_messages() or exc}"
            ) from exc
        self.time = t + h

    # -------------------------------------------------------------- life cycle
    def close(self) -> None:
        """Terminate, free the instance and remove the extracted files."""
        if self._instantiated:
            try:
                self.slave.terminate()
            except FMICallException:
                pass
            self.slave.freeInstance()
            self._instantiated = False
        shutil.rmtree(self._unzipdir, ignore_errors=True)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
