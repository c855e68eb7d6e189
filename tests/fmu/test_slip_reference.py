"""slip_mode 1's linear-time friction solver against the dense solver it replaced (issue 14).

The dense O(n^3) solver (the LCP matrix formed and solved by projected Gauss-Seidel, finished by
an exact solve on the sticking set) is the tests' own C file, ``tests/csrc/slip_dense.c``: it
defines the same functions as the FMU's ``slip_solver.c``. This test compiles the FMU's own
``sources/`` a second time with the dense file in place of ``slip_solver.c`` and runs both
libraries side by side through the same inputs on scenarios in which wheels stick, slide and
switch: the trajectories must agree to round-off (both solve the same LCP, which has one
solution) and the stick/slip flags must be identical.
"""

from __future__ import annotations

import math
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

H = 0.005
KINEMATIC = ("x", "y", "theta", "phi", "v", "w", "slide_speed")
FORCES = ("F_lat", "hitch_fx", "hitch_fy")


def _uneven(n):
    """Links, masses, inertias and payloads that differ from trailer to trailer (a solver that
    confused F_k, R_k or F_k + R_k, or two trailers' masses, would show)."""
    return {**{f"front[{i}]": 0.4 + 0.07 * (i % 4) for i in range(1, n + 1)},
            **{f"rear[{i}]": 0.65 - 0.05 * (i % 3) for i in range(n)},
            **{f"mass[{i}]": 30.0 + 7.0 * (i % 5) for i in range(1, n + 1)},
            **{f"inertia[{i}]": 2.0 + 0.6 * (i % 4) for i in range(1, n + 1)},
            **{f"payload[{i}]": 15.0 * (i % 2) for i in range(1, n + 1)}}


def _scenario(name, n):
    """(parameters, inputs(k) -> dict of the inputs at step k) of a scenario."""
    if name == "mixed":  # a gentle swing on low friction: part of the wheels slide, part stick
        params = {**_uneven(n), **{f"mu[{i}]": 0.002 for i in range(1, n + 1)}}
        return params, lambda k: {"v_cmd": -0.05, "w_cmd": 0.3 if (k // 100) % 2 == 0 else -0.3}
    if name == "pushed":  # the tail is pushed sideways while the robot reverses and turns
        params = {**_uneven(n), "mu[1]": 0.5, "v_start": -0.1, "w_start": 0.1,
                  **{f"mu[{i}]": 0.05 + 0.05 * (i % 3) for i in range(2, n + 1)}}
        return params, lambda k: {"v_cmd": -0.1, "w_cmd": 0.1,
                                  "push_y": 60.0 if 40 <= k < 160 else 0.0}
    if name == "whip":  # the robot whips +-2 rad/s at 1 Hz on very low friction: every wheel slides
        params = {"robot_alpha_max": 50.0, **{f"mu[{i}]": 0.0005 for i in range(1, n + 1)}}
        return params, lambda k: {"v_cmd": -0.05, "w_cmd": 2.0 * math.sin(2 * math.pi * k * H)}
    raise ValueError(name)


DENSE_SOLVER = Path(__file__).parents[1] / "csrc" / "slip_dense.c"
PRODUCT_SOLVER = "slip_solver.c"  # the FMU's source file the dense solver stands in for


def _reference_build(unzipdir, target):
    """A copy of the extracted FMU whose library is rebuilt from its sources with the dense
    solver (:data:`DENSE_SOLVER`) in place of :data:`PRODUCT_SOLVER`."""
    import fmpy

    compiler = shutil.which("cc") or shutil.which("gcc")
    if compiler is None:
        pytest.fail("a C compiler (cc) is required to build the dense reference solver")
    shutil.copytree(unzipdir, target)
    library = target / "binaries" / "linux64" / "TrailerTrain.so"
    library.unlink()
    product = sorted((target / "sources").glob("*.c"))
    assert PRODUCT_SOLVER in [path.name for path in product], "the FMU's solver file was renamed"
    sources = [str(path) for path in product if path.name != PRODUCT_SOLVER] + [str(DENSE_SOLVER)]
    headers = Path(fmpy.__file__).parent / "c-code"
    done = subprocess.run([compiler, "-std=c99", "-O2", "-shared", "-fPIC", "-fvisibility=hidden",
                           "-Wall", "-Wextra", "-Werror", f"-I{headers}",
                           f"-I{target / 'sources'}", *sources, "-o", str(library), "-lm"],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    return target


@pytest.fixture(scope="module")
def reference_unzipped(built_fmu_unzipped, tmp_path_factory):
    """Factory ``reference_unzipped(n) -> unzipdir`` of the dense-solver build (once per n)."""
    cache = {}

    def get(n):
        if n not in cache:
            unzipdir, _ = built_fmu_unzipped(n)
            cache[n] = _reference_build(unzipdir, tmp_path_factory.mktemp(f"dense_n{n}") / "fmu")
        return cache[n]

    return get


def _run(unzipdir, md, n, scenario, steps):
    """Outputs after each new input (before the step: the onset forces when rolling needs more
    than friction) and after each step: {block: (2 * steps, width) array}."""
    from fmpy.fmi2 import FMU2Slave

    vr = {v.name: v.valueReference for v in md.modelVariables}
    blocks = {**{b: [f"{b}[{i}]" for i in range(n + 1)] for b in ("x", "y", "theta", "v", "w")},
              **{b: [f"{b}[{i}]" for i in range(1, n + 1)]
                 for b in ("phi", "slide_speed", *FORCES, "F_lat_max")}}
    real_refs = [vr[name] for names in blocks.values() for name in names]
    flag_refs = [vr[f"slipping[{i}]"] for i in range(1, n + 1)]
    params, inputs = _scenario(scenario, n)

    def set_inputs(k):
        values = inputs(k)
        slave.setReal([vr[name] for name in values], list(values.values()))

    slave = FMU2Slave(guid=md.guid, unzipDirectory=str(unzipdir), modelIdentifier="TrailerTrain",
                      instanceName=f"{scenario}-{n}")
    slave.instantiate()
    try:
        slave.setupExperiment(startTime=0.0)
        slave.enterInitializationMode()
        slave.setInteger([vr["slip_mode"]], [1])
        slave.setReal([vr[name] for name in params], list(params.values()))
        set_inputs(0)
        slave.exitInitializationMode()
        rows, flags = [], []
        for k in range(steps):
            set_inputs(k)
            rows.append(slave.getReal(real_refs))  # after the set
            flags.append(slave.getBoolean(flag_refs))
            slave.doStep(k * H, H)
            rows.append(slave.getReal(real_refs))  # after the step
            flags.append(slave.getBoolean(flag_refs))
        slave.terminate()
    finally:
        slave.freeInstance()
    rows = np.array(rows)
    out, col = {"slipping": np.array(flags, dtype=bool)}, 0
    for block, names in blocks.items():
        out[block] = rows[:, col:col + len(names)]
        col += len(names)
    return out


CASES = [(3, "mixed", 600), (3, "pushed", 300), (3, "whip", 400),
         (10, "mixed", 600), (10, "pushed", 300), (10, "whip", 400),
         pytest.param(30, "mixed", 300, marks=pytest.mark.slow),
         pytest.param(30, "pushed", 250, marks=pytest.mark.slow),
         pytest.param(30, "whip", 200, marks=pytest.mark.slow)]


@pytest.mark.parametrize("n, scenario, steps", CASES)
def test_linear_solver_follows_the_dense_solver(built_fmu_unzipped, reference_unzipped, n,
                                                scenario, steps):
    unzipdir, md = built_fmu_unzipped(n)
    fast = _run(unzipdir, md, n, scenario, steps)
    dense = _run(reference_unzipped(n), md, n, scenario, steps)

    # the scenario is what it claims: wheels slide, and in "mixed"/"pushed" others stick
    sliding = dense["slipping"][1::2]
    if scenario == "whip":
        assert np.mean(np.all(sliding[steps // 4:], axis=1)) > 0.8  # every wheel slides
    else:
        assert sliding.any() and not sliding.all()
        assert np.any(sliding.any(axis=1) & ~sliding.all(axis=1))  # sticking and sliding at once

    np.testing.assert_array_equal(fast["slipping"], dense["slipping"])
    for block in KINEMATIC:  # the state: round-off of the two solves, which a wildly spinning
        # tail (pushed, n = 30: 23 rad/s) amplifies over the run (seen: 2e-13 of the scale)
        scale = max(1.0, np.max(np.abs(dense[block])))
        np.testing.assert_allclose(fast[block], dense[block], rtol=0, atol=1e-11 * scale,
                                   err_msg=block)
    # Forces are impulses / dt (x 2000 for 0.5 ms substeps), and the dense solver stops its
    # Gauss-Seidel iteration at a relative change of 1e-10 where its exact sticking-set solve is
    # not taken: 1e-8 of the block's largest force (seen: at most 3e-10).
    for block in FORCES:
        np.testing.assert_allclose(fast[block], dense[block], rtol=0,
                                   atol=1e-8 * np.max(np.abs(dense[block])), err_msg=block)
    # the reference is an independent computation: its round-off is not the fast solver's
    assert any(np.any(fast[block] != dense[block]) for block in (*KINEMATIC, *FORCES))
