"""The first-order velocity axis against its analytic step response."""
import numpy as np
from numpy.testing import assert_allclose

from contouring_ros.core.disturbances import ConstantDisturbance
from contouring_ros.core.plants import FirstOrderVelocityAxis


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
