"""``pushtrain export-bag`` and ``plan-and-run --bag``: the bags read back with a second reader
(``mcap`` + ``mcap-ros2-support``, which did not write them) and checked against the run folder's
own files (``results.npz``, ``path.json``, ``scenario.json``, ``summary.json``) and against
an analytic integration of the planned segments written here."""

from __future__ import annotations

import dataclasses
import json
import math
import re
from collections import defaultdict
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import EXAMPLES, invoke_cli

from pushtrain.cosim.result import load_results

pytest.importorskip("mcap_ros2")

ROOT = Path(__file__).resolve().parents[2]
LAYOUT = ROOT / "docs" / "foxglove_layout.json"
EPOCH_NS = 946_684_800 * 10**9  # the documented default epoch, 2000-01-01T00:00:00Z

MOTION_TOPICS = {
    "/tf": "tf2_msgs/msg/TFMessage",
    "/joint_states": "sensor_msgs/msg/JointState",
    "/joint_states/measured": "sensor_msgs/msg/JointState",
    "/train_markers": "visualization_msgs/msg/MarkerArray",
    "/cmd_vel": "geometry_msgs/msg/Twist",
    "/tracking_error": "geometry_msgs/msg/Vector3Stamped",
    "/reference": "nav_msgs/msg/Path",
}
STILL_TOPICS = {
    "/map": "nav_msgs/msg/OccupancyGrid",
    "/plan": "nav_msgs/msg/Path",
    "/goal": "geometry_msgs/msg/PoseStamped",
    "/summary": "std_msgs/msg/String",
}
LATCHED = {"/map", "/plan", "/reference", "/goal", "/summary"}


# ------------------------------------------------------------------------- the second reader
class Bag:
    """A bag folder read with ``mcap`` + ``mcap-ros2-support`` and its metadata.yaml; the
    messages are decoded when asked for (:meth:`at`), their log times at once (:meth:`times`)."""

    def __init__(self, folder: Path):
        from mcap.reader import make_reader
        from mcap_ros2.decoder import DecoderFactory

        self.folder = folder
        self.metadata = yaml.safe_load((folder / "metadata.yaml").read_text())
        info = self.metadata["rosbag2_bagfile_information"]
        (name,) = info["relative_file_paths"]
        self.raw = defaultdict(list)  # topic -> [(log time ns, CDR bytes)]
        factory, self.decoders = DecoderFactory(), {}
        with open(folder / name, "rb") as f:
            reader = make_reader(f)
            summary = reader.get_summary()
            self.types = {c.topic: summary.schemas[c.schema_id].name
                          for c in summary.channels.values()}
            self.encodings = {c.topic: c.message_encoding for c in summary.channels.values()}
            for schema, channel, message in reader.iter_messages(log_time_order=True):
                if channel.topic not in self.decoders:
                    self.decoders[channel.topic] = factory.decoder_for(
                        channel.message_encoding, schema)
                self.raw[channel.topic].append((message.log_time, message.data))

    def times(self, topic: str) -> np.ndarray:
        return np.array([time for time, _ in self.raw[topic]], dtype=np.int64)

    def count(self, topic: str) -> int:
        return len(self.raw[topic])

    def at(self, topic: str, j: int):
        """(log time [ns], decoded message) of the j-th message on ``topic``."""
        time, data = self.raw[topic][j]
        return time, self.decoders[topic](data)

    def only(self, topic: str):
        """The one message of a latched topic."""
        assert self.count(topic) == 1, topic
        return self.at(topic, 0)[1]

    def qos(self, topic: str) -> list[dict]:
        info = self.metadata["rosbag2_bagfile_information"]
        for entry in info["topics_with_message_count"]:
            if entry["topic_metadata"]["name"] == topic:
                return yaml.safe_load(entry["topic_metadata"]["offered_qos_profiles"])
        raise KeyError(topic)


def _ns(stamp) -> int:
    return stamp.sec * 10**9 + stamp.nanosec


def _yaw(q) -> float:
    return 2.0 * math.atan2(q.z, q.w)


def _wrapped(a):
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


def analytic_poses(start, segments, s):
    """Poses (x, y, theta) at travelled distances ``s`` along line/arc ``segments`` from
    ``start``, integrated in closed form: per metre travelled the axle moves along -e(theta)
    when pushing and +e(theta) when pulling, and theta turns by the curvature."""
    x, y, th = (float(v) for v in start)
    ends, poses = [0.0], [(x, y, th)]
    for g in segments:
        d = 1.0 if g["direction"] == "push" else -1.0
        k, length = g["curvature"], g["length"]
        if abs(k) < 1e-12:
            x, y = x - d * length * math.cos(th), y - d * length * math.sin(th)
        else:
            x -= d * (math.sin(th + k * length) - math.sin(th)) / k
            y += d * (math.cos(th + k * length) - math.cos(th)) / k
            th += k * length
        ends.append(ends[-1] + length)
        poses.append((x, y, th))
    out = []
    for si in np.atleast_1d(s):
        j = min(max(int(np.searchsorted(ends, si, side="right")) - 1, 0), len(segments) - 1)
        g, (x0, y0, t0), u = segments[j], poses[j], si - ends[j]
        d, k = (1.0 if g["direction"] == "push" else -1.0), g["curvature"]
        if abs(k) < 1e-12:
            out.append((x0 - d * u * math.cos(t0), y0 - d * u * math.sin(t0), t0))
        else:
            out.append((x0 - d * (math.sin(t0 + k * u) - math.sin(t0)) / k,
                        y0 + d * (math.cos(t0 + k * u) - math.cos(t0)) / k, t0 + k * u))
    return np.array(out)


def check_plan(bag: Bag, path_file: Path) -> None:
    """Every /plan pose lies on the path of ``path_file`` within 1 mm (and its heading within
    1 mrad), from the start to the end."""
    plan = json.loads(path_file.read_text())
    msg = bag.only("/plan")
    assert msg.header.frame_id == "map"
    xy = np.array([(p.pose.position.x, p.pose.position.y) for p in msg.poses])
    yaw = np.array([_yaw(p.pose.orientation) for p in msg.poses])
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))])
    total = sum(g["length"] for g in plan["segments"])
    assert s[-1] == pytest.approx(total, abs=1e-3)
    expected = analytic_poses(plan["start"], plan["segments"], s)
    assert np.max(np.hypot(*(xy - expected[:, :2]).T)) < 1e-3
    assert np.max(np.abs(_wrapped(yaw - expected[:, 2]))) < 1e-3


def check_map_cells(bag: Bag, free_points, blocked_points) -> None:
    grid = bag.only("/map")
    info = grid.info
    data = np.asarray(grid.data, dtype=int).reshape(info.height, info.width)
    ox, oy, h = info.origin.position.x, info.origin.position.y, info.resolution

    def cell(x, y):
        return data[int((y - oy) // h), int((x - ox) // h)]

    assert [cell(*p) for p in free_points] == [0] * len(free_points)
    assert [cell(*p) for p in blocked_points] == [100] * len(blocked_points)


# ------------------------------------------------------------------------------------ runs
def _narrow_l(tmp_path) -> Path:
    """The L corridor with its vertical leg 0.8 m wide and a 0.2 s budget: no plan, a
    partial one (about 6 m short of the goal)."""
    text = (EXAMPLES / "l_corridor.toml").read_text()
    text = text.replace("[7.0, 9.0], [7.0, 2.0]", "[8.2, 9.0], [8.2, 2.0]")
    text = text.replace("time_budget = 2.0", "time_budget = 0.2").replace("x = 8.0", "x = 8.6")
    path = tmp_path / "narrow_l.toml"
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """Run folders and their bags: n = 1 (plan-and-run --bag), the bundled L corridor with
    n = 3 (export-bag), n = 10 (corner_10, export-bag --rate 20) and a failed plan
    (plan-and-run --bag)."""
    base = tmp_path_factory.mktemp("bags")
    out = {}
    one = invoke_cli(["plan-and-run", EXAMPLES / "l_corridor.toml", "--trailers", 1,
                      "--no-plots", "--bag", "--out", base / "n1"])
    assert one.exit_code == 0, one.output
    out[1] = (base / "n1", base / "n1" / "bag", None)
    three = invoke_cli(["plan-and-run", EXAMPLES / "l_corridor.toml", "--no-plots",
                        "--out", base / "n3"])
    assert three.exit_code == 0, three.output
    exported = invoke_cli(["export-bag", base / "n3", "--out", base / "n3_bag"])
    assert exported.exit_code == 0, exported.output
    out[3] = (base / "n3", base / "n3_bag", None)
    ten = invoke_cli(["plan-and-run", EXAMPLES / "corner_10.toml", "--no-plots",
                      "--out", base / "n10"])
    assert ten.exit_code == 0, ten.output
    exported = invoke_cli(["export-bag", base / "n10", "--out", base / "n10_bag",
                           "--rate", 20])
    assert exported.exit_code == 0, exported.output
    out[10] = (base / "n10", base / "n10_bag", 20.0)
    failed = invoke_cli(["plan-and-run", _narrow_l(base), "--no-plots", "--bag",
                         "--out", base / "failed"])
    assert failed.exit_code == 1, failed.output
    out["failed"] = (base / "failed", base / "failed" / "bag", None)
    return {key: (run, Bag(bag), rate) for key, (run, bag, rate) in out.items()}


MOVING = [1, 3, 10]


@pytest.mark.parametrize("n", MOVING)
def test_topics_and_types_are_the_listed_ones(runs, n):
    _, bag, _ = runs[n]
    assert bag.types == {**STILL_TOPICS, **MOTION_TOPICS}
    assert set(bag.encodings.values()) == {"cdr"}
    info = bag.metadata["rosbag2_bagfile_information"]
    assert info["storage_identifier"] == "mcap"
    listed = {e["topic_metadata"]["name"]: e["topic_metadata"]["type"]
              for e in info["topics_with_message_count"]}
    assert listed == bag.types
    for topic in bag.types:
        durability = {q["durability"] for q in bag.qos(topic)}
        assert durability == ({1} if topic in LATCHED else {2}), topic  # 1 transient_local


@pytest.mark.parametrize("n", MOVING)
def test_every_pose_and_joint_angle_is_the_recorded_one(runs, n):
    run, bag, _ = runs[n]
    data = load_results(run)
    rows = {int(round(t * 1e9)): k for k, t in enumerate(data["t"])}
    picks = np.linspace(0, bag.count("/tf") - 1, 7).astype(int)
    frames = ["base_link"] + [f"trailer_{i}" for i in range(1, n + 1)]
    for j in picks:
        time, msg = bag.at("/tf", j)
        k = rows[time - EPOCH_NS]
        assert [t.child_frame_id for t in msg.transforms] == frames
        for i, t in enumerate(msg.transforms):
            assert t.header.frame_id == "map" and _ns(t.header.stamp) == time
            assert math.hypot(t.transform.translation.x - data[f"x{i}"][k],
                              t.transform.translation.y - data[f"y{i}"][k]) < 1e-3
            assert abs(_wrapped(_yaw(t.transform.rotation) - data[f"theta{i}"][k])) < 1e-9
    for topic, column in (("/joint_states", "phi"), ("/joint_states/measured", "phi_meas")):
        assert np.array_equal(bag.times(topic), bag.times("/tf"))
        for j in picks:
            time, msg = bag.at(topic, j)
            k = rows[time - EPOCH_NS]
            assert list(msg.name) == [f"joint_{i}" for i in range(1, n + 1)]
            expected = [data[f"{column}{i}"][k] for i in range(1, n + 1)]
            assert np.max(np.abs(np.array(msg.position) - expected)) <= 1e-9


@pytest.mark.parametrize("n", MOVING)
def test_samples_cover_the_whole_run_at_10_hz_or_more(runs, n):
    run, bag, rate = runs[n]
    t = load_results(run)["t"]
    for topic in ("/tf", "/joint_states", "/joint_states/measured", "/cmd_vel",
                  "/tracking_error", "/train_markers"):
        times = bag.times(topic)
        assert times[0] == EPOCH_NS + round(t[0] * 1e9), topic
        assert times[-1] == EPOCH_NS + round(t[-1] * 1e9), topic
        assert np.max(np.diff(times)) <= 0.1e9 + 1, topic
    tf = bag.times("/tf")
    if rate is None:  # every recorded sample
        assert np.array_equal(tf, EPOCH_NS + np.round(t * 1e9).astype(np.int64))
    else:
        assert np.max(np.diff(tf)) <= 1e9 / rate + 1 and len(tf) < len(t) / 2


@pytest.mark.parametrize("n", MOVING)
def test_commands_errors_reference_and_summary_are_the_run_s(runs, n):
    run, bag, _ = runs[n]
    data = load_results(run)
    rows = {int(round(t * 1e9)): k for k, t in enumerate(data["t"])}
    for j in range(0, bag.count("/cmd_vel"), 997):
        time, msg = bag.at("/cmd_vel", j)
        k = rows[time - EPOCH_NS]
        assert (msg.linear.x, msg.angular.z) == (data["v_cmd"][k], data["w_cmd"][k])
    for j in range(0, bag.count("/tracking_error"), 997):
        time, msg = bag.at("/tracking_error", j)
        k = rows[time - EPOCH_NS]
        assert (msg.vector.x, msg.vector.y, msg.vector.z) == (
            data["e_lon"][k], data["e_lat"][k], data["e_theta"][k])
    reference = bag.only("/reference")
    for pose in reference.poses:
        k = rows[_ns(pose.header.stamp) - EPOCH_NS]
        assert math.hypot(pose.pose.position.x - data["x_d"][k],
                          pose.pose.position.y - data["y_d"][k]) < 1e-3
    stamps = np.array([_ns(p.header.stamp) for p in reference.poses])
    assert np.max(np.diff(stamps)) <= 0.1e9 + 1
    summary = bag.only("/summary")
    assert json.loads(summary.data) == json.loads((run / "summary.json").read_text())
    scenario = json.loads((run / "scenario.json").read_text())
    goal = bag.only("/goal")
    assert (goal.pose.position.x, goal.pose.position.y) == (scenario["goal"]["x"],
                                                            scenario["goal"]["y"])
    assert abs(_wrapped(_yaw(goal.pose.orientation)
                        - math.radians(scenario["goal"]["theta_deg"]))) < 1e-9


@pytest.mark.parametrize("n", MOVING)
def test_the_plan_is_path_json(runs, n):
    run, bag, _ = runs[n]
    check_plan(bag, run / "path.json")


@pytest.mark.parametrize("n", MOVING)
def test_the_markers_draw_every_body_at_its_size_in_its_frame(runs, n):
    run, bag, _ = runs[n]
    train = json.loads((run / "scenario.json").read_text())["train"]
    frames = {t.child_frame_id for t in bag.at("/tf", 0)[1].transforms}
    _, markers = bag.at("/train_markers", bag.count("/train_markers") // 2)
    boxes = [m for m in markers.markers if m.type == 1]  # CUBE
    assert [m.header.frame_id for m in boxes] == (
        ["base_link"] + [f"trailer_{i}" for i in range(1, n + 1)])
    assert {m.header.frame_id for m in markers.markers} <= frames
    for m in boxes:
        size = train["robot_size" if m.header.frame_id == "base_link" else "trailer_size"]
        assert (m.scale.x, m.scale.y) == (size["length"], size["width"])
        assert m.pose.position.x == size["offset"] and m.frame_locked


@pytest.mark.parametrize("n", MOVING)
def test_the_frames_and_hitch_bars_hold_the_train_together(runs, n):
    """The train in the bag is one chain: with every body frame's +x toward the robot, the
    rear hitch of body i-1 (R_{i-1} behind its origin) is the front hitch of trailer i (F_i
    ahead of its origin), within 1 mm, and the hitch bars drawn on /train_markers end there."""
    run, bag, _ = runs[n]
    link = json.loads((run / "scenario.json").read_text())["train"]["link"]
    markers_at = dict(zip(bag.times("/train_markers").tolist(),
                          range(bag.count("/train_markers")), strict=True))
    tf_at = dict(zip(bag.times("/tf").tolist(), range(bag.count("/tf")), strict=True))
    for time in sorted(markers_at)[:: max(1, len(markers_at) // 5)]:
        _, tf = bag.at("/tf", tf_at[time])
        poses = {t.child_frame_id: (t.transform.translation.x, t.transform.translation.y,
                                    _yaw(t.transform.rotation)) for t in tf.transforms}

        def in_map(frame, x_along, poses=poses):
            x, y, th = poses[frame]
            return np.array([x + x_along * math.cos(th), y + x_along * math.sin(th)])

        frames = ["base_link"] + [f"trailer_{i}" for i in range(1, n + 1)]
        for ahead, behind in zip(frames[:-1], frames[1:], strict=True):
            gap = in_map(ahead, -link) - in_map(behind, link)
            assert np.hypot(*gap) < 1e-3, (time, ahead, behind, gap)
        _, markers = bag.at("/train_markers", markers_at[time])
        ends = {}
        for m in markers.markers:
            if m.type == 5:  # LINE_LIST: (origin, bar end) pairs
                ends[m.header.frame_id] = [p.x for p in m.points[1::2]]
        for ahead, behind in zip(frames[:-1], frames[1:], strict=True):
            rear = [in_map(ahead, x) for x in ends[ahead] if x < 0]
            front = [in_map(behind, x) for x in ends[behind] if x > 0]
            assert len(rear) == len(front) == 1
            assert np.hypot(*(rear[0] - front[0])) < 1e-3


def test_the_map_is_the_l_corridor_at_the_planner_s_cell(runs):
    _, bag, _ = runs[3]
    grid = bag.only("/map")
    assert grid.info.resolution == pytest.approx(0.02) and grid.header.frame_id == "map"
    assert (grid.info.width, grid.info.height) == (450, 450)  # 9 m x 9 m
    check_map_cells(bag, free_points=[(1.0, 1.0), (8.0, 8.0), (4.0, 1.95)],
                    blocked_points=[(5.0, 5.0), (1.0, 2.05), (6.95, 8.0)])


def test_a_failed_plan_gives_the_map_and_the_partial_plan_and_no_motion(runs):
    run, bag, _ = runs["failed"]
    summary = json.loads((run / "summary.json").read_text())
    assert summary["status"] == "planning_failed"
    assert bag.types == STILL_TOPICS
    partial = json.loads((run / "partial_path.json").read_text())
    assert partial["info"]["partial"] is True
    check_plan(bag, run / "partial_path.json")
    check_map_cells(bag, free_points=[(1.0, 1.0), (8.6, 5.0)],
                    blocked_points=[(5.0, 5.0), (7.5, 5.0)])
    text = bag.only("/summary")
    assert json.loads(text.data) == summary


# -------------------------------------------------------------------------- foxglove layout
def test_the_foxglove_layout_shows_topics_of_the_bag(runs):
    layout = json.loads(LAYOUT.read_text())
    _, bag, _ = runs[3]
    panels = layout["configById"]
    three_d = [c for key, c in panels.items() if key.startswith("3D!")]
    assert len(three_d) == 1
    shown = {t for t, c in three_d[0]["topics"].items() if c.get("visible")}
    assert {"/map", "/plan", "/train_markers"} <= shown
    plotted = {p["value"] for key, c in panels.items() if key.startswith("Plot!")
               for p in c["paths"]}
    assert any(v.startswith("/joint_states") for v in plotted)
    assert any(v.startswith("/tracking_error") for v in plotted)
    used = shown | {re.match(r"(/[\w/]+?)\.", v).group(1) for v in plotted}
    used |= {c["topicPath"].split(".")[0] for c in panels.values() if "topicPath" in c}
    assert used <= set(bag.types), used - set(bag.types)
    assert three_d[0]["followTf"] in {t.child_frame_id
                                      for t in bag.at("/tf", 0)[1].transforms}

    def leaves(node):
        return [node] if isinstance(node, str) else leaves(node["first"]) + leaves(
            node["second"])

    assert sorted(leaves(layout["layout"])) == sorted(panels)


def _camel(name: str) -> str:
    head, *rest = name.split("_")
    return head + "".join(part.title() for part in rest)


def _keys(cls) -> set[str]:
    """The layout keys of one of Foxglove's own config classes (``foxglove.layouts``)."""
    return {_camel(f.name) for f in dataclasses.fields(cls)}


def test_the_layout_s_settings_are_ones_foxglove_s_schema_knows(runs):
    """Every key of the layout's panels is a field of the class Foxglove's SDK generates from
    its layout schema, for the panel and for the message type each topic has in the bag."""
    fl = pytest.importorskip("foxglove.layouts")
    _, bag, _ = runs[3]
    panels = json.loads(LAYOUT.read_text())["configById"]
    by_type = {"nav_msgs/msg/OccupancyGrid": fl.BaseRendererRosOccupancyGridTopicSettings,
               "nav_msgs/msg/Path": fl.BaseRendererPosesTopicSettings,
               "geometry_msgs/msg/PoseStamped": fl.BaseRendererPoseTopicSettings,
               "visualization_msgs/msg/MarkerArray": fl.BaseRendererRosMarkerTopicSettings}
    parts = {"cameraState": fl.ThreeDeeCameraState, "scene": fl.BaseRendererSceneSettings,
             "publish": fl.ThreeDeePublishSettings}
    checked = 0
    for key, config in panels.items():
        kind = key.split("!")[0]
        if kind == "3D":
            assert set(config) <= _keys(fl.ThreeDeeConfig)
            for part, cls in parts.items():
                assert set(config.get(part, {})) <= _keys(cls), part
            assert set(config["scene"]["transforms"]) <= _keys(fl.BaseRendererTransforms)
            for layer in config["layers"].values():
                assert set(layer) <= _keys(fl.BaseRendererGridLayerSettings) | {"visible"}
            for topic, settings in config["topics"].items():
                assert set(settings) <= _keys(by_type[bag.types[topic]]), topic
        elif kind == "Plot":
            assert set(config) - {"title"} <= _keys(fl.PlotConfig)
            for series in config["paths"]:
                assert set(series) <= _keys(fl.PlotSeries)
        else:
            assert kind == "RawMessages" and set(config) <= _keys(fl.RawMessagesConfig)
        checked += 1
    assert checked == len(panels) == 5


def test_a_grid_map_keeps_its_own_cells():
    """``/map`` of a map_server map is its image, cell for cell: free where the pixel's
    occupancy p = (255 - value) / 255 is below free_thresh (negate 0), else blocked; the
    image's resolution and origin (read here with Pillow and PyYAML, not with pushtrain)."""
    from PIL import Image

    from pushtrain.facility.loading import map_world
    from pushtrain.ros.bag import map_cells

    spec_file = EXAMPLES / "maps" / "warehouse.yaml"
    spec = yaml.safe_load(spec_file.read_text())
    assert spec["negate"] == 0 and spec["origin"][2] == 0.0
    pixels = np.asarray(Image.open(spec_file.parent / spec["image"]), dtype=float)
    free = (255.0 - pixels) / 255.0 < spec["free_thresh"]
    occupancy, resolution, origin = map_cells(map_world(grid=str(spec_file)))
    assert resolution == spec["resolution"]
    assert origin == pytest.approx((spec["origin"][0], spec["origin"][1], 0.0), abs=1e-12)
    assert np.array_equal(occupancy, np.where(free[::-1], 0, 100))
    assert 0.2 < np.mean(occupancy == 0) < 0.95
