"""The axis models against their analytic responses."""
import numpy as np
import pytest
from numpy.testing import assert_allclose

from contouring_ros.core.disturbances import ConstantDisturbance
from contouring_ros.core.plants import FirstOrderVelocityAxis, MassDamperAxis


def test_step_response_is_exact():
    # Paper 000 eq. 1-2 with a constant input u from rest:
    # V(t) = k u (1 - exp(-t/tau)),  P(t) = k u (t - tau (1 - exp(-t/tau))).
    k, tau, ts, u = 10.3, 0.040, 0.001, 0.02
    axis = FirstOrderVelocityAxis(k, tau, ts)
    states = np.array([axis.step(u, i * ts) for i in range(500)])
    t = ts * np.arange(1, 501)
    assert_allclose(states[:, 1], k * u * (1 - np.exp(-t / tau)), rtol=1e-12)
    assert_allclose(states[:, 0], k * u * (t - tau * (1 - np.exp(-t / tau))), rtol=1e-12, atol=1e-16)


def test_disturbance_adds_to_the_command():
    a = FirstOrderVelocityAxis(10.0, 0.045, 0.001, ConstantDisturbance(0.01))
    b = FirstOrderVelocityAxis(10.0, 0.045, 0.001)
    for i in range(100):
        a.step(0.0, i * 0.001)
        b.step(0.01, i * 0.001)
    assert (a.position, a.velocity) == (b.position, b.velocity)


def test_discrete_pole_is_exp_of_continuous_pole():
    axis = FirstOrderVelocityAxis(1.0, 0.05, 0.002, velocity=1.0)
    axis.step(0.0, 0.0)
    assert_allclose(axis.velocity, np.exp(-0.002 / 0.05), rtol=1e-15)


def test_mass_damper_step_response_is_exact():
    # K / (M s^2 + B s) with a constant command u from rest, a = B / M:
    # V(t) = K u / B (1 - exp(-a t)),  P(t) = K u / B (t - (1 - exp(-a t)) / a).
    m, b, k, ts, u = 2.0, 400.0, 16.23, 0.001, 0.3
    axis = MassDamperAxis(m, b, k, ts)
    states = np.array([axis.step(u, i * ts) for i in range(300)])
    t, a = ts * np.arange(1, 301), b / m
    assert_allclose(states[:, 1], k * u / b * (1 - np.exp(-a * t)), rtol=1e-12)
    assert_allclose(states[:, 0], k * u / b * (t - (1 - np.exp(-a * t)) / a), rtol=1e-11)


def test_pure_mass_is_the_limit_of_no_damping():
    axis = MassDamperAxis(0.5, 0.0, 1.0, 0.001)
    for i in range(100):
        axis.step(0.2, i * 0.001)
    t = 0.1
    assert_allclose([axis.position, axis.velocity], [0.2 / 0.5 * t * t / 2, 0.2 / 0.5 * t], rtol=1e-12)


def test_coulomb_friction_and_saturation_in_steady_state():
    # Moving forward, friction F+ opposes: steady velocity K (sat(u) - F+) / B; backward, -K (sat(u) - F-)/B.
    forward = MassDamperAxis(1.0, 800.0, 16.0, 0.001, saturation=10.0, coulomb_positive=0.12,
                             coulomb_negative=0.11, velocity=0.01)
    backward = MassDamperAxis(1.0, 800.0, 16.0, 0.001, saturation=10.0, coulomb_positive=0.12,
                              coulomb_negative=0.11, velocity=-0.01)
    for i in range(200):
        forward.step(25.0, i * 0.001)
        backward.step(-3.0, i * 0.001)
    assert_allclose(forward.velocity, 16.0 * (10.0 - 0.12) / 800.0, rtol=1e-9)
    assert_allclose(backward.velocity, 16.0 * (-3.0 + 0.11) / 800.0, rtol=1e-9)


def test_encoder_reads_the_position_to_its_resolution():
    axis = MassDamperAxis(1.0, 100.0, 1.0, 0.001, position=1.23456789e-3, encoder_resolution=5e-7)
    position, velocity = axis.measure()
    assert position == pytest.approx(1.2345e-3, abs=1e-15) and velocity == axis.velocity
    assert FirstOrderVelocityAxis(1.0, 0.01, 0.001, position=2.5e-7 + 1e-12, encoder_resolution=5e-7).measure()[0] \
        == pytest.approx(5e-7)


def test_cascade_servo_follows_a_ramp_with_no_steady_state_error_despite_friction():
    """P position over PI velocity with Coulomb feedforward (paper 002 Fig. 5) on a torque-driven axis
    with friction: at constant velocity the integral supplies B v / K, the feedforward the friction, and
    the velocity feedforward leaves no position error."""
    from contouring_ros.core.servo import CascadeServo
    ts, v = 0.001, 0.05
    axis = MassDamperAxis(1.0, 798.5, 16.23, ts, coulomb_positive=0.12, coulomb_negative=0.11, saturation=10.0)
    servo = CascadeServo(40.0, 20.0, 1000.0, ts, coulomb_positive=0.12, coulomb_negative=0.11, output_limit=10.0)
    for k in range(3000):
        t = k * ts
        axis.step(servo.step(v * t, v, 0.0, axis.position, axis.velocity, 0.0), t)
    assert abs(axis.position - v * 3.0) < 1e-9
    assert abs(axis.velocity - v) < 1e-9
