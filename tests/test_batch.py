"""Batch simulation: many experiments of one structure advanced together equal each experiment run alone."""
import numpy as np
import pytest
import yaml

from contouring_ros.config import build_loop, parse_experiment
from contouring_ros.core.batch import NotBatchable, batchable, simulate_batch, stack
from contouring_ros.core.curves import Circle, Parabola
from contouring_ros.core.pid import DiscretePID
from contouring_ros.core.simulation import simulate
from contouring_ros.sweep import combinations, parse_grid, run_sweep
from conftest import CONFIG, DEFAULT, shortened


def _loops(text, specs):
    return [build_loop(experiment) for _, experiment in combinations(text, parse_grid(specs))]


def _assert_equal_runs(batch, singles):
    # the same operations on the same float64 values; a vectorised sum (the ESO's matrix products) may round
    # differently, and the closed loop carries that rounding on (through a CCC's derivative gain): equal to
    # 1e-9 of each signal's size
    for run, alone in zip(batch, singles):
        for name, value in vars(alone).items():
            assert np.max(np.abs(getattr(run, name) - value)) <= 1e-9 * np.max(np.abs(value)), name


def _with_estimator(path, **estimator):
    data = yaml.safe_load(shortened(path, 0.4))
    data["/contour_estimator"]["ros__parameters"] = estimator
    return yaml.safe_dump(data)


def _on_ellipse():
    # a closed curve: the Newton estimate wraps around the period
    data = yaml.safe_load(shortened(DEFAULT, 0.4))
    data["/**"]["ros__parameters"]["curve"] = {"type": "ellipse", "a": 0.02, "b": 0.01}
    data["/**"]["ros__parameters"]["schedule"] = {"type": "uniform", "theta_start": 6.0, "theta_end": 6.8,
                                                  "duration": 0.4}
    return yaml.safe_dump(data)


@pytest.mark.parametrize("text, specs", [
    (shortened(DEFAULT, 0.4),
     ["ccc.kp=0.5,4", "x/servo.a=10,12.5", "curve.h=40,50", "y/plant.time_constant=0.03,0.045"]),
    (shortened(CONFIG / "paper000_a_pidff_h50_newton.yaml", 0.4),
     ["x/servo.kp=5,8.08", "contour_estimator.k_prime=300,500"]),
    (_with_estimator(DEFAULT, type="tangent_line"), ["ccc.kd=0,0.1", "curve.a=0.015,0.02", "schedule.duration=1.5,2"]),
    (shortened(CONFIG / "paper000_b_ismc_h50_vgccc.yaml", 0.4), ["ccc.kp=20,40", "curve.h=50,100"]),
    (_on_ellipse(), ["ccc.kp=0.5,4", "curve.b=0.01,0.015"]),
    (shortened(CONFIG / "paper004_saddle_eso.yaml", 0.3), ["x/servo.k=50,80", "z/plant.mass=1.5,2"]),
    (shortened(CONFIG / "paper004_screw_no_eso.yaml", 0.3), ["x/servo.c=30,40", "x/plant.disturbance.frequency=0.5,1"]),
    (shortened(CONFIG / "paper001_caseI_pd.yaml", 0.3), ["x/servo.kd=7e5,8e5", "curve.radius=0.06,0.1"]),
    (shortened(CONFIG / "paper002_butterfly_c2_osculating_circle.yaml", 0.5), ["ccc.kp=100,140"]),
    # h = 0: a straight parabola, where the osculating circle falls back to the tangent line, beside curved ones
    (_with_estimator(DEFAULT, type="osculating_circle"), ["curve.h=0,50", "ccc.kp=0.5,4"]),
], ids=["ismc-newton", "pidff-newton", "ismc-tangent-line", "variable-gain", "ellipse-newton", "eso-saddle",
        "no-eso-screw", "pd-osculating-circle", "feedrate-osculating-circle", "osculating-circle-straight"])
def test_batch_equals_each_experiment_alone(text, specs):
    loops = _loops(text, specs)
    assert batchable(loops)
    _assert_equal_runs(simulate_batch(loops), [simulate(loop) for loop in _loops(text, specs)])


def test_branch_check_restarts_only_the_runs_that_need_it():
    # a slow Newton flow (k' = 50, capped at 2 inner iterations) lags the foot point and its branch check
    # restarts it again and again; started at the far end of the parabola (theta0 = +a) it restarts once
    # more, at step 0. The batch must restart each run exactly where that run alone does.
    text = _with_estimator(DEFAULT, type="newton", k_prime=50.0, c_prime=500.0, max_iterations=2)
    specs = ["contour_estimator.theta0=-0.02,0.02"]
    alone = _loops(text, specs)
    results = [simulate(loop) for loop in alone]
    recoveries = [loop.estimator.recoveries for loop in alone]
    assert 0 < recoveries[0] < recoveries[1]
    _assert_equal_runs(simulate_batch(_loops(text, specs)), results)


def test_stack_makes_differing_numbers_batch_columns_and_keeps_equal_ones():
    stacked = stack([Parabola(0.02, 40.0), Parabola(0.02, 50.0)])
    assert stacked.a == 0.02 and stacked.h.shape == (2, 1)
    np.testing.assert_array_equal(stacked.columns(np.array([[0.01], [0.01]]))[0][1][:, 0], [0.004, 0.005])
    pid = stack([DiscretePID(1.0, 2.0, 0.0, 0.001), DiscretePID(3.0, 2.0, 0.0, 0.001)])
    assert pid.ki == 2.0 and pid.kp[:, 0].tolist() == [1.0, 3.0]


def test_a_stacked_direct_servo_clips_each_run_at_its_own_limit():
    from contouring_ros.core.servo import DirectServo
    servo = stack([DirectServo(0.0), DirectServo(1.0), DirectServo(3.0)])     # 0: no limit
    command = servo.step(0.0, 0.0, 0.0, np.zeros((3, 1)), np.zeros((3, 1)), np.array([[2.0], [-2.0], [2.0]]))
    assert command[:, 0].tolist() == [2.0, -1.0, 2.0]
    assert DirectServo(1.0).step(0.0, 0.0, 0.0, 0.0, 0.0, -2.0) == -1.0


def test_stack_refuses_what_has_no_batch_path_or_mixes_classes():
    with pytest.raises(NotBatchable, match="no batch path"):
        stack([object(), object()])
    with pytest.raises(NotBatchable, match="mixes"):
        stack([Parabola(0.02, 50.0), Circle(0.02)])


def test_feedrate_profiles_batch_only_when_they_are_the_same():
    text = shortened(CONFIG / "paper002_butterfly_c1_tangent_line.yaml", 0.2)
    assert batchable(_loops(text, ["ccc.kp=100,140"]))
    assert not batchable(_loops(text, ["schedule.feedrate=0.05,0.1"]))


def test_loops_of_a_class_without_batch_path_are_not_batchable():
    text = shortened(CONFIG / "paper001_caseI_adaptive_tnb.yaml", 0.2)   # the adaptive TNB CCC has none
    assert not batchable(_loops(text, ["x/servo.kd=7e5,8e5"]))


def test_sweep_vectorises_what_it_can_and_runs_the_rest_alone():
    text = shortened(DEFAULT, 0.3)
    # with and without the disturbance observer: two structures, each its own vectorised batch
    rows = run_sweep(text, parse_grid(["ccc.kp=0.5,1,2,4", "x/servo.observer=true,false"]), workers=1)
    assert len(rows) == 8 and all(row.vectorised for row in rows)
    for row in rows:      # each row is the score of that combination run alone
        data = yaml.safe_load(text)
        data["/ccc"]["ros__parameters"]["kp"] = row.settings["ccc.kp"]
        data["/x/servo"]["ros__parameters"]["observer"] = row.settings["x/servo.observer"]
        loop = build_loop(parse_experiment(yaml.safe_dump(data), "one"))
        np.testing.assert_allclose(row.scores.mce, _mce(loop), rtol=1e-9)
    rows = run_sweep(shortened(CONFIG / "paper001_caseI_adaptive_tnb.yaml", 0.2),
                     parse_grid(["x/servo.kd=7e5,8e5,9e5,1e6"]), workers=1)
    assert not any(row.vectorised for row in rows)
    assert {row.alone for row in rows} == {"AdaptiveTNBCCC has no batch path"}     # said, for the CLI to print


def _mce(loop):
    from contouring_ros.scoring import score_run
    return score_run(loop.curve, simulate(loop)).mce


def test_sweep_batches_each_structure_apart_when_numbers_change_it():
    # 0 branch-check samples means no branch check: a different structure from the same-shaped file
    text = shortened(DEFAULT, 0.2)
    rows = run_sweep(text, parse_grid(["ccc.kp=0.5,1,2,4", "contour_estimator.branch_check_samples=0,256"]), workers=1)
    assert len(rows) == 8 and all(row.vectorised for row in rows)
