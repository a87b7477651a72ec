"""The zero phase error tracking controller (Tomizuka 1987): its closed-loop model is the loop the simulation
runs, its feedforward cancels that loop's phase at every frequency, and on a sine the axis follows with the
gain error B_u(z) B_u(z^-1) / B_u(1)^2 predicts and no lag; it starts without a bump, steps as a batch bit for bit as alone, and
survives a plant 30 % off its model better than the feedback alone."""
import math

import numpy as np
import pytest
from scipy import signal

from contouring_ros.core.pid import DiscretePID
from contouring_ros.core.plants import FirstOrderVelocityAxis
from contouring_ros.core.servo import ZPETCServo, closed_loop, zpetc_design

TS, GAIN, TAU = 1e-3, 10.3, 0.040
LOOPS = [(8.08, 93.2, 0.24, 0), (8.08, 0.0, 0.24, 0), (20.0, 100.0, 0.0, 1), (8.08, 93.2, 0.24, 2)]


def _run(servo_step, reference, plant, steps):
    """Positions of ``plant`` under ``servo_step(k, position, velocity) -> command`` for ``steps`` steps."""
    out = np.empty(steps)
    for k in range(steps):
        position, velocity = plant.measure()
        out[k] = position
        plant.step(servo_step(k, position, velocity), k * TS)
    return out


@pytest.mark.parametrize("kp,ki,kd,delay", LOOPS)
def test_the_closed_loop_model_is_the_loop_the_servo_runs(kp, ki, kd, delay):
    # the design's G_c = z^-d B / A against the PID (derivative on the measured velocity) on the sampled axis
    numerator, denominator, d = closed_loop(kp, ki, kd, GAIN, TAU, TS, delay)
    assert d == delay + 1
    steps = 400
    r = np.sin(np.arange(steps) * 0.05) * 1e-3
    pid = DiscretePID(kp, ki, kd, TS)
    simulated = _run(lambda k, p, v: pid.step(r[k] - p, -v), r, FirstOrderVelocityAxis(GAIN, TAU, TS, command_delay=delay),
                     steps)
    modelled = signal.lfilter(np.concatenate([np.zeros(d), numerator]), denominator, r)
    np.testing.assert_allclose(simulated, modelled, rtol=0, atol=1e-12)      # 1e-9 of the 1 mm input


@pytest.mark.parametrize("kp,ki,kd,delay", LOOPS)
def test_the_feedforward_times_the_loop_has_zero_phase_and_the_gain_b_u_b_u_star(kp, ki, kd, delay):
    design = zpetc_design(*closed_loop(kp, ki, kd, GAIN, TAU, TS, delay))
    assert len(design.uncancelled) == 1 and -1.0 < design.uncancelled[0].real < -0.9     # the sampled axis' zero
    b_u = np.real(np.poly(design.uncancelled))
    for hz in (0.5, 5.0, 50.0, 200.0):
        z = np.exp(1j * 2 * math.pi * hz * TS)
        loop = z ** -design.delay * np.polyval(design.numerator[::-1], 1 / z) / np.polyval(design.denominator[::-1], 1 / z)
        feedforward = z ** design.preview * np.polyval(design.feedforward[::-1], 1 / z) \
            / np.polyval(np.concatenate([[1.0], design.recursion])[::-1], 1 / z)
        total = loop * feedforward
        expected = abs(np.polyval(b_u[::-1], 1 / z)) ** 2 / np.sum(b_u) ** 2
        assert abs(np.angle(total)) < 1e-9, hz
        assert total.real == pytest.approx(expected, rel=1e-9), hz


def _sine_tracking(servo_for, plant_gain=GAIN, plant_tau=TAU, hz=2.0, steps=6000):
    """RMS error of the last 2000 steps following 1 mm at ``hz`` with the law ``servo_for`` builds, and the lag
    [steps] of the output behind the desired position (cross-correlation peak)."""
    t = np.arange(steps + 20) * TS
    desired = 1e-3 * np.sin(2 * math.pi * hz * t)
    servo = servo_for()
    preview = getattr(servo, "preview", 0)

    def step(k, position, velocity):
        if preview:
            servo.look_ahead(desired[k + 1:k + 1 + preview])
        velocity_ref = 1e-3 * 2 * math.pi * hz * math.cos(2 * math.pi * hz * t[k])
        return servo.step(desired[k], velocity_ref, 0.0, position, velocity, 0.0)
    y = _run(step, desired, FirstOrderVelocityAxis(plant_gain, plant_tau, TS), steps)
    error = (y - desired[:steps])[-2000:]
    tail, ref = y[-2000:], desired[steps - 2000:steps]
    lags = np.arange(-20, 21)
    lag = lags[np.argmax([np.dot(np.roll(tail, -lag), ref) for lag in lags])]
    return float(np.sqrt(np.mean(error ** 2))), int(lag)


class _FeedbackOnly:
    def __init__(self, kp, ki, kd):
        self.pid = DiscretePID(kp, ki, kd, TS)

    def step(self, ref_pos, ref_vel, ref_acc, position, velocity, correction):
        return self.pid.step(ref_pos - position, -velocity)


def test_on_a_sine_the_axis_follows_with_the_predicted_gain_error_and_no_lag():
    kp, ki, kd = 8.08, 93.2, 0.24
    zpetc, zpetc_lag = _sine_tracking(lambda: ZPETCServo(kp, ki, kd, GAIN, TAU, TS))
    feedback, feedback_lag = _sine_tracking(lambda: _FeedbackOnly(kp, ki, kd))
    b_u = np.real(np.poly(zpetc_design(*closed_loop(kp, ki, kd, GAIN, TAU, TS)).uncancelled))
    z = np.exp(1j * 2 * math.pi * 2.0 * TS)
    predicted = 1e-3 * (1 - abs(np.polyval(b_u[::-1], 1 / z)) ** 2 / np.sum(b_u) ** 2) / math.sqrt(2)
    assert zpetc == pytest.approx(predicted, rel=0.02)
    assert zpetc_lag == 0 and feedback_lag > 0
    assert zpetc < 1e-4 * feedback


def test_with_the_plant_30_percent_off_its_model_it_still_beats_the_feedback_alone():
    kp, ki, kd = 8.08, 93.2, 0.24
    for gain, tau in ((1.3 * GAIN, TAU), (GAIN, 0.7 * TAU), (0.7 * GAIN, 1.3 * TAU)):
        zpetc, _ = _sine_tracking(lambda: ZPETCServo(kp, ki, kd, GAIN, TAU, TS), gain, tau)
        feedback, _ = _sine_tracking(lambda: _FeedbackOnly(kp, ki, kd), gain, tau)
        assert zpetc < 0.5 * feedback, (gain, tau)


def test_an_axis_that_starts_moving_on_its_reference_starts_without_a_bump():
    # an axis moving and accelerating at step 0: the filter's past is that motion and the integral the command
    # the sampled axis needs for it, so the error goes straight to the steady value B_u(z) B_u(z^-1) / B_u(1)^2 gives for a constant
    # acceleration, y - y_d = -z0 / (1 - z0)^2 a Ts^2 (B_u = 1 - z0 z^-1), and never beyond it
    kp, ki, kd = 8.08, 93.2, 0.24
    velocity, acceleration = 0.05, 0.8
    desired = lambda k: 0.01 + velocity * k * TS + 0.5 * acceleration * (k * TS) ** 2        # noqa: E731
    plant = FirstOrderVelocityAxis(GAIN, TAU, TS, position=desired(0), velocity=velocity)
    servo = ZPETCServo(kp, ki, kd, GAIN, TAU, TS)
    errors = []
    for k in range(400):
        position, measured = plant.measure()
        errors.append(position - desired(k))
        servo.look_ahead([desired(k + j) for j in range(1, servo.preview + 1)])
        plant.step(servo.step(desired(k), velocity + acceleration * k * TS, acceleration, position, measured, 0.0),
                   k * TS)
    z0 = zpetc_design(*closed_loop(kp, ki, kd, GAIN, TAU, TS)).uncancelled[0].real
    steady = -z0 / (1 - z0) ** 2 * acceleration * TS ** 2
    assert errors[-1] == pytest.approx(steady, rel=0.01)
    assert max(abs(e) for e in errors) <= 1.05 * abs(steady)        # a past held still gave millimetres


@pytest.mark.parametrize("key,values", [("kp", (8.08, 12.0, 5.0)), ("ki", (93.2, 0.0, 200.0)), ("kd", (0.24, 0.0, 0.5))])
def test_a_batch_of_zpetc_loops_with_different_gains_gives_each_run_alone_bit_for_bit(key, values):
    from contouring_ros.core.batch import simulate_batch
    from contouring_ros.core.simulation import simulate
    from contouring_ros.experiment.build import build_loop
    from contouring_ros.experiment.validate import parse_experiment
    from conftest import CONFIG, shortened
    text = shortened(CONFIG / "zpetc_ellipse.yaml", 0.2)
    assert f"{key}: {values[0]}" in text
    experiments = [parse_experiment(text.replace(f"{key}: {values[0]}", f"{key}: {v}")) for v in values]
    loops = [build_loop(experiment) for experiment in experiments]
    assert loops[0].preview == 4
    batch = simulate_batch(loops)
    for alone, batched in zip([simulate(build_loop(experiment)) for experiment in experiments], batch):
        for name in ("position", "command", "estimate_signed"):
            np.testing.assert_array_equal(getattr(batched, name), getattr(alone, name), err_msg=name)
