"""The planner's closed-loop prediction against a co-simulation through the FMU."""

import math

import numpy as np

from pushtrain.core.controller import ControllerConfig
from pushtrain.core.reference import Reference
from pushtrain.core.segment import PULL, PUSH, Segment
from pushtrain.cosim.master import simulate
from pushtrain.cosim.plant import InitialState
from pushtrain.facility.free_space import World
from pushtrain.planner.config import TrackerConfig
from pushtrain.planner.train import Train
from pushtrain.planner.train_check import check_train


def test_predicted_last_trailer_matches_the_fmu(fmu3):
    train = Train.uniform(3)
    world = World.from_dict({"bounds": [-20, -20, 20, 20]})
    # pushing arcs, a cusp, a pulling arc and line, from a bent chain: transients of
    # several centimetres to predict
    segs = [Segment("line", 0.5, 0.0, PUSH), Segment("arc", 1.0, 1 / 1.2, PUSH),
            Segment("arc", 0.6, -1 / 1.5, PUSH), Segment("arc", 0.8, 1 / 1.5, PULL),
            Segment("line", 0.8, 0.0, PULL)]
    start = (0.0, 0.0, math.pi)
    theta0 = math.pi + np.array([0.4, 0.25, 0.1, 0.0])
    controller = ControllerConfig(geometry=train.geometry)
    tracker = TrackerConfig(controller=controller, speed=0.08, cusp_dwell=1.0, goal_tolerance=None)
    res = check_train(world, train, start, segs, theta0, tracker=tracker)
    assert res.ok, res.failure
    assert res.max_tracking_error > 0.04  # a run with real transients

    reference = Reference.from_segments(start, segs, 0.08, 1.0)
    initial = InitialState.behind_reference(reference, train.geometry,
                                            joint_angles=theta0[:-1] - theta0[1:])
    run = simulate(fmu3, reference, controller, initial=initial, settle_time=2.0, check_goal=False)
    data = run.data
    tr = res.run
    z = tr.states
    # the planner's last-trailer trajectory at the co-simulation's times
    x = z[:, 0] - np.array([_chain_offset(train, th)[0] for th in z[:, 2:]])
    y = z[:, 1] - np.array([_chain_offset(train, th)[1] for th in z[:, 2:]])
    t = data["t"]
    err = np.hypot(data["x3"] - np.interp(t, tr.t, x), data["y3"] - np.interp(t, tr.t, y))
    # the FMU's robot follows the command with a 0.05 s lag, the prediction ignores it
    assert err.max() < 0.03
    # the robot as well, and the joint angles within a few degrees (measured: 2.1 cm, 1.6 cm,
    # 3.3 deg)
    robot = np.hypot(data["x0"] - np.interp(t, tr.t, z[:, 0]),
                     data["y0"] - np.interp(t, tr.t, z[:, 1]))
    assert robot.max() < 0.03
    for i in range(1, 4):
        phi = np.interp(t, tr.t, z[:, 1 + i] - z[:, 2 + i])
        assert np.abs(data[f"phi{i}"] - phi).max() < math.radians(5.0)
    # the tracking error the planner reports is the co-simulation's, to the same few cm
    # (0.67 m: the pulled last trailer lags far behind its reference)
    fmu_err = np.hypot(data["x3"] - data["x_d"], data["y3"] - data["y_d"])
    assert abs(fmu_err.max() - res.max_tracking_error) < 0.03


def _chain_offset(train, theta):
    """Vector [m] from the last trailer to the robot for headings ``theta``."""
    g = train.geometry
    c, s = np.cos(theta), np.sin(theta)
    return (float(np.sum(g.front * c[1:] + g.rear * c[:-1])),
            float(np.sum(g.front * s[1:] + g.rear * s[:-1])))
