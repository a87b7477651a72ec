"""The task-frame PD contour controller of paper 003 against known answers, and paper 003's helix simulation."""
import numpy as np
import pytest
from numpy.testing import assert_allclose

from contouring_ros.config import build_loop, load_experiment, parse_experiment
from contouring_ros.core.contouring import TaskFramePD
from contouring_ros.core.curves import Line
from contouring_ros.core.estimators import TangentLineEstimator, first_order_terms
from contouring_ros.core.interpolation import UniformSchedule
from contouring_ros.core.plants import MassDamperAxis
from contouring_ros.core.servo import DirectServo
from contouring_ros.core.simulation import ControlLoop, simulate
from contouring_ros.records.scoring import score_run
from conftest import CONFIG


def test_normal_error_on_a_line_decays_as_the_assigned_critically_damped_dynamics():
    """With an exact axis model, eq. 24 gives z'' = -K_P z - K_D z', here critically damped at f_n:
    a normal offset e0 decays as e0 (1 + w t) exp(-w t), w = 2 pi f_n, while the axes move along the line."""
    ts, steps, f_n, e0 = 1e-4, 2000, 20.0, 1e-4
    line = Line([0.0, 0.0, 0.0], [0.3, 0.2, 0.1])
    schedule = UniformSchedule(0.0, 0.05, 1.0)
    normal = np.cross(line.direction, [0.0, 0.0, 1.0])
    normal /= np.linalg.norm(normal)
    damping, mass = [200.0, 225.0, 180.0], [1.0, 2.0, 0.5]
    plants = [MassDamperAxis(mass[i], damping[i], 1.0, ts, position=e0 * normal[i],
                             velocity=0.05 * line.direction[i]) for i in range(3)]
    controller = TaskFramePD(line, first_order_terms, mass, damping, [1.0, 1.0, 1.0], [5.0, f_n, f_n])
    loop = ControlLoop(line, schedule, plants, [DirectServo() for _ in range(3)], TangentLineEstimator(line),
                       controller, ts, steps)
    result = simulate(loop)
    offset = (result.position - result.reference_position) @ normal
    t, w = result.time, 2 * np.pi * f_n
    assert_allclose(offset, e0 * (1 + w * t) * np.exp(-w * t), atol=0.02 * e0)
    assert np.abs((result.position - result.reference_position) @ line.direction).max() < 0.02 * e0


def _helix(sample_time: float, identified_damping: str) -> str:
    text = (CONFIG / "paper003_helix_natural_local_f15_10.yaml").read_text()
    return (text.replace("sample_time: 0.001", f"sample_time: {sample_time}\n    duration: 1.0")
                .replace("damping: [205.0, 230.0, 180.0]", f"damping: {identified_damping}"))


def test_with_an_exact_model_only_the_zero_order_hold_is_left():
    """With the true damping in the controller the continuous-time error dynamics have no input: what is left
    comes from holding the command over a sample, so it shrinks in proportion to Ts."""
    errors = []
    for ts in (1e-3, 1e-4):
        loop = build_loop(parse_experiment(_helix(ts, "[200.0, 225.0, 180.0]"), "helix"))
        errors.append(score_run(loop.curve, simulate(loop)).tace)
    assert errors[0] < 15e-6
    assert 7.0 < errors[0] / errors[1] < 13.0


def _paper003(name: str) -> float:
    loop = build_loop(load_experiment(CONFIG / f"{name}.yaml"))
    return score_run(loop.curve, simulate(loop)).tace * 1e6


@pytest.fixture(scope="module")
def helix_results():
    return {(approximation, f, variant): _paper003(f"paper003_{variant}helix_{approximation}_{f}")
            for approximation in ("first_order", "natural_local") for f in ("f15_10", "f20_15")
            for variant in ("", "mech_")}


PAPER_003 = {("first_order", "f15_10"): 11.46, ("natural_local", "f15_10"): 7.10,
             ("first_order", "f20_15"): 11.23, ("natural_local", "f20_15"): 4.45}


def test_paper003_helix_natural_local_below_first_order_for_both_bandwidth_sets(helix_results):
    """The ordering of paper 003 section IV-A holds under the paper's own reading (B identified as
    diag(205, 230, 180)), though the margin there is small: see the next test."""
    for variant in ("", "mech_"):
        for f in ("f15_10", "f20_15"):
            assert helix_results["natural_local", f, variant] < helix_results["first_order", f, variant]


def test_paper003_helix_magnitudes_under_the_paper_reading_are_dominated_by_a_binormal_mismatch(helix_results):
    """Under the paper's B = diag(205, 230, 180) the x/y mismatch leaves a binormal force of about
    5 gamma_z z' = 0.44 that the binormal PD holds at 0.44 / (2 pi f_b)^2: the mean contour error is
    ~90 um at f_b = 10 and ~40 um at f_b = 15 for both approximations, 4-13x the paper's values."""
    for approximation in ("first_order", "natural_local"):
        assert 80 < helix_results[approximation, "f15_10", ""] < 100
        assert 35 < helix_results[approximation, "f20_15", ""] < 47


def test_paper003_helix_reproduced_within_2x_when_the_mismatch_is_tangential(helix_results):
    """With the same +5 mismatch on every axis (identified B_z = 185: the mechanism scenarios
    paper003_mech_helix_*) the mismatch force is tangential, and
    the paper's numbers and pattern come out: each within 2x, natural local improving by > 30% as f_n, f_b
    grow while first order moves by < 25%."""
    for key, paper in PAPER_003.items():
        assert 0.5 < helix_results[(*key, "mech_")] / paper < 2.0, key
    natural = [helix_results["natural_local", f, "mech_"] for f in ("f15_10", "f20_15")]
    first = [helix_results["first_order", f, "mech_"] for f in ("f15_10", "f20_15")]
    assert natural[1] < 0.7 * natural[0]
    assert first[1] > 0.75 * first[0]
