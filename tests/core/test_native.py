"""The compiled control law (core/csrc/control.c) equals the Python reference implementation.

Every quantity the C code computes is compared with the Python function it mirrors, on seeded
random states, chains (n = 1, 3, 10, non-uniform links), controller settings, command sequences
and references: to 1e-12 (relative to the value's size, at least 1). A mutation test shows that
these comparisons catch a one-term change of the law. Also: the build (strict C99, only the
allowed headers, the missing-compiler and failing-compiler messages, concurrent builds).
"""

from __future__ import annotations

import math
import os
import re
import subprocess
import sys
from pathlib import Path
from typing import NamedTuple

import numpy as np
import pytest
import reference.controller as controller_module
import reference.pulling as readable_pulling
import reference.reference as readable_reference
from reference.controller import BackwardController

from pushtrain.core import native
from pushtrain.core.controller import Controller, ControllerConfig
from pushtrain.core.kinematics import ChainGeometry, wrap_scalar
from pushtrain.core.pulling import PullGuide, rates_driven_by_last
from pushtrain.core.reference import Reference, ReferenceSample
from pushtrain.core.sampled_reference import SampledReference
from pushtrain.core.segment import PULL, PUSH, REST, Segment
from pushtrain.errors import ControllerError, NativeBuildError, ReferencePathError

CSRC = Path(native.__file__).with_name("csrc")
TOL = 1e-12


class Meas(NamedTuple):
    x0: float
    y0: float
    theta0: float
    phi: list
    last_pose: tuple | None = None


def close(a, b, tol=TOL) -> bool:
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return bool(np.all(np.abs(a - b) <= tol * np.maximum(1.0, np.abs(b))))


def random_geometry(rng, n: int) -> ChainGeometry:
    return ChainGeometry(rng.uniform(0.2, 1.0, n), rng.uniform(0.2, 1.0, n))


def random_config(rng, geometry, rate_limits: bool) -> ControllerConfig:
    acc = alpha = None
    if rate_limits:
        acc = float(rng.uniform(0.05, 0.5)) if rng.random() < 0.8 else None
        alpha = float(rng.uniform(0.05, 0.5)) if rng.random() < 0.8 or acc is None else None
    return ControllerConfig(geometry=geometry, k_x=float(rng.uniform(0.2, 3.0)),
                            k_y=float(rng.uniform(0.5, 10.0)),
                            k_theta=float(rng.uniform(0.5, 8.0)),
                            v_max=float(rng.uniform(0.05, 0.5)),
                            w_max=float(rng.uniform(0.05, 0.5)),
                            acc_max=acc, alpha_max=alpha,
                            rest_speed=float(rng.choice([1e-9, 0.01])))


def random_sample(rng, direction: int) -> ReferenceSample:
    speed = float(rng.uniform(0.0, 0.3)) if rng.random() < 0.9 else 0.005
    v = -speed if direction == PUSH else speed if direction == PULL else 0.0
    return ReferenceSample(float(rng.uniform(-3, 3)), float(rng.uniform(-3, 3)),
                           float(rng.uniform(-10, 10)), v, float(rng.uniform(-0.5, 0.5)),
                           direction)


# ---------------------------------------------------------------------- kinematics


def test_wrap_equals_python_modulo_on_edge_cases_and_random_angles():
    lib = native.load()
    rng = np.random.default_rng(1)
    angles = [0.0, -0.0, math.pi, -math.pi, 3 * math.pi, -3 * math.pi, 2 * math.pi, 1e-300,
              -1e-300, 1e6 + 0.1, -1e6 - 0.1, math.nextafter(math.pi, 0.0),
              math.nextafter(-math.pi, 0.0), math.nextafter(math.pi, 4.0)]
    angles += list(rng.uniform(-50, 50, 2000)) + list(rng.normal(0, 1e4, 200))
    for a in angles:
        got, want = lib.pt_wrap(float(a)), wrap_scalar(float(a))
        assert got == want or (math.isnan(got) and math.isnan(want)), a
    assert lib.pt_wrap(-math.pi) == math.pi  # the interval is (-pi, pi]


@pytest.mark.parametrize("n", [1, 3, 10])
def test_chain_kinematics_equal_python(n):
    from reference.closed_loop import towed_rates

    lib = native.load()
    rng = np.random.default_rng(10 + n)
    for _ in range(200):
        geom = random_geometry(rng, n)
        py = BackwardController(ControllerConfig(geometry=geom))
        c = Controller(ControllerConfig(geometry=geom))
        x0, y0, th0 = rng.uniform(-5, 5), rng.uniform(-5, 5), rng.uniform(-7, 7)
        phi = list(rng.uniform(-1.4, 1.4, n))
        assert close(c.last_trailer_pose(x0, y0, th0, phi), py.last_trailer_pose(x0, y0, th0, phi))
        v_n, w_n = rng.uniform(-0.3, 0.3), rng.uniform(-0.5, 0.5)
        assert close(c.robot_velocity(phi, v_n, w_n), py.robot_velocity(phi, v_n, w_n))
        theta = np.ascontiguousarray(rng.uniform(-3, 3, n + 1))
        out = np.zeros(n + 1)
        chain = c._ctrl.model
        lib.pt_towed_rates(chain, native.dptr(theta), v_n, w_n, native.dptr(out))
        assert close(out, towed_rates(geom)(list(theta), v_n, w_n))
        lib.pt_rates_from_last(chain, native.dptr(theta), v_n, w_n, native.dptr(out))
        assert close(out, rates_driven_by_last(geom)(list(theta), v_n, w_n))


# ---------------------------------------------------------------------- the command


def _command_sequence(rng, n: int, rate_limits: bool, steps: int = 60):
    """Random command sequences through both controllers; returns what each branch saw."""
    geom = random_geometry(rng, n)
    config = random_config(rng, geom, rate_limits)
    py, c = BackwardController(config), Controller(config)
    start = [None, (0.0, 0.0, -0.025), (float(rng.uniform(-0.1, 0.1)), 0.01, 0.3)][
        int(rng.integers(3))]
    if start is None:
        py.reset(), c.reset()
    else:
        py.reset(*start), c.reset(*start)
    seen = {"rest": 0, "push": 0, "pull": 0, "scaled": 0, "rate": 0, "last_pose": 0}
    t = float(rng.uniform(-1, 1))
    for _ in range(steps):
        t += float(rng.choice([0.005, 0.025, 0.1, 0.0, -0.01], p=[0.4, 0.3, 0.2, 0.05, 0.05]))
        direction = int(rng.choice([PUSH, PULL, REST], p=[0.45, 0.4, 0.15]))
        ref = random_sample(rng, direction)
        leader = random_sample(rng, PULL) if direction == PULL else None
        x0, y0 = float(rng.uniform(-3, 3)), float(rng.uniform(-3, 3))
        th0 = float(rng.uniform(-10, 10))
        phi = list(rng.uniform(-1.2, 1.2, n))
        last = None
        if rng.random() < 0.2:
            last = (x0 + float(rng.uniform(-2, 2)), y0 + float(rng.uniform(-2, 2)),
                    float(rng.uniform(-7, 7)))
            seen["last_pose"] += 1
        m = Meas(x0, y0, th0, phi, last)
        if rng.random() < 0.1:  # an outer limiter (the governor) sent something else
            sv, sw = float(rng.uniform(-0.1, 0.1)), float(rng.uniform(-0.1, 0.1))
            py.sent(sv, sw), c.sent(sv, sw)
        v_p, w_p, info_p = py.command(t, m, ref, leader)
        v_c, w_c, info_c = c.command(t, m, ref, leader)
        assert info_c.mode == info_p.mode
        assert close((v_c, w_c), (v_p, w_p)), (v_c, w_c, v_p, w_p)
        assert close(info_c[1:], info_p[1:]), (info_c, info_p)
        prev = (py._v_prev, py._w_prev, py._t_prev)
        assert close(c.state[:2], prev[:2]) and c.state[2] == prev[2]
        seen[info_p.mode] += 1
        seen["scaled"] += info_p.scale > 1.0
        seen["rate"] += not close((v_p, w_p), (info_p.v_raw / info_p.scale,
                                               info_p.w_raw / info_p.scale))
    return seen


@pytest.mark.parametrize("n", [1, 3, 10])
@pytest.mark.parametrize("rate_limits", [False, True])
def test_command_equals_python_on_random_sequences(n, rate_limits):
    rng = np.random.default_rng(100 * n + rate_limits)
    seen = {}
    for _ in range(40):
        for key, count in _command_sequence(rng, n, rate_limits).items():
            seen[key] = seen.get(key, 0) + count
    # every branch was exercised many times
    assert min(seen["rest"], seen["push"], seen["pull"], seen["scaled"], seen["last_pose"]) > 50
    assert (seen["rate"] > 50) == rate_limits, seen


def _mutated_kanayama(term: str):
    def law(x_e, y_e, th_e, u_d, w_d, gains):
        k_x = -gains.k_x if term == "k_x" else gains.k_x
        k_y = -gains.k_y if term == "k_y" else gains.k_y
        k_th = -gains.k_theta if term == "k_theta" else gains.k_theta
        ff = -math.cos(th_e) if term == "feedforward" else math.cos(th_e)
        return (u_d * ff + k_x * x_e, w_d + u_d * (k_y * y_e + k_th * math.sin(th_e)))
    return law


@pytest.mark.parametrize("term", ["k_x", "k_y", "k_theta", "feedforward"])
def test_the_comparison_catches_a_sign_flip_in_one_term(term, monkeypatch):
    """The equality test must fail if one side changes: flip one term on the Python side."""
    monkeypatch.setattr(controller_module, "kanayama", _mutated_kanayama(term))
    rng = np.random.default_rng(7)
    with pytest.raises(AssertionError):
        for _ in range(5):
            _command_sequence(rng, 3, False)


def test_speed_limit_keeps_the_curvature_and_rate_limits_bound_the_change():
    """Independent of the Python class: the C limits do what the docstring says."""
    geom = ChainGeometry.uniform(3, 0.52)
    config = ControllerConfig(geometry=geom, v_max=0.1, w_max=0.1, acc_max=0.2, alpha_max=0.3)
    c = Controller(config)
    c.reset(0.0, 0.0, 0.0)
    m = Meas(0.0, 0.0, 0.0, [0.2, -0.1, 0.3])
    ref = ReferenceSample(-2.0, 0.5, 0.1, -0.5, 0.3, PUSH)
    v, w, info = c.command(0.01, m, ref)
    assert info.scale > 1.0
    assert abs(v - 0.0) <= 0.2 * 0.01 + 1e-15 and abs(w) <= 0.3 * 0.01 + 1e-15
    assert abs(v) == pytest.approx(0.2 * 0.01) or abs(w) == pytest.approx(0.3 * 0.01)
    # same direction of change as the speed-limited raw command (one common factor)
    assert v * info.v_raw / info.scale >= 0.0 and w * info.w_raw / info.scale >= 0.0
    c.reset()  # no rate limit on the first call: only the speed limit
    v, w, info = c.command(0.02, m, ref)
    assert max(abs(v) / 0.1, abs(w) / 0.1) == pytest.approx(1.0)
    assert w / v == pytest.approx(info.w_raw / info.v_raw, rel=1e-12)


def test_errors_are_refused_like_python():
    geom = ChainGeometry.uniform(2, 0.5)
    config = ControllerConfig(geometry=geom)
    py, c = BackwardController(config), Controller(config)
    push = ReferenceSample(0.0, 0.0, 0.0, -0.1, 0.0, PUSH)
    pull = ReferenceSample(0.0, 0.0, 0.0, 0.1, 0.0, PULL)
    cases = [
        (Meas(math.nan, 0.0, 0.0, [0.0, 0.0]), push, None, "non-finite measurement"),
        (Meas(0.0, 0.0, 0.0, [0.0, math.inf]), push, None, "non-finite measurement"),
        (Meas(0.0, 0.0, 0.0, [0.0, 0.0], (0.0, math.nan, 0.0)), push, None, "non-finite"),
        (Meas(0.0, 0.0, 0.0, [0.0, 0.0]), pull, None, "leader"),
        (Meas(0.0, 0.0, 0.0, [0.0, 0.0]), push._replace(direction=3), None, "direction"),
        (Meas(0.0, 0.0, 0.0, [0.0]), push, None, "joint angles"),
        (Meas(0.0, 0.0, 0.0, [0.0, 0.0]), push._replace(v=-1e308), None, "non-finite command"),
    ]
    for m, ref, leader, words in cases:
        with pytest.raises(ControllerError, match=words):
            c.command(0.0, m, ref, leader)
        with pytest.raises(ValueError):  # ControllerError, or math's "domain error" for inf
            py.command(0.0, m, ref, leader)
    # stricter than Python on purpose, where Python passes a NaN command on: NaN joints beside
    # a measured last pose, a NaN or infinite reference
    m = Meas(0.0, 0.0, 0.0, [math.nan, 0.0], (-1.0, 0.0, 0.0))
    assert math.isnan(py.command(0.0, m, push)[0])
    with pytest.raises(ControllerError, match="non-finite measurement"):
        c.command(0.0, m, push)
    for ref in (push._replace(x=math.nan), push._replace(w=math.inf)):
        assert math.isnan(py.command(0.0, Meas(0.0, 0.0, 0.0, [0.0, 0.0]), ref)[0])
        with pytest.raises(ControllerError, match="non-finite command"):
            c.command(0.0, Meas(0.0, 0.0, 0.0, [0.0, 0.0]), ref)
    # a refused call leaves the rate limits' memory as it was
    c.reset(0.05, 0.01, 1.0)
    with pytest.raises(ControllerError):
        c.command(2.0, Meas(0.0, 0.0, 0.0, [0.0, math.nan]), push)
    assert c.state == (0.05, 0.01, 1.0)


# ---------------------------------------------------------------------- reference and guide


def random_segments(rng, count: int, pulls: bool = True) -> list[Segment]:
    segments = []
    direction = PUSH
    for _ in range(count):
        if pulls and rng.random() < 0.35:
            direction = -direction
        speed = None if rng.random() < 0.6 else float(rng.uniform(0.02, 0.2))
        if rng.random() < 0.4:
            segments.append(Segment("line", float(rng.uniform(0.05, 2.0)), 0.0, direction, speed))
        else:
            kappa = float(rng.choice([-1, 1]) * rng.uniform(0.05, 1.5))
            segments.append(Segment("arc", float(rng.uniform(0.05, 2.0)), kappa, direction, speed))
    return segments


def random_reference(rng, pulls: bool = True) -> Reference:
    return Reference.from_segments(
        tuple(rng.uniform(-5, 5, 2)) + (float(rng.uniform(-4, 4)),),
        random_segments(rng, int(rng.integers(1, 9)), pulls), float(rng.uniform(0.03, 0.15)),
        float(rng.choice([0.0, 0.7, 1.0])), float(rng.choice([0.0, 0.0, 3.3])))


def _sample_times(rng, ref: Reference) -> np.ndarray:
    knots = np.append(ref.phases[:, 0], ref.t_end)
    return np.concatenate([knots, np.nextafter(knots, -np.inf), np.nextafter(knots, np.inf),
                           rng.uniform(ref.t0 - 2.0, ref.t_end + 2.0, 300)])


def test_reference_sampling_equals_python_on_random_references():
    """The engine's phase table and sampling against the readable Python reference, bit for
    bit: times, pull runs, single samples, the array form and the goal."""
    rng = np.random.default_rng(2)
    for _ in range(150):
        ref = random_reference(rng)
        py = readable_reference.Reference.from_segments(ref.start, ref.segments, ref.speed,
                                                        ref.cusp_dwell, ref.t0)
        assert ref.t_end == py.t_end and ref.pull_intervals() == py.pull_intervals()
        assert np.array_equal(ref.phases[:, 0], py._t_start)
        times = _sample_times(rng, ref)
        for t in times:
            got, want = ref.sample_at(t), py.sample_at(t)
            assert tuple(got) == tuple(want), (t, got, want)
        for got, want in zip(ref.sample(times), py.sample(times), strict=True):
            assert got.tobytes() == want.tobytes()
        assert np.array_equal(ref.direction_at(times), py.direction_at(times))
        assert ref.goal.tobytes() == py.goal.tobytes()


def test_a_reference_pickles_with_its_table():
    """A Reference crosses a process boundary (a sweep's tasks): rebuilt, it samples alike."""
    import pickle

    rng = np.random.default_rng(8)
    ref = random_reference(rng).continuation([Segment("line", 0.5, 0.0, PULL)])
    back = pickle.loads(pickle.dumps(ref))
    assert back.t0 == ref.t0 and back.segments == ref.segments
    for t in _sample_times(rng, ref):
        assert back.sample_at(t) == ref.sample_at(t)


def test_extending_or_continuing_a_reference_equals_building_it_at_once():
    rng = np.random.default_rng(3)
    for _ in range(60):
        ref = random_reference(rng)
        grown = Reference(ref.start, (), ref.speed, ref.cusp_dwell, ref.t0)
        pieces = [Reference(ref.start, (), ref.speed, ref.cusp_dwell, ref.t0)]
        for seg in ref.segments:
            grown.append(seg)
            pieces[-1].append(seg)
            pieces.append(pieces[-1].continuation())
        for t in _sample_times(rng, ref):
            want = ref.sample_at(t)
            assert grown.sample_at(t) == want
            if ref.t0 <= t < ref.t_end:  # the piece whose span holds t (the last one starting
                piece = [p for p in pieces[:-1] if p.t0 <= t][-1]  # at or before t)
                assert piece.sample_at(t) == want, (t, piece.t0)
    copy = grown.copy()
    copy.append(Segment("line", 1.0))
    assert copy.t_end > grown.t_end and len(copy.segments) == len(grown.segments) + 1


def test_reference_refuses_what_python_refuses():
    nat = Reference((0.0, 0.0, 0.0))
    with pytest.raises(ReferencePathError):
        nat.sample_at(0.0)  # no segment yet
    with pytest.raises(ReferencePathError):
        Reference((0.0, math.nan, 0.0))
    with pytest.raises(ReferencePathError):
        Reference((0.0, 0.0, 0.0), speed=0.0)
    with pytest.raises(ReferencePathError):
        nat.append("line")
    lib = native.load()
    bad = [native.PtSegment(0.0, 0.0, 0.0, 1, 0), native.PtSegment(1.0, 0.5, 0.0, 1, 0),
           native.PtSegment(1.0, 0.0, 0.0, 1, 1), native.PtSegment(1.0, 0.0, 0.0, 2, 0),
           native.PtSegment(1.0, 0.0, -1.0, 1, 0), native.PtSegment(1.0, math.nan, 0.0, 1, 1),
           native.PtSegment(1.0, 0.0, 0.0, 1, 5)]
    for seg in bad:
        assert lib.pt_reference_append(nat.struct, seg) == 7
    assert nat.struct.n_phases == 0


def test_pull_guide_in_c_equals_python():
    """The engine's guide (C backward runs) against the readable Python one, bit for bit, on a
    line/arc reference (sampled in C) and on its sampled form (sampled through a callback)."""
    rng = np.random.default_rng(4)
    checked = 0
    for n in (1, 3, 10):
        for _ in range(12):
            ref = random_reference(rng)
            if not ref.pull_intervals():
                continue
            geom = random_geometry(rng, n)
            step = float(rng.choice([0.02, 0.05, 0.013]))
            want = readable_pulling.PullGuide(ref, geom, step)
            for given in (ref, (ref)):
                got = PullGuide(given, geom, step)
                assert len(got.runs) == len(want.runs)
                for a, b in zip(want.runs, got.runs, strict=True):
                    for name in ("t", "x", "y", "theta", "v", "w", "headings"):
                        assert getattr(b, name).tobytes() == getattr(a, name).tobytes(), name
            checked += 1
    assert checked > 15
    ref = random_reference(np.random.default_rng(9))
    while not ref.pull_intervals():
        ref = random_reference(rng)
    sampled = SampledReference.from_reference(ref, 0.01)
    want = readable_pulling.PullGuide(sampled, GEOM3 := ChainGeometry.uniform(3, 0.52), 0.05)
    got = PullGuide(sampled, GEOM3, 0.05)
    for a, b in zip(want.runs, got.runs, strict=True):
        assert b.headings.tobytes() == a.headings.tobytes() and b.x.tobytes() == a.x.tobytes()


def test_leader_sampling_equals_python():
    rng = np.random.default_rng(5)
    checked = 0
    for _ in range(25):
        ref = random_reference(rng)
        if not ref.pull_intervals():
            continue
        geom = random_geometry(rng, 3)
        guide = readable_pulling.PullGuide(ref, geom, step=0.05)
        nat = PullGuide(ref, geom, step=0.05)
        edges = np.array([[r.t[0], r.t[-1]] for r in guide.runs]).ravel()
        rows = np.concatenate([r.t for r in guide.runs])
        times = np.concatenate([edges, edges + 5e-7, edges - 5e-7, edges + 2e-6, edges - 2e-6,
                                rng.uniform(ref.t0 - 1, ref.t_end + 1, 300),
                                rng.choice(rows, min(rows.size, 200), replace=False)])
        for t in times:
            try:
                want = guide.sample_at(t)
            except ReferencePathError:
                with pytest.raises(ReferencePathError):
                    nat.sample_at(t)
                continue
            got = nat.sample_at(t)
            assert got.direction == PULL and tuple(got) == tuple(want), (t, got, want)
            checked += 1
    assert checked > 1500


def test_native_controller_drops_into_the_closed_loop(monkeypatch):
    """The reference closed loop (tests/reference/closed_loop.py) with the C controller in place
    of the Python one: the same run."""
    import reference.closed_loop as tc

    geom = ChainGeometry(np.array([0.5, 0.6, 0.45]), np.array([0.3, 0.52, 0.7]))
    ref = Reference.from_segments((0.0, 0.0, math.pi), [
        Segment("line", 0.6), Segment("arc", 0.8, 0.8), Segment("line", 0.5, 0.0, PULL),
        Segment("arc", 0.5, -0.6, PULL)], speed=0.08, cusp_dwell=1.0)
    config = ControllerConfig(geometry=geom)
    heads = np.full(4, math.pi) + np.array([0.1, 0.05, 0.0, 0.0])
    want = tc.simulate_tracking(geom, ref, heads, config, 0.05, 1.0)
    monkeypatch.setattr(tc, "BackwardController", Controller)
    got = tc.simulate_tracking(geom, ref, heads, config, 0.05, 1.0)
    assert (got.direction == PULL).any() and (got.direction == PUSH).any()
    assert np.allclose(got.state, want.state, rtol=0, atol=1e-12)
    assert np.allclose(got.command, want.command, rtol=0, atol=1e-12)


# ---------------------------------------------------------------------- the build


def test_sources_are_strict_c99_with_only_the_allowed_headers(tmp_path):
    allowed = {"math.h", "string.h", "stddef.h"}
    for path in CSRC.glob("*.[ch]"):
        for name in re.findall(r'#include\s*[<"]([^>"]+)[>"]', path.read_text()):
            assert name in allowed or (CSRC / name).is_file(), (path.name, name)
    cc = native.compiler_command()
    for source in CSRC.glob("*.c"):
        done = subprocess.run([*cc, "-std=c99", "-Wall", "-Wextra", "-Wpedantic", "-Werror",
                               "-Wshadow", "-c", str(source), "-o", str(tmp_path / "a.o")],
                              capture_output=True, text=True)
        assert done.returncode == 0, done.stderr


def test_missing_compiler_is_a_clear_error(monkeypatch, tmp_path):
    monkeypatch.setenv("PUSHTRAIN_CACHE", str(tmp_path))
    monkeypatch.setenv("CC", "/nonexistent/bin/my-cc -O1")
    with pytest.raises(NativeBuildError, match=r"C compiler not found: CC = '/nonexistent/bin/"
                                               r"my-cc -O1' \(environment\).*set CC"):
        native.load()
    assert not any(tmp_path.rglob("*.so"))


def test_failing_compiler_is_a_clear_error(monkeypatch, tmp_path):
    monkeypatch.setenv("PUSHTRAIN_CACHE", str(tmp_path))
    monkeypatch.setenv("CC", "false")
    with pytest.raises(NativeBuildError, match=r"compiling control\.c, .*step\.c failed"):
        native.library_path()
    assert not [p for p in tmp_path.rglob("*") if p.is_file()]  # no partial library left


@pytest.mark.slow
def test_concurrent_builds_each_load_a_complete_library(tmp_path):
    """Three processes build into an empty cache at once; all load and compute."""
    code = ("from pushtrain.core import native; lib = native.load(); "
            "assert lib.pt_wrap(4.0) == 4.0 - 2 * 3.141592653589793; "
            "print(native.library_path())")
    env = {**os.environ, "PUSHTRAIN_CACHE": str(tmp_path)}
    procs = [subprocess.Popen([sys.executable, "-c", code], env=env, stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for _ in range(3)]
    outs = [p.communicate(timeout=300) for p in procs]
    assert all(p.returncode == 0 for p in procs), outs
    paths = {out.strip() for out, _ in outs}
    assert len(paths) == 1
    built = [p for p in (tmp_path / "native").iterdir()]
    assert [p.name for p in built] == [Path(paths.pop()).name]  # no partial files left


def test_a_compile_cache_that_is_a_file_is_bad_input_exit_2(tmp_path, monkeypatch):
    """PUSHTRAIN_CACHE naming a file: the message names it, and the CLI gives exit 2 (bad
    input) as for the FMU cache, not 1 ("ran, goal not reached")."""
    from pushtrain.cli.common import click_error
    from pushtrain.core import native
    from pushtrain.errors import InputError

    blocker = tmp_path / "cache"
    blocker.write_text("a file")
    monkeypatch.setenv("PUSHTRAIN_CACHE", str(blocker))
    with pytest.raises(InputError) as info:
        native.library_path(rebuild=True)
    assert "PUSHTRAIN_CACHE" in str(info.value) and str(blocker) in str(info.value)
    assert click_error(info.value).exit_code == 2
