"""Shared fixtures of the test suite.

FMU fixtures (prefixed ``built_fmu``) build the TrailerTrain FMU once per number of trailers per
session, extract it once, and hand out thin, name-based FMU2Slave wrappers (:class:`TrailerSim`)
that record the FMU's log messages and are freed at teardown.
"""

from __future__ import annotations

import pathlib
from ctypes import byref

import numpy as np
import pytest


class TrailerSim:
    """One FMU2Slave instance of the TrailerTrain FMU, addressed by variable name.

    Parameters
    ----------
    unzipdir : pathlib.Path
        Folder of the extracted FMU.
    model_description : fmpy.model_description.ModelDescription
        Its model description (read from the XML, not from ``fmu/variables.py``).
    instance_name : str
        FMI instance name.
    logging_on : bool
        ``loggingOn`` argument of ``fmi2Instantiate``.
    guid : str or None
        GUID passed to ``fmi2Instantiate``; None passes the model description's GUID.
    messages : list or None
        List that collects the log messages (so they survive a failed instantiation).

    Attributes
    ----------
    messages : list of (int, str, str)
        Every message the FMU logged: (status, category, message).
    time : float
        The master's current communication point [s].
    """

    def __init__(self, unzipdir, model_description, instance_name="train", logging_on=False,
                 guid=None, messages=None):
        from fmpy import calloc, free
        from fmpy.fmi2 import (
            FMU2Slave,
            fmi2CallbackAllocateMemoryTYPE,
            fmi2CallbackFreeMemoryTYPE,
            fmi2CallbackFunctions,
            fmi2CallbackLoggerTYPE,
        )
        from fmpy.logging import addLoggerProxy

        self.md = model_description
        self.variables = {v.name: v for v in model_description.modelVariables}
        self.n = sum(1 for name in self.variables if name.startswith("front["))
        self.messages: list[tuple[int, str, str]] = [] if messages is None else messages
        self.time = 0.0
        self._freed = False

        def _log(_env, _instance, status, category, message):
            self.messages.append(
                (int(status), (category or b"").decode("utf-8", "replace"),
                 (message or b"").decode("utf-8", "replace"))
            )

        callbacks = fmi2CallbackFunctions()
        callbacks.logger = fmi2CallbackLoggerTYPE(_log)
        callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        addLoggerProxy(byref(callbacks))
        self._callbacks = callbacks  # keep the ctypes objects alive
        self._log = _log

        self.fmu = FMU2Slave(
            guid=model_description.guid if guid is None else guid,
            unzipDirectory=str(unzipdir),
            modelIdentifier=model_description.coSimulation.modelIdentifier,
            instanceName=instance_name,
        )
        try:
            self.fmu.instantiate(callbacks=callbacks, loggingOn=logging_on)
        except Exception:
            self.fmu.freeLibrary()
            self._freed = True
            raise

    # -- values by name -------------------------------------------------------------------------
    def vr(self, name: str) -> int:
        """Value reference of ``name``."""
        return self.variables[name].valueReference

    def set(self, values: dict) -> None:
        """Set variables by name (Real, Integer or Boolean, grouped by type)."""
        groups: dict[str, tuple[list, list]] = {"Real": ([], []), "Integer": ([], []),
                                                "Boolean": ([], [])}
        for name, value in values.items():
            var = self.variables[name]
            refs, vals = groups[var.type]
            refs.append(var.valueReference)
            vals.append(value)
        if groups["Real"][0]:
            self.fmu.setReal(*groups["Real"])
        if groups["Integer"][0]:
            self.fmu.setInteger(groups["Integer"][0], [int(v) for v in groups["Integer"][1]])
        if groups["Boolean"][0]:
            self.fmu.setBoolean(groups["Boolean"][0], [bool(v) for v in groups["Boolean"][1]])

    def get(self, names) -> list:
        """Values of the variables ``names``, each read with the getter of its type."""
        out = []
        for name in names:
            var = self.variables[name]
            if var.type == "Real":
                out.append(self.fmu.getReal([var.valueReference])[0])
            elif var.type == "Integer":
                out.append(self.fmu.getInteger([var.valueReference])[0])
            else:
                out.append(bool(self.fmu.getBoolean([var.valueReference])[0]))
        return out

    def real(self, name: str) -> float:
        """One Real value."""
        return self.fmu.getReal([self.vr(name)])[0]

    def array(self, block: str) -> np.ndarray:
        """All elements ``block[i]`` in index order (Real blocks as floats, Booleans as bools)."""
        names = sorted(
            (name for name in self.variables
             if name.startswith(block + "[") and name.endswith("]")),
            key=lambda name: int(name[len(block) + 1:-1]),
        )
        var_type = self.variables[names[0]].type
        refs = [self.vr(name) for name in names]
        if var_type == "Real":
            return np.array(self.fmu.getReal(refs), dtype=float)
        if var_type == "Boolean":
            return np.array(self.fmu.getBoolean(refs), dtype=bool)
        return np.array(self.fmu.getInteger(refs), dtype=int)

    # -- life cycle -------------------------------------------------------------------------------
    def initialize(self, params: dict | None = None, inputs: dict | None = None,
                   after_enter: dict | None = None, start_time: float = 0.0) -> None:
        """Set up, set ``params`` and ``inputs``, enter init, set ``after_enter``, exit init."""
        self.fmu.setupExperiment(startTime=start_time)
        if params:
            self.set(params)
        if inputs:
            self.set(inputs)
        self.fmu.enterInitializationMode()
        if after_enter:
            self.set(after_enter)
        self.fmu.exitInitializationMode()
        self.time = start_time

    def step(self, h: float) -> None:
        """One fmi2DoStep from the current communication point."""
        self.fmu.doStep(currentCommunicationPoint=self.time, communicationStepSize=h)
        self.time = self.time + h

    def free(self) -> None:
        """fmi2FreeInstance and unload (idempotent)."""
        if not self._freed:
            self._freed = True
            self.fmu.freeInstance()


@pytest.fixture(scope="session")
def built_fmu():
    """Factory ``built_fmu(n) -> pathlib.Path`` of the TrailerTrain FMU for n trailers (cached)."""
    from pushtrain.fmu.build import build_fmu

    cache: dict[int, pathlib.Path] = {}

    def get(n_trailers: int) -> pathlib.Path:
        if n_trailers not in cache:
            cache[n_trailers] = pathlib.Path(build_fmu(n_trailers))
        return cache[n_trailers]

    return get


@pytest.fixture(scope="session")
def built_fmu_unzipped(built_fmu, tmp_path_factory):
    """Factory ``built_fmu_unzipped(n) -> (unzipdir, model_description)``, extracted once per n."""
    from fmpy import extract, read_model_description

    cache: dict[int, tuple[pathlib.Path, object]] = {}

    def get(n_trailers: int):
        if n_trailers not in cache:
            path = built_fmu(n_trailers)
            target = tmp_path_factory.mktemp(f"trailertrain_n{n_trailers}")
            unzipdir = pathlib.Path(extract(str(path), unzipdir=str(target)))
            cache[n_trailers] = (unzipdir, read_model_description(str(path)))
        return cache[n_trailers]

    return get


@pytest.fixture
def built_fmu_sim(built_fmu_unzipped):
    """Factory ``built_fmu_sim(n, **kw) -> TrailerSim`` (instantiated; freed at teardown)."""
    made: list[TrailerSim] = []

    def make(n_trailers: int, **kwargs) -> TrailerSim:
        unzipdir, md = built_fmu_unzipped(n_trailers)
        sim = TrailerSim(unzipdir, md, **kwargs)
        made.append(sim)
        return sim

    yield make
    for sim in reversed(made):
        sim.free()



@pytest.fixture(scope="session")
def fmu3(built_fmu):
    """The TrailerTrain FMU for 3 trailers (the paper's train)."""
    return built_fmu(3)


# --------------------------------------------------------------- the CLI, for the tests of it
EXAMPLES = pathlib.Path(__file__).resolve().parents[1] / "examples"


def invoke_cli(args):
    """``pushtrain ARGS`` through click's runner; never a traceback (asserted)."""
    from click.testing import CliRunner

    from pushtrain.cli.main import cli

    result = CliRunner().invoke(cli, [str(a) for a in args])
    assert result.exception is None or isinstance(result.exception, SystemExit), result.output
    assert "Traceback" not in result.output, result.output
    return result


def short_run(tmp_path, n=3, horizon=0.3):
    """straight_push with ``n`` trailers, without its shove, and a horizon far too short for
    the goal (exit 1)."""
    text = (EXAMPLES / "straight_push.toml").read_text().replace("n = 3", f"n = {n}")
    path = tmp_path / f"short{n}.toml"
    path.write_text(text[:text.index("[[events]]")] + f"[sim]\nhorizon = {horizon}\n")
    return path
