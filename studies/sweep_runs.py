"""Sweep runs: expansion of a spec into runs, and their scenarios, plans and FMUs.

:func:`expand_runs` turns a :class:`~pushtrain.studies.sweep_spec.SweepSpec` into
:class:`SweepRun` objects, each keyed by a stable hash of its index and parameter values
(:func:`run_key`). :func:`prepare_runs` is the scenario layer: it resolves and validates every
run's scenario before anything runs, plans ``plan`` missions once per distinct train geometry in
the client (OMPL objects are not picklable: the path travels as ``PlannedPath.to_dict()`` data),
builds one FMU per distinct number of trailers and fills each run's picklable ``payload`` for
:func:`~pushtrain.studies.sweep_task.run_task`.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import logging
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from pushtrain.errors import ScenarioError, SweepError
from pushtrain.mission.scenario import Scenario, parse_scenario

from .sweep_spec import SweepSpec, get_path, parse_path, plain_value, resolve, set_path
from .sweep_task import FmuRef, sha256_of

__all__ = ["SweepRun", "STATUS_PLANNING_FAILED", "run_key", "expand_runs", "prepare_runs",
           "bias_swept"]

log = logging.getLogger(__name__)

_PER_TRAILER = {("sensors", "joint_bias_deg"), ("train", "mass"), ("train", "inertia"),
                ("train", "payload"), ("train", "mu")}
_NOT_FOR_PLANNING = ("mass", "inertia", "payload", "mu")
STATUS_PLANNING_FAILED = "planning_failed"
MAX_LISTED = 20


# ------------------------------------------------------------------------------------ expansion
@dataclass
class SweepRun:
    """One run of a sweep.

    ``params`` maps each swept path to this run's value; ``key`` is a stable hash of the index
    and the values (:func:`run_key`). The scenario layer fills ``payload`` (what the task function
    needs, picklable), ``extras`` (columns computed in the client, e.g. the predicted offset) and
    ``failure`` ((status, message) when the run is known to fail before it is started).
    """

    index: int
    key: str
    params: dict
    payload: Any = None
    extras: dict = field(default_factory=dict)
    failure: tuple[str, str] | None = None


def run_key(index: int, params: dict) -> str:
    """Stable 16-hex-digit key of a run: SHA-256 of its index and (path, value) pairs."""
    text = json.dumps({"index": int(index),
                       "params": [[k, plain_value(v)] for k, v in params.items()]},
                      sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def expand_runs(spec: SweepSpec) -> list[SweepRun]:
    """All runs of ``spec``: the Cartesian product (first parameter slowest) or ``samples`` draws.

    Monte Carlo draws come from ``numpy.random.default_rng(spec.seed)``, run by run and parameter
    by parameter, so a larger ``samples`` keeps the first runs unchanged.
    """
    runs = []
    if spec.mode == "grid":
        combos = itertools.product(*(p.grid_values() for p in spec.parameters))
    else:
        rng = np.random.default_rng(spec.seed)
        combos = ([p.draw(rng) for p in spec.parameters] for _ in range(spec.samples))
    for index, combo in enumerate(combos):
        params = {p.path: plain_value(v) for p, v in zip(spec.parameters, combo, strict=True)}
        runs.append(SweepRun(index, run_key(index, params), params))
    return runs


# ------------------------------------------------------------------------------------ scenarios
def _base_dict(sc: Scenario, spec: SweepSpec) -> dict:
    """The fully resolved base scenario; per-trailer single values that a path indexes become
    lists of n (``joint_bias_deg = 0.0`` -> ``[0.0, 0.0, 0.0]``), which means the same."""
    data = sc.model_dump(mode="json")
    n = spec.overrides.get("train.n", sc.train.n)
    for path in [*spec.overrides, *(p.path for p in spec.parameters)]:
        parts = parse_path(path)
        if len(parts) >= 3 and tuple(parts[:2]) in _PER_TRAILER and isinstance(parts[2], int):
            value = data[parts[0]][parts[1]]
            if not isinstance(value, list) and isinstance(n, int):
                data[parts[0]][parts[1]] = [value] * n
    return data


def _check_paths(base: dict, spec: SweepSpec) -> None:
    problems = []
    data = json.loads(json.dumps(base))
    for path, value in spec.overrides.items():
        try:
            set_path(data, path, value)
        except KeyError as exc:
            problems.append((f"overrides.{path!r}", value, exc.args[0]))
    for k, p in enumerate(spec.parameters):
        try:
            get_path(data, p.path)
        except KeyError as exc:
            problems.append((f"parameters[{k}].path", p.path, exc.args[0]))
    if problems:
        raise SweepError(spec.name, problems)


def _scenarios(base: dict, spec: SweepSpec, runs: list[SweepRun]) -> dict[int, Scenario]:
    """Every run's validated scenario by run index; all problems raised at once."""
    problems, scenarios = [], {}
    for run in runs:
        data = resolve(base, spec.overrides, run.params)
        if spec.seed_per_run:
            data["seed"] = spec.seed + run.index
        try:
            scenarios[run.index] = parse_scenario(data, f"run {run.index}")
        except ScenarioError as exc:
            values = ", ".join(f"{k} = {v!r}" for k, v in run.params.items())
            problems += [(f"run {run.index} ({values}): {where}", value, allowed)
                         for where, value, allowed in exc.errors]
    if problems:
        listed = problems[:MAX_LISTED]
        if len(problems) > MAX_LISTED:
            listed.append(("...", len(problems) - MAX_LISTED, "more problems not listed"))
        raise SweepError(f"{spec.name}: invalid parameter combination(s)", listed)
    return scenarios


def _fmu_refs(trailer_counts, fmus: dict | None, ship_fmu: bool) -> tuple[dict, dict]:
    """One :class:`FmuRef` per number of trailers (built unless given), and the shared bytes."""
    from pushtrain.fmu.build import build_fmu

    refs, shared = {}, {}
    for n in sorted(trailer_counts):
        path = Path(fmus[n]) if fmus and n in fmus else Path(build_fmu(n))
        refs[n] = FmuRef(n, str(path), sha256_of(path))
        if ship_fmu:
            shared[f"fmu-{refs[n].sha256}"] = path.read_bytes()
    return refs, shared


def _planning_key(data: dict) -> str:
    train = {k: v for k, v in data["train"].items() if k not in _NOT_FOR_PLANNING}
    keep = {k: data.get(k) for k in ("map", "start", "goal", "planner", "seed")}
    return json.dumps({"train": train, **keep}, sort_keys=True)


def _plan(sc: Scenario):
    from pushtrain.errors import PlanningError
    from pushtrain.mission.runner import plan_path

    try:
        return plan_path(sc).to_dict(), None
    except PlanningError as exc:
        return None, f"planning failed ({getattr(exc, 'reason', '')}): {exc}"


def bias_swept(spec: SweepSpec) -> bool:
    """Whether the spec sets joint biases (then rows carry the predicted steady offset)."""
    paths = [*spec.overrides, *(p.path for p in spec.parameters)]
    return any(p.startswith("sensors.joint_bias_deg") for p in paths)


def _predicted(sc: Scenario) -> dict:
    """eps_eff [deg] and the closed-form steady offset [m] (core.analysis, as `analyze`)."""
    from pushtrain.core import analysis
    from pushtrain.mission.runner import bias_model

    c = sc.controller
    link, speed, bias, eps = bias_model(sc)
    if sc.sensors.localize == "last_trailer":
        pred = analysis.steady_lateral_error(eps, link, c.k_y)
    else:
        pred = analysis.steady_lateral_error_estimated_pose(bias, link, c.k_x, c.k_y, c.k_theta,
                                                            speed)
    return {"eps_eff_deg": math.degrees(eps), "predicted_steady_lat_m": float(pred)}


def prepare_runs(sc: Scenario, spec: SweepSpec, *, fmus: dict | None = None,
                 ship_fmu: bool = False):
    """Expand, resolve and validate every run; plan and build FMUs in the client.

    Parameters
    ----------
    sc : Scenario
        The base scenario.
    spec : SweepSpec
    fmus : dict, optional
        ``{n: path}`` FMU files to use instead of :func:`pushtrain.fmu.build.build_fmu`.
    ship_fmu : bool
        Also return the FMU bytes as shared data (for workers on other machines).

    Returns
    -------
    runs : list of SweepRun
        With ``payload``, ``extras`` and (planning failures) ``failure`` filled in.
    shared : dict
        Data for every task (``fmu-<sha256>`` -> bytes when shipping).
    manifest : dict
        Spec and base scenario (their fingerprint guards resume).

    Raises
    ------
    SweepError
        A path that is not in the scenario, or runs whose resolved scenario is invalid (all
        reported before anything runs).
    """
    base = _base_dict(sc, spec)
    _check_paths(base, spec)
    runs = expand_runs(spec)
    scenarios = _scenarios(base, spec, runs)
    refs, shared = _fmu_refs({s.train.n for s in scenarios.values()}, fmus, ship_fmu)
    plans: dict[str, tuple] = {}
    with_prediction = bias_swept(spec)
    for run in runs:
        run_sc = scenarios[run.index]
        data = run_sc.model_dump(mode="json")
        path_data = None
        if run_sc.mission.kind == "plan":
            key = _planning_key(data)
            if key not in plans:
                plans[key] = _plan(run_sc)
            path_data, failure = plans[key]
            if failure is not None:
                run.failure = (STATUS_PLANNING_FAILED, failure)
        run.payload = {"scenario": data, "fmu": refs[run_sc.train.n], "path": path_data}
        if with_prediction and run_sc.mission.kind != "rotation":
            run.extras = _predicted(run_sc)
    if plans:
        log.info("planned %d distinct train geometries in the client", len(plans))
    manifest = {"spec": spec.model_dump(mode="json"), "base": base}
    return runs, shared, manifest
