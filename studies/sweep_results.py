"""Sweep results on disk: CSV rows, chunk files, the resume guard and the combined table.

Rows are written incrementally as CSV chunks (``chunks/chunk-000012.csv``, each written
atomically) and combined into ``results.csv``; a sweep re-run into the same folder skips the runs
whose rows exist (resume), except rows with status ``lost`` (the worker died: run again).
``sweep.json`` holds the fingerprint of the spec and base scenario, so rows of a different sweep
are never mixed in.
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import logging
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

from pushtrain.errors import SweepError
from pushtrain.files import atomic_write_text

from .sweep_runs import SweepRun
from .sweep_spec import OK_STATUSES, SPEC_FORMAT, STATUS_LOST, plain_value

__all__ = ["SweepOutcome", "read_results", "write_rows_csv", "columns_of", "finish_row",
           "ChunkWriter", "check_manifest", "existing_rows", "combine"]

log = logging.getLogger(__name__)


# -------------------------------------------------------------------------------------- CSV rows
def _encode(value) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return "nan" if math.isnan(value) else repr(value)
    if isinstance(value, (int, str)):
        return str(value)
    return json.dumps(plain_value(value))


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
        return [{c: v if c in _TEXT_COLUMNS else _decode(v)
                 for c, v in zip(header, line, strict=False)}
                for line in reader]



# ------------------------------------------------------------------------------------- outcome
@dataclass
class SweepOutcome:
    """What :func:`run_sweep` did.

    ``rows`` holds the row of each run done so far (all runs when ``complete``), in run order;
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
    def remaining(self) -> int:
        """Runs still to do: those without a row, and those whose row is ``lost``."""
        return self.n_runs - sum(1 for r in self.rows if r["status"] != STATUS_LOST)

    @property
    def complete(self) -> bool:
        """Every run has a row, and none was lost (a lost run runs again on resume)."""
        return self.remaining == 0

    @property
    def failures(self) -> list[dict]:
        return [r for r in self.rows if not r["ok"]]


# ---------------------------------------------------------------------------------- chunk files
def columns_of(param_paths, metrics, extras) -> list[str]:
    """The columns of a sweep table, in order."""
    return (["index", "key", *param_paths, "status", "ok", "error", *metrics, *extras,
             "task_time_s"])


def finish_row(row: dict, run: SweepRun) -> dict:
    """A task's row completed with the run's parameters, extras, ``ok`` and ``error``."""
    row = dict(row)
    row.update(run.params)
    row.update(run.extras)
    row["index"], row["key"] = run.index, run.key
    row["ok"] = row["status"] in OK_STATUSES
    row["error"] = "" if row["ok"] else row.get("message", "")
    return row


class ChunkWriter:
    """Buffers rows and writes every ``chunk_size`` of them as the next ``chunk-NNNNNN.csv``."""

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


def check_out_folder(out_dir: Path) -> None:
    """Refuse an output folder that is neither new, nor empty, nor a sweep's own (it has
    ``sweep.json`` or ``chunks/``): a sweep's files must not mix with a run's or anything else
    (a run folder is replaced whole by the next run into it)."""
    if out_dir.exists() and not out_dir.is_dir():
        raise SweepError(str(out_dir), [("out", str(out_dir), "is a file: a sweep needs a folder")])
    if not out_dir.is_dir() or (out_dir / "sweep.json").is_file() or (out_dir / "chunks").is_dir():
        return
    others = sorted(p.name for p in out_dir.iterdir())
    if others:
        listed = ", ".join(others[:3]) + (", ..." if len(others) > 3 else "")
        raise SweepError(str(out_dir), [(
            "out", str(out_dir),
            f"holds other files ({listed}): a sweep writes into a new or empty folder, or "
            "resumes in its own")])


def check_manifest(out_dir: Path, manifest: dict | None) -> None:
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


def existing_rows(chunk_dir: Path) -> dict[str, dict]:
    """Rows of earlier chunks by run key, without ``lost`` rows (those runs are run again)."""
    rows = {}
    for path in sorted(chunk_dir.glob("chunk-*.csv")):
        for row in read_results(path):
            if row.get("status") != STATUS_LOST and isinstance(row.get("key"), str):
                rows[row["key"]] = row
    return rows


def combine(out: Path, runs, existing, new_rows, columns, skipped) -> SweepOutcome:
    """Write ``results.csv`` (one row per run that has one, in run order) and read it back."""
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
