"""The OMPL planners of the last trailer (``planner = "rrtconnect"`` etc.): planning in the
reference worlds, whole-train validity, errors, reproducibility, export."""

import math
import subprocess
import sys

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from shapely.geometry import Polygon

from pushtrain.core.kinematics import (
    body_positions,
    heading_rates_from_last,
    heading_rates_from_robot,
    joint_angles,
)
from pushtrain.core.reference import Reference
from pushtrain.core.segment import PULL, PUSH
from pushtrain.errors import PlanningError, PlanningInputError
from pushtrain.facility import example_layouts
from pushtrain.facility.free_space import World
from pushtrain.planner.config import PlannerConfig, turning_radius_from_joint_limit
from pushtrain.planner.path import PlannedPath
from pushtrain.planner.planner import plan
from pushtrain.planner.train import Train
from pushtrain.planner.train_check import check_train

TRAIN = Train.uniform(3, link=0.52)


def ompl(**settings) -> PlannerConfig:
    """The OMPL RRTConnect planner of the last trailer with ``settings`` (a budget of 2 s
    unless given: these tests were measured with it)."""
    return PlannerConfig(planner="rrtconnect", **{"time_budget": 2.0, **settings})


OMPL = ompl()
"""This module tests the OMPL planners of the last trailer; the default whole-train planner is
tested in test_planner_lattice.py."""


def _corners(fp, x, y, th):
    c, s = math.cos(th), math.sin(th)
    out = []
    for a, b in ((1, 1), (-1, 1), (-1, -1), (1, -1)):
        u, v = fp.offset + a * fp.length / 2, b * fp.width / 2
        out.append((x + u * c - v * s, y + u * s + v * c))
    return out


def _independent_push_check(world, path, train):
    """Integrate the chain with scipy along a pushing-only path with the last trailer exactly on
    it (open loop), check bodies every 1 cm; returns the joint angles (N, n) at ``path.s``."""
    geom = train.geometry
    theta = np.full(train.n + 1, path.start[2])
    pos = 0.0
    ref = Reference.from_segments(path.start, path.segments, speed=1.0, cusp_dwell=0.0)
    phi = np.empty((path.s.size, train.n))
    for seg in path.segments:
        assert seg.direction == PUSH
        sol = solve_ivp(lambda s, th, k=seg.curvature: heading_rates_from_last(th, -1.0, k, geom),
                        (0.0, seg.length), theta, rtol=1e-9, atol=1e-11, dense_output=True)
        m = max(2, int(math.ceil(seg.length / 0.01)) + 1)
        for s in np.linspace(0.0, seg.length, m):
            th = sol.sol(s)
            x, y, _, _, _ = ref.sample([pos + s])
            bx, by = body_positions(x[0], y[0], th, geom, from_last=True)
            for i, fp in enumerate(train.bodies):
                poly = Polygon(_corners(fp, bx[i], by[i], th[i]))
                assert world.free.contains(poly), f"body {i} hits at s = {pos + s:.3f} m"
        here = (path.s >= pos - 1e-9) & (path.s <= pos + seg.length + 1e-9)
        phi[here] = joint_angles(sol.sol(path.s[here] - pos).T)
        theta = sol.sol(seg.length)
        pos += seg.length
    return phi


@pytest.mark.parametrize("name", ["straight", "l_2.0", "l_1.5"])
def test_corridors_whole_train_valid(name):
    case = example_layouts.CASES[name]()
    world = World.from_dict(case["world"])
    path = plan(world, case["start"], case["goal"], TRAIN, ompl(seed=2))
    assert np.allclose(path.goal[:2], case["goal"][:2], atol=1e-6)
    assert abs(math.remainder(path.goal[2] - case["goal"][2], 2 * math.pi)) < 1e-6
    assert np.all(np.diff(path.s) <= 0.01 + 1e-12)
    phi_open = _independent_push_check(world, path, TRAIN)
    assert np.abs(phi_open).max() <= TRAIN.phi_max
    # the path's joint angles are the closed loop's when the reference passes each pose; it
    # tracks these corridors within about a centimetre laterally (along the track ~1.6 cm from
    # the start ramp, up to ~5.5 cm where two arcs of opposite turn meet and the robot's rate
    # limits hold back the change of its yaw rate), so they are close to the open-loop angles
    check = path.info["train_check"]
    assert check["max_lateral_error"] < 0.015 and check["max_tracking_error"] < 0.06
    assert np.abs(path.joint_angles() - phi_open).max() < 0.12  # 0.10 rad at an S-turn
    assert np.abs(path.joint_angles()).max() <= max(check["max_abs_phi"]) + 1e-12
    # every arc uses the planning radius
    for seg in path.segments:
        if seg.kind == "arc":
            assert abs(seg.curvature) == pytest.approx(1.0 / path.turning_radius)


def test_bay_one_direction_change_whole_train_valid():
    case = example_layouts.bay()
    world = World.from_dict(case["world"])
    path = plan(world, case["start"], case["goal"], TRAIN, ompl(seed=2))
    assert path.n_cusps == 1
    assert {g.direction for g in path.segments} == {PUSH, PULL}
    assert np.allclose(path.goal[:2], case["goal"][:2], atol=1e-6)
    # re-run the closed-loop check and test its samples independently (shapely, 1 cm, joints)
    res = check_train(world, TRAIN, path.start, path.segments, margin=0.0, resolution=0.01)
    assert res.ok, res.failure
    for k in range(0, res.t.size):
        for i, fp in enumerate(TRAIN.bodies):
            poly = Polygon(_corners(fp, res.x[k, i], res.y[k, i], res.headings[k, i]))
            assert world.free.contains(poly), (k, i)
    corners = np.array([[_corners(fp, res.x[k, i], res.y[k, i], res.headings[k, i])
                         for i, fp in enumerate(TRAIN.bodies)] for k in range(res.t.size)])
    step = np.linalg.norm(np.diff(corners, axis=0), axis=-1).max(axis=(1, 2))
    assert step.max() <= 0.01 + 1e-9
    assert np.abs(joint_angles(res.headings)).max() <= TRAIN.phi_max
    # the simulated motion obeys the chain kinematics under the held robot command, pulling
    # (towed chain) and pushing alike: compare each step's change with the rates at its middle
    tr = res.run
    k = np.flatnonzero(tr.direction != 0)
    for j in k[:: max(1, k.size // 300)]:
        h = tr.t[j + 1] - tr.t[j]
        th0, th1 = tr.states[j, 2:], tr.states[j + 1, 2:]
        v0, w0 = tr.commands[j]
        mid = 0.5 * (th0 + th1)
        rates = heading_rates_from_robot(mid, v0, w0, TRAIN.geometry)
        assert (th1 - th0) / h == pytest.approx(rates, abs=1e-4)
        d = (tr.states[j + 1, :2] - tr.states[j, :2]) / h
        assert d == pytest.approx(v0 * np.array([math.cos(mid[0]), math.sin(mid[0])]), abs=1e-5)
    assert {int(a) for a in tr.direction[k]} == {PUSH, PULL}
    # the path's headings are the closed loop's: they start with the start headings and the
    # last one stays within the worst heading error of the planned heading
    assert np.allclose(path.headings[0], path.start[2])
    err = np.angle(np.exp(1j * (path.headings[:, -1] - path.poses[:, 2])))
    assert np.abs(err).max() <= res.max_heading_error + 1e-9


@pytest.mark.parametrize("seed", [1, 3, 4])
def test_bay_pulls_end_with_a_free_straight_train_and_start_near_straight(seed):
    """The planner's pull rules, checked independently on its result: at every pull's end
    (cusp or goal) the train drawn out straight ahead of the last trailer is free, and the
    first pull, drawn back from that straight end, needs a chain within the tolerance of the
    straight start chain (robot offset measured with core.kinematics)."""
    case = example_layouts.bay()
    world = World.from_dict(case["world"])
    cfg = ompl(seed=seed, check_train=False, max_attempts=4)
    path = plan(world, case["start"], case["goal"], TRAIN, cfg)
    region = world.eroded(cfg.inflation)
    geom = TRAIN.geometry
    ref = Reference.from_segments(path.start, path.segments, speed=0.08, cusp_dwell=0.0)
    pos, runs = 0.0, []
    for _k, seg in enumerate(path.segments):
        if seg.direction == PULL:
            if runs and abs(runs[-1][1] - pos) < 1e-12:
                runs[-1][1] = pos + seg.length
            else:
                runs.append([pos, pos + seg.length])
        pos += seg.length
    assert runs, "the bay needs a pull"
    for _a, b in runs:
        x, y, th, _, _ = ref.sample([(b - 1e-9) / 0.08])
        straight = np.full(TRAIN.n + 1, th[0])
        bx, by = body_positions(x[0], y[0], straight, geom, from_last=True)
        for i, fp in enumerate(TRAIN.bodies):
            assert region.contains(Polygon(_corners(fp, bx[i], by[i], th[0]))), (i, b)
    a, b = runs[0]
    s = np.linspace(a, b - 1e-9, 800)
    x, y, th, _, _ = ref.sample(s / 0.08)
    theta = np.full(TRAIN.n + 1, th[-1])
    for j in range(s.size - 1, 0, -1):  # drawn back: pushing the last trailer (scipy)
        ds = s[j] - s[j - 1]
        w = (th[j] - th[j - 1]) / ds
        sol = solve_ivp(lambda _s, q, w=w: -heading_rates_from_last(q, 1.0, w, geom), (0.0, ds),
                        theta, rtol=1e-10, atol=1e-12)
        theta = sol.y[:, -1]
        theta[-1] = th[j - 1]
    bx, by = body_positions(0.0, 0.0, theta, geom, from_last=True)
    sx, sy = body_positions(0.0, 0.0, np.full(TRAIN.n + 1, th[0]), geom, from_last=True)
    assert np.hypot(bx - sx, by - sy).max() <= cfg.pull_start_tolerance + 0.02


def test_replanning_changes_what_the_failure_calls_for():
    from pushtrain.planner.ompl_search import Attempt
    from pushtrain.planner.planner import _next_attempt

    cfg = ompl()
    base = Attempt(radius=1.0, inflation=0.05)
    hit = {"kind": "collision", "x": 1.0, "y": 2.0}
    # the robot (or a leading trailer) hits while pulling: only a larger radius helps
    for body in (0, TRAIN.n - 1):
        nxt = _next_attempt(base, {**hit, "body": body, "direction": PULL}, TRAIN, cfg)
        assert nxt.radius == pytest.approx(1.2) and not nxt.blocks and nxt.inflation == 0.05
    # the last trailer while pulling, or any body while pushing: block the spot
    for body, direction in ((TRAIN.n, PULL), (0, PUSH), (2, PUSH)):
        nxt = _next_attempt(base, {**hit, "body": body, "direction": direction}, TRAIN, cfg)
        assert nxt.radius == 1.0 and len(nxt.blocks) == 1
        assert nxt.blocks[0].bounds == pytest.approx((0.75, 1.75, 1.25, 2.25))
        again = _next_attempt(nxt, {**hit, "body": body, "direction": direction}, TRAIN, cfg)
        assert len(again.blocks) == 2 and again.inflation == pytest.approx(0.1)
    for kind in ("joint_limit", "goal_missed"):
        nxt = _next_attempt(base, {"kind": kind, "body": 3, "direction": PUSH, "x": 0, "y": 0},
                            TRAIN, cfg)
        assert nxt.radius == pytest.approx(1.2) and not nxt.blocks


def test_planner_checks_with_the_given_tracker():
    from pushtrain.core.controller import ControllerConfig

    case = example_layouts.straight_corridor()
    world = World.from_dict(case["world"])
    slow = ControllerConfig.uniform(3, v_max=0.05)  # cannot follow 0.08 m/s: misses the goal
    with pytest.raises(PlanningError) as info:
        plan(world, case["start"], case["goal"], TRAIN,
             ompl(seed=2, controller=slow, max_attempts=2))
    failure = info.value.details["failure"]
    assert failure["kind"] == "goal_missed"
    assert failure["distance"] == pytest.approx(5.0 - 0.05 * 5.0 / 0.08, abs=0.01)
    path = plan(world, case["start"], case["goal"], TRAIN,
                ompl(seed=2, controller=slow, speed=0.04, cusp_dwell=0.5))
    assert path.info["train_check"]["speed"] == 0.04
    assert path.info["train_check"]["goal_error"][0] < 0.05
    with pytest.raises(PlanningInputError, match="n = 2"):
        plan(world, case["start"], case["goal"], TRAIN,
             ompl(controller=ControllerConfig.uniform(2)))
    with pytest.raises(PlanningInputError, match="speed"):
        ompl(speed=-1.0)


def test_same_seed_same_plan_and_different_seed_differs():
    case = example_layouts.l_corridor(2.0)
    world = World.from_dict(case["world"])
    cfg = ompl(seed=7, check_train=False)
    a = plan(world, case["start"], case["goal"], TRAIN, cfg)
    b = plan(world, case["start"], case["goal"], TRAIN, cfg)
    assert a.to_dict()["segments"] == b.to_dict()["segments"]
    others = {
        tuple(round(g.length, 9) for g in
              plan(world, case["start"], case["goal"], TRAIN,
                   ompl(seed=s, check_train=False)).segments)
        for s in (8, 9, 10)
    }
    assert len(others | {tuple(round(g.length, 9) for g in a.segments)}) > 1


def test_json_roundtrip_and_reference():
    case = example_layouts.bay()
    world = World.from_dict(case["world"])
    path = plan(world, case["start"], case["goal"], TRAIN, ompl(seed=2))
    again = PlannedPath.from_json(path.to_json())
    assert again.to_dict() == path.to_dict()
    assert np.allclose(again.poses, path.poses)
    ref = path.to_reference(speed=0.1, cusp_dwell=2.0)
    assert ref.t_end == pytest.approx(path.length / 0.1 + 2.0 * path.n_cusps)
    # sample the reference at the dense poses' travel distances (before/after the dwell)
    t = path.s / 0.1 + 2.0 * (path.s > path.s[path.cusps[0]])
    x, y, th, v, w = ref.sample(t)
    assert np.allclose(np.column_stack([x, y, th]), path.poses, atol=1e-9)
    # at interval midpoints: w_d = |v_d| * curvature and the sign of v_d is -direction
    s_mid = 0.5 * (path.s[1:] + path.s[:-1])
    t_mid = s_mid / 0.1 + 2.0 * (s_mid > path.s[path.cusps[0]])
    _, _, _, v, w = ref.sample(t_mid)
    kappa = np.array([path.segments[j].curvature for j in path.interval_segment])
    direction = np.array([path.segments[j].direction for j in path.interval_segment])
    assert np.allclose(w, 0.1 * kappa) and np.allclose(v, -0.1 * direction)


def test_radius_rule_and_transient_margin():
    d, phi_max = 0.52, math.pi / 2
    r = turning_radius_from_joint_limit(phi_max, d, 0.6)
    assert 2 * math.atan(d / r) == pytest.approx(phi_max / 1.6)
    assert ompl().radius_for(TRAIN) == pytest.approx(r)
    # kinematic worst case: steady left arc, then a right arc (3 trailers, pushing)
    from pushtrain.core.segment import Segment

    world = World.from_dict({"bounds": [-50, -50, 50, 50]})
    segs = [
        Segment("arc", 2 * math.pi * r, 1 / r, PUSH), Segment("arc", 2 * math.pi * r, -1 / r, PUSH)
    ]
    res = check_train(world, TRAIN, (0, 0, 0), segs, resolution=0.01)
    assert res.max_abs_phi.max() <= phi_max
    r0 = turning_radius_from_joint_limit(phi_max, d, 0.0)  # no margin: the reversal overshoots
    segs0 = [
        Segment("arc", 2 * math.pi * r0, 1 / r0, PUSH),
        Segment("arc", 2 * math.pi * r0, -1 / r0, PUSH),
    ]
    res0 = check_train(world, TRAIN, (0, 0, 0), segs0, resolution=0.01)
    assert res0.max_abs_phi.max() > phi_max


@pytest.mark.parametrize(
    "case, reason",
    [
        (lambda: example_layouts.two_rooms(0.0), "unreachable"),
        (lambda: example_layouts.two_rooms(0.5), "unreachable"),
        (lambda: {"world": {"free": [[0, 0], [10, 0], [10, 0], [0, 0]]},
                  "start": [1, 0, math.pi], "goal": [9, 0, math.pi]}, "no_free_space"),
        (lambda: {"world": {"free": [[0, 0], [10, 0], [10, 0.5], [0, 0.5]]},
                  "start": [4, 0.25, math.pi], "goal": [9, 0.25, math.pi]}, "no_free_space"),
    ],
)
def test_errors_are_named(case, reason):
    # plan time is measured by benchmarks/bench_planner.py, not asserted here
    c = case()
    world = World.from_dict(c["world"])
    with pytest.raises(PlanningError) as info:
        plan(world, c["start"], c["goal"], TRAIN, ompl(time_budget=5.0))
    assert info.value.reason == reason
    assert str(info.value).startswith(f"[{reason}]")


def test_colliding_start_and_goal():
    case = example_layouts.l_corridor(2.0)
    world = World.from_dict(case["world"])
    with pytest.raises(PlanningError) as info:
        # the straight chain behind the last trailer sticks out of the corridor's left end
        plan(world, (2.0, 1.0, math.pi), case["goal"], TRAIN, OMPL)
    assert info.value.reason == "start_in_collision"
    assert info.value.details["body"] == 0 and info.value.where[0] < 0.0
    with pytest.raises(PlanningError) as info:
        plan(world, case["start"], (4.0, 0.1, math.pi), TRAIN, OMPL)
    assert info.value.reason == "goal_in_collision" and info.value.where[:2] == (4.0, 0.1)


def test_approximate_only_is_an_error():
    # with r = 6 m the 2 m corridor needs many cusps: not found within 0.05 s
    case = example_layouts.l_corridor(2.0)
    world = World.from_dict(case["world"])
    cfg = ompl(turning_radius=6.0, time_budget=0.05, check_train=False)
    with pytest.raises(PlanningError) as info:
        plan(world, case["start"], case["goal"], TRAIN, cfg)
    assert info.value.reason in ("approximate_only", "unreachable")
    assert info.value.where is not None


def test_config_validation():
    with pytest.raises(PlanningInputError, match="planner"):
        PlannerConfig(planner="astar")
    with pytest.raises(PlanningInputError, match="check_resolution"):
        ompl(check_resolution=0.02)
    with pytest.raises(PlanningInputError, match="seed"):
        ompl(seed=0)
    with pytest.raises(PlanningInputError, match="rrt_range"):
        ompl(rrt_range=0.0)
    with pytest.raises(PlanningInputError, match="pull_start_tolerance"):
        ompl(pull_start_tolerance=-0.1)


@pytest.mark.parametrize("name", ["rrtstar", "bitstar"])
def test_anytime_planners(name):
    case = example_layouts.l_corridor(2.0)
    world = World.from_dict(case["world"])
    path = plan(world, case["start"], case["goal"], TRAIN,
                PlannerConfig(planner=name, anytime_time=1.0, time_budget=3.0))
    assert path.info["planner"] == name and path.length > 9.0


@pytest.mark.parametrize("name", ["l_2.0", "bay"])
def test_restarts_shortens_the_first_solution_and_the_train_passes(name):
    """The restarts planner (RRTConnect + simplification + local search, best of several; the
    first restart uses the seed itself) returns a path no longer than RRTConnect's with the
    same seed and no shorter than the Reeds-Shepp distance; plan() checks the whole train on
    it as usual."""
    case = example_layouts.CASES[name]()
    world = World.from_dict(case["world"])
    first = plan(world, case["start"], case["goal"], TRAIN,
                 ompl(seed=3, check_train=False))
    best = plan(world, case["start"], case["goal"], TRAIN,
                PlannerConfig(planner="restarts", seed=3, anytime_time=0.5, check_train=False))
    assert best.info["planner"] == "restarts"
    assert best.info["attempts"][-1]["restarts"] >= 1
    assert best.length <= first.length + 1e-9
    if name == "l_2.0":  # with the train check (the bay's shortest paths hug its corners,
        # and whether a replan in a fixed time finds one that passes depends on the machine)
        checked = plan(world, case["start"], case["goal"], TRAIN,
                       PlannerConfig(planner="restarts", seed=3, anytime_time=0.5))
        assert checked.info["attempts"][-1]["train_ok"]
    from pushtrain.planner.reeds_shepp import rs_distance
    radius = best.turning_radius
    yaw = lambda p: (p[0], p[1], p[2] + math.pi)  # noqa: E731
    assert best.length >= rs_distance(radius, yaw(case["start"]), yaw(case["goal"])) - 1e-9


def test_local_search_keeps_the_path_valid_and_never_longer():
    from pushtrain.planner.ompl_search import Attempt, solve_once
    from pushtrain.planner.reeds_shepp import chain_to_planner_state, segments_from_states

    case = example_layouts.bay()
    world = World.from_dict(case["world"])
    cfg = ompl(check_train=False)
    attempt = Attempt(cfg.radius_for(TRAIN), cfg.inflation)
    pairs = []
    for seed in range(5, 15):  # seeds whose plain solve passes the planner's pull rules
        # 1000 motion checks: 1 s of budget
        args = (world, TRAIN, chain_to_planner_state(case["start"]),
                chain_to_planner_state(case["goal"]), cfg, attempt, 1000, seed)
        try:
            plain, _ = solve_once(*args)
            refined, info = solve_once(*args, refine_checks=1000)
        except PlanningError:
            continue
        assert info["refine_time"] < 1.0  # it stops when it stops gaining
        lengths = [sum(g.length for g in segments_from_states(st, attempt.radius)[0])
                   for st in (plain, refined)]
        assert lengths[1] <= lengths[0] + 1e-9
        pairs.append((lengths[0] - lengths[1], refined))
    assert len(pairs) >= 3
    gain, refined = max(pairs, key=lambda p: p[0])
    assert gain > 0.3  # e.g. 7.80 m -> 6.77 m
    # the refined path is collision-free for the last trailer at 1 cm (independent shapely
    # check with the clearance the whole-train check asks for; the planner checks every
    # 0.1 m with offtrack_allowance on top)
    segments, _ = segments_from_states(refined, attempt.radius)
    length = sum(g.length for g in segments)
    ref = Reference.from_segments(case["start"], segments, speed=1.0, cusp_dwell=0.0)
    x, y, th, _, _ = ref.sample(np.linspace(0.0, ref.t_end - 1e-9, int(length / 0.01) + 2))
    region = world.eroded(cfg.inflation)
    for xi, yi, ti in zip(x, y, th, strict=True):
        assert region.contains(Polygon(_corners(TRAIN.last, xi, yi, ti)))


def test_ompl_log_level_is_the_callers(capfd):
    """Importing the planner leaves OMPL's process-wide log level alone; plan() silences OMPL
    only while it runs (nothing reaches stdout/stderr) and restores the caller's level, also
    when it fails."""
    code = ("from ompl import util as ou; ou.setLogLevel(ou.LOG_INFO); import pushtrain.planner; "
            "print(ou.getLogLevel() == ou.LOG_INFO)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "True"

    from ompl import util as ou

    before = ou.getLogLevel()
    try:
        ou.setLogLevel(ou.LOG_INFO)  # OMPL would report its planner runs at this level
        case = example_layouts.l_corridor(2.0)
        world = World.from_dict(case["world"])
        capfd.readouterr()
        plan(world, case["start"], case["goal"], TRAIN, ompl(seed=1, check_train=False))
        assert ou.getLogLevel() == ou.LOG_INFO
        assert capfd.readouterr() == ("", "")
        ou.setLogLevel(ou.LOG_WARN)
        with pytest.raises(PlanningError):
            plan(world, case["start"], case["goal"], TRAIN,
                 ompl(turning_radius=6.0, time_budget=0.05, check_train=False))
        assert ou.getLogLevel() == ou.LOG_WARN
    finally:
        ou.setLogLevel(before)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["rrtconnect", "restarts"])
def test_same_seed_same_plan_at_once_on_a_loaded_cpu(name):
    """Results depend on the seed, not on the wall clock: two plans of the bay with the same
    seed, run at once in two threads while another process keeps a core busy, give the same
    segments as each other and as a plan run alone."""
    from concurrent.futures import ThreadPoolExecutor

    case = example_layouts.bay()
    world = World.from_dict(case["world"])
    # restarts: passes the train check on replan (within 2 s of budget)
    cfg = PlannerConfig(planner=name, seed=1, time_budget=2.0)

    def run(_=None):
        return plan(world, case["start"], case["goal"], TRAIN, cfg).to_dict()["segments"]

    busy = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    try:
        with ThreadPoolExecutor(max_workers=2) as pool:
            a, b = pool.map(run, range(2))
    finally:
        busy.kill()
        busy.wait()
    assert a == b
    assert run() == a


def test_wall_clock_cap_only_stops_a_search_and_says_so(caplog):
    """The wall clock stops planning only at ``time_cap``: a plan cut short by it says so in
    its info (and a warning); a PlanningError in its details."""
    import logging

    case = example_layouts.l_corridor(2.0)
    world = World.from_dict(case["world"])
    plain = plan(
        world, case["start"], case["goal"], TRAIN, ompl(seed=1, check_train=False)
    )
    assert plain.info["time_capped"] is False
    assert 0 < plain.info["checks"] <= plain.info["budget_checks"] == 2000
    # restarts with a budget of 10^6 motion checks: the cap ends them after the first
    cfg = PlannerConfig(planner="restarts", seed=1, anytime_time=1000.0, time_budget=1000.0,
                        time_cap=1.0, check_train=False)
    with caplog.at_level(logging.WARNING, logger="pushtrain.planner"):
        capped = plan(world, case["start"], case["goal"], TRAIN, cfg)
    assert capped.info["time_capped"] is True and capped.info["attempts"][-1]["time_capped"]
    assert capped.info["checks"] < cfg.anytime_checks()
    assert "safety cap" in caplog.text
    with pytest.raises(PlanningError) as info:
        plan(world, case["start"], case["goal"], TRAIN, ompl(seed=1, time_cap=1e-9))
    assert info.value.details["time_capped"] is True and "safety cap" in str(info.value)
    with pytest.raises(PlanningInputError, match="time_cap"):
        ompl(time_cap=0.0)


def test_prmstar_returns():
    """PRM* evaluates its termination condition on a second thread too; a condition written
    in Python would deadlock there (run in a subprocess, so a regression fails, not hangs)."""
    code = (
        "from pushtrain.errors import PlanningError\n"
        "from pushtrain.facility import example_layouts\n"
        "from pushtrain.planner.config import PlannerConfig\n"
        "from pushtrain.planner.planner import plan\n"
        "from pushtrain.facility.free_space import World\n"
        "from pushtrain.planner.train import Train\n"
        "c = example_layouts.l_corridor(2.0)\n"
        "try:\n"
        "    p = plan(World.from_dict(c['world']), c['start'], c['goal'], Train.uniform(3),\n"
        "             PlannerConfig(planner='prmstar', anytime_time=0.2, check_train=False))\n"
        "    print('path', p.length)\n"
        "except PlanningError as e:\n"
        "    print('error', e.reason)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split()[0] in ("path", "error")
