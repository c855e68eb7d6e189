"""The TrailerTrain FMU's variables: the one table that describes them.

The builder renders both model descriptions and the C header ``variables.h`` (value-reference
enums, names, types, causalities) from it, so adding a variable means a row here plus its place in
the C model (``src/variables.c``; the compiler names a missing one). Start values here must equal
what the C code sets in ``model_set_defaults``: the builder renders them into ``start_values.h``,
which ``model.c`` reads (and a test checks them through the built FMUs). The trailers' start
values are the paper's Table 1 (:mod:`pushtrain.table1`).

- FMI 2.0 (one build per n): scalars have ``vr < 100``; element ``i`` of array block ``b`` is the
  scalar variable ``name[i]`` with ``vr = 100 * b + i``, ``i`` the body index (0 = robot, 1..n
  trailers).
- FMI 3.0 (one build for every n): the same scalars; block ``b`` is one array variable ``name``
  with ``vr = 100 * b`` whose elements are ``name[first]`` .. ``name[last]`` of the FMI 2.0
  contract, in that order. Its ``<Dimension>`` references the structural parameter ``n`` (n
  elements: the per-trailer blocks and ``rear``) or ``n_bodies`` (n + 1 elements: the per-body
  blocks, robot first), because a dimension can only be the value of a variable, never ``n + 1``;
  the FMU keeps ``n_bodies = n + 1``.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from pushtrain import defaults
from pushtrain.limits import BOUNDS
from pushtrain.table1 import LINK, MU, TRAILER_INERTIA, TRAILER_MASS

__all__ = [
    "ARRAYS",
    "ArrayBlock",
    "DEFAULT_TRAILERS",
    "FEEDTHROUGH",
    "FMI_VERSIONS",
    "MAX_TRAILERS",
    "SCALARS",
    "VR_STRIDE",
    "Variable",
    "describe",
    "direct_inputs",
    "scalars_for",
    "variables_for",
]

VR_STRIDE = 100
MAX_TRAILERS = 50
DEFAULT_TRAILERS = 3  # FMI 3.0: the start value of the structural parameter n
FMI_VERSIONS = (2, 3)


# Direct feedthrough of an output (for element i of an array, n trailers): the inputs whose change
# changes the output without a step, as the C code computes it in either slip_mode.
# - "none": the state only (poses, joint angles, the robot's own velocities);
# - "inputs": every input. The wheel and hitch forces (and the slipping flags made from them)
#   follow the robot's commanded accelerations (v_cmd, w_cmd through its velocity loop), the
#   push on the last trailer and, through the rolling kinematics, every imposed slide;
# - "slides_before" / "slides_through": slide[1..i-1] / slide[1..i]: the rolling map
#   v_i = c v_{i-1} + s (R_{i-1} w_{i-1} - u_{i-1}), w_i = (... - u_i) / F_i (chain.c);
# - "own_slide": slide[i] (the rolling model reports the imposed slide as the sliding speed).
FEEDTHROUGH = ("none", "inputs", "slides_before", "slides_through", "own_slide")


def direct_inputs(feedthrough: str, i: int, n_trailers: int) -> list[str]:
    """Names of the inputs an output depends on directly (see ``FEEDTHROUGH``)."""
    slides = [f"slide[{k}]" for k in range(1, n_trailers + 1)]
    if feedthrough == "none":
        return []
    if feedthrough == "inputs":
        return ["v_cmd", "w_cmd", "push_x", "push_y", *slides]
    if feedthrough == "slides_before":
        return slides[: max(i - 1, 0)]
    if feedthrough == "slides_through":
        return slides[:i]
    if feedthrough == "own_slide":
        return [f"slide[{i}]"]
    raise ValueError(f"feedthrough = {feedthrough!r}: allowed are {', '.join(FEEDTHROUGH)}")


@dataclass(frozen=True)
class Variable:
    """One scalar FMI variable (``type`` in FMI 2.0 spelling; FMI 3.0 renders Real as Float64 and
    Integer as Int32; UInt64 exists in FMI 3.0 only)."""

    name: str
    vr: int
    type: str  # "Real", "Integer", "Boolean", "UInt64"
    # "input", "output", "parameter", "calculatedParameter", "local", and in FMI 3.0
    # "structuralParameter", "independent"
    causality: str
    variability: str  # "constant", "fixed", "tunable", "discrete", "continuous"
    description: str
    start: float | int | bool | None = None
    unit: str | None = None
    initial: str | None = None  # "exact", "approx", "calculated" or None (default)
    depends_on: tuple[str, ...] = ()  # outputs: the inputs of their direct feedthrough
    min: float | int | None = None
    max: float | int | None = None
    versions: tuple[int, ...] = FMI_VERSIONS  # the FMI versions that have this variable


@dataclass(frozen=True)
class ArrayBlock:
    """A family ``name[i]`` of variables, i from ``first`` to n (or n-1 if ``to_n_minus_1``).

    ``description`` is a template for :func:`describe`.
    """

    name: str
    block: int
    type: str
    causality: str
    variability: str
    description: str
    first: int
    to_n_minus_1: bool = False
    start: float | int | bool | None = None
    unit: str | None = None
    initial: str | None = None
    feedthrough: str = "none"  # outputs: see FEEDTHROUGH
    min: float | int | None = None
    max: float | int | None = None

    def count(self, n_trailers: int) -> int:
        """Number of elements for ``n_trailers`` trailers (n or n + 1)."""
        return n_trailers + 1 - self.first - (1 if self.to_n_minus_1 else 0)

    @property
    def size_variable(self) -> str:
        """The FMI 3.0 structural parameter that holds the length: ``n`` or ``n_bodies``."""
        return "n" if self.count(1) == 1 else "n_bodies"


def _bounded(row):
    """The row with ``min``/``max`` from :data:`pushtrain.limits.BOUNDS` if it has a bound."""
    bound = BOUNDS.get(row.name)
    return row if bound is None else replace(row, min=bound.lo, max=bound.hi)


SCALARS: tuple[Variable, ...] = tuple(map(_bounded, (
    Variable("v_cmd", 1, "Real", "input", "continuous",
             "Robot commanded longitudinal speed", 0.0, "m/s"),
    Variable("w_cmd", 2, "Real", "input", "continuous",
             "Robot commanded yaw rate", 0.0, "rad/s"),
    Variable("push_x", 3, "Real", "input", "continuous",
             "External force on the last trailer's axle midpoint, world x", 0.0, "N"),
    Variable("push_y", 4, "Real", "input", "continuous",
             "External force on the last trailer's axle midpoint, world y", 0.0, "N"),
    Variable("g", 5, "Real", "parameter", "fixed", "Gravitational acceleration",
             defaults.GRAVITY, "m/s2"),
    Variable("robot_tau", 6, "Real", "parameter", "fixed",
             "Robot velocity loop first-order time constant", defaults.ROBOT_TAU, "s"),
    Variable("robot_acc_max", 7, "Real", "parameter", "fixed",
             "Robot longitudinal acceleration limit", defaults.ROBOT_ACC_MAX, "m/s2"),
    Variable("robot_alpha_max", 8, "Real", "parameter", "fixed",
             "Robot yaw acceleration limit", defaults.ROBOT_ALPHA_MAX, "rad/s2"),
    Variable("slip_mode", 9, "Integer", "parameter", "fixed",
             "0: rolling wheels, forces estimated; 1: wheels slide past friction", 0,
             min=0, max=1),
    Variable("phi_max", 10, "Real", "parameter", "fixed",
             "Jackknife limit on every absolute joint angle |phi|", 1.5707963267948966, "rad"),
    Variable("x0_start", 11, "Real", "parameter", "fixed", "Initial robot x", 0.0, "m"),
    Variable("y0_start", 12, "Real", "parameter", "fixed", "Initial robot y", 0.0, "m"),
    Variable("v_start", 13, "Real", "parameter", "fixed",
             "Initial robot longitudinal speed", 0.0, "m/s"),
    Variable("w_start", 14, "Real", "parameter", "fixed", "Initial robot yaw rate", 0.0, "rad/s"),
    Variable("max_substep", 15, "Real", "parameter", "fixed",
             "Largest internal RK4 substep", 0.005, "s"),
    Variable("n", 16, "Integer", "output", "constant",
             "Number of trailers (fixed by the build)", None, None, "exact", versions=(2,)),
    Variable("n", 16, "UInt64", "structuralParameter", "fixed",
             "Number of trailers: the length of the per-trailer arrays and of rear; set it "
             "before initialization (Configuration Mode or Instantiated)",
             DEFAULT_TRAILERS, min=1, max=MAX_TRAILERS, versions=(3,)),
    Variable("jackknifed", 17, "Boolean", "output", "discrete",
             "Some absolute joint angle |phi| exceeds phi_max", None, None, "calculated"),
    Variable("slip_substep", 18, "Real", "parameter", "fixed",
             "Largest internal substep while some wheel slides, slip_mode 1", 0.0005, "s"),
    Variable("time", 0, "Real", "independent", "continuous", "Simulation time", unit="s",
             versions=(3,)),
    Variable("n_bodies", 19, "UInt64", "structuralParameter", "fixed",
             "Number of bodies, n + 1 (robot and trailers): the length of the per-body arrays; "
             "it follows n (setting it to another value is an error)",
             DEFAULT_TRAILERS + 1, min=2, max=MAX_TRAILERS + 1, versions=(3,)),
)))

ARRAYS: tuple[ArrayBlock, ...] = tuple(map(_bounded, (
    ArrayBlock("front", 1, "Real", "parameter", "fixed",
               "Front hitch link F_{i} of trailer {i}", 1, start=LINK, unit="m"),
    ArrayBlock("rear", 2, "Real", "parameter", "fixed",
               "Rear hitch link R_{i} of {body}", 0, to_n_minus_1=True, start=LINK, unit="m"),
    ArrayBlock("mass", 3, "Real", "parameter", "fixed",
               "Mass of trailer {i} without payload", 1, start=TRAILER_MASS, unit="kg"),
    ArrayBlock("inertia", 4, "Real", "parameter", "fixed",
               "Yaw inertia of trailer {i} about its axle midpoint, without payload", 1,
               start=TRAILER_INERTIA, unit="kg.m2"),
    ArrayBlock("payload", 5, "Real", "parameter", "fixed",
               "Payload mass at the axle midpoint of trailer {i}", 1, start=0.0, unit="kg"),
    ArrayBlock("mu", 6, "Real", "parameter", "fixed",
               "Lateral wheel friction coefficient of trailer {i}", 1, start=MU),
    ArrayBlock("theta_start", 7, "Real", "parameter", "fixed",
               "Initial heading of {body}", 0, start=0.0, unit="rad"),
    ArrayBlock("x", 8, "Real", "output", "continuous",
               "x of {point}", 0, unit="m",
               initial="calculated"),
    ArrayBlock("y", 9, "Real", "output", "continuous",
               "y of {point}", 0, unit="m",
               initial="calculated"),
    ArrayBlock("theta", 10, "Real", "output", "continuous",
               "Heading of {body} (trailers point toward the robot), continuous (not wrapped)", 0,
               unit="rad", initial="calculated"),
    ArrayBlock("phi", 11, "Real", "output", "continuous",
               "Joint angle theta[{prev}] - theta[{i}], wrapped to (-pi, pi]", 1, unit="rad",
               initial="calculated"),
    ArrayBlock("v", 12, "Real", "output", "continuous",
               "Longitudinal speed of {body} along its heading", 0, unit="m/s",
               initial="calculated", feedthrough="slides_before"),
    ArrayBlock("w", 13, "Real", "output", "continuous", "Yaw rate of {body}", 0, unit="rad/s",
               initial="calculated", feedthrough="slides_through"),
    ArrayBlock("F_lat", 14, "Real", "output", "continuous",
               "Lateral wheel force on trailer {i} along its left normal", 1, unit="N",
               initial="calculated", feedthrough="inputs"),
    ArrayBlock("F_lat_max", 15, "Real", "calculatedParameter", "fixed",
               "Lateral friction limit of trailer {i}, mu[{i}] (mass[{i}] + payload[{i}]) g", 1,
               unit="N", initial="calculated"),
    ArrayBlock("slipping", 16, "Boolean", "output", "discrete",
               "Wheel of trailer {i} slides (slip_mode 1) or would slide (slip_mode 0)", 1,
               initial="calculated", feedthrough="inputs"),
    ArrayBlock("slide", 17, "Real", "input", "continuous",
               "Imposed lateral sliding speed of trailer {i}'s wheel along its left normal "
               "(kinematic disturbance)", 1, start=0.0, unit="m/s"),
    ArrayBlock("hitch_fx", 18, "Real", "output", "continuous",
               "Force of {prev_body} on trailer {i} at their hitch, world x", 1, unit="N",
               initial="calculated", feedthrough="inputs"),
    ArrayBlock("hitch_fy", 19, "Real", "output", "continuous",
               "Force of {prev_body} on trailer {i} at their hitch, world y", 1, unit="N",
               initial="calculated", feedthrough="inputs"),
    ArrayBlock("slide_speed", 20, "Real", "output", "continuous",
               "Lateral sliding speed of trailer {i}'s wheel along its left normal", 1, unit="m/s",
               initial="calculated", feedthrough="own_slide"),
)))


def _body(i: int) -> str:
    return "the robot" if i == 0 else f"trailer {i}"


def describe(template: str, i: int) -> str:
    """The description of element ``i`` of an array block from its template.

    Fields: ``{i}``, ``{prev}`` (i - 1), ``{body}`` ("the robot" or "trailer i"), ``{prev_body}``
    (body i - 1) and ``{point}`` (the robot's centre or trailer i's axle midpoint).
    """
    point = "the robot's centre" if i == 0 else f"the axle midpoint of trailer {i}"
    return template.format(i=i, prev=i - 1, body=_body(i), prev_body=_body(i - 1), point=point)


def scalars_for(fmi_version: int) -> list[Variable]:
    """The scalar variables of an FMI 2.0 or 3.0 FMU, ordered by value reference."""
    if fmi_version not in FMI_VERSIONS:
        raise ValueError(f"fmi_version = {fmi_version!r}: allowed are 2 and 3")
    return sorted((v for v in SCALARS if fmi_version in v.versions), key=lambda v: v.vr)


def variables_for(n_trailers: int) -> list[Variable]:
    """Every scalar variable of an FMI 2.0 FMU built for ``n_trailers``, ordered by value
    reference."""
    out = scalars_for(2)
    for block in ARRAYS:
        last = n_trailers - 1 if block.to_n_minus_1 else n_trailers
        for i in range(block.first, last + 1):
            out.append(
                Variable(
                    f"{block.name}[{i}]",
                    VR_STRIDE * block.block + i,
                    block.type,
                    block.causality,
                    block.variability,
                    describe(block.description, i),
                    block.start,
                    block.unit,
                    block.initial,
                    tuple(direct_inputs(block.feedthrough, i, n_trailers)),
                    block.min,
                    block.max,
                )
            )
    return sorted(out, key=lambda v: v.vr)
