"""A run folder as a rosbag2 folder: :func:`export_bag`.

The bag is ``metadata.yaml`` and one MCAP file (zstd chunks), rosbag2 metadata version 8 (QoS
profiles as a YAML string, type description hashes), standard ROS 2 messages only
(:data:`TOPICS`), written by the ``rosbags`` library (PyPI; pure Python, maintained, writes MCAP
and the metadata that ``ros2 bag`` needs; no CDR is written by hand here).

Time: a sample recorded at simulated time t [s] is stamped ``epoch + t`` (nanoseconds since the
Unix epoch), both in the bag and in every message header; the default epoch is
:data:`EPOCH_S` (2000-01-01T00:00:00Z), so that no stamp is zero (tf2 reads time zero as "the
latest"). Every recorded sample is written (the run's communication step, 200 Hz by default),
unless ``rate_hz`` thins them to every k-th sample (at least 10 Hz; the first and last are kept).

Frames: ``map`` is the world; ``base_link`` is the robot (origin at its centre) and
``trailer_1`` .. ``trailer_n`` the trailers (origin at the axle midpoint), each a child of ``map``
(one transform per body on ``/tf``, not a chain of hitch frames, so each pose is read directly).
Every body frame's +x is pushtrain's heading, which points toward the robot: pushing drives the
train along -x.
"""

from __future__ import annotations

import json
import logging
import math
import os
import shutil
import tempfile
import uuid
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pushtrain.errors import InputError
from pushtrain.files import WriteError

from . import messages as msg
from .run_folder import RunFolder, read_run

__all__ = ["export_bag", "BagExport", "TOPICS", "EPOCH_S", "MIN_RATE_HZ", "MARKER_RATE_HZ",
           "robot_frame", "trailer_frame", "joint_names", "map_cells"]

log = logging.getLogger(__name__)

EPOCH_S = 946_684_800
"""Default epoch [s since 1970-01-01T00:00:00Z] of simulated time zero: 2000-01-01T00:00:00Z."""
MIN_RATE_HZ = 10.0
"""Lowest sample rate [Hz] the bag may be thinned to."""
MARKER_RATE_HZ = 10.0
"""Rate [Hz] of ``/train_markers`` (frame-locked: the bodies move with ``/tf`` in between)."""

TOPICS = {
    "/map": "nav_msgs/msg/OccupancyGrid",
    "/plan": "nav_msgs/msg/Path",
    "/reference": "nav_msgs/msg/Path",
    "/goal": "geometry_msgs/msg/PoseStamped",
    "/tf": "tf2_msgs/msg/TFMessage",
    "/joint_states": "sensor_msgs/msg/JointState",
    "/joint_states/measured": "sensor_msgs/msg/JointState",
    "/train_markers": "visualization_msgs/msg/MarkerArray",
    "/cmd_vel": "geometry_msgs/msg/Twist",
    "/tracking_error": "geometry_msgs/msg/Vector3Stamped",
    "/summary": "std_msgs/msg/String",
}
"""Every topic a bag may hold and its message type (a run writes the ones it has data for)."""

LATCHED = ("/map", "/plan", "/reference", "/goal", "/summary")
"""Topics written once, at the start, offered ``transient_local`` (latched)."""

ROBOT_RGBA = (0.12, 0.47, 0.71, 0.9)
TRAILER_RGBA = (1.0, 0.50, 0.05, 0.8)
LAST_TRAILER_RGBA = (0.84, 0.15, 0.16, 0.8)


def robot_frame() -> str:
    """The robot's TF frame."""
    return "base_link"


def trailer_frame(i: int) -> str:
    """Trailer ``i``'s TF frame (i = 1..n)."""
    return f"trailer_{i}"


def joint_names(n: int) -> list[str]:
    """Joint names ``joint_1..n`` (joint i between body i-1 and trailer i), on
    ``/joint_states`` (the true angles phi_i = theta_{i-1} - theta_i) and on
    ``/joint_states/measured`` (what the controller's joint sensors read), in this order on
    both: index k is joint k+1 whatever n is."""
    return [f"joint_{i}" for i in range(1, n + 1)]


@dataclass(frozen=True)
class BagExport:
    """What :func:`export_bag` wrote: the bag folder, its MCAP file and {topic: messages}."""

    folder: Path
    mcap: Path
    counts: dict


def _qos(latched: bool):
    from rosbags.interfaces import (
        Qos,
        QosDurability,
        QosHistory,
        QosLiveliness,
        QosReliability,
        QosTime,
    )

    forever = QosTime(2147483647, 4294967295)  # rmw's "infinite" duration
    return [Qos(QosHistory.KEEP_LAST, 1 if latched else 10, QosReliability.RELIABLE,
                QosDurability.TRANSIENT_LOCAL if latched else QosDurability.VOLATILE,
                forever, forever, QosLiveliness.AUTOMATIC, forever, False)]


# ---------------------------------------------------------------------------------- the map
def map_cells(world) -> tuple[np.ndarray, float, tuple[float, float, float]]:
    """The occupancy grid of ``world`` as the planner sees it: ``(occupancy, resolution,
    origin)``, occupancy (ny, nx) int8 (0 free, 100 blocked; row 0 lowest), the corner of cell
    (0, 0) at ``origin`` (x, y, yaw) [m, m, rad].

    A grid map (with any polygons burned in) gives its own cells; a drawn map (polygons, a DXF
    plan) is rasterised at the planner's cell
    (:data:`~pushtrain.facility.distance_field.DEFAULT_RESOLUTION`): a cell is free when its
    centre lies in the free space.
    """
    if world.occupancy is not None:
        grid = world.occupancy
        h = float(grid.resolution)
        occupancy = np.where(grid.blocked, 100, 0).astype(np.int8)
        return occupancy, h, (grid.x0 - 0.5 * h, grid.y0 - 0.5 * h, 0.0)
    import shapely

    from pushtrain.facility.distance_field import DEFAULT_RESOLUTION

    h = DEFAULT_RESOLUTION
    xmin, ymin, xmax, ymax = world.outline.bounds
    nx = max(int(math.ceil((xmax - xmin) / h - 1e-9)), 1)
    ny = max(int(math.ceil((ymax - ymin) / h - 1e-9)), 1)
    xs = xmin + h * (np.arange(nx) + 0.5)
    ys = ymin + h * (np.arange(ny) + 0.5)
    free = shapely.contains_xy(world.free, xs[None, :], ys[:, None])
    return np.where(free, 0, 100).astype(np.int8), h, (xmin, ymin, 0.0)


def _world(run: RunFolder):
    from pushtrain.facility.loading import map_world

    m = run.scenario.map
    if m is None:
        return None
    return map_world(free=m.free, bounds=m.bounds, obstacles=m.obstacles, walls=m.walls,
                     grid=m.grid, dxf=m.dxf, layers=m.layers or (),
                     line_thickness=m.line_thickness, dxf_units=m.dxf_units)


# ---------------------------------------------------------------------------- the out folder
def _is_bag(folder: Path) -> bool:
    """Whether ``folder`` holds a rosbag2 bag and nothing else (metadata.yaml, .mcap/.db3)."""
    meta = folder / "metadata.yaml"
    if not meta.is_file():
        return False
    try:
        head = meta.read_text(encoding="utf-8", errors="replace")[:4096]
    except OSError:
        return False
    if "rosbag2_bagfile_information" not in head:
        return False
    return all(p.is_file() and (p.name == "metadata.yaml" or p.suffix in (".mcap", ".db3", ".zstd"))
               for p in folder.iterdir())


def _check_out(out: Path) -> None:
    if out.exists() and not out.is_dir():
        raise InputError(f"--out {str(out)!r} is a file; allowed: a new folder, an empty one or "
                         "an earlier bag (replaced)")
    if out.is_dir() and any(out.iterdir()) and not _is_bag(out):
        raise InputError(f"--out {str(out)!r} holds files that are not a rosbag2 bag; allowed: "
                         "a new folder, an empty one or an earlier bag (replaced)")


def _install(written: Path, out: Path) -> None:
    """Move the finished bag ``written`` to ``out`` (renames: ``out`` is never half-written)."""
    old = None
    if out.exists():
        old = out.with_name(f".{out.name}.replaced-{uuid.uuid4().hex[:12]}")
        os.rename(out, old)
    try:
        os.rename(written, out)
    except OSError:
        if old is not None:
            os.rename(old, out)
        raise
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


# ---------------------------------------------------------------------------- the messages
class _Stamps:
    def __init__(self, epoch_s: float):
        self.epoch_ns = int(round(epoch_s * 1e9))

    def __call__(self, t: float) -> int:
        return self.epoch_ns + int(round(float(t) * 1e9))


def _rows(t: np.ndarray, rate_hz: float | None) -> np.ndarray:
    """Indices of the samples written: all of them, or every k-th for ``rate_hz`` (first and
    last kept)."""
    if rate_hz is None or len(t) < 2:
        return np.arange(len(t))
    step = float(np.median(np.diff(t)))
    k = max(1, int(math.floor((1.0 / rate_hz) / step + 1e-9)))
    rows = np.arange(0, len(t), k)
    return rows if rows[-1] == len(t) - 1 else np.append(rows, len(t) - 1)


def _bodies(run: RunFolder) -> list[msg.BodyShape]:
    sc = run.scenario
    n = sc.train.n
    front = sc.train.front or [sc.train.link] * n
    rear = sc.train.rear or [sc.train.link] * n
    robot, trailer = sc.train.robot_size, sc.train.trailer_size
    bodies = [msg.BodyShape(robot_frame(), robot.length, robot.width, robot.offset,
                            (-rear[0],), ROBOT_RGBA)]
    for i in range(1, n + 1):
        bars = (front[i - 1],) + ((-rear[i],) if i < n else ())
        bodies.append(msg.BodyShape(trailer_frame(i), trailer.length, trailer.width,
                                    trailer.offset, bars,
                                    LAST_TRAILER_RGBA if i == n else TRAILER_RGBA))
    return bodies


def _tracked(run: RunFolder) -> bool:
    """Whether the run tracked a reference (a rotation mission turns the robot open-loop)."""
    return run.scenario.mission.kind != "rotation"


def _latched(run: RunFolder, ns0: int, stamps: _Stamps, world) -> list[tuple[str, object]]:
    out = []
    if world is not None:
        occupancy, h, origin = map_cells(world)
        out.append(("/map", msg.occupancy_grid(ns0, occupancy, h, origin)))
    if run.path is not None:
        out.append(("/plan", msg.path(ns0, run.path.poses)))
    elif run.planning_failed:  # no partial plan: the start pose alone
        st = run.scenario.start
        out.append(("/plan", msg.path(ns0, [[st.x, st.y, math.radians(st.theta_deg)]])))
    data = run.data
    if data is not None and _tracked(run):
        rows = _rows(data["t"], MIN_RATE_HZ)
        poses = np.column_stack([data["x_d"][rows], data["y_d"][rows], data["theta_d"][rows]])
        out.append(("/reference", msg.path(ns0, poses, [stamps(t) for t in data["t"][rows]])))
    if run.scenario.mission.kind == "plan":
        g = run.scenario.goal
        out.append(("/goal", msg.pose_stamped(ns0, "map", g.x, g.y, math.radians(g.theta_deg))))
    out.append(("/summary", msg.string(json.dumps(run.summary, indent=2))))
    return out


def _samples(run: RunFolder, stamps: _Stamps, rate_hz: float | None):
    """(topic, bag time [ns], message) of every written sample, in time order."""
    data, n = run.data, run.n
    frames = [robot_frame()] + [trailer_frame(i) for i in range(1, n + 1)]
    names = joint_names(n)
    xs = np.column_stack([data[f"x{i}"] for i in range(n + 1)])
    ys = np.column_stack([data[f"y{i}"] for i in range(n + 1)])
    ths = np.column_stack([data[f"theta{i}"] for i in range(n + 1)])
    phis = np.column_stack([data[f"phi{i}"] for i in range(1, n + 1)])
    measured = np.column_stack([data[f"phi_meas{i}"] for i in range(1, n + 1)])
    bodies = _bodies(run)
    tracked = _tracked(run)
    marker_rows = set(_rows(data["t"], MARKER_RATE_HZ).tolist())
    for k in _rows(data["t"], rate_hz):
        ns = stamps(data["t"][k])
        yield "/tf", ns, msg.tf_message(ns, frames, xs[k], ys[k], ths[k])
        yield "/joint_states", ns, msg.joint_state(ns, names, phis[k])
        yield "/joint_states/measured", ns, msg.joint_state(ns, names, measured[k])
        yield "/cmd_vel", ns, msg.twist(data["v_cmd"][k], data["w_cmd"][k])
        if tracked:
            yield "/tracking_error", ns, msg.vector3_stamped(
                ns, trailer_frame(n), data["e_lon"][k], data["e_lat"][k], data["e_theta"][k])
        if k in marker_rows:
            yield "/train_markers", ns, msg.train_markers(ns, bodies)


# ---------------------------------------------------------------------------------- export
def _custom_data(run: RunFolder, epoch_s: float) -> dict[str, str]:
    """``custom_data`` of metadata.yaml: where the bag came from and how to read its stamps."""
    return {"pushtrain.scenario": run.scenario.name,
            "pushtrain.status": str(run.summary.get("status", "")),
            "pushtrain.trailers": str(run.n),
            "pushtrain.epoch_s": repr(float(epoch_s)),
            "pushtrain.time": "stamp = epoch + simulated time",
            "pushtrain.frames": "map -> base_link (robot centre), map -> trailer_i (axle "
                                "midpoint); +x along pushtrain's heading, toward the robot"}


def export_bag(run_dir, out, *, epoch_s: float = EPOCH_S,
               rate_hz: float | None = None) -> BagExport:
    """Write the run folder ``run_dir`` as the rosbag2 folder ``out``.

    Parameters
    ----------
    run_dir : path
        A folder written by ``plan-and-run`` or ``run`` (a failed plan too: its bag holds the
        map, the partial plan, the goal and the summary, and no motion).
    out : path
        The bag folder: new, empty or an earlier bag (replaced). It is written beside, in a
        temporary folder of the same parent, and renamed into place when complete.
    epoch_s : float
        Unix time [s] of simulated time zero.
    rate_hz : float or None
        Thin the samples to every k-th, at least this rate (>= :data:`MIN_RATE_HZ`); None
        writes every recorded sample.

    Raises
    ------
    InputError
        Not a run folder (naming the missing file), an ``out`` that is neither new, empty nor a
        bag, or a rate below :data:`MIN_RATE_HZ`.
    """
    from rosbags.rosbag2 import CompressionFormat, CompressionMode, StoragePlugin, Writer

    if rate_hz is not None and not (math.isfinite(rate_hz) and rate_hz >= MIN_RATE_HZ):
        raise InputError(f"rate = {rate_hz!r} Hz: allowed a rate >= {MIN_RATE_HZ:g} Hz")
    if not (math.isfinite(epoch_s) and epoch_s >= 0.0):
        raise InputError(f"epoch = {epoch_s!r} s: allowed a Unix time >= 0")
    run = read_run(run_dir)
    out = Path(out)
    _check_out(out)
    if out.resolve() == Path(run_dir).resolve():
        raise InputError(f"--out {str(out)!r} is the run folder itself; allowed: a folder of "
                         "its own, e.g. RUN_DIR/bag")
    world = _world(run)
    stamps = _Stamps(epoch_s)
    t0 = float(run.data["t"][0]) if run.data is not None else 0.0
    ns0 = stamps(t0)
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        work = Path(tempfile.mkdtemp(prefix=f".{out.name}.", suffix=".partial",
                                     dir=out.parent))
    except OSError as exc:
        raise InputError(f"--out {str(out)!r}: no folder can be made there ({exc.strerror}); "
                         "allowed: a folder path in a writable place") from None
    try:
        written = work / out.name
        counts: dict[str, int] = {}
        writer = Writer(written, version=8, storage_plugin=StoragePlugin.MCAP)
        writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
        for key, value in _custom_data(run, epoch_s).items():
            writer.set_custom_data(key, value)
        with writer:
            connections = {}

            def put(topic: str, ns: int, message) -> None:
                if topic not in connections:
                    connections[topic] = writer.add_connection(
                        topic, TOPICS[topic], typestore=msg.TYPESTORE,
                        offered_qos_profiles=_qos(topic in LATCHED))
                writer.write(connections[topic], ns, msg.serialize(message))
                counts[topic] = counts.get(topic, 0) + 1

            for topic, message in _latched(run, ns0, stamps, world):
                put(topic, ns0, message)
            if run.data is not None:
                for topic, ns, message in _samples(run, stamps, rate_hz):
                    put(topic, ns, message)
        _install(written, out)
    except OSError as exc:  # a full disk, a folder taken away: a run-time failure (exit 1)
        raise WriteError(out / f"{out.name}.mcap", exc) from exc
    finally:
        shutil.rmtree(work, ignore_errors=True)
    mcap = next(out.glob("*.mcap"))
    log.info("wrote %s: %s", out, ", ".join(f"{t} {c}" for t, c in counts.items()))
    return BagExport(out, mcap, counts)
