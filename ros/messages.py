"""Standard ROS 2 messages of a run, as objects of the ``rosbags`` type store (ROS 2 Jazzy's
definitions), ready for :meth:`Typestore.serialize_cdr <rosbags.typesys.store.Typestore>`.

Conventions: SI units and radians; a pose (x, y, theta) is a position in the ``map`` plane and a
rotation of ``theta`` about +z (REP 103: x forward, y left, z up). pushtrain's headings point
toward the robot (the towing direction), so a body frame's +x points toward the robot and
pushing moves the train along -x. Times are integer nanoseconds since the bag's epoch.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from rosbags.typesys import Stores, get_typestore

__all__ = ["TYPESTORE", "stamp", "header", "pose_of", "occupancy_grid", "path", "pose_stamped",
           "tf_message", "joint_state", "twist", "vector3_stamped", "string", "BodyShape",
           "train_markers", "serialize"]

TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
"""The message definitions written into the bag (ROS 2 Jazzy's standard messages)."""

_T = TYPESTORE.types
_Time = _T["builtin_interfaces/msg/Time"]
_Duration = _T["builtin_interfaces/msg/Duration"]
_Header = _T["std_msgs/msg/Header"]
_ColorRGBA = _T["std_msgs/msg/ColorRGBA"]
_String = _T["std_msgs/msg/String"]
_Point = _T["geometry_msgs/msg/Point"]
_Quaternion = _T["geometry_msgs/msg/Quaternion"]
_Pose = _T["geometry_msgs/msg/Pose"]
_PoseStamped = _T["geometry_msgs/msg/PoseStamped"]
_Vector3 = _T["geometry_msgs/msg/Vector3"]
_Vector3Stamped = _T["geometry_msgs/msg/Vector3Stamped"]
_Transform = _T["geometry_msgs/msg/Transform"]
_TransformStamped = _T["geometry_msgs/msg/TransformStamped"]
_Twist = _T["geometry_msgs/msg/Twist"]
_TFMessage = _T["tf2_msgs/msg/TFMessage"]
_JointState = _T["sensor_msgs/msg/JointState"]
_CompressedImage = _T["sensor_msgs/msg/CompressedImage"]
_MapMetaData = _T["nav_msgs/msg/MapMetaData"]
_OccupancyGrid = _T["nav_msgs/msg/OccupancyGrid"]
_Path = _T["nav_msgs/msg/Path"]
_Marker = _T["visualization_msgs/msg/Marker"]
_MarkerArray = _T["visualization_msgs/msg/MarkerArray"]


def serialize(message) -> bytes:
    """The CDR bytes of ``message`` (rosbags' serializer)."""
    return bytes(TYPESTORE.serialize_cdr(message, message.__msgtype__))


def stamp(ns: int):
    """``builtin_interfaces/msg/Time`` of ``ns`` nanoseconds since the Unix epoch."""
    sec, nanosec = divmod(int(ns), 1_000_000_000)
    return _Time(sec=sec, nanosec=nanosec)


def header(ns: int, frame_id: str):
    """``std_msgs/msg/Header`` at ``ns`` in ``frame_id``."""
    return _Header(stamp=stamp(ns), frame_id=frame_id)


def _yaw(theta: float):
    half = 0.5 * float(theta)
    return _Quaternion(x=0.0, y=0.0, z=math.sin(half), w=math.cos(half))


def pose_of(x: float, y: float, theta: float, z: float = 0.0):
    """``geometry_msgs/msg/Pose`` at (x, y, z) [m] turned by ``theta`` [rad] about +z."""
    return _Pose(position=_Point(x=float(x), y=float(y), z=float(z)), orientation=_yaw(theta))


def pose_stamped(ns: int, frame_id: str, x: float, y: float, theta: float):
    """``geometry_msgs/msg/PoseStamped``."""
    return _PoseStamped(header=header(ns, frame_id), pose=pose_of(x, y, theta))


def occupancy_grid(ns: int, occupancy: np.ndarray, resolution: float, origin: Sequence[float],
                   frame_id: str = "map"):
    """``nav_msgs/msg/OccupancyGrid`` of ``occupancy`` (ny, nx) int8 (0 free, 100 occupied, -1
    unknown; row 0 lowest, as the message stores it), cells ``resolution`` [m] wide, the corner
    of cell (0, 0) at ``origin`` (x, y, yaw) [m, m, rad]."""
    occupancy = np.asarray(occupancy, dtype=np.int8)
    ny, nx = occupancy.shape
    info = _MapMetaData(map_load_time=stamp(ns), resolution=float(resolution), width=nx,
                        height=ny, origin=pose_of(*origin))
    return _OccupancyGrid(header=header(ns, frame_id), info=info,
                          data=np.ascontiguousarray(occupancy).reshape(-1))


def path(ns: int, poses: np.ndarray, stamps_ns: Sequence[int] | None = None,
         frame_id: str = "map"):
    """``nav_msgs/msg/Path`` of ``poses`` (N, 3) (x, y, theta) [m, m, rad]; each pose stamped
    with its own time from ``stamps_ns`` (N,), or with ``ns`` when None."""
    poses = np.asarray(poses, dtype=float).reshape(-1, 3)
    times = [ns] * len(poses) if stamps_ns is None else list(stamps_ns)
    return _Path(header=header(ns, frame_id), poses=[
        pose_stamped(t, frame_id, x, y, th) for t, (x, y, th) in zip(times, poses, strict=True)])


def tf_message(ns: int, frames: Sequence[str], x, y, theta, parent: str = "map"):
    """``tf2_msgs/msg/TFMessage``: one transform ``parent -> frames[i]`` per body, the body at
    (x[i], y[i]) [m] with heading theta[i] [rad]."""
    head = header(ns, parent)
    return _TFMessage(transforms=[
        _TransformStamped(header=head, child_frame_id=frame, transform=_Transform(
            translation=_Vector3(x=float(xi), y=float(yi), z=0.0), rotation=_yaw(th)))
        for frame, xi, yi, th in zip(frames, x, y, theta, strict=True)])


def joint_state(ns: int, names: Sequence[str], positions):
    """``sensor_msgs/msg/JointState`` of ``positions`` [rad] (no velocities or efforts)."""
    empty = np.zeros(0, dtype=np.float64)
    return _JointState(header=header(ns, ""), name=list(names),
                       position=np.asarray(positions, dtype=np.float64), velocity=empty,
                       effort=empty)


def twist(v: float, w: float):
    """``geometry_msgs/msg/Twist``: speed ``v`` [m/s] along +x, yaw rate ``w`` [rad/s]."""
    return _Twist(linear=_Vector3(x=float(v), y=0.0, z=0.0),
                  angular=_Vector3(x=0.0, y=0.0, z=float(w)))


def vector3_stamped(ns: int, frame_id: str, x: float, y: float, z: float):
    """``geometry_msgs/msg/Vector3Stamped``."""
    return _Vector3Stamped(header=header(ns, frame_id),
                           vector=_Vector3(x=float(x), y=float(y), z=float(z)))


def string(text: str):
    """``std_msgs/msg/String``."""
    return _String(data=text)


class BodyShape:
    """One body drawn as a box: its frame, footprint and colour.

    Parameters
    ----------
    frame : str
        The body's TF frame (origin at the robot centre or the trailer's axle midpoint).
    length, width : float
        Footprint along and across the heading [m].
    offset : float
        Footprint centre minus the frame origin along +x [m].
    bars : sequence of float
        Hitch bars from the origin along +x [m] (a front link F_i > 0, a rear link -R_i < 0).
    rgba : (4,) float
        Colour, each in [0, 1].
    """

    def __init__(self, frame: str, length: float, width: float, offset: float,
                 bars: Sequence[float], rgba: Sequence[float]):
        self.frame, self.length, self.width, self.offset = frame, length, width, offset
        self.bars, self.rgba = tuple(bars), tuple(rgba)


BODY_HEIGHT = 0.3
"""Height [m] of the drawn boxes (the model is planar; only the footprint is real)."""


def _color(rgba) -> object:
    r, g, b, a = (float(c) for c in rgba)
    return _ColorRGBA(r=r, g=g, b=b, a=a)


def _marker(ns: int, frame: str, ident: int, kind: int, pose, scale, rgba, points=()):
    no_texture = _CompressedImage(header=header(0, ""), format="", data=np.zeros(0, np.uint8))
    return _Marker(
        header=header(ns, frame), ns="train", id=ident, type=kind, action=_Marker.ADD, pose=pose,
        scale=_Vector3(x=float(scale[0]), y=float(scale[1]), z=float(scale[2])),
        color=_color(rgba), lifetime=_Duration(sec=0, nanosec=0), frame_locked=True,
        points=list(points), colors=[], texture_resource="", texture=no_texture,
        uv_coordinates=[], text="", mesh_resource="", mesh_file=_T[
            "visualization_msgs/msg/MeshFile"](filename="", data=np.zeros(0, np.uint8)),
        mesh_use_embedded_materials=False)


def train_markers(ns: int, bodies: Sequence[BodyShape]):
    """``visualization_msgs/msg/MarkerArray``: every body as a box of its real footprint
    (``CUBE``, ids 0..n) and its hitch bars (``LINE_LIST``, ids 100..100+n), each in its own
    TF frame and ``frame_locked``, so that RViz and Foxglove move them with ``/tf``."""
    markers = []
    for k, body in enumerate(bodies):
        markers.append(_marker(ns, body.frame, k, _Marker.CUBE,
                               pose_of(body.offset, 0.0, 0.0, 0.5 * BODY_HEIGHT),
                               (body.length, body.width, BODY_HEIGHT), body.rgba))
    for k, body in enumerate(bodies):
        points = [_Point(x=float(x), y=0.0, z=BODY_HEIGHT)
                  for bar in body.bars for x in (0.0, bar)]
        if points:
            markers.append(_marker(ns, body.frame, 100 + k, _Marker.LINE_LIST,
                                   pose_of(0.0, 0.0, 0.0), (0.04, 0.0, 0.0),
                                   (0.2, 0.2, 0.2, 1.0), points))
    return _MarkerArray(markers=markers)
