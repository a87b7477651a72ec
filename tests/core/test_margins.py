"""Gain margin, phase margin and peak sensitivity Ms of the linear loops (core/margins.py): known answers,
independent evaluations, and the loop transfer functions against the code's own difference equations."""
from __future__ import annotations

import math

import control
import numpy as np
import pytest
from scipy.linalg import expm
from scipy.signal import lfilter

from conftest import CONFIG

from contouring_ros.config import load_experiment
from contouring_ros.core import contouring, servo as servos
from contouring_ros.core.curves import Helix, Line
from contouring_ros.core.estimators import TangentLineEstimator
from contouring_ros.core.interpolation import Reference
from contouring_ros.core.margins import (LoopMargins, axis_loop, coupled_loop, margins,
                                         plant_transfer)
from contouring_ros.core.plants import FirstOrderVelocityAxis, MassDamperAxis
from contouring_ros.studies.loops import experiment_margins

TS = 1e-3
PIDFF = CONFIG / "paper000_a_pidff_h50_newton.yaml"
# paper 000's axes and PIDs (x, y)
AXES_000 = [((10.3, 0.040), (8.08, 93.2, 0.24)), ((10.0, 0.045), (9.36, 108.0, 0.3))]


def first_order(k=10.3, tau=0.040, **kw):
    return FirstOrderVelocityAxis(k, tau, TS, **kw)


def pidff(kp=8.08, ki=93.2, kd=0.24, k=10.3, tau=0.040):
    return servos.PIDFeedforwardServo(kp, ki, kd, k, tau, TS)


def mass_damper(mass=3075.37344, damping=896.724, gain=1.0, **kw):
    return MassDamperAxis(mass, damping, gain, TS, **kw)


def pd_001():      # paper 001's x axis PD
    return servos.PIDServo(19610586.489482205, 0.0, 490264.66223705513, TS)


def zpetc(kp, ki, kd, command_delay=0):
    """The ZPETC servo on paper 000's x axis, its preview of the reference held at zero."""
    law = servos.ZPETCServo(kp, ki, kd, 10.3, 0.040, TS, command_delay=command_delay)
    law.look_ahead([0.0] * law.preview)
    return law


def cascade():
    return servos.CascadeServo(60.0, 400.0, 20000.0, TS)


def integrator_loop(a: float) -> control.TransferFunction:
    """K / s under a zero-order hold at Ts: K Ts / (z - 1), with a = K Ts."""
    return control.c2d(control.tf([a / TS], [1.0, 0.0]), TS, method="zoh")


def evaluate(loop, theta):
    z = np.exp(1j * np.asarray(theta))
    return np.polyval(loop.num[0][0], z) / np.polyval(loop.den[0][0], z)


def sample_loops() -> list:
    """(name, L) of every kind this module builds, for the properties every loop must have."""
    vg = contouring.VariableGainCCC(Line([0.0, 0.0], [1.0, 1.0]), 8.0, 80.0, 0.6, TS)
    uv = contouring.UnitVectorCCC(2, 1.0, 10.0, 0.1, TS)
    delayed = first_order()
    delayed.command_delay = 3
    loops = [(f"integrator a={a}", integrator_loop(a)) for a in (0.05, 0.5, 1.0, 1.5, 1.95)]
    for i, ((k, tau), (kp, ki, kd)) in enumerate(AXES_000):
        plant, law = first_order(k, tau), pidff(kp, ki, kd, k, tau)
        loops += [(f"000 axis {i}", axis_loop(plant, law, TS)), (f"000 vg {i}", coupled_loop(plant, law, vg, TS)),
                  (f"000 uv {i}", coupled_loop(plant, law, uv, TS))]
    loops += [("000 pidff delay 3", axis_loop(delayed, pidff(), TS)),
              ("000 pid kp 2.5", axis_loop(first_order(), servos.PIDServo(2.5, 0.0, 0.0, TS), TS)),
              ("001 pd", axis_loop(mass_damper(), pd_001(), TS)),
              ("001 pd + vg", coupled_loop(mass_damper(), pd_001(), contouring.VariableGainCCC(
                  Line([0.0, 0.0], [1.0, 1.0]), 22e6, 0.0, 0.0, TS), TS)),
              ("cascade", axis_loop(mass_damper(1.0, 200.0, 1.0), cascade(), TS)),
              ("cascade + vg", coupled_loop(mass_damper(1.0, 200.0, 1.0), cascade(), vg, TS))]
    return loops


# (1) ------------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("a", [0.05, 0.5, 1.0, 1.5, 1.95])
def test_proportional_loop_on_a_discrete_integrator(a):
    """L(z) = K Ts / (z - 1): the closed-loop pole 1 - K Ts is inside the unit circle iff 0 < K Ts < 2, so the
    gain margin is 2 / (K Ts), found at the Nyquist frequency (where L(-1) = -K Ts / 2 is real)."""
    loop = integrator_loop(a)
    np.testing.assert_allclose(loop.num[0][0], [a], rtol=1e-12)
    np.testing.assert_allclose(loop.den[0][0], [1.0, -1.0], rtol=1e-12)
    result = margins(loop, TS)
    assert isinstance(result, LoopMargins) and result.stable
    assert result.gain_margin == pytest.approx(2.0 / a, rel=1e-6)
    # |L| = a / (2 sin(theta / 2)) = 1 and arg L = -(90 deg + theta / 2): PM = 90 deg - theta_c / 2
    theta_c = 2.0 * math.asin(a / 2.0)
    assert result.crossover_hz == pytest.approx(theta_c / (2.0 * math.pi * TS), rel=1e-9)
    assert result.phase_margin_deg == pytest.approx(90.0 - math.degrees(theta_c) / 2.0, rel=1e-9)
    # |S|^2 = x / ((1 - a) x + a^2), x = |z - 1|^2, grows with x: its peak is at Nyquist, 2 / (2 - a)
    assert result.ms == pytest.approx(2.0 / (2.0 - a), rel=1e-9)


@pytest.mark.parametrize("a", [2.05, 3.0])
def test_proportional_loop_past_the_gain_margin_is_unstable(a):
    result = margins(integrator_loop(a), TS)
    assert not result.stable
    assert result.gain_margin == pytest.approx(2.0 / a, rel=1e-6) and result.gain_margin < 1.0


# (2), (3) ----------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("name, loop", sample_loops(), ids=[name for name, _ in sample_loops()])
def test_classic_bounds_and_crossover_residual(name, loop):
    """Ms >= GM / (GM - 1) and Ms >= 1 / (2 sin(PM / 2)) (the Nyquist curve passes within 1/Ms of -1 but
    through -1/GM and through a point at angle PM on the unit circle), and |L| = 1 at the crossover."""
    result = margins(loop, TS)
    assert result.stable, name
    assert 1.0 < result.gain_margin < math.inf and 0.0 < result.phase_margin_deg < 180.0
    assert result.ms >= result.gain_margin / (result.gain_margin - 1.0) * (1.0 - 1e-9)
    assert result.ms >= 1.0 / (2.0 * math.sin(math.radians(result.phase_margin_deg) / 2.0)) * (1.0 - 1e-9)
    theta_c = 2.0 * math.pi * result.crossover_hz * TS
    assert abs(abs(evaluate(loop, theta_c)) - 1.0) < 1e-6
    angle = math.degrees(np.angle(evaluate(loop, theta_c)))
    assert (angle + 180.0 - result.phase_margin_deg + 180.0) % 360.0 == pytest.approx(180.0, abs=1e-6)


# (4) ------------------------------------------------------------------------------------------------------

def independent_pidff_margins(k, tau, kp, ki, kd):
    """Margins of PID + feedforward on k / (s (tau s + 1)) straight from the state space, with numpy only:
    Phi, Gamma from the matrix exponential, P(e^{jw Ts}) = c (zI - Phi)^-1 Gamma on a fine grid,
    C = kp + ki Ts z / (z - 1) on the position and kd on the velocity."""
    a = np.array([[0.0, 1.0], [0.0, -1.0 / tau]])
    b = np.array([[0.0], [k / tau]])
    block = np.zeros((3, 3))
    block[:2, :2], block[:2, 2:] = a, b
    e = expm(block * TS)
    phi, gamma = e[:2, :2], e[:2, 2]
    theta = np.linspace(math.pi / 400000, math.pi, 400000)
    z = np.exp(1j * theta)
    resolvent = np.linalg.solve(z[:, None, None] * np.eye(2) - phi, np.broadcast_to(gamma, (len(z), 2))[..., None])
    p_pos, p_vel = resolvent[:, 0, 0], resolvent[:, 1, 0]
    loop = (kp + ki * TS * z / (z - 1.0)) * p_pos + kd * p_vel
    ms = float(np.max(1.0 / np.abs(1.0 + loop)))
    gain = np.abs(loop)
    i = int(np.flatnonzero(np.diff(np.sign(gain - 1.0)))[0])
    w = (1.0 - gain[i]) / (gain[i + 1] - gain[i])
    theta_c = theta[i] + w * (theta[i + 1] - theta[i])
    phase = np.unwrap(np.angle(loop))
    pm = 180.0 + math.degrees(phase[i] + w * (phase[i + 1] - phase[i]))
    crossings = [1.0 / abs(loop[j]) for j in np.flatnonzero(np.diff(np.sign(loop.imag))) if loop[j].real < 0]
    if loop[-1].real < 0:
        crossings.append(1.0 / abs(loop[-1]))
    poles = np.roots(np.poly(phi))     # only for the record: the open loop's are 1 and exp(-Ts / tau)
    return ms, theta_c / (2.0 * math.pi * TS), pm, min(crossings), poles


def test_paper000_pidff_axes_against_an_independent_grid():
    experiment = load_experiment(PIDFF)
    result = experiment_margins(experiment)
    for axis, ((k, tau), (kp, ki, kd)) in zip(experiment.axes, AXES_000):
        ms, crossover_hz, pm, gm, poles = independent_pidff_margins(k, tau, kp, ki, kd)
        np.testing.assert_allclose(sorted(poles.real), sorted([math.exp(-TS / tau), 1.0]), rtol=1e-12)
        got = result[axis]["axis"]
        assert got.stable
        assert got.ms == pytest.approx(ms, rel=1e-3)
        assert got.crossover_hz == pytest.approx(crossover_hz, rel=1e-3)
        assert got.phase_margin_deg == pytest.approx(pm, rel=1e-3)
        assert got.gain_margin == pytest.approx(gm, rel=1e-3)
        assert got == margins(axis_loop(first_order(k, tau), pidff(kp, ki, kd, k, tau), TS), TS)
        assert result[axis]["coupled"].stable and result[axis]["coupled"].ms > got.ms


# (5) ------------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("make", [lambda: (first_order(), pidff()), lambda: (mass_damper(), pd_001()),
                                  lambda: (mass_damper(1.0, 200.0, 1.0), cascade())])
def test_each_sample_of_delay_takes_wc_ts_off_the_phase_margin(make):
    plant, law = make()
    before = margins(axis_loop(plant, law, TS), TS)
    for delay in (1, 2):
        plant.command_delay = delay
        after = margins(axis_loop(plant, law, TS), TS)
        assert after.crossover_hz == pytest.approx(before.crossover_hz, rel=1e-9)
        lost = math.degrees(2.0 * math.pi * before.crossover_hz * TS) * delay
        assert before.phase_margin_deg - after.phase_margin_deg == pytest.approx(lost, abs=1e-6)
        assert after.gain_margin < before.gain_margin and after.ms > before.ms


# (6) ------------------------------------------------------------------------------------------------------

def independent_characteristic(plant, law, scale):
    """1 + scale L(z) = 0 as a polynomial, built with python-control's arithmetic from the continuous
    model (control.c2d) and the PID written out: C_p = kp + ki Ts z / (z - 1), C_v = kd."""
    if isinstance(plant, FirstOrderVelocityAxis):
        position = control.tf([plant.gain], [plant.time_constant, 1.0, 0.0])
        velocity = control.tf([plant.gain], [plant.time_constant, 1.0])
    else:
        position = control.tf([plant.gain], [plant.mass, plant.damping, 0.0])
        velocity = control.tf([plant.gain], [plant.mass, plant.damping])
    pid = law.pid
    z = control.tf([1.0, 0.0], [1.0], TS)
    c_position = pid.kp + pid.ki * TS * z / (z - 1) if pid.ki else control.tf([pid.kp], [1.0], TS)
    loop = scale * (c_position * control.c2d(position, TS, "zoh") + pid.kd * control.c2d(velocity, TS, "zoh"))
    return np.polyadd(loop.den[0][0], loop.num[0][0])


@pytest.mark.parametrize("make", [lambda: (first_order(), pidff()), lambda: (mass_damper(), pd_001()),
                                  lambda: (first_order(), servos.PIDServo(2.5, 0.0, 0.0, TS))])
def test_stable_flag_agrees_with_the_roots_of_the_characteristic_polynomial(make):
    plant, law = make()
    loop = axis_loop(plant, law, TS)
    verdicts = []
    for scale in np.geomspace(0.05, 200.0, 31):
        stable = margins(scale * loop, TS).stable
        roots = np.roots(independent_characteristic(plant, law, scale))
        assert stable == bool(np.all(np.abs(roots) < 1.0)), scale
        verdicts.append(stable)
    assert any(verdicts) and not all(verdicts)
    gain_margin = margins(loop, TS).gain_margin
    assert margins((1.0 - 1e-6) * gain_margin * loop, TS).stable
    assert not margins((1.0 + 1e-6) * gain_margin * loop, TS).stable


# (7) ------------------------------------------------------------------------------------------------------

class _Schedule:
    theta_start, theta_end = 0.0, 1.0


def test_laws_that_are_not_linear_feedback_have_no_loop():
    plant = first_order()
    ismc = servos.IntegralSlidingModeServo(12.5, 12.5, 1e-3, 0.2985, 10.3, 0.04, TS)
    eso = servos.ESOSlidingModeServo(5.8, 244.0, 10.9, 500.0, 100.0, (6.0, 11.0, 6.0), 0.01, TS)
    vg = contouring.VariableGainCCC(Line([0.0, 0.0], [1.0, 1.0]), 8.0, 80.0, 0.6, TS)
    for law in (ismc, eso, servos.DirectServo()):
        assert axis_loop(plant, law, TS) is None
        assert coupled_loop(plant, law, vg, TS) is None
    line = Line([0.0, 0.0], [1.0, 1.0])
    tnb = contouring.AdaptiveTNBCCC(line, [1.0, 1.0], 40.0, [0.0, 0.0], [0.0, 0.0], [1.0, 1.0], [1.0, 1.0], TS)
    tvt = contouring.TangentialVelocityCCC(line, _Schedule(), 1.0)
    helix = Helix(0.01, 0.01, 0.001, 1.0, 1.0)
    for controller in (tnb, tvt, contouring.VariableGainCCC(helix, 8.0, 80.0, 0.0, TS)):
        assert coupled_loop(plant, pidff(), controller, TS) is None
    # proportional only, the 3-D variable-gain CCC is kp E: linear
    assert coupled_loop(plant, pidff(), contouring.VariableGainCCC(helix, 8.0, 0.0, 0.0, TS), TS) is not None
    for name in ("paper000_b_ismc_h50_newton", "paper003_ellipse_first_order_fn100", "paper004_saddle_eso"):
        result = experiment_margins(load_experiment(CONFIG / f"{name}.yaml"))
        assert all(loops == {"axis": None, "coupled": None} for loops in result.values()), name


# the transfer functions are the code's ------------------------------------------------------------------------

def impulse_response(loop, n: int) -> np.ndarray:
    num, den = loop.num[0][0], loop.den[0][0]
    return lfilter(np.r_[np.zeros(len(den) - len(num)), num], den, np.r_[1.0, np.zeros(n - 1)])


def code_impulse_response(plant, law, n: int) -> np.ndarray:
    """The loop broken at the plant input, run with the real objects: a unit impulse into the plant, the
    servo's command (reference zero) read back; L's impulse response is minus that command."""
    out = np.empty(n)
    for k in range(n):
        position, velocity = plant.measure()
        out[k] = -law.step(0.0, 0.0, 0.0, position, velocity, 0.0)
        plant.step(1.0 if k == 0 else 0.0, k * TS)
    return out


@pytest.mark.parametrize("make", [
    lambda: (first_order(), pidff()),
    lambda: (first_order(10.0, 0.045), servos.PIDServo(9.36, 108.0, 0.3, TS)),
    lambda: (mass_damper(), pd_001()),
    lambda: (mass_damper(1.0, 200.0, 1.0), cascade()),
    lambda: (mass_damper(2.0, 0.0, 1.0), servos.PIDServo(4000.0, 2000.0, 100.0, TS)),     # undamped
    lambda: (first_order(command_delay=1), zpetc(8.08, 93.2, 0.24, command_delay=1)),   # the feedforward's loop
])
def test_axis_loop_is_the_code_difference_equations(make):
    loop = axis_loop(*make(), TS)
    expected = code_impulse_response(*make(), 300)
    np.testing.assert_allclose(impulse_response(loop, 300), expected, rtol=0, atol=1e-7 * np.max(np.abs(expected)))


def test_axis_loop_with_the_plant_delay_and_encoder_velocity_of_the_code():
    try:
        plants = [first_order(command_delay=2, velocity_measurement="encoder") for _ in range(2)]
    except TypeError:
        pytest.skip("the plants take no command_delay / velocity_measurement yet")
    loop = axis_loop(plants[0], pidff(), TS)
    expected = code_impulse_response(plants[1], pidff(), 300)
    np.testing.assert_allclose(impulse_response(loop, 300), expected, rtol=0, atol=1e-7 * np.max(np.abs(expected)))


def code_coupled_impulse_response(make_axis, controller, n: int) -> tuple:
    """Two identical axes under the contour controller on the line y = x (45 degrees), the tangent-line
    estimate, the reference held at the origin; a unit impulse into the plants along the normal n. Returns
    (n . -commands, t . -commands)."""
    curve = Line([0.0, 0.0], [1.0, 1.0])
    estimator = TangentLineEstimator(curve)
    axes = [make_axis() for _ in range(2)]
    tangent = np.array([1.0, 1.0]) / math.sqrt(2.0)
    normal = np.array([-tangent[1], tangent[0]])
    zero = np.zeros(2)
    reference = Reference(theta=0.0, theta_dot=0.0, theta_ddot=0.0, position=zero, velocity=zero, acceleration=zero)
    along_normal, along_tangent = np.empty(n), np.empty(n)
    for k in range(n):
        measured = [plant.measure() for plant, _ in axes]
        position, velocity = np.array([m[0] for m in measured]), np.array([m[1] for m in measured])
        correction = controller.step(estimator.step(reference, position), reference, position, velocity)
        command = np.array([law.step(0.0, 0.0, 0.0, position[i], velocity[i], correction[i])
                            for i, (_, law) in enumerate(axes)])
        along_normal[k], along_tangent[k] = -normal @ command, -tangent @ command
        for i, (plant, _) in enumerate(axes):
            plant.step(normal[i] if k == 0 else 0.0, k * TS)
    return along_normal, along_tangent


@pytest.mark.parametrize("make_axis, scale", [(lambda: (first_order(), pidff()), 1.0),
                                              (lambda: (mass_damper(), pd_001()), 1e6),     # paper 001's units
                                              (lambda: (mass_damper(1.0, 200.0, 1.0), cascade()), 1.0)])
@pytest.mark.parametrize("make_controller", [
    lambda g: contouring.VariableGainCCC(Line([0.0, 0.0], [1.0, 1.0]), 8.0 * g, 80.0 * g, 0.6 * g, TS),
    lambda g: contouring.UnitVectorCCC(2, 1.0 * g, 10.0 * g, 0.1 * g, TS)])
def test_coupled_loop_is_the_code_on_a_45_degree_line(make_axis, scale, make_controller):
    loop = coupled_loop(*make_axis(), make_controller(scale), TS)
    normal, tangent = code_coupled_impulse_response(make_axis, make_controller(scale), 300)
    atol = 1e-7 * np.max(np.abs(normal))
    np.testing.assert_allclose(impulse_response(loop, 300), normal, rtol=0, atol=atol)
    np.testing.assert_allclose(tangent, 0.0, atol=atol)       # identical axes: the normal loop is decoupled


def test_plant_transfer_is_the_zoh_discretisation_of_the_continuous_model():
    """P(z) against control.c2d(..., 'zoh') of the continuous state space x = (position, velocity), both
    evaluated on the unit circle (a transfer-function c2d of K / (M s^2 + B s) loses digits to its scaling)."""
    theta = np.linspace(1e-3, 3.0, 60)
    cases = [(first_order(), 1.0 / 0.040, 10.3 / 0.040), (mass_damper(), 896.724 / 3075.37344, 1.0 / 3075.37344),
             (mass_damper(2.0, 0.0, 1.0), 0.0, 0.5)]
    for plant, decay, input_gain in cases:
        a, b = [[0.0, 1.0], [0.0, -decay]], [[0.0], [input_gain]]
        for discrete, c in zip(plant_transfer(plant, TS), ([[1.0, 0.0]], [[0.0, 1.0]])):
            model = control.c2d(control.ss(a, b, c, 0.0), TS, method="zoh")
            np.testing.assert_allclose(discrete.frequency_response(theta / TS).complex.ravel(),
                                       model.frequency_response(theta / TS).complex.ravel(), rtol=1e-9)
    assert plant_transfer(object(), TS) is None


def test_coupled_loop_adds_the_contour_pid_to_the_servo():
    """L = (C_servo + C_ccc) P for a proportional servo, C_ccc = kp + ki Ts z / (z - 1) + kd (z - 1) / (Ts z)."""
    plant, law = first_order(), servos.PIDServo(2.5, 0.0, 0.0, TS)
    controller = contouring.UnitVectorCCC(2, 1.0, 10.0, 0.1, TS)
    z = control.tf([1.0, 0.0], [1.0], TS)
    c_ccc = 1.0 + 10.0 * TS * z / (z - 1) + 0.1 * (z - 1) / (TS * z)
    expected = (2.5 + c_ccc) * control.c2d(control.tf([10.3 / 0.040], [1.0, 1.0 / 0.040, 0.0]), TS, "zoh")
    theta = np.linspace(1e-3, 3.0, 200)
    np.testing.assert_allclose(evaluate(coupled_loop(plant, law, controller, TS), theta), evaluate(expected, theta),
                               rtol=1e-7)     # polynomials with (z - 1)^2 evaluated near z = 1 on both sides
    uncoupled, alone = coupled_loop(plant, law, contouring.NoCoupling(2), TS), axis_loop(plant, law, TS)
    np.testing.assert_array_equal(uncoupled.num[0][0], alone.num[0][0])
    np.testing.assert_array_equal(uncoupled.den[0][0], alone.den[0][0])


def test_sample_times_must_agree():
    with pytest.raises(ValueError, match="Ts"):
        axis_loop(first_order(), pidff(), 2 * TS)
    with pytest.raises(ValueError, match="time step"):
        margins(integrator_loop(0.5), 2 * TS)
    with pytest.raises(ValueError, match="continuous"):
        margins(control.tf([1.0], [1.0, 0.0]), TS)


def test_the_largest_gain_scale_at_a_chosen_ms_has_its_known_answer():
    """K Ts / (z - 1) alone: |S| peaks at Nyquist, 2 / (2 - K Ts), so Ms = 2 at K Ts = 1 and Ms = 1.5 at
    K Ts = 2/3; the scale found is that K, and the loop there has that Ms."""
    import control
    from contouring_ros.core.margins import GainScaledLoops, quick_robustness
    ts = 1e-3
    zero, unit = control.tf([0.0], [1.0], ts), control.tf([ts], [1.0, -1.0], ts)
    loops = GainScaledLoops([(zero, {"kp": (unit, 1.0)}, 2.0)], 2.0)
    for ms, k_ts in ((2.0, 1.0), (1.5, 2.0 / 3.0)):
        k = loops.largest_scale({"kp": 1.0}, ms / 2.0)
        assert k * ts == pytest.approx(k_ts, rel=1e-5)
        assert quick_robustness(control.tf([k * ts], [1.0, -1.0], ts))[0] == pytest.approx(ms, rel=1e-4)
        assert loops.peak({"kp": 1.0}, k) * 2.0 == pytest.approx(ms, rel=1e-4)
    # a loop already beyond the target without the controller: no scale
    assert loops.largest_scale({"kp": 0.0}, 0.4) == 0.0


def test_a_gain_scale_is_the_top_of_the_lowest_range_or_of_the_highest_stable_one():
    """Ranges of scales within the bound at [0, 1], [5, 8] and [20, inf), a loop 0.1 k / (z - 1) deciding
    stability (stable for k < 20): the lowest range gives its top, 1; the highest stable range below the cap
    100 is [5, 8] (the one above is unstable), below a cap of 7 its top is the cap, and below a cap of 3
    only the lowest is left."""
    import control
    from contouring_ros.core.margins import GainScaledLoops
    ts = 1e-3
    zero, unit = control.tf([0.0], [1.0], ts), control.tf([ts], [1.0, -1.0], ts)
    loops = GainScaledLoops([(zero, {"kp": (unit, 1.0)}, 2.0,
                              lambda gains: control.tf([0.1 * gains["kp"]], [1.0, -1.0], ts))], 2.0)
    loops.ranges = lambda shape, share: [(0.0, 1.0), (5.0, 8.0), (20.0, math.inf)]
    assert loops.largest_scale({"kp": 1.0}, 1.0, 100.0, highest=False) == pytest.approx(1.0, rel=1e-5)
    assert loops.largest_scale({"kp": 1.0}, 1.0, 100.0) == pytest.approx(8.0, rel=1e-5)     # loop_of given: highest
    assert loops.largest_scale({"kp": 1.0}, 1.0, 7.0) == 7.0
    assert loops.largest_scale({"kp": 1.0}, 1.0, 3.0) == pytest.approx(1.0, rel=1e-5)
    loops.ranges = lambda shape, share: [(0.0, 1.0), (20.0, math.inf)]
    loops.axes = [axis[:3] + (None,) for axis in loops.axes]     # no loop_of: stable only in the range from 0
    assert loops.largest_scale({"kp": 1.0}, 1.0, 100.0, highest=True) == pytest.approx(1.0, rel=1e-5)


def test_the_axes_ranges_of_scales_are_intersected():
    from contouring_ros.core.margins import _intersected
    assert _intersected([(0.0, 1.0), (2.0, 5.0), (6.0, math.inf)], [(0.0, 3.0), (4.0, math.inf)]) == \
        [(0.0, 1.0), (2.0, 3.0), (4.0, 5.0), (6.0, math.inf)]
    assert _intersected([(0.0, 1.0)], [(2.0, math.inf)]) == []
