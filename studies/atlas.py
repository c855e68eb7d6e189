"""The facility atlas: which stations a train reaches, and with how many trailers.

:func:`load_facility` reads a facility file (a scenario's ``[map]``, ``[[stations]]`` and
optional ``[train]``, ``[planner]``, ``[sim]``, ``[controller]`` sections). :func:`atlas` plans
and co-simulates, for every ordered pair of stations, the mission from one to the other with
n = 1, 2, ... trailers exactly as ``plan-and-run`` does, and writes ``atlas.json``,
``atlas.csv``, ``missions/FROM-TO-nK.toml``, ``atlas.png``, ``matrix.png`` and ``report.html``.

The work: one task per pair tries n in increasing order and stops at the first n that fails
(the answer is the largest n before it). A train of more trailers needs at least the room of a
shorter one: its last trailer is the same and its followers sweep more, so a larger n is not
tried once one fails (its mission file is still written, and replays to a failure). A pair
found impossible (no way of the last trailer's width: "unreachable") is impossible for every n.
Pairs run in parallel on Dask (a LocalCluster by default, any cluster by its scheduler's
address) or serially, with the same answers: a plan depends on its scenario alone. Each pair's
answer is written to ``pairs/FROM-TO.json`` as soon as it is known; a run into the same folder
with the same facility and trailer range resumes where it stopped.

Units: lengths [m], times [s], angles in degrees only in ``*_deg`` fields.
"""

from __future__ import annotations

import contextlib
import csv
import hashlib
import io
import json
import logging
import math
import re
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from pushtrain.errors import InputError, PlanningError, PushtrainError, ScenarioError
from pushtrain.files import atomic_write_text
from pushtrain.fmu.variables import MAX_TRAILERS
from pushtrain.mission.scenario import parse_scenario

__all__ = ["Facility", "AtlasError", "load_facility", "parse_trailers", "mission_dict",
           "run_pair", "atlas", "SECTIONS", "RESULT_FIELDS"]

log = logging.getLogger(__name__)

SECTIONS = ("map", "train", "planner", "sim", "controller")
"""The scenario sections a facility file may hold (applied to every mission)."""
RESULT_FIELDS = ("status", "plan_s", "length_m", "duration_s", "max_phi_deg", "min_clearance_m",
                 "reason")
"""What ``atlas.json`` records of each mission (``by_n``) and ``atlas.csv`` per row."""
_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.]*")
"""A station's name (names files): matched whole (``fullmatch``; a ``$`` would let a trailing
newline through)."""
_FACILITY_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]*")
"""A facility's name (names its missions, their files and the page's title)."""
_TRAILERS = re.compile(r"([0-9]{1,6})(?:-([0-9]{1,6}))?|[0-9]{1,6}(?:,[0-9]{1,6})+")
"""``--trailers``: a count, a range of two counts or counts separated by commas (plain digits:
no sign, no ``_``, no spaces inside)."""


class AtlasError(InputError):
    """A facility file, an option or an output folder the atlas cannot use (exit 2)."""


@dataclass(frozen=True)
class Facility:
    """A facility: its ``name``, the scenario ``sections`` shared by every mission and the
    ``stations`` as (name, x [m], y [m], theta_deg) (the last trailer's pose, as a scenario's
    start and goal)."""

    name: str
    sections: dict
    stations: tuple

    def digest(self) -> str:
        """A hash of everything that decides the answers (for resuming)."""
        text = json.dumps({"sections": self.sections, "stations": self.stations},
                          sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()[:16]


def _bad(where: str, value, allowed: str) -> AtlasError:
    from pushtrain.validation import clipped

    return AtlasError(f"{where} = {clipped(repr(value))}: {allowed}")


def load_facility(path) -> Facility:
    """The facility file at ``path``, checked: every station named once with finite
    coordinates, every mission a valid scenario (errors name the field)."""
    from pushtrain.validation import read_toml

    data = read_toml(path, ScenarioError)
    return parse_facility(data, str(path))


def parse_facility(data: dict, source: str = "<facility>") -> Facility:
    """:func:`load_facility` of a parsed document."""
    allowed_keys = {"name", "description", "stations", *SECTIONS}
    for key in data:
        if key not in allowed_keys:
            raise _bad(f"{source}: {key}", "...", "not a facility field; allowed: "
                       + ", ".join(sorted(allowed_keys)))
    if "map" not in data:
        raise _bad(f"{source}: map", None, "a [map] section is needed (as in a scenario)")
    stations = data.get("stations")
    if not isinstance(stations, list) or len(stations) < 2:
        raise _bad(f"{source}: stations", stations,
                   "at least two [[stations]], each with name, x, y and theta_deg")
    seen, out = set(), []
    for k, st in enumerate(stations):
        where = f"{source}: stations[{k}]"
        if not isinstance(st, dict):
            raise _bad(where, st, "a table with name, x, y and theta_deg")
        extra = set(st) - {"name", "x", "y", "theta_deg"}
        if extra:
            raise _bad(f"{where}.{sorted(extra)[0]}", st[sorted(extra)[0]],
                       "not a station field; allowed: name, x, y, theta_deg")
        name = st.get("name")
        if not isinstance(name, str) or not _NAME.fullmatch(name) or len(name) > 40:
            raise _bad(f"{where}.name", name, "1-40 letters, digits, '_' or '.', starting "
                       "with a letter or digit (it names files)")
        if name in seen:
            raise _bad(f"{where}.name", name, "each station's name once")
        seen.add(name)
        pose = []
        for field in ("x", "y", "theta_deg"):
            v = st.get(field)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise _bad(f"{where}.{field}", v, "a finite number"
                           + (" [deg]" if field == "theta_deg" else " [m]"))
            pose.append(float(v))
        out.append((name, *pose))
    name = data.get("name", Path(source).stem)
    if not isinstance(name, str) or not _FACILITY_NAME.fullmatch(name) or len(name) > 60:
        raise _bad(f"{source}: name", name, "1-60 letters, digits, '_', '.' or '-', starting "
                   "with a letter or digit (it names the missions and their files)")
    train = data.get("train")
    if isinstance(train, dict) and "n" in train:
        raise _bad(f"{source}: train.n", train["n"], "not in a facility: the atlas tries the "
                   "trailer counts of --trailers (e.g. --trailers "
                   f"{train['n']!s:.12}); remove n from [train]")
    facility = Facility(name, {s: data[s] for s in SECTIONS if s in data}, tuple(out))
    # every station must be a valid start and goal of a scenario, in the map's free space:
    # checked once, with n = 1 (a longer train that does not fit there fails its missions)
    from pushtrain.mission.runner import check_start_in_map

    problems = []
    for k, station in enumerate(out):
        other = out[1] if k == 0 else out[0]
        try:
            check_start_in_map(parse_scenario(mission_dict(facility, station[0], other[0], 1),
                                              source))
        except ScenarioError as exc:
            problems += [text.strip().replace("start", f"stations[{k}] ({station[0]})", 1)
                         for text in str(exc).splitlines()[1:]
                         if text.strip().startswith("start")]
            problems += [text.strip() for text in str(exc).splitlines()[1:]
                         if not text.strip().startswith(("start", "goal"))]
        except ValueError as exc:
            problems.append(f"map: {exc}")
    if problems:
        unique = list(dict.fromkeys(problems))
        raise AtlasError(f"{source}: {len(unique)} problem(s)\n  " + "\n  ".join(unique))
    return facility


def parse_trailers(text: str) -> tuple[int, ...]:
    """``--trailers``: "1-5", "2" or "1,3,5" as a sorted tuple of trailer counts (the bounds
    are checked before a range is expanded)."""
    allowed = f"a range like 1-5, a count, or counts like 1,3,5, within 1..{MAX_TRAILERS}"
    match = _TRAILERS.fullmatch(text.strip()) if isinstance(text, str) else None
    if match is None:
        raise _bad("--trailers", text, allowed)
    if match.group(1) is not None:
        lo = int(match.group(1))
        hi = int(match.group(2)) if match.group(2) is not None else lo
        if not 1 <= lo <= hi <= MAX_TRAILERS:
            raise _bad("--trailers", text, allowed + " (a range from low to high)")
        return tuple(range(lo, hi + 1))
    values = [int(p) for p in text.strip().split(",")]
    if any(v < 1 or v > MAX_TRAILERS for v in values):
        raise _bad("--trailers", text, allowed)
    return tuple(sorted(set(values)))


def mission_dict(facility: Facility, origin: str, target: str, n: int) -> dict:
    """The plan-and-run scenario (plain data) of the mission from station ``origin`` to
    ``target`` with ``n`` trailers."""
    poses = {s[0]: s[1:] for s in facility.stations}
    data = json.loads(json.dumps(facility.sections))  # a deep copy of plain data
    data["train"] = {**data.get("train", {}), "n": n}
    data.update({"name": f"{facility.name}-{origin}-{target}-n{n}",
                 "description": f"atlas of {facility.name}: {origin} to {target} with {n} "
                                f"trailer{'s' if n > 1 else ''}",
                 "mission": {"kind": "plan"},
                 "start": dict(zip(("x", "y", "theta_deg"), poses[origin], strict=True)),
                 "goal": dict(zip(("x", "y", "theta_deg"), poses[target], strict=True))})
    order = ["name", "description", "mission", "train", "map", "start", "goal", "planner",
             "sim", "controller"]
    return {k: data[k] for k in order if k in data}


# ---------------------------------------------------------------------------- one pair
def _one_mission(data: dict) -> dict:
    """Plan and co-simulate one mission as plan-and-run does: what ``atlas.json`` records, and
    (for atlas.png) the planned path or the failure's route and bottleneck."""
    import numpy as np

    from pushtrain.mission import runner

    sc = parse_scenario(data, data["name"])
    out = dict.fromkeys(RESULT_FIELDS)
    t0 = time.perf_counter()
    try:
        path = runner.plan_path(sc)
    except PlanningError as exc:
        details = exc.details or {}
        route = details.get("route") or {}
        out.update(status="no_plan", plan_s=round(time.perf_counter() - t0, 3),
                   reason=exc.reason, message=str(exc)[:400],
                   bottleneck=details.get("bottleneck") or route.get("bottleneck"),
                   route=route.get("points"))
        return out
    out["plan_s"] = round(time.perf_counter() - t0, 3)
    out["length_m"] = round(path.length, 3)
    reference = path.to_reference(speed=sc.planner.speed, cusp_dwell=sc.planner.cusp_dwell)
    try:
        result = runner.run_scenario(sc, None, reference=reference, progress=False)
    except PushtrainError as exc:  # a co-simulation that could not run is this mission's end
        out.update(status="error", reason=type(exc).__name__, message=str(exc)[:400])
        return out
    summary = result.summary
    phis = summary.get("max_abs_phi_deg") or [math.nan]
    clearance = (summary.get("map_check") or {}).get("min_clearance_m")
    step = max(1, len(path.poses) // 300)
    out.update(status=result.status, duration_s=round(float(summary.get("t_final", math.nan)), 3),
               max_phi_deg=round(float(np.nanmax(phis)), 2),
               min_clearance_m=None if clearance is None else round(float(clearance), 4),
               reason=None if result.ok else result.status,
               message=None if result.ok else result.message[:400],
               path=np.round(path.poses[::step, :2], 3).tolist())
    return out


def run_pair(facility: Facility, origin: str, target: str, trailers) -> dict:
    """The answer for one ordered pair: n in ``trailers`` in increasing order until one fails.
    ``max_trailers`` is the largest n before the first failure (0 when the first fails)."""
    by_n, shapes, best = {}, {}, 0
    for n in trailers:
        got = _one_mission(mission_dict(facility, origin, target, n))
        shapes[n] = {k: got.pop(k) for k in ("path", "route", "bottleneck", "message")
                     if k in got}
        by_n[str(n)] = got
        if got["status"] != "goal_reached":
            break
        best = n
    last = max(int(k) for k in by_n)
    return {"from": origin, "to": target, "max_trailers": best, "by_n": by_n,
            "shape": shapes[best] if best else shapes[last],
            "failure": None if by_n[str(last)]["status"] == "goal_reached" else
            {"n": last, **{k: shapes[last].get(k) for k in ("message", "bottleneck", "route")}}}


def _pair_task(facility: Facility, origin: str, target: str, trailers) -> dict:
    """:func:`run_pair` on a worker, quiet (the client reports progress)."""
    logging.getLogger("pushtrain").setLevel(logging.WARNING)
    return run_pair(facility, origin, target, trailers)


# ---------------------------------------------------------------------------- the whole
def _pair_file(out: Path, origin: str, target: str) -> Path:
    return out / "pairs" / f"{origin}-{target}.json"


def _prepare_folder(out: Path, facility: Facility, trailers) -> dict:
    """The folder ready for this atlas; the answers already there of the same atlas."""
    manifest = {"facility": facility.digest(), "trailers": list(trailers)}
    marker = out / "atlas_manifest.json"
    if out.exists() and not out.is_dir():
        raise _bad("--out", str(out), "a folder (new, empty, or an earlier atlas of the same "
                   "facility and --trailers)")
    if out.is_dir() and any(out.iterdir()):
        if not marker.is_file():
            raise _bad("--out", str(out), "a new or empty folder, or an earlier atlas's "
                       "(this one holds other files)")
        try:
            old = json.loads(marker.read_text())
        except (OSError, ValueError):
            old = None
        if old != manifest:
            what = ("of another facility" if (old or {}).get("facility") != manifest["facility"]
                    else f"with --trailers {(old or {}).get('trailers')}")
            raise _bad("--out", str(out), f"an atlas {what} is there; give a new folder")
    (out / "pairs").mkdir(parents=True, exist_ok=True)
    (out / "missions").mkdir(exist_ok=True)
    atomic_write_text(marker, json.dumps(manifest))
    done = {}
    for f in (out / "pairs").glob("*.json"):
        with contextlib.suppress(OSError, ValueError):
            answer = json.loads(f.read_text())
            done[(answer["from"], answer["to"])] = answer
    return done


def _write_missions(out: Path, facility: Facility, answer: dict, trailers) -> None:
    """Every mission of the pair as a scenario file: the n it ran, and the larger n it did not
    try (a replay of those fails too)."""
    import tomli_w

    for n in trailers:
        data = mission_dict(facility, answer["from"], answer["to"], int(n))
        atomic_write_text(out / "missions" / f"{answer['from']}-{answer['to']}-n{n}.toml",
                          tomli_w.dumps(data))


def atlas(facility: Facility, trailers, out_dir, *, serial: bool = False, client=None,
          scheduler: str | None = None, workers: int | None = None,
          progress: Callable[[int, int, float], None] | None = None,
          only: tuple | None = None, on_cluster: Callable[[str], None] | None = None) -> dict:
    """Answer every ordered pair of ``facility``'s stations (those named in ``only``, if
    given) for ``trailers`` and write the atlas into ``out_dir``; returns ``atlas.json``'s
    content. ``progress(done, total, elapsed_s)`` is called as pairs finish (``elapsed_s``
    counted from when the work started, after Dask's start-up); ``on_cluster(text)`` says
    what Dask is doing before the first pair starts (starting a cluster: tens of seconds)."""
    out = Path(out_dir)
    trailers = tuple(trailers)
    names = [s[0] for s in facility.stations if only is None or s[0] in only]
    pairs = [(a, b) for a in names for b in names if a != b]
    done = _prepare_folder(out, facility, trailers)
    todo = [p for p in pairs if p not in done]
    t0 = [time.perf_counter()]

    def started() -> None:
        t0[0] = time.perf_counter()

    def record(answer: dict) -> None:
        done[(answer["from"], answer["to"])] = answer
        _write_missions(out, facility, answer, trailers)
        atomic_write_text(_pair_file(out, answer["from"], answer["to"]), json.dumps(answer))
        if progress:
            progress(sum(p in done for p in pairs), len(pairs), time.perf_counter() - t0[0])

    if progress:
        progress(len(pairs) - len(todo), len(pairs), 0.0)
    if serial or not todo:
        for a, b in todo:
            record(run_pair(facility, a, b, trailers))
    else:
        _on_dask(todo, facility, trailers, record, client=client, scheduler=scheduler,
                 workers=workers, started=started, on_cluster=on_cluster)
    return _write_outputs(out, facility, trailers, [done[p] for p in pairs], names)


def _on_dask(todo, facility, trailers, record, *, client, scheduler, workers, started,
             on_cluster) -> None:
    from .sweep import completed, dask_client

    with contextlib.ExitStack() as stack:
        if client is None:
            if on_cluster is not None:
                on_cluster(f"connecting to the Dask scheduler at {scheduler}" if scheduler else
                           "starting a local Dask cluster of "
                           f"{workers or 'one worker per core'}"
                           f"{' worker(s)' if workers else ''}")
            client = stack.enter_context(dask_client(scheduler, workers))
        started()
        shared = client.scatter(facility, broadcast=True)
        futures = [client.submit(_pair_task, shared, a, b, trailers, pure=False)
                   for a, b in todo]
        try:
            for future in completed(futures):
                record(future.result())
        finally:
            for f in futures:
                f.cancel()


def _write_outputs(out: Path, facility: Facility, trailers, answers: list, names) -> dict:
    stations = [{"name": s[0], "x": s[1], "y": s[2], "theta_deg": s[3]}
                for s in facility.stations if s[0] in names]
    doc = {"facility": facility.name, "trailers": list(trailers), "stations": stations,
           "pairs": [{k: a[k] for k in ("from", "to", "max_trailers", "by_n")}
                     for a in answers]}
    atomic_write_text(out / "atlas.json", json.dumps(doc, indent=1))
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["from", "to", "max_trailers", "n", *RESULT_FIELDS])
    for a in answers:
        for n, r in a["by_n"].items():
            w.writerow([a["from"], a["to"], a["max_trailers"], n,
                        *("" if r.get(k) is None else r[k] for k in RESULT_FIELDS)])
    atomic_write_text(out / "atlas.csv", buf.getvalue())
    try:
        from pushtrain.mission.runner import world_of
        from pushtrain.report.atlas import atlas_figure, matrix_figure, save_figure
        from pushtrain.report.html import write_table_page

        first = mission_dict(facility, names[0], names[1], 1)
        world = world_of(parse_scenario(first, facility.name))
        images = [save_figure(atlas_figure(world, stations, answers, max(trailers)),
                              out / "atlas.png"),
                  save_figure(matrix_figure(names, answers, max(trailers)), out / "matrix.png")]
        rows = [[a["from"], a["to"], a["max_trailers"], int(n), *(r.get(k) for k in
                                                                   RESULT_FIELDS),
                 (a.get("failure") or {}).get("message") if r["status"] != "goal_reached"
                 else None, f"missions/{a['from']}-{a['to']}-n{n}.toml"]
                for a in answers for n, r in a["by_n"].items()]
        write_table_page(out / "report.html", f"Atlas of {facility.name}",
                         {"facility": facility.name, "stations": len(names),
                          "pairs": len(answers), "trailers": f"{min(trailers)}-{max(trailers)}",
                          "pairs reached with every n": sum(a["max_trailers"] == max(trailers)
                                                            for a in answers),
                          "pairs reached with no n": sum(a["max_trailers"] == 0
                                                         for a in answers)},
                         ["from", "to", "max_trailers", "n", *RESULT_FIELDS, "message",
                          "mission file (plan-and-run replays it)"], rows,
                         images=images, fail_column="reason",
                         message="Each row is one mission (missions/FROM-TO-nK.toml replays "
                                 "it with plan-and-run). Click a row to see it.")
    except Exception:  # the pictures must never lose the answers
        log.exception("drawing the atlas's pictures failed")
    return doc
