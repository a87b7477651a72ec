"""Each servo law with each contour controller, closed around the plant, on a straight line."""
import itertools

import numpy as np
import pytest

from contouring_ros.config import build_loop, parse_experiment
from contouring_ros.core.geometry import ExactContourError
from contouring_ros.core.simulation import simulate

LINE = """
/**:
  ros__parameters:
    sample_time: 0.001
    duration: 2.0
    axes: ["x", "y"]
    curve: {{type: line, start: [0.0, 0.0], end: [0.03, 0.04]}}
    schedule: {{type: uniform, theta_start: 0.0, theta_end: 0.05, duration: 2.0}}
    initial_state: on_reference
/x/plant:
  ros__parameters: {{model: first_order_velocity, gain: 10.3, time_constant: 0.040,
                    disturbance: {{type: constant, value: 1.5e-4}}}}
/y/plant:
  ros__parameters: {{model: first_order_velocity, gain: 10.0, time_constant: 0.045}}
/x/servo:
  ros__parameters: {servo_x}
/y/servo:
  ros__parameters: {servo_y}
/contour_estimator:
  ros__parameters: {estimator}
/ccc:
  ros__parameters: {ccc}
"""
SERVOS = {
    "pid_feedforward": ("{law: pid_feedforward, kp: 8.08, ki: 93.2, kd: 0.24, gain: 10.3, time_constant: 0.040}",
                        "{law: pid_feedforward, kp: 9.36, ki: 108.0, kd: 0.3, gain: 10.0, time_constant: 0.045}"),
    "ismc": ("{law: ismc, a: 12.5, b: 12.5, mu: 1.0e-3, kappa: 0.2985, gain: 10.3, time_constant: 0.040, "
             "observer: true, c: 25.0, d: 25.0}",
             "{law: ismc, a: 11.1, b: 11.1, mu: 1.0e-3, kappa: 0.3, gain: 10.0, time_constant: 0.045}"),
}
PAIRS = {
    "none": ("{type: tangent_line}", "{type: none}"),
    "variable_gain": ("{type: tangent_line}", "{type: variable_gain, kp: 8.0, ki: 80.0, kd: 0.6}"),
    "unit_vector": ("{type: newton, k_prime: 500.0, c_prime: 500.0}", "{type: unit_vector, kp: 1.0, ki: 10.0, kd: 0.1}"),
}


@pytest.mark.parametrize("servo,pair", list(itertools.product(SERVOS, PAIRS)))
def test_closed_loop_settles_on_a_line(servo, pair):
    text = LINE.format(servo_x=SERVOS[servo][0], servo_y=SERVOS[servo][1], estimator=PAIRS[pair][0],
                       ccc=PAIRS[pair][1])
    loop = build_loop(parse_experiment(text, "line"))
    result = simulate(loop)
    error = ExactContourError(loop.curve)(result.position).distance
    tracking = np.linalg.norm(result.reference_position - result.position, axis=1)
    assert np.all(np.isfinite(result.position))
    # The constant load on x excites a transient at the start; the loop must settle while moving.
    assert tracking.max() < 5e-3
    assert error[-1] < 1e-7 and error[-1] < 0.1 * error[:500].max()
    assert tracking[-1] < 1e-6 and tracking[-1] < 0.1 * tracking[:500].max()
