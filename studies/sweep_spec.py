"""Sweep specifications: the spec model, field paths and run counts.

A sweep specification (:class:`SweepSpec`, a TOML file of its own, read by
:func:`load_sweep_spec`) names scenario fields by path (``"sensors.joint_bias_deg[2]"``,
``"controller.model_link"``, ``"train.n"``, ``"events[0].distance"``) and gives each a list of
values, a linspace ``range`` or (Monte Carlo) a seeded random distribution. :func:`resolve`
applies the overrides and one run's values to a plain scenario dict; :func:`count_runs` says how
many runs a spec makes without making them.

Units: lengths [m], times [s], angles in degrees only in ``*_deg`` columns.
"""

from __future__ import annotations

import copy
import math
import re
from typing import Annotated, Literal, Union

import numpy as np
from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    StrictBool,
    StrictInt,
    model_validator,
)

from pushtrain.errors import FieldErrors, SweepError
from pushtrain.limits import SWEEP_MAX_TOTAL
from pushtrain.validation import FiniteFloat, Integer, PositiveFloat, read_toml, validate_model

__all__ = ["RangeSpec", "ParameterSpec", "SweepSpec", "METRICS", "DEFAULT_METRICS",
           "TIMING_COLUMNS", "OK_STATUSES", "STATUS_ERROR", "STATUS_LOST", "parse_path", "get_path",
           "set_path", "resolve", "parse_sweep_spec", "load_sweep_spec", "count_runs", "check_size",
           "DEFAULT_MAX_TOTAL", "plain_value"]

Value = Union[StrictBool, StrictInt, FiniteFloat, str, list[Union[StrictInt, FiniteFloat]]]

OK_STATUSES = ("goal_reached", "completed")
STATUS_ERROR = "error"  # the task raised (bad combination found at run time, FMU load failure, ...)
STATUS_LOST = "lost"  # the worker died or the task was cancelled: run again on resume
SPEC_FORMAT = "pushtrain.sweep"
DEFAULT_MAX_TOTAL = SWEEP_MAX_TOTAL
"""Most runs a sweep makes unless the caller raises the limit (``max_total``, ``--max-total``)."""

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


def plain_value(value):
    """``value`` with numpy scalars (also inside lists) as plain Python numbers."""
    if isinstance(value, (np.floating,)):
        return float(value)
    if isinstance(value, (np.integer,)):
        return int(value)
    if isinstance(value, (list, tuple)):
        return [plain_value(v) for v in value]
    return value


# ----------------------------------------------------------------------------------------- spec
class _Section(BaseModel):
    # strict: a TOML boolean or string is not a number (num = true is not 1, num = "3" not 3)
    model_config = ConfigDict(extra="forbid", frozen=True, strict=True)


class RangeSpec(_Section):
    """``num`` evenly spaced values from ``start`` to ``stop`` (both included)."""

    start: FiniteFloat
    stop: FiniteFloat
    num: Annotated[Integer, Field(ge=1, le=100_000)]


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

    @property
    def n_values(self) -> int:
        """Length of the grid axis (``values`` or ``range.num``), without making the values."""
        if self.values is not None:
            return len(self.values)
        if self.range is not None:
            return self.range.num
        raise ValueError(f"{self.path}: a distribution has no grid values")

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
    samples: Annotated[Integer, Field(ge=1, le=1_000_000)] | None = None
    seed: Annotated[Integer, Field(ge=1)] = 1  # Monte Carlo draws; base of seed_per_run
    seed_per_run: bool = False  # set the scenario's seed (noise, planner) to seed + run index
    parameters: Annotated[list[ParameterSpec], Field(min_length=1)]
    metrics: list[Literal[tuple(METRICS)]] | None = None  # type: ignore[valid-type]
    steady_window: PositiveFloat = 10.0
    chunk_size: Annotated[Integer, Field(ge=1, le=10_000)] = 8
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
    def shape(self) -> tuple[int, ...]:
        """Axis lengths of the grid (first parameter first), or ``(samples,)`` for Monte Carlo."""
        if self.mode == "monte_carlo":
            return (int(self.samples),)
        return tuple(p.n_values for p in self.parameters)

    @property
    def n_runs(self) -> int:
        """Number of runs, computed from :attr:`shape` (nothing is expanded)."""
        return math.prod(self.shape)

    @property
    def size_text(self) -> str:
        """``"grid 3 x 100000"`` or ``"monte_carlo, 500 samples"``."""
        if self.mode == "monte_carlo":
            return f"monte_carlo, {self.samples} samples"
        return "grid " + " x ".join(str(n) for n in self.shape)


def parse_sweep_spec(data: dict, source: str = "<sweep>") -> SweepSpec:
    """Validate plain data (a parsed TOML document) into a :class:`SweepSpec`.

    Raises
    ------
    SweepError
        Every problem at once, each with its field path, value and what is allowed.
    """
    return validate_model(SweepSpec, data, source, SweepError)


def load_sweep_spec(path) -> SweepSpec:
    """Read and validate a sweep TOML file (raises :class:`SweepError`)."""
    return parse_sweep_spec(read_toml(path, SweepError), str(path))



def count_runs(spec: SweepSpec) -> int:
    """How many runs ``spec`` makes: the product of the grid's axis lengths, or ``samples``.

    Cheap for any size (no run is made), so a caller can refuse a huge sweep before expanding it.
    """
    return spec.n_runs


def check_size(spec: SweepSpec, max_total: int | None = DEFAULT_MAX_TOTAL) -> int:
    """The number of runs of ``spec`` (:func:`count_runs`), refused above ``max_total``.

    Raises
    ------
    SweepError
        The spec makes more than ``max_total`` runs (None: no limit); nothing was expanded.
    """
    n_runs = count_runs(spec)
    if max_total is not None and n_runs > max_total:
        raise SweepError(spec.name, [(
            f"runs ({spec.size_text})", n_runs,
            f"more than the limit of {max_total} runs (max_total, --max-total): use fewer "
            "values or samples, or raise the limit")])
    return n_runs
