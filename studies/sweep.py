"""Robustness sweeps: many co-simulations over a grid or a Monte Carlo sample of parameters.

A sweep specification (:class:`SweepSpec`, a TOML file of its own, read by
:func:`load_sweep_spec`) names scenario fields by path (``"sensors.joint_bias_deg[2]"``,
``"controller.model_link"``, ``"train.n"``, ``"events[0].distance"``) and gives each a list of
values, a linspace ``range`` or (Monte Carlo) a seeded random distribution. :func:`expand_runs`
turns it into :class:`SweepRun` objects, each keyed by a stable hash of its index and parameter
values; :func:`resolve` applies the overrides and one run's values to a plain scenario dict.

:func:`run_sweep` executes runs on a Dask ``distributed`` client or serially in this process
(the same task function either way, so both give identical numbers). Each task runs one
co-simulation and returns one row of metrics (:func:`metrics_of`); a task that raises or ends in a
failure status is a recorded failure row, not a lost sweep. Rows are written incrementally as
CSV chunks (``chunks/chunk-000012.csv``, each written atomically) and combined into
``results.csv``; a sweep re-run into the same folder skips the runs whose rows exist (resume).

This module knows nothing about scenario files: the scenario layer (``pushtrain.cli.sweep``)
validates the resolved dicts, plans, builds FMUs and provides the task function.

Units: lengths [m], times [s], angles in degrees only in ``*_deg`` columns.
"""

from __future__ import annotations

import copy
import csv
import hashlib
import io
import itertools
import json
import logging
import math
import os
import re
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any, Callable, Literal, Sequence, Union

import numpy as np
from pydantic import (BaseModel, ConfigDict, Field, StrictBool, StrictInt, ValidationError,
                      model_validator)

from pushtrain.errors import FieldErrors, SweepError
from pushtrain.files import atomic_write_text
from pushtrain.validation import field_errors, read_toml

__all__ = [
    "SweepError",
    "RangeSpec",
    "ParameterSpec",
    "SweepSpec",
    "SweepRun",
    "SweepOutcome",
    "METRICS",
    "DEFAULT_METRICS",
    "OK_STATUSES",
    "STATUS_ERROR",
    "STATUS_LOST",
    "parse_path",
    "get_path",
    "set_path",
    "parse_sweep_spec",
    "load_sweep_spec",
    "expand_runs",
    "run_key",
    "resolve",
    "metrics_of",
    "failure_row",
    "run_sweep",
    "read_results",
    "write_rows_csv",
]

log = logging.getLogger(__name__)

FiniteFloat = Annotated[float, Field(allow_inf_nan=False)]
PositiveFloat = Annotated[float, Field(gt=0, allow_inf_nan=False)]
Value = Union[StrictBool, StrictInt, FiniteFloat, str, list[Union[StrictInt, FiniteFloat]]]

OK_STATUSES = ("goal_reached", "completed")
STATUS_ERROR = "error"  # the task raised (bad combination found at run time, FMU load failure, ...)
STATUS_LOST = "lost"  # the worker died or the task was cancelled: run again on resume
SPEC_FORMAT = "pushtrain.sweep"

METRICS = {
    "rms_lat_m": "RMS lateral error of the last trailer [m]",
    "max_lat_m": "max |lateral error| of the last trailer [m]",
    "final_lat_m": "final lateral error [m]",
    "steady_lat_m": "steady lateral offset: mean lateral error over the last steady_window s [m]",
    "rms_heading_deg": "RMS heading error [deg]",
    "max_heading_deg": "max |heading error| [deg]",
    "max_abs_phi_deg": "max |joint angle| over all joints [deg]",
    "max_F_lat_ratio": "max |F_lat| / friction limit over all trailers [-]",
    "slip_events": "number of slip onsets, all trailers [-]",
    "slip_time_s": "time spent slipping, summed over trailers [s]",
    "t_final": "simulated time at the end of the run [s]",
    "steps": "communication steps [-]",
    "wall_time_s": "wall time of the co-simulation loop [s]",
}
"""Metric columns a sweep can keep (``metrics`` in the spec), with their meaning."""

DEFAULT_METRICS = ("rms_lat_m", "max_lat_m", "final_lat_m", "steady_lat_m", "max_abs_phi_deg",
                   "max_F_lat_ratio", "slip_events", "wall_time_s")
"""Metrics kept when the spec does not list any (``status``, ``ok`` and ``error`` always are)."""

TIMING_COLUMNS = ("wall_time_s", "task_time_s")
"""Columns that measure time and so differ between otherwise identical runs."""


# ---------------------------------------------------------------------------------------- paths
_PATH_RE = re.compile(r"[A-Za-z_][A-Za-z0-9_]*|\[\d+\]")


def parse_path(path: str) -> tuple[str | int, ...]:
    """Split ``"sensors.joint_bias_deg[2]"`` into ``("sensors", "joint_bias_deg", 2)``.

    Raises
    ------
    ValueError
        Not of the form ``name(.name | [index])*``.
    """
    if not isinstance(path, str) or not path:
        raise ValueError("a path like 'sensors.joint_bias_deg[2]' or 'train.n'")
    parts: list[str | int] = []
    pos = 0
    while pos < len(path):
        if parts and path[pos] == ".":
            pos += 1
        match = _PATH_RE.match(path, pos)
        if match is None or (not parts and match.group().startswith("[")):
            raise ValueError(f"not a field path at character {pos + 1}: use names joined by '.' "
                             "and [index] for list items, e.g. 'sensors.joint_bias_deg[2]'")
        token = match.group()
        parts.append(int(token[1:-1]) if token.startswith("[") else token)
        pos = match.end()
        if pos < len(path) and path[pos] not in ".[":
            raise ValueError(f"unexpected {path[pos]!r} at character {pos + 1}")
    return tuple(parts)


def _walk(data, parts, path: str):
    node = data
    for depth, part in enumerate(parts):
        where = path if depth == len(parts) - 1 else _join(parts[:depth + 1])
        if isinstance(part, int):
            if not isinstance(node, list):
                raise KeyError(f"{_join(parts[:depth]) or '(top)'} is {node!r}, not a list: "
                               f"{where} cannot index it")
            if part >= len(node):
                raise KeyError(f"{where}: index out of range (the list has {len(node)} items)")
        else:
            if not isinstance(node, dict):
                raise KeyError(f"{_join(parts[:depth]) or '(top)'} is {node!r}, not a table: "
                               f"no field {part!r}")
            if part not in node:
                raise KeyError(f"{where}: no such field (known: {', '.join(sorted(node))})")
        if depth == len(parts) - 1:
            return node, part
        node = node[part]
    raise KeyError("empty path")


def _join(parts) -> str:
    out = ""
    for part in parts:
        out += f"[{part}]" if isinstance(part, int) else ("." if out else "") + part
    return out


def get_path(data: dict, path: str):
    """The value at ``path`` in nested dicts/lists (KeyError naming the path if absent)."""
    node, last = _walk(data, parse_path(path), path)
    return node[last]


def set_path(data: dict, path: str, value) -> None:
    """Set the value at ``path`` in place; the field (and list item) must exist already."""
    node, last = _walk(data, parse_path(path), path)
    node[last] = copy.deepcopy(value)


def resolve(base: dict, overrides: dict, params: dict) -> dict:
    """A copy of ``base`` with ``overrides`` then ``params`` (both path -> value) applied."""
    data = copy.deepcopy(base)
    for path, value in overrides.items():
        set_path(data, path, value)
    for path, value in params.items():
        set_path(data, path, value)
    return data


# ----------------------------------------------------------------------------------------- spec
class _Section(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class RangeSpec(_Section):
    """``num`` evenly spaced values from ``start`` to ``stop`` (both included)."""

    start: FiniteFloat
    stop: FiniteFloat
    num: Annotated[int, Field(ge=1, le=100_000)]


class ParameterSpec(_Section):
    """One swept scenario field: ``values``, a ``range``, or (Monte Carlo) a distribution."""

    path: str
    values: Annotated[list[Value], Field(min_length=1)] | None = None
    range: RangeSpec | None = None
    dist: Literal["uniform", "normal"] | None = None
    low: FiniteFloat | None = None
    high: FiniteFloat | None = None
    mean: FiniteFloat | None = None
    std: Annotated[float, Field(gt=0, allow_inf_nan=False)] | None = None
    label: str | None = None

    @model_validator(mode="after")
    def _one_source(self):
        try:
            parse_path(self.path)
        except ValueError as exc:
            raise ValueError(f"path {self.path!r}: {exc}") from None
        given = [name for name in ("values", "range", "dist") if getattr(self, name) is not None]
        if len(given) != 1:
            raise ValueError("give exactly one of 'values' (a list), 'range' ({start, stop, num}) "
                             f"or 'dist' ('uniform' or 'normal'); got {given or 'none'}")
        if self.dist == "uniform":
            if self.low is None or self.high is None or not self.low < self.high:
                raise ValueError("dist = 'uniform' needs 'low' < 'high'")
            if self.mean is not None or self.std is not None:
                raise ValueError("dist = 'uniform' takes 'low' and 'high', not 'mean'/'std'")
        elif self.dist == "normal":
            if self.mean is None or self.std is None:
                raise ValueError("dist = 'normal' needs 'mean' and 'std' (> 0)")
            if self.low is not None or self.high is not None:
                raise ValueError("dist = 'normal' takes 'mean' and 'std', not 'low'/'high'")
        elif any(getattr(self, k) is not None for k in ("low", "high", "mean", "std")):
            raise ValueError("'low', 'high', 'mean' and 'std' belong to a 'dist'")
        return self

    @property
    def name(self) -> str:
        """Column name and axis label: ``label`` or the path."""
        return self.label or self.path

    def grid_values(self) -> list:
        """The listed values or the linspace of ``range`` (plain Python numbers)."""
        if self.values is not None:
            return list(self.values)
        if self.range is not None:
            r = self.range
            return [float(v) for v in np.linspace(r.start, r.stop, r.num)]
        raise ValueError(f"{self.path}: a distribution has no grid values")

    def draw(self, rng: np.random.Generator):
        """One Monte Carlo draw: from the distribution, or uniformly among the grid values."""
        if self.dist == "uniform":
            return float(rng.uniform(self.low, self.high))
        if self.dist == "normal":
            return float(rng.normal(self.mean, self.std))
        values = self.grid_values()
        return copy.deepcopy(values[int(rng.integers(len(values)))])


class SweepSpec(_Section):
    """A whole sweep file."""

    name: str = "sweep"
    description: str = ""
    mode: Literal["grid", "monte_carlo"] = "grid"
    samples: Annotated[int, Field(ge=1, le=1_000_000)] | None = None
    seed: Annotated[int, Field(ge=1)] = 1  # Monte Carlo draws; base of seed_per_run
    seed_per_run: bool = False  # set the scenario's seed (noise, planner) to seed + run index
    parameters: Annotated[list[ParameterSpec], Field(min_length=1)]
    metrics: list[Literal[tuple(METRICS)]] | None = None  # type: ignore[valid-type]
    steady_window: PositiveFloat = 10.0
    chunk_size: Annotated[int, Field(ge=1, le=10_000)] = 8
    overrides: dict[str, Value | None] = {}

    @model_validator(mode="after")
    def _consistent(self):
        problems = []
        if self.mode == "grid":
            if self.samples is not None:
                problems.append(("samples", self.samples, "only with mode = 'monte_carlo'"))
            for k, p in enumerate(self.parameters):
                if p.dist is not None:
                    problems.append((f"parameters[{k}].dist", p.dist,
                                     "only with mode = 'monte_carlo'; a grid needs 'values' "
                                     "or 'range'"))
        elif self.samples is None:
            problems.append(("samples", None, "required when mode = 'monte_carlo' (>= 1)"))
        seen = {}
        for k, p in enumerate(self.parameters):
            if p.path in seen:
                problems.append((f"parameters[{k}].path", p.path,
                                 f"already swept by parameters[{seen[p.path]}]"))
            seen.setdefault(p.path, k)
            if p.path == "seed" and self.seed_per_run:
                problems.append((f"parameters[{k}].path", p.path, "not with seed_per_run = true"))
        for path in self.overrides:
            try:
                parse_path(path)
            except ValueError as exc:
                problems.append((f"overrides.{path!r}", path, str(exc)))
            if path in seen:
                problems.append((f"overrides.{path!r}", path, "also swept in parameters"))
        if problems:
            raise FieldErrors("", problems)
        return self

    @property
    def kept_metrics(self) -> tuple[str, ...]:
        return tuple(self.metrics) if self.metrics is not None else DEFAULT_METRICS

    @property
    def n_runs(self) -> int:
        if self.mode == "monte_carlo":
            return int(self.samples)
        return math.prod(len(p.grid_values()) for p in self.parameters)


def parse_sweep_spec(data: dict, source: str = "<sweep>") -> SweepSpec:
    """Validate plain data (a parsed TOML document) into a :class:`SweepSpec`.

    Raises
    ------
    SweepError
        Every problem at once, each with its field path, value and what is allowed.
    """
    try:
        return SweepSpec.model_validate(data)
    except ValidationError as exc:
        raise SweepError(source, field_errors(exc)) from None


def load_sweep_spec(path) -> SweepSpec:
    """Read and validate a sweep TOML file (raises :class:`SweepError`)."""
    return parse_sweep_spec(read_toml(path, SweepError), str(path))


# ----------------------------------------------------------------------------------------- runs
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


def _plain(value):
    if isinstance(value, (np.floating,)):
        return float(value)
    if isinstance(value, (np.integer,)):
        return int(value)
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value


def run_key(index: int, params: dict) -> str:
    """Stable 16-hex-digit key of a run: SHA-256 of its index and (path, value) pairs."""
    text = json.dumps({"index": int(index), "params": [[k, _plain(v)] for k, v in params.items()]},
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
        params = {p.path: _plain(v) for p, v in zip(spec.parameters, combo)}
        runs.append(SweepRun(index, run_key(index, params), params))
    return runs


# -------------------------------------------------------------------------------------- metrics
def _max_or_nan(values) -> float:
    vals = [v for v in values if v is not None and math.isfinite(v)]
    return max(vals) if vals else math.nan


def metrics_of(result, steady_window: float) -> dict:
    """Every metric of :data:`METRICS` (plus ``status`` and ``message``) from a
    :class:`~pushtrain.cosim.master.Result`.

    ``steady_lat_m`` is the mean lateral error over the last ``steady_window`` seconds of the run
    [m]; NaN when the run is shorter than that.
    """
    s = result.summary
    nan = math.nan
    lat = s.get("lateral_error_m", {})
    head = s.get("heading_error_rad", {})
    slips = s.get("slip", [])
    row = {
        "status": result.status,
        "message": result.message,
        "rms_lat_m": lat.get("rms", nan),
        "max_lat_m": lat.get("max", nan),
        "final_lat_m": lat.get("final", nan),
        "steady_lat_m": nan,
        "rms_heading_deg": math.degrees(head["rms"]) if "rms" in head else nan,
        "max_heading_deg": math.degrees(head["max"]) if "max" in head else nan,
        "max_abs_phi_deg": _max_or_nan(s.get("max_abs_phi_deg", [])),
        "max_F_lat_ratio": _max_or_nan(s.get("max_F_lat_ratio", [])),
        "slip_events": int(sum(e["events"] for e in slips)),
        "slip_time_s": float(sum(e["time_slipping_s"] for e in slips)),
        "t_final": s.get("t_final", nan),
        "steps": s.get("steps", 0),
        "wall_time_s": s.get("wall_time_s", nan),
    }
    data = result.data
    if len(data) and "e_lat" in data.dtype.names:
        t = data["t"]
        if t[-1] - t[0] >= steady_window - 1e-9:
            mask = t >= t[-1] - steady_window - 1e-9
            e_lat = data["e_lat"][mask]
            if np.all(np.isfinite(e_lat)):
                row["steady_lat_m"] = float(np.mean(e_lat))
    return row


def failure_row(status: str, message: str) -> dict:
    """The metric part of a row for a run that produced no result."""
    row = {name: math.nan for name in METRICS}
    row.update(status=status, message=message, slip_events=0, steps=0)
    return row


def _execute(task_fn: Callable, index: int, key: str, payload, shared,
             steady_window: float) -> dict:
    """Worker side: run one task, never raise (an exception becomes a failure row)."""
    t0 = time.perf_counter()
    try:
        row = metrics_of(task_fn(payload, shared), steady_window)
    except Exception as exc:  # any failure of one run is recorded, not fatal to the sweep
        log.info("run %d (%s) failed: %s: %s", index, key, type(exc).__name__, exc)
        row = failure_row(STATUS_ERROR, f"{type(exc).__name__}: {exc}")
    row["task_time_s"] = time.perf_counter() - t0
    row["index"], row["key"] = index, key
    return row


# ---------------------------------------------------------------------------------- CSV rows
def _encode(value) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return "nan" if math.isnan(value) else repr(value)
    if isinstance(value, (int, str)):
        return str(value)
    return json.dumps(_plain(value))


def _decode(text: str):
    if text == "":
        return None
    if text == "nan":
        return math.nan
    try:
        return json.loads(text)
    except (json.JSONDecodeError, ValueError):
        return text


def write_rows_csv(path: Path, rows: Sequence[dict], columns: Sequence[str]) -> None:
    """Write ``rows`` (dicts) as CSV with ``columns``, atomically (temporary file, rename)."""
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(columns)
    for row in rows:
        writer.writerow([_encode(row.get(c)) for c in columns])
    atomic_write_text(path, buf.getvalue())


_TEXT_COLUMNS = ("key", "status", "error")


def read_results(path) -> list[dict]:
    """Rows of a sweep CSV (a chunk or ``results.csv``) with values decoded."""
    with open(path, newline="") as f:
        reader = csv.reader(f)
        header = next(reader, None)
        if header is None:
            return []
        return [{c: v if c in _TEXT_COLUMNS else _decode(v) for c, v in zip(header, line)}
                for line in reader]


# ------------------------------------------------------------------------------------ execution
@dataclass
class SweepOutcome:
    """What :func:`run_sweep` did.

    ``rows`` holds one row per run that has a result (all runs when ``complete``), sorted by index;
    ``new`` counts the runs executed by this call, ``skipped`` the runs resumed from earlier chunks.
    """

    rows: list[dict]
    columns: list[str]
    n_runs: int
    new: int
    skipped: int
    out_dir: Path
    files: dict = field(default_factory=dict)
    interrupted: bool = False
    report: dict = field(default_factory=dict)

    @property
    def complete(self) -> bool:
        return len(self.rows) == self.n_runs

    @property
    def failures(self) -> list[dict]:
        return [r for r in self.rows if not r["ok"]]


def _columns(param_paths, metrics, extras) -> list[str]:
    return (["index", "key", *param_paths, "status", "ok", "error", *metrics, *extras,
             "task_time_s"])


def _finish_row(row: dict, run: SweepRun) -> dict:
    row = dict(row)
    row.update(run.params)
    row.update(run.extras)
    row["index"], row["key"] = run.index, run.key
    row["ok"] = row["status"] in OK_STATUSES
    row["error"] = "" if row["ok"] else row.get("message", "")
    return row


class _ChunkWriter:
    def __init__(self, folder: Path, columns, chunk_size: int):
        self.folder = folder
        self.columns = columns
        self.chunk_size = chunk_size
        self.buffer: list[dict] = []
        numbers = [int(p.stem.split("-")[1]) for p in folder.glob("chunk-*.csv")]
        self.next = max(numbers, default=-1) + 1
        self.written: list[Path] = []

    def add(self, row: dict) -> None:
        self.buffer.append(row)
        if len(self.buffer) >= self.chunk_size:
            self.flush()

    def flush(self) -> None:
        if not self.buffer:
            return
        path = self.folder / f"chunk-{self.next:06d}.csv"
        write_rows_csv(path, self.buffer, self.columns)
        log.debug("wrote %s (%d rows)", path, len(self.buffer))
        self.written.append(path)
        self.next += 1
        self.buffer = []


def _fingerprint(manifest: dict) -> str:
    return hashlib.sha256(json.dumps(manifest, sort_keys=True, default=str).encode()).hexdigest()


def _check_manifest(out_dir: Path, manifest: dict | None) -> None:
    """Refuse to mix rows of a different sweep into ``out_dir``; write ``sweep.json``."""
    if manifest is None:
        return
    digest = _fingerprint(manifest)
    path = out_dir / "sweep.json"
    if path.is_file():
        try:
            old = json.loads(path.read_text()).get("fingerprint")
        except (json.JSONDecodeError, OSError):
            old = None
        if old != digest:
            raise SweepError(str(out_dir), [(
                "out", str(out_dir),
                "holds the results of a different sweep (the spec or the base scenario changed); "
                "choose another output folder or delete this one")])
        return
    text = json.dumps({"format": SPEC_FORMAT, "fingerprint": digest, **manifest}, indent=2,
                      default=str)
    atomic_write_text(path, text)


def _existing_rows(chunk_dir: Path) -> dict[str, dict]:
    rows = {}
    for path in sorted(chunk_dir.glob("chunk-*.csv")):
        for row in read_results(path):
            if row.get("status") != STATUS_LOST and isinstance(row.get("key"), str):
                rows[row["key"]] = row
    return rows


def run_sweep(
    runs: Sequence[SweepRun],
    task_fn: Callable,
    out_dir,
    *,
    metrics: Sequence[str] = DEFAULT_METRICS,
    steady_window: float = 10.0,
    chunk_size: int = 8,
    client=None,
    serial: bool = False,
    shared: dict | None = None,
    max_runs: int | None = None,
    manifest: dict | None = None,
    on_row: Callable[[dict, int, int], None] | None = None,
) -> SweepOutcome:
    """Execute ``runs`` (those without rows in ``out_dir`` yet) and combine every row.

    Parameters
    ----------
    runs : sequence of SweepRun
        From :func:`expand_runs`, with ``payload`` (and maybe ``extras``/``failure``) filled in.
    task_fn : callable
        ``task_fn(payload, shared) -> Result``; a module-level function (pickled by reference
        for the workers). It may raise: the run is then a failure row with status ``error``.
    out_dir : path-like
        Output folder: ``chunks/chunk-NNNNNN.csv``, ``results.csv`` and ``sweep.json``.
    metrics : sequence of str
        Metric columns to keep (see :data:`METRICS`).
    steady_window : float
        Averaging window of ``steady_lat_m`` [s].
    chunk_size : int
        Rows per chunk file.
    client : distributed.Client, optional
        Run on this Dask client (required unless ``serial``).
    serial : bool
        Run the same tasks one after another in this process.
    shared : dict, optional
        Data every task needs (e.g. FMU bytes): scattered once to all workers (broadcast) and
        passed to ``task_fn`` as its second argument.
    max_runs : int, optional
        Execute at most this many new runs, then stop (the sweep can be resumed later).
    manifest : dict, optional
        A description of the sweep (spec, base scenario); its fingerprint is stored in
        ``sweep.json`` and must match when resuming into the same folder.
    on_row : callable, optional
        ``on_row(row, done, total)`` after each new row (progress display).

    Returns
    -------
    SweepOutcome

    Raises
    ------
    SweepError
        ``out_dir`` holds a different sweep; neither a client nor ``serial`` given.
    """
    if client is None and not serial:
        raise SweepError("run_sweep", [("client", None, "a distributed.Client, or serial=True")])
    out = Path(out_dir)
    chunk_dir = out / "chunks"
    chunk_dir.mkdir(parents=True, exist_ok=True)
    _check_manifest(out, manifest)
    param_paths = list(dict.fromkeys(p for run in runs for p in run.params))
    extras = list(dict.fromkeys(k for run in runs for k in run.extras))
    columns = _columns(param_paths, list(metrics), extras)
    existing = _existing_rows(chunk_dir)
    todo = [run for run in runs if run.key not in existing]
    skipped = len(runs) - len(todo)
    if max_runs is not None:
        todo = todo[:max(0, int(max_runs))]
    log.info("sweep: %d runs, %d already done, %d to run now", len(runs), skipped, len(todo))

    writer = _ChunkWriter(chunk_dir, columns, chunk_size)
    new_rows: dict[str, dict] = {}
    total = len(todo)
    interrupted = False

    def collect(raw: dict, run: SweepRun) -> None:
        row = _finish_row(raw, run)
        new_rows[run.key] = row
        writer.add(row)
        if on_row is not None:
            on_row(row, len(new_rows), total)

    try:
        known = [run for run in todo if run.failure is not None]
        for run in known:
            collect(failure_row(*run.failure) | {"task_time_s": 0.0}, run)
        pending = [run for run in todo if run.failure is None]
        if serial:
            for run in pending:
                collect(_execute(task_fn, run.index, run.key, run.payload, shared or {},
                                 steady_window), run)
        else:
            _run_distributed(client, pending, task_fn, shared or {}, steady_window, collect)
    except KeyboardInterrupt:
        interrupted = True
        log.warning("sweep interrupted: %d new rows kept; run again to resume", len(new_rows))
        raise
    finally:
        writer.flush()
        outcome = _combine(out, runs, existing, new_rows, columns, len(todo), skipped)
        outcome.interrupted = interrupted
    return outcome


def _run_distributed(client, runs, task_fn, shared, steady_window, collect) -> None:
    from distributed import as_completed

    if not runs:
        return
    shared_f = {name: client.scatter(value, broadcast=True, hash=False)
                for name, value in shared.items()}
    by_key = {}
    futures = []
    for run in runs:
        fut = client.submit(_execute, task_fn, run.index, run.key, run.payload, shared_f,
                            steady_window, key=f"pushtrain-run-{run.key}-{os.getpid()}-{id(runs)}",
                            pure=False)
        by_key[fut.key] = run
        futures.append(fut)
    try:
        for fut in as_completed(futures):
            run = by_key[fut.key]
            try:
                raw = fut.result()
            except Exception as exc:  # the worker died or the task was cancelled
                raw = failure_row(STATUS_LOST, f"{type(exc).__name__}: {exc}")
                raw["task_time_s"] = math.nan
            collect(raw, run)
            fut.release()
    finally:
        client.cancel([f for f in futures if not f.done()])


def _combine(out: Path, runs, existing, new_rows, columns, attempted, skipped) -> SweepOutcome:
    rows = []
    for run in runs:
        row = new_rows.get(run.key) or existing.get(run.key)
        if row is not None:
            rows.append({c: row.get(c) for c in columns})
    results = out / "results.csv"
    write_rows_csv(results, rows, columns)
    rows = read_results(results)  # the same decoded values whether a row is new or resumed
    return SweepOutcome(rows, columns, len(runs), len(new_rows), skipped, out,
                        {"results": str(results), "chunks": str(out / "chunks")})
