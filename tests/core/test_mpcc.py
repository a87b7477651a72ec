"""Model predictive contouring control (core/mpc.py): its model is the plant the simulation steps, it keeps
its command limits, its contour weighting is what lowers the contour error (flipped weights raise it), it
beats paper 003's task-frame PD on that paper's ellipse and drives, and its delay model and disturbance
estimate do what they are for."""
import dataclasses

import numpy as np
import pytest

from contouring_ros.core.mpc import sampled_mass_damper
from contouring_ros.core.plants import MassDamperAxis
from contouring_ros.core.simulation import simulate
from contouring_ros.experiment.build import build_loop
from contouring_ros.experiment.validate import parse_experiment
from contouring_ros.records.scoring import score_run
from conftest import CONFIG, shortened

SCENARIO = CONFIG / "paper003_ellipse_natural_local_fn100.yaml"
MODEL = "    mass: [1.0, 1.0]\n    damping: [798.5, 862.75]\n    gain: [16.23, 17.58]\n"


def _mpcc(duration: float = 0.6, plant_delay: int = 0, **keys):
    """Paper 003's ellipse (fn100 file: its plants, direct servos with their 10 V limit) with an mpcc section."""
    text = shortened(SCENARIO, duration)
    if plant_delay:
        text = text.replace("{model: mass_damper,", f"{{model: mass_damper, command_delay: {plant_delay},")
    section = {"horizon": 20, "q_contour": 1e6, "q_lag": 1e4, "r_rate": 1e-6, "disturbance_gain": 0.2, **keys}
    lines = "".join(f"    {key}: {value}\n" for key, value in section.items())
    text = text[:text.index("/ccc:")] + "/ccc:\n  ros__parameters:\n    type: mpcc\n" + MODEL + lines
    return _run(text)


def _run(text: str):
    loop = build_loop(parse_experiment(text, "scenario.yaml"))
    return loop, simulate(loop)


def _steady_rms(run, from_time=0.3) -> float:
    """RMS of the exact contour error from ``from_time`` on [m]."""
    loop, result = run
    return score_run(loop.curve, result, from_time).rms


def test_the_model_is_the_mass_damper_the_simulation_steps():
    a, b = sampled_mass_damper(1.0, 798.5, 16.23, 1e-3)
    plant = MassDamperAxis(1.0, 798.5, 16.23, 1e-3, position=0.01, velocity=0.02)
    x = np.array([0.01, 0.02])
    for k, u in enumerate(np.sin(np.arange(50) * 0.3)):
        plant.step(u, k * 1e-3)
        x = a @ x + b * u
        assert plant.position == pytest.approx(x[0], abs=1e-15) and plant.velocity == pytest.approx(x[1], rel=1e-12)


def test_it_keeps_its_command_limit_where_the_unconstrained_optimum_would_not():
    _, free = _mpcc()
    peak = np.abs(free.command).max()
    limit = round(0.9 * peak, 3)
    bound = _mpcc(command_limit=f"[{limit}]")
    assert np.abs(bound[1].command).max() <= limit + 1e-9 < peak
    assert _steady_rms(bound) < 1e-4          # still near the contour where the drive cannot follow it exactly


def test_where_the_limits_do_not_bind_the_unconstrained_optimum_is_osqp_s_solution():
    # the step's QP solved both ways: the linear system's solution (within the limits, so the QP's) and OSQP's
    loop, _ = _mpcc(0.05, command_limit="[10.0]")
    rows = loop.controller._rows
    size = rows.n * rows.horizon
    rng = np.random.default_rng(1)
    factor = rng.normal(size=(size, size))
    hessian = factor @ factor.T + size * np.eye(size)
    linear = rng.normal(size=size)
    free = rows._solve(hessian[None], linear[None])[0]
    assert np.abs(free).max() < 10.0
    np.testing.assert_allclose(rows._solve_bounded(0, hessian, linear), free, rtol=1e-6, atol=1e-9)
    clipped = rows._solve(hessian[None], 50.0 * linear[None] / np.abs(free).max())[0]   # the optimum outside
    assert np.abs(clipped).max() <= 10.0 + 1e-12 and np.isclose(np.abs(clipped).max(), 10.0)


def test_weighting_the_contour_error_is_what_lowers_it():
    contouring = _steady_rms(_mpcc(q_contour=1e6, q_lag=1e4))
    isotropic = _steady_rms(_mpcc(q_contour=1e6, q_lag=1e6))
    flipped = _steady_rms(_mpcc(q_contour=1e4, q_lag=1e6))
    assert contouring <= 1.01 * isotropic          # on this ellipse the lag's weight hardly matters ...
    assert contouring < 0.5 * flipped              # ... but weighting the lag above the contour error costs


def test_on_paper_003_s_ellipse_it_beats_the_paper_s_task_frame_pd_on_the_same_drives():
    paper = _run(shortened(SCENARIO, 0.6))
    mpcc = _mpcc()
    assert _steady_rms(mpcc) < 0.5 * _steady_rms(paper)
    assert len(mpcc[0].controller.solve_times) == mpcc[0].n_steps


def test_its_delay_model_pays_off_on_a_drive_with_a_computation_delay():
    knows = _steady_rms(_mpcc(plant_delay=1, command_delay=1))
    ignores = _steady_rms(_mpcc(plant_delay=1, command_delay=0))
    assert knows < 0.5 * ignores


def test_the_disturbance_estimate_removes_a_constant_load_s_offset():
    text_load = "{type: constant, value: 0.05}"

    def with_load(gain):
        text = shortened(SCENARIO, 0.6)
        text = text.replace("{model: mass_damper,", "{model: mass_damper, disturbance: " + text_load + ",")
        section = "    horizon: 20\n    q_contour: 1.0e6\n    q_lag: 1.0e4\n    r_rate: 1.0e-6\n" \
                  f"    disturbance_gain: {gain}\n"
        text = text[:text.index("/ccc:")] + "/ccc:\n  ros__parameters:\n    type: mpcc\n" + MODEL + section
        return _steady_rms(_run(text))
    assert with_load(0.2) < 0.3 * with_load(0.0)


def test_weights_that_leave_no_error_to_lower_are_refused_in_one_line():
    from contouring_ros.errors import ConfigError
    with pytest.raises(ConfigError, match=r"/ccc\.q_contour: with q_contour and q_lag both 0 the MPCC has no error"):
        _mpcc(q_contour=0.0, q_lag=0.0)


def test_the_model_velocity_estimate_is_the_plants_velocity_and_beats_a_differentiated_encoder():
    """On a mass-damper whose time constant (1.25 ms) is near the sample time the encoder's difference is the
    mean velocity of the last step, half a sample late: the deadbeat reconstruction through the model gives
    the true velocity (model matched, no noise), and the MPCC reading it tracks the ellipse far closer."""
    from contouring_ros.core.plants import MassDamperAxis
    from contouring_ros.core.mpc import reconstructed_velocity
    ts, mass, damping, gain = 1e-3, 1.0, 800.0, 16.0
    (_, pv), (_, vv) = sampled_mass_damper(mass, damping, gain, ts)[0]
    b0, b1 = sampled_mass_damper(mass, damping, gain, ts)[1]
    plant = MassDamperAxis(mass, damping, gain, ts)
    for k, u in enumerate(np.sin(np.arange(40) * 0.3) * 2.0):
        before = plant.position
        plant.step(u, k * ts)
        assert reconstructed_velocity(plant.position, before, u, pv, vv, b0, b1) == pytest.approx(
            plant.velocity, rel=1e-9, abs=1e-15), k
    text = shortened(CONFIG / "paper003_ellipse_natural_local_fn100.yaml", 0.5)
    text = text[:text.index("/ccc:")] + ("/ccc:\n  ros__parameters:\n    type: mpcc\n    mass: [1.0, 1.0]\n"
                                         "    damping: [798.5, 862.75]\n    gain: [16.23, 17.58]\n    horizon: 10\n"
                                         "    r_rate: 1.0e-6\n    command_limit: [10.0]\n    command_delay: 1\n    disturbance_gain: 0.2\n")
    tace = {}
    for estimate in ("measured", "model"):
        experiment = parse_experiment(text.replace("    horizon: 10\n", f"    horizon: 10\n    velocity_estimate: {estimate}\n"),
                                      "mpcc.yaml")
        plants = {a: {**p, "velocity_measurement": "encoder", "command_delay": 1, "encoder_resolution": 1e-7}
                  for a, p in experiment.plants.items()}
        loop = build_loop(dataclasses.replace(experiment, plants=plants))
        tace[estimate] = score_run(loop.curve, simulate(loop)).tace
    assert tace["model"] < 0.1 * tace["measured"], tace
