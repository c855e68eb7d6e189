"""Tests of pushtrain.report.plots: files written atomically, artists where the data put them.

Data come from a short real co-simulation (3 trailers, line then arc, a joint bias and an imposed
slide) and from a synthetic run integrated here with the chain kinematics (known, unequal hitch
links; forces and slip flags chosen by the test).
"""

from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest
from PIL import Image

from pushtrain.core.kinematics import ChainGeometry, body_positions, forward_velocities
from pushtrain.cosim.master import _columns
from pushtrain.errors import PlotError
from pushtrain.report import animation, common, mapview, plots, timeseries
from pushtrain.report import geometry as report_geometry

D = 0.52


# ------------------------------------------------------------------------------------ fixtures
@pytest.fixture(scope="module")
def run3(built_fmu):
    """A real co-simulation: robot + 3 trailers pushing along a line then an arc."""
    from pushtrain.core.controller import ControllerConfig
    from pushtrain.core.reference import Reference
    from pushtrain.core.segment import Segment
    from pushtrain.core.sensors import SensorConfig
    from pushtrain.cosim.events import Slide
    from pushtrain.cosim.master import simulate

    reference = Reference.from_segments((0, 0, 0), [Segment("line", 1.0), Segment("arc", 1.0, 0.4)])
    sensors = SensorConfig(3, joint_bias=[0.0, 0.0, math.radians(3.0)])
    result = simulate(built_fmu(3), reference, ControllerConfig.uniform(3), sensors,
                      events=[Slide(4.0, 1.0, 0.05)], check_goal=False, settle_time=0)
    assert len(result.data) > 1000
    return result


def synthetic(n, geometry, t_end=10.0, h=0.01, v0=-0.1, w0=0.08, forces=None, limit=37.17):
    """Integrate the chain kinematics (Euler, headings only) for a robot driving (v0, w0) and
    fill every column of ``master._columns(n)``; ``forces(t) -> (rows, n)`` gives F_lat."""
    t = h * np.arange(int(round(t_end / h)) + 1)
    rows = t.size
    theta = np.zeros((rows, n + 1))
    x0 = np.zeros(rows)
    y0 = np.zeros(rows)
    x0[0] = 3.0
    theta[0] = np.linspace(0.0, 0.3, n + 1)  # bent from the start
    v = np.zeros((rows, n + 1))
    w = np.zeros((rows, n + 1))
    for k in range(rows):
        phi = theta[k, :-1] - theta[k, 1:]
        v[k], w[k] = forward_velocities(phi, v0, w0, geometry)
        if k + 1 < rows:
            theta[k + 1] = theta[k] + h * w[k]
            x0[k + 1] = x0[k] + h * v0 * math.cos(theta[k, 0])
            y0[k + 1] = y0[k] + h * v0 * math.sin(theta[k, 0])
    xy = [body_positions(x0[k], y0[k], theta[k], geometry) for k in range(rows)]
    xs = np.array([p[0] for p in xy])
    ys = np.array([p[1] for p in xy])
    data = np.zeros(rows, dtype=[(c, "f8") for c in _columns(n)])
    data["t"] = t
    for i in range(n + 1):
        data[f"x{i}"], data[f"y{i}"], data[f"theta{i}"] = xs[:, i], ys[:, i], theta[:, i]
        data[f"v{i}"], data[f"w{i}"] = v[:, i], w[:, i]
    f_lat = forces(t) if forces is not None else np.zeros((rows, n))
    for i in range(1, n + 1):
        data[f"phi{i}"] = theta[:, i - 1] - theta[:, i]
        data[f"phi_meas{i}"] = data[f"phi{i}"]
        data[f"F_lat{i}"] = f_lat[:, i - 1]
        data[f"F_lat_max{i}"] = limit
        data[f"slipping{i}"] = np.abs(f_lat[:, i - 1]) > limit
    data["v_cmd"], data["w_cmd"] = v0, w0
    data["x_d"], data["y_d"], data["theta_d"] = xs[:, n], ys[:, n], theta[:, n]
    data["v_d"], data["w_d"] = v[:, n], w[:, n]
    data["direction"] = np.where(t < 0.7 * t_end, 1.0, 0.0)
    return data


def expected_intervals(t, mask):
    """Slip/band intervals computed directly: from the first sample of a run to the first
    sample after it (or the last sample)."""
    out, k = [], 0
    while k < len(mask):
        if mask[k]:
            j = k
            while j + 1 < len(mask) and mask[j + 1]:
                j += 1
            out.append((t[k], t[min(j + 1, len(t) - 1)]))
            k = j + 1
        else:
            k += 1
    return out


def same_spans(got, expect, tol=1e-9):
    """Two lists of (start, end) intervals are equal within ``tol``."""
    got, expect = np.asarray(got, float).reshape(-1, 2), np.asarray(expect, float).reshape(-1, 2)
    return got.shape == expect.shape and np.allclose(got, expect, atol=tol, rtol=0)


def png_size(path):
    with Image.open(path) as im:
        assert im.format == "PNG"
        arr = np.asarray(im.convert("RGB"))
        assert arr.std() > 10.0, "image is (nearly) blank"
        return im.size


def fig_pixels(fig, dpi=common.DPI):
    w, h = fig.get_size_inches()
    return round(w * dpi), round(h * dpi)


def leftovers(folder):
    return sorted(p.name for p in folder.iterdir() if ".part" in p.name)


# ------------------------------------------------------------------------------------ map
def test_plot_map_writes_png_of_the_figure_size(run3, tmp_path):
    out = mapview.plot_map(run3.data, 3, tmp_path / "map.png", snapshots=6)
    assert out == tmp_path / "map.png"
    assert png_size(out) == fig_pixels(mapview.map_figure(run3.data, 3, snapshots=6))
    assert leftovers(tmp_path) == []


def test_map_snapshots_are_drawn_at_the_bodies_poses(run3):
    data, n, count = run3.data, 3, 5
    fig = mapview.map_figure(data, n, snapshots=count)
    patches = {p.get_gid(): p for p in fig.axes[0].patches if p.get_gid()}
    rows = list(fig.snapshot_rows)
    sizes = [(0.6, 0.5)] + [(0.8, 0.6)] * n
    assert 2 <= len(rows) <= count and rows[0] == 0 and rows[-1] == len(data) - 1
    assert len(patches) == len(rows) * (n + 1)
    for k, r in enumerate(rows):
        for i in range(n + 1):
            xy = patches[f"snapshot{k}:body{i}"].get_xy()[:4]
            centre = xy.mean(axis=0)
            assert centre == pytest.approx([data[f"x{i}"][r], data[f"y{i}"][r]], abs=1e-9)
            along = xy[0] - xy[1]  # front-left minus rear-left corner
            across = xy[0] - xy[3]
            assert np.hypot(*along) == pytest.approx(sizes[i][0])
            assert np.hypot(*across) == pytest.approx(sizes[i][1])
            heading = math.atan2(along[1], along[0])
            turn = math.remainder(heading - data[f"theta{i}"][r], 2 * math.pi)
            assert turn == pytest.approx(0, abs=1e-9)


def test_map_train_line_goes_through_the_hitch_points(run3):
    data, n = run3.data, 3
    fig = mapview.map_figure(data, n, snapshots=4)
    lines = {ln.get_gid(): ln for ln in fig.axes[0].lines if ln.get_gid()}
    rows = fig.snapshot_rows
    for k, r in enumerate(rows):
        px, py = lines[f"snapshot{k}:train"].get_data()
        assert len(px) == 2 * n + 1
        for i in range(n + 1):
            body = (data[f"x{i}"][r], data[f"y{i}"][r])
            assert (px[2 * i], py[2 * i]) == pytest.approx(body, abs=1e-9)
        for i in range(1, n + 1):
            # rear hitch of body i-1 at P_{i-1} - R e_{i-1} with the plant's R = 0.52 m
            th = data[f"theta{i - 1}"][r]
            hitch = (data[f"x{i - 1}"][r] - D * math.cos(th),
                     data[f"y{i - 1}"][r] - D * math.sin(th))
            assert (px[2 * i - 1], py[2 * i - 1]) == pytest.approx(hitch, abs=1e-6)


def test_map_with_world_path_and_custom_footprints(run3, tmp_path):
    class FakeWorld:
        bounds = (-4.0, -2.0, 5.0, 3.0)
        calls = []

        def plot(self, ax):
            self.calls.append(ax)
            ax.fill([-4, 5, 5, -4], [-2, -2, 3, 3], color="0.9", zorder=0)

    world = FakeWorld()
    path_xy = np.column_stack([np.linspace(0, -2, 50), np.zeros(50)])
    feet = {"robot": (0.7, 0.55), "trailers": [(0.5, 0.4), (0.9, 0.6, 0.1), (0.8, 0.7)]}
    fig = mapview.map_figure(run3.data, 3, world=world, path_xy=path_xy, footprints=feet,
                             snapshots=2)
    ax = fig.axes[0]
    assert world.calls == [ax]
    x0, x1 = ax.get_xlim()
    y0, y1 = ax.get_ylim()
    assert x0 <= -4.0 and x1 >= 5.0 and y0 <= -2.0 and y1 >= 3.0
    planned = [ln for ln in ax.lines if ln.get_label().startswith("planned path")]
    assert len(planned) == 1 and np.allclose(planned[0].get_xydata(), path_xy)
    # trailer 2's rectangle is offset 0.1 m ahead of its axle midpoint
    r = fig.snapshot_rows[1]
    xy = next(p for p in ax.patches if p.get_gid() == "snapshot1:body2").get_xy()[:4]
    th = run3.data["theta2"][r]
    expect = (run3.data["x2"][r] + 0.1 * math.cos(th), run3.data["y2"][r] + 0.1 * math.sin(th))
    assert xy.mean(axis=0) == pytest.approx(expect, abs=1e-9)
    out = mapview.plot_map(run3.data, 3, tmp_path / "world.png", world=world, path_xy=path_xy,
                         footprints=feet, title="custom")
    png_size(out)


@pytest.mark.parametrize("width", [6.0, 14.0, 28.0])
def test_map_labels_and_legend_stay_inside_the_figure(width):
    """Wide and tall maps alike: nothing of the axes (y label, tick labels, the legend beside
    them, the colour bar below) lies outside the figure (bay's y label was clipped)."""

    class Walls:
        bounds = (0.0, -1.5, width, 6.0)

        def plot(self, ax):
            ax.fill([0, width, width, 0], [-1.5, -1.5, 6, 6], color="0.4", zorder=0)

    data = synthetic(3, ChainGeometry(np.full(3, D), np.full(3, D)))
    path_xy = np.column_stack([data["x_d"], data["y_d"]])
    fig = mapview.map_figure(data, 3, world=Walls(), path_xy=path_xy,
                           title="Robot with 3 trailers: goal reached")
    fig.canvas.draw()  # one layout pass from scratch, as savefig does
    renderer = fig.canvas.get_renderer()
    inside = fig.bbox.padded(0.5)  # half a pixel for rounding
    for ax in fig.axes:
        box = ax.get_tightbbox(renderer)
        assert inside.containsx(box.x0) and inside.containsx(box.x1), (ax, box, fig.bbox)
        assert inside.containsy(box.y0) and inside.containsy(box.y1), (ax, box, fig.bbox)


def test_hitch_links_recovers_unequal_links_from_a_bent_chain():
    geometry = ChainGeometry(np.array([0.4, 0.6]), np.array([0.5, 0.3]))
    data = synthetic(2, geometry, t_end=5.0)
    front, rear = report_geometry.hitch_links(data, 2)
    assert front == pytest.approx(geometry.front, abs=1e-6)
    assert rear == pytest.approx(geometry.rear, abs=1e-6)
    # a chain that never bends only fixes F + R: the split is even
    straight = synthetic(2, geometry, t_end=2.0, w0=0.0)
    for i in range(3):
        straight[f"theta{i}"] = 0.0
        straight[f"x{i}"] = -np.cumsum([0.0, 0.9, 0.9])[i]
        straight[f"y{i}"] = 0.0
    front, rear = report_geometry.hitch_links(straight, 2)
    assert front == pytest.approx([0.45, 0.45]) and rear == pytest.approx([0.45, 0.45])


def test_snapshot_and_frame_indices():
    t = np.linspace(0.0, 10.0, 1001)
    idx = report_geometry.snapshot_indices(t, 6)
    assert idx.tolist() == [int(np.argmin(np.abs(t - tk))) for tk in np.linspace(0, 10, 6)]
    assert report_geometry.snapshot_indices(t, 0).size == 0
    assert report_geometry.snapshot_indices(t[:3], 8).tolist() == [0, 1, 2]
    frames = report_geometry.frame_indices(1001, 150)
    assert frames.size == 150 and frames[0] == 0 and frames[-1] == 1000
    assert np.ptp(np.diff(frames)) <= 1
    assert report_geometry.frame_indices(20, 150).tolist() == list(range(20))
    with pytest.raises(PlotError, match="snapshots"):
        report_geometry.snapshot_indices(t, -1)
    with pytest.raises(PlotError, match="max_frames"):
        report_geometry.frame_indices(10, 0)


# ------------------------------------------------------------------------------------ time plots
def test_inputs_and_joints_shows_degrees_and_measured_angles(run3, tmp_path):
    data = run3.data
    fig = timeseries.inputs_and_joints_figure(data, 3)
    lines = {ln.get_gid(): ln for ax in fig.axes for ln in ax.lines if ln.get_gid()}
    assert np.allclose(lines["v0"].get_ydata(), data["v0"])
    assert np.allclose(lines["w_cmd"].get_ydata(), np.degrees(data["w_cmd"]))
    assert np.allclose(lines["w0"].get_ydata(), np.degrees(data["w0"]))
    for i in (1, 2, 3):
        assert np.allclose(lines[f"phi{i}"].get_ydata(), np.degrees(data[f"phi{i}"]))
    # only joint 3 has a bias: only its measured angle is drawn (dotted)
    assert "phi_meas3" in lines and lines["phi_meas3"].get_linestyle() == ":"
    assert "phi_meas1" not in lines and "phi_meas2" not in lines
    assert [ax.get_ylabel() for ax in fig.axes[:3]] == ["v0 [m/s]", "w0 [deg/s]",
                                                        "joint angle phi_i [deg]"]
    out = timeseries.plot_inputs_and_joints(data, 3, tmp_path / "inputs.png")
    assert png_size(out) == fig_pixels(fig)


def test_tracking_error_units_and_direction_bands(run3, tmp_path):
    data = run3.data
    fig = timeseries.tracking_error_figure(data, 3)
    axes = fig.axes[:3]
    lines = {ln.get_gid(): ln for ax in axes for ln in ax.lines if ln.get_gid()}
    assert np.allclose(lines["e_lat"].get_ydata(), 100.0 * data["e_lat"])
    assert np.allclose(lines["e_lon"].get_ydata(), 100.0 * data["e_lon"])
    assert np.allclose(lines["e_theta"].get_ydata(), np.degrees(data["e_theta"]))
    t = data["t"]
    push = expected_intervals(t, data["direction"] == 1)
    rest = expected_intervals(t, data["direction"] == 0)
    assert push and rest  # the reference rests at its end
    for ax in axes:
        for gid, expect in (("direction+1", push), ("direction+0", rest)):
            extents = sorted((p.get_x(), p.get_x() + p.get_width()) for p in ax.patches
                             if p.get_gid() == gid)
            assert same_spans(extents, expect)
        assert not [p for p in ax.patches if p.get_gid() == "direction-1"]
    slide = expected_intervals(t, data["slide"] != 0)
    assert slide and slide[0][0] == pytest.approx(4.0, abs=0.01)
    out = timeseries.plot_tracking_error(data, 3, tmp_path / "err.png")
    assert png_size(out) == fig_pixels(fig)


def _force_profile(n, t_slip):
    """F_lat [N] that exceeds the 37.17 N limit on trailer i during t_slip[i]."""
    def forces(t):
        f = np.tile(10.0 * np.sin(t)[:, None], (1, n))
        for i, spans in enumerate(t_slip):
            for a, b in spans:
                f[(t >= a) & (t < b), i] = -50.0
        return f
    return forces


def test_lateral_forces_limits_and_slip_spans(tmp_path):
    spans = [[(1.0, 2.0), (6.0, 6.5)], [(3.0, 3.2)]]
    data = synthetic(2, ChainGeometry.uniform(2), forces=_force_profile(2, spans))
    fig = timeseries.lateral_forces_figure(data, 2)
    t = data["t"]
    for i in (1, 2):
        ax = fig.axes[i - 1]
        lines = {ln.get_gid(): ln for ln in ax.lines}
        assert np.allclose(lines[f"F_lat{i}"].get_ydata(), np.abs(data[f"F_lat{i}"]))
        assert np.allclose(lines[f"F_lat_max{i}"].get_ydata(), 37.17)
        shaded = sorted((p.get_x(), p.get_x() + p.get_width()) for p in ax.patches
                        if p.get_gid() == f"slip{i}")
        assert same_spans(shaded, expected_intervals(t, data[f"slipping{i}"] > 0.5))
        assert len(shaded) == len(spans[i - 1])
    out = timeseries.plot_lateral_forces(data, 2, tmp_path / "forces.png")
    assert png_size(out) == fig_pixels(fig)


def test_lateral_forces_many_trailers_uses_a_slip_timeline(tmp_path):
    n = 6
    spans = [[(1.0, 1.5)], [], [(2.0, 2.5), (4.0, 4.2)], [], [], [(7.0, 7.1)]]
    data = synthetic(n, ChainGeometry.uniform(n), forces=_force_profile(n, spans))
    fig = timeseries.lateral_forces_figure(data, n)
    force_ax, slip_ax = fig.axes[0], fig.axes[1]
    assert {ln.get_gid() for ln in force_ax.lines} >= {f"F_lat{i}" for i in range(1, n + 1)}
    for i in range(1, n + 1):
        expect = expected_intervals(data["t"], data[f"slipping{i}"] > 0.5)
        assert len(expect) == len(spans[i - 1])
        got = sorted((path.vertices[:, 0].min(), path.vertices[:, 0].max())
                     for c in slip_ax.collections if c.get_gid() == f"slip{i}"
                     for path in c.get_paths())
        assert same_spans(got, expect)
    png_size(timeseries.plot_lateral_forces(data, n, tmp_path / "forces6.png"))


# ------------------------------------------------------------------------------------ animation
def test_animate_writes_a_gif_with_one_frame_per_sample(run3, tmp_path):
    out = animation.animate(run3.data, 3, tmp_path / "train.gif", max_frames=40, fps=5)
    with Image.open(out) as im:
        assert im.format == "GIF"
        assert im.n_frames == len(report_geometry.frame_indices(len(run3.data), 40)) == 40
        assert im.info["duration"] == 200  # 1000 ms / 5 fps
        size = im.size
        first = np.asarray(im.convert("RGB")).copy()
        im.seek(im.n_frames - 1)
        last = np.asarray(im.convert("RGB"))
        assert im.size == size and size[0] > 300 and size[1] > 150
    assert np.abs(first.astype(int) - last.astype(int)).sum() > 0  # the train moved
    assert leftovers(tmp_path) == []


def _palette_image(colors):
    palette = Image.new("P", (1, 1))
    palette.putpalette([c for rgb in colors for c in rgb] + [0] * 3 * (256 - len(colors)))
    return palette


def _decoded(data: bytes) -> tuple[list[np.ndarray], list[int]]:
    """The frames of a GIF as RGB arrays, composed as a viewer shows them, and their
    durations [ms]."""
    import io

    frames, durations = [], []
    with Image.open(io.BytesIO(data)) as im:
        for k in range(im.n_frames):
            im.seek(k)
            frames.append(np.asarray(im.convert("RGB")).copy())
            durations.append(im.info["duration"])
    return frames, durations


def test_gif_stream_stores_changed_rectangles_and_composes_back():
    import io

    from pushtrain.report.animation import _GifStream

    colors = [(255, 255, 255), (200, 30, 30), (20, 60, 200), (0, 0, 0)]
    rgba = [np.append(np.array(c, np.uint8), 255) for c in colors]
    frame = np.empty((40, 60, 4), np.uint8)
    frame[:] = rgba[0]
    expected = []
    out = io.BytesIO()
    gif = _GifStream(out, _palette_image(colors), duration=131.0)  # 130 ms in GIF units

    def add(changed_frame):
        gif.add(changed_frame)
        expected.append(changed_frame[:, :, :3].copy())

    add(frame.copy())
    written = []
    for k, (y, x, c) in enumerate([(5, 5, 1), (30, 50, 2), (10, 20, 3), (10, 20, 0)]):
        frame[y:y + 4, x:x + 6] = rgba[c]  # a block appears (or is erased again)
        frame[0, k] = rgba[3]  # and a pixel far from it
        add(frame.copy())
        written.append(len(out.getvalue()))
    gif.add(frame.copy())  # unchanged: the last frame shows twice as long
    assert gif.close() == 5
    assert written == sorted(written) and written[0] > 800  # frames go out as they come
    frames, durations = _decoded(out.getvalue())
    assert len(frames) == 5
    for got, want in zip(frames, expected, strict=True):
        assert np.array_equal(got, want)
    assert durations == [130, 130, 130, 130, 260]


def test_gif_stream_maps_colours_to_the_nearest_palette_entry():
    import io

    from pushtrain.report.animation import _GifStream

    colors = [(255, 255, 255), (0, 0, 0), (250, 0, 0)]
    frame = np.full((8, 8, 4), 255, np.uint8)
    frame[2:4, 2:4, :3] = (240, 10, 5)  # nearest: red
    frame[5:7, 5:7, :3] = (30, 20, 25)  # nearest: black
    out = io.BytesIO()
    gif = _GifStream(out, _palette_image(colors), duration=100.0)
    gif.add(frame)
    gif.close()
    (got,), _ = _decoded(out.getvalue())
    assert tuple(got[2, 2]) == (250, 0, 0) and tuple(got[6, 6]) == (0, 0, 0)
    assert tuple(got[0, 0]) == (255, 255, 255)
    with pytest.raises(PlotError, match="no frames"):
        _GifStream(io.BytesIO(), _palette_image(colors), 100.0).close()


def test_animate_frames_show_the_train_where_the_data_put_it(run3, tmp_path):
    """The last frame's robot body is drawn in its face colour around the robot's last pose,
    and the time stamp (drawn over the axes' top-left corner) differs between frames."""
    from matplotlib.colors import to_rgb

    from pushtrain.report.animation import _ROBOT_FACE

    out = animation.animate(run3.data, 3, tmp_path / "train.gif", max_frames=6)
    frames, durations = _decoded(out.read_bytes())
    assert len(frames) == 6 and set(durations) == {100}
    face = np.array([round(255 * c) for c in to_rgb(_ROBOT_FACE)])
    near_face = np.all(np.abs(frames[-1].astype(int) - face) <= 24, axis=2)
    assert near_face.sum() > 30  # the robot body is drawn
    top_left = (slice(0, 60), slice(0, 250))
    assert not np.array_equal(frames[0][top_left], frames[-1][top_left])  # the stamp changed


def test_animate_writes_150_frames(run3, tmp_path):
    # how long it takes is measured by benchmarks/, not asserted here (timed tests fail under load)
    out = animation.animate(run3.data, 3, tmp_path / "train.gif")
    with Image.open(out) as im:
        assert im.n_frames == 150


# ------------------------------------------------------------------------------------ plot_all
def test_plot_all_writes_the_standard_files(run3, tmp_path):
    written = plots.plot_all(run3, 3, tmp_path / "out")
    assert [p.name for p in written] == ["map.png", "inputs_joints.png", "tracking_error.png",
                                         "lateral_forces.png", "train.gif"]
    for p in written[:4]:
        png_size(p)
    with Image.open(written[4]) as im:
        assert im.n_frames == 150
    again = plots.plot_all(run3.data, 3, tmp_path / "nogif", gif=False)
    assert [p.name for p in again] == [p.name for p in written[:4]]
    assert sorted(p.name for p in (tmp_path / "nogif").iterdir()) == sorted(p.name for p in again)
    with pytest.raises(PlotError, match="n_trailers = 3"):
        plots.plot_all(run3, 2, tmp_path / "bad")


# ------------------------------------------------------------------------------------ failures
def test_failed_save_leaves_nothing_behind(run3, tmp_path, monkeypatch):
    from matplotlib.figure import Figure

    target = tmp_path / "map.png"
    target.write_bytes(b"old")

    def broken_savefig(self, fname, **kwargs):
        with open(fname, "wb") as f:
            f.write(b"partial")
        raise RuntimeError("disk full")

    monkeypatch.setattr(Figure, "savefig", broken_savefig)
    with pytest.raises(RuntimeError, match="disk full"):
        mapview.plot_map(run3.data, 3, target)
    assert target.read_bytes() == b"old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["map.png"]


def test_failed_gif_leaves_nothing_behind(run3, tmp_path, monkeypatch):
    from PIL import GifImagePlugin

    calls = []

    def broken_frame(image, offset, **info):  # the header is written, then frame 3 fails
        calls.append(offset)
        if len(calls) == 3:
            raise OSError("disk full")
        return [b"frame"]

    monkeypatch.setattr(GifImagePlugin, "getdata", broken_frame)
    target = tmp_path / "train.gif"
    target.write_bytes(b"old")
    with pytest.raises(OSError, match="disk full"):
        animation.animate(run3.data, 3, target, max_frames=5)
    assert target.read_bytes() == b"old"
    assert [p.name for p in tmp_path.iterdir()] == ["train.gif"]


def test_bad_arguments_raise_plot_errors(run3, tmp_path):
    data = run3.data
    names = [c for c in data.dtype.names if c != "x_d"]
    without = np.empty(len(data), dtype=[(c, "f8") for c in names])
    for c in names:
        without[c] = data[c]
    with pytest.raises(PlotError, match="x_d"):
        mapview.plot_map(without, 3, tmp_path / "m.png")
    with pytest.raises(PlotError, match="more than 2 trailers"):
        timeseries.plot_tracking_error(data, 2, tmp_path / "e.png")
    with pytest.raises(PlotError, match="n = 0"):
        timeseries.plot_lateral_forces(data, 0, tmp_path / "f.png")
    with pytest.raises(PlotError, match="no rows"):
        timeseries.plot_inputs_and_joints(data[:0], 3, tmp_path / "i.png")
    with pytest.raises(PlotError, match="structured array"):
        mapview.plot_map(np.zeros((10, 3)), 3, tmp_path / "m.png")
    with pytest.raises(PlotError, match="footprints\\['robot'\\]"):
        mapview.plot_map(data, 3, tmp_path / "m.png", footprints={"robot": (0.6, -0.5)})
    with pytest.raises(PlotError, match="unknown keys"):
        mapview.plot_map(data, 3, tmp_path / "m.png", footprints={"car": (1, 1)})
    with pytest.raises(PlotError, match="suffix"):
        mapview.plot_map(data, 3, tmp_path / "m.xyz")
    with pytest.raises(PlotError, match=r"\.gif"):
        animation.animate(data, 3, tmp_path / "train.png")
    with pytest.raises(PlotError, match="fps"):
        animation.animate(data, 3, tmp_path / "train.gif", fps=0)
    with pytest.raises(PlotError, match="path_xy"):
        mapview.plot_map(data, 3, tmp_path / "m.png", path_xy=np.zeros(5))
    assert list(tmp_path.iterdir()) == []


def test_module_imports_neither_pyplot_nor_fmpy():
    code = ("import sys, pushtrain.report.plots; "
            "print(sorted(m for m in ('matplotlib.pyplot', 'fmpy') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


# ------------------------------------------------------------------- what the pictures show
def test_map_snapshots_can_be_told_apart_and_the_robot_is_marked():
    from shapely import Polygon, union_all

    n = 3  # 12 m, a gentle turn then mostly straight: time-spaced snapshots would overlap
    data = synthetic(n, ChainGeometry(np.full(n, D), np.full(n, D)), t_end=120.0, h=0.05,
                     w0=0.0)
    fig = mapview.map_figure(data, n, snapshots=8)
    rows = list(fig.snapshot_rows)
    sizes = [(0.6, 0.5)] + [(0.8, 0.6)] * n

    def train(r):  # the snapshot's bodies, computed here from the data
        out = []
        for i in range(n + 1):
            c, s = math.cos(data[f"theta{i}"][r]), math.sin(data[f"theta{i}"][r])
            L, W = sizes[i]
            pts = [(data[f"x{i}"][r] + a * L / 2 * c - b * W / 2 * s,
                    data[f"y{i}"][r] + a * L / 2 * s + b * W / 2 * c)
                   for a, b in ((1, 1), (-1, 1), (-1, -1), (1, -1))]
            out.append(Polygon(pts))
        return union_all(out)

    shapes = [train(r) for r in rows]
    assert rows[0] == 0 and rows[-1] == len(data) - 1 and len(rows) >= 3
    for a in range(len(shapes)):
        for b in range(a + 1, len(shapes)):
            overlap = shapes[a].intersection(shapes[b]).area
            assert overlap <= 0.25 * min(shapes[a].area, shapes[b].area) + 1e-9
    ax = fig.axes[0]
    fills = {p.get_gid(): p for p in ax.patches if p.get_gid()}
    # every body of a snapshot is filled alike (the robot no darker than its trailers)
    assert {round(fills[f"snapshot0:body{i}"].get_alpha(), 6) for i in range(n + 1)} == {0.45}
    labels = ax.get_legend().get_texts()
    assert any("robot" in t.get_text() for t in labels)
    assert any("trailers" in t.get_text() for t in labels)


def test_planned_path_is_a_band_wider_than_the_lines_on_it(run3):
    path_xy = np.column_stack([run3.data["x_d"], run3.data["y_d"]])
    fig = mapview.map_figure(run3.data, 3, path_xy=path_xy[::50], snapshots=2)
    lines = {ln.get_label(): ln for ln in fig.axes[0].lines}
    band = lines["planned path (last trailer)"]
    assert band.get_linewidth() > 3 * lines["reference (last trailer)"].get_linewidth()
    assert band.get_zorder() < lines["reference (last trailer)"].get_zorder()


def test_inputs_show_the_command_on_top_and_the_joint_limit(run3):
    fig = timeseries.inputs_and_joints_figure(run3.data, 3, phi_max_deg=80.0)
    lines = {ln.get_gid(): ln for ax in fig.axes for ln in ax.lines if ln.get_gid()}
    for cmd, actual in (("v_cmd", "v0"), ("w_cmd", "w0")):
        assert lines[cmd].get_zorder() > lines[actual].get_zorder()
        assert lines[cmd].get_linewidth() < lines[actual].get_linewidth()
    limit = [ln for ln in fig.axes[2].lines if ln.get_linestyle() == "--"]
    assert sorted(float(ln.get_ydata()[0]) for ln in limit) == [-80.0, 80.0]
    assert "joint limit ±80 deg" in [t.get_text() for t in fig.axes[2].get_legend().get_texts()]


def test_tracking_error_legend_names_only_the_bands_drawn(run3):
    data = run3.data.copy()
    data["direction"] = 1.0
    data["direction"][-1] = 0.0  # a rest of no duration: nothing is shaded for it
    fig = timeseries.tracking_error_figure(data, 3)
    names = [t.get_text() for lg in fig.legends for t in lg.get_texts()]
    assert "push (trailer first)" in names and "rest" not in names
    data["direction"][-200:] = 0.0
    fig = timeseries.tracking_error_figure(data, 3)
    assert "rest" in [t.get_text() for lg in fig.legends for t in lg.get_texts()]


def test_a_legend_goes_where_it_hides_the_fewest_points():
    """report.common.legend_place (the cheap loc="best"): a line along the top of the axes
    sends the legend to the bottom, one along the bottom to the top right, a falling line
    (top left to bottom right) to the lower left or upper right, away from it."""
    from pushtrain.report.common import legend_place, new_figure

    def place(x, y):
        ax = new_figure(4.0, 3.0).add_subplot()
        ax.plot(x, y)
        ax.plot([0.0, 10.0], [0.0, 10.0], alpha=0)  # fixes the limits: 0..10 both ways
        ax.lines[-1].remove()
        ax.set_xlim(0.0, 10.0)
        ax.set_ylim(0.0, 10.0)
        return legend_place(ax)

    x = np.linspace(0.0, 10.0, 25_000)
    assert place(x, np.full_like(x, 9.5)) == "lower left"
    assert place(x, np.full_like(x, 0.5)) == "upper right"
    assert place(x, 10.0 - x) in ("lower left", "upper right")
    assert place(x, 10.0 - x) != "upper left"
