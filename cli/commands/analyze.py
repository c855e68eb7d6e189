"""``pushtrain analyze``: stability and predicted offsets of a scenario's controller."""

from __future__ import annotations

import math

import click

from ..common import click_errors, load_scenario_with_overrides, scenario_argument

__all__ = ["analyze_cmd"]


def _stability_lines(c, speed: float) -> list[str]:
    from pushtrain.core import analysis

    lines = []
    frames = ((speed, "pushing, direction-of-travel frame"), (-speed, "chain frame (v_d < 0)"))
    for v_d, label in frames:
        poles = analysis.closed_loop_poles(c.k_x, c.k_y, c.k_theta, v_d)
        polynomial = analysis.characteristic_polynomial(c.k_x, c.k_y, c.k_theta, v_d)
        verdict = analysis.routh_hurwitz(polynomial)
        roots = ", ".join(f"{r.real:+.4f}{r.imag:+.4f}j" for r in poles)
        lines.append(f"v_d = {v_d:+.3f} m/s ({label}): Eq. 13 roots {roots} -> "
                     f"{'stable' if verdict.stable else 'UNSTABLE'} (Routh-Hurwitz, "
                     f"{verdict.sign_changes} sign change(s))")
    return lines


@click.command("analyze", short_help="Stability (Eq. 12-13, Routh-Hurwitz) and predicted "
                                     "joint-bias offsets.")
@scenario_argument
def analyze_cmd(scenario):
    """Stability (Eq. 12-13, Routh-Hurwitz) and predicted offsets from joint biases (Eq. 9).

    \b
    Example:
      pushtrain analyze examples/joint_bias_5deg.toml
    """
    from pushtrain.core import analysis
    from pushtrain.mission.runner import bias_model

    sc = load_scenario_with_overrides(scenario)
    c = sc.controller
    with click_errors():
        link, speed, bias, eps = bias_model(sc)
        stability = _stability_lines(c, speed)
        exact = analysis.steady_lateral_error(eps, link, c.k_y)
        paper = analysis.steady_lateral_error(eps, link, c.k_y, form="paper")
        localized = sc.sensors.localize == "last_trailer"
        if not localized:
            est = analysis.steady_lateral_error_estimated_pose(bias, link, c.k_x, c.k_y,
                                                               c.k_theta, speed)
    click.echo(f"controller gains: K_x = {c.k_x}, K_y = {c.k_y}, K_theta = {c.k_theta}; "
               f"D = {link} m")
    for line in stability:
        click.echo(line)
    click.echo(f"effective joint bias: {math.degrees(eps):.3f} deg (alternating sum of "
               f"{[round(math.degrees(b), 3) for b in bias]} deg)")
    if localized:
        click.echo(f"predicted steady lateral error y_e (last trailer localized): "
                   f"{exact * 100:.2f} cm (paper's Eq. 9, tan form: {paper * 100:.2f} cm)")
    else:
        click.echo(f"predicted steady lateral error y_e (last trailer computed from the biased "
                   f"joints): {est * 100:.2f} cm; with the last trailer localized it would be "
                   f"{exact * 100:.2f} cm (Eq. 9: {paper * 100:.2f} cm)")
