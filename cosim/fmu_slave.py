"""A thin, fast wrapper around fmpy's ``FMU2Slave`` for the TrailerTrain FMU.

Value references are looked up by name from the model description; per-step calls use
preallocated ctypes arrays viewed as numpy arrays, so stepping costs a few microseconds. FMU log
messages go to :mod:`logging` and the last ones are kept for error messages.
"""

from __future__ import annotations

import ctypes
import logging
import shutil
import tempfile
from collections import deque
from pathlib import Path

import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import (
    FMU2Slave,
    fmi2CallbackAllocateMemoryTYPE,
    fmi2CallbackFreeMemoryTYPE,
    fmi2CallbackFunctions,
    fmi2Boolean,
    fmi2CallbackLoggerTYPE,
    fmi2Real,
    fmi2ValueReference,
)

from pushtrain.errors import CosimError, CosimInputError

__all__ = ["CosimError", "TrailerTrainSlave"]

log = logging.getLogger(__name__)
_STATUS = ["OK", "WARNING", "DISCARD", "ERROR", "FATAL", "PENDING"]


class _FmuLog:
    """Receives the FMU's log messages: forwards them to logging and keeps the last few."""

    def __init__(self, name: str):
        self.name = name
        self.recent: deque[str] = deque(maxlen=20)
        self.callbacks = fmi2CallbackFunctions()
        self.callbacks.logger = fmi2CallbackLoggerTYPE(self._log)
        libc = ctypes.CDLL(None)
        libc.calloc.restype = ctypes.c_void_p
        libc.calloc.argtypes = [ctypes.c_size_t, ctypes.c_size_t]
        libc.free.argtypes = [ctypes.c_void_p]
        self._calloc = libc.calloc
        self._free = libc.free
        self.callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(self._calloc)
        self.callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(self._free)
        from fmpy.logging import addLoggerProxy

        addLoggerProxy(ctypes.byref(self.callbacks))

    def _log(self, env, instance_name, status, category, message):
        text = message.decode("utf-8", "replace") if isinstance(message, bytes) else str(message)
        label = _STATUS[status] if 0 <= status < len(_STATUS) else str(status)
        self.recent.append(f"[{label}] {text}")
        level = logging.ERROR if status >= 3 else logging.WARNING if status == 1 else logging.DEBUG
        log.log(level, "FMU %s: %s", self.name, text)


class TrailerTrainSlave:
    """One instance of a TrailerTrain FMU, ready to step.

    Parameters
    ----------
    fmu_path : path-like
        The ``.fmu`` file.
    instance_name : str
        Name passed to ``fmi2Instantiate``.
    """

    def __init__(self, fmu_path, instance_name: str = "train"):
        self.fmu_path = Path(fmu_path)
        if not self.fmu_path.is_file():
            raise CosimInputError(f"FMU file {str(self.fmu_path)!r} does not exist")
        self.md = read_model_description(str(self.fmu_path))
        if self.md.coSimulation is None:
            raise CosimInputError(f"{self.fmu_path} has no Co-Simulation interface")
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self._types = {v.name: v.type for v in self.md.modelVariables}
        n_var = next((v for v in self.md.modelVariables if v.name == "n"), None)
        if n_var is None:
            raise CosimInputError(f"{self.fmu_path} is not a TrailerTrain FMU (no variable 'n')")
        self.n = int(n_var.start)
        self._unzipdir = tempfile.mkdtemp(prefix="pushtrain-fmu-")
        extract(str(self.fmu_path), self._unzipdir)
        self._log = _FmuLog(instance_name)
        self.slave = FMU2Slave(
            guid=self.md.guid,
            unzipDirectory=self._unzipdir,
            modelIdentifier=self.md.coSimulation.modelIdentifier,
            instanceName=instance_name,
        )
        self._instantiated = False
        self.time = 0.0

    # -------------------------------------------------------------- set-up
    def names(self, base: str, first: int, last: int) -> list[str]:
        """``[f"{base}[{i}]" for i in first..last]``."""
        return [f"{base}[{i}]" for i in range(first, last + 1)]

    def _refs(self, names) -> list[int]:
        missing = [name for name in names if name not in self.vr]
        if missing:
            raise CosimError(
                f"FMU {self.fmu_path.name} (n = {self.n}) has no variable(s) {missing}"
            )
        return [self.vr[name] for name in names]

    def start(self, start_values: dict, t0: float = 0.0) -> None:
        """Instantiate, set parameters and start values, and initialize at ``t0`` [s]."""
        try:
            self.slave.instantiate(callbacks=self._log.callbacks, loggingOn=False)
            self._instantiated = True
            self.slave.setupExperiment(startTime=t0)
            self._set_values(start_values)
            self.slave.enterInitializationMode()
            self.slave.exitInitializationMode()
        except FMICallException as exc:
            raise CosimError(f"FMU initialization failed: {self.last_messages() or exc}") from exc
        self.time = t0

    def _set_values(self, values: dict) -> None:
        reals, ints, bools = {}, {}, {}
        for name, value in values.items():
            kind = self._types.get(name)
            if kind is None:
                raise CosimError(
                    f"FMU {self.fmu_path.name} (n = {self.n}) has no variable {name!r}"
                )
            {"Real": reals, "Integer": ints, "Boolean": bools}[kind][name] = value
        if reals:
            self.slave.setReal(self._refs(reals), [float(v) for v in reals.values()])
        if ints:
            self.slave.setInteger(self._refs(ints), [int(v) for v in ints.values()])
        if bools:
            self.slave.setBoolean(self._refs(bools), [bool(v) for v in bools.values()])

    def last_messages(self) -> str:
        """The FMU's last log messages, one per line."""
        return "\n".join(self._log.recent)

    # -------------------------------------------------------------- fast per-step access
    def real_reader(self, names):
        """A function returning the current values of ``names`` as a (reused) numpy array."""
        return self._reader(names, fmi2Real, self.slave.fmi2GetReal)

    def bool_reader(self, names):
        """A function returning the current values of the Booleans ``names`` as a (reused)
        numpy array of 0/1 (fmi2Boolean)."""
        return self._reader(names, fmi2Boolean, self.slave.fmi2GetBoolean)

    def _reader(self, names, ctype, get):
        refs = (fmi2ValueReference * len(names))(*self._refs(names))
        buffer = (ctype * len(names))()
        view = np.ctypeslib.as_array(buffer)
        component = self.slave.component
        count = len(names)

        def read() -> np.ndarray:
            try:
                get(component, refs, count, buffer)
            except FMICallException as exc:
                raise CosimError(
                    f"reading {names[0]} .. {names[-1]} failed at t = {self.time:.6f} s: "
                    f"{self.last_messages() or exc}"
                ) from exc
            return view

        return read

    def real_writer(self, names):
        """A function ``write(values)`` setting ``names`` (in order) from a sequence of floats."""
        refs = (fmi2ValueReference * len(names))(*self._refs(names))
        buffer = (fmi2Real * len(names))()
        view = np.ctypeslib.as_array(buffer)
        set_ = self.slave.fmi2SetReal
        component = self.slave.component
        count = len(names)

        def write(values) -> None:
            view[:] = values
            try:
                set_(component, refs, count, buffer)
            except FMICallException as exc:
                raise CosimError(
                    f"setting {list(names)} = {list(view)} failed at t = {self.time:.6f} s: "
                    f"{self.last_messages() or exc}"
                ) from exc

        return write

    def get_reals(self, names) -> np.ndarray:
        """The current values of the Reals ``names`` (a new array; for set-up, not per step)."""
        return np.array(self.slave.getReal(self._refs(names)))

    def do_step(self, t: float, h: float) -> None:
        """One communication step from ``t`` to ``t + h`` [s]; raises CosimError on failure."""
        try:
            self.slave.fmi2DoStep(self.slave.component, t, h, 1)
        except FMICallException as exc:
            raise CosimError(
                f"fmi2DoStep failed at t = {t:.6f} s (h = {h} s): {self.last_messages() or exc}"
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
