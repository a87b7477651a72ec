"""Batch simulation: many experiments of one structure advanced together equal each experiment run alone."""
import copy

import numpy as np
import pytest
import yaml

from contouring_ros.config import CONTROLLERS, build_loop, parse_experiment
from contouring_ros.core.batch import NotBatchable, _stacked, batch_problem, batchable, simulate_batch, stack
from contouring_ros.core.contouring import NoCoupling
from contouring_ros.core.curves import Circle, Parabola
from contouring_ros.core.pid import DiscretePID
from contouring_ros.core.simulation import simulate
from contouring_ros.studies.sweep import combinations, run_sweep
from contouring_ros.experiment.settings import parse_grid
from conftest import CONFIG, DEFAULT, load_tool, shortened


def _loops(text, specs):
    return [build_loop(experiment) for _, experiment in combinations(text, parse_grid(specs))]


def _assert_equal_runs(batch, singles, tolerance=1e-9):
    # the same operations on the same float64 values; a vectorised sum (the ESO's matrix products) may round
    # differently, and the closed loop carries that rounding on (through a CCC's derivative gain): equal to
    # 1e-9 of each signal's size
    for run, alone in zip(batch, singles):
        for name, value in vars(alone).items():
            assert np.max(np.abs(getattr(run, name) - value)) <= tolerance * np.max(np.abs(value)), name


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


def _settings(name, duration, grid):
    return shortened(CONFIG / name, duration), grid


# the task-frame PD (natural-local and first-order approximations, 2 and 3 axes), the natural-local and
# foot-point search estimates, the TVT and adaptive TNB controllers: each batch member equals its run alone to
# 1e-12 of each signal's size (the frames, products and sums are formed in the scalar path's order; only the
# curves' trigonometric functions may round an array differently from one float)
@pytest.mark.parametrize("text, grid", [
    _settings("paper003_ellipse_natural_local_fn80.yaml", 0.3, {"ccc.f_n": [60.0, 80.0], "ccc.f_t": [40.0, 50.0],
                                                                 "curve.b": [0.01, 0.012]}),
    _settings("paper003_helix_natural_local_f15_10.yaml", 0.3, {"ccc.f_n": [12.0, 15.0], "ccc.f_b": [10.0, 12.0],
                                                                 "curve.c": [0.01, 0.02]}),
    _settings("paper003_figure_eight_first_order_fn80.yaml", 0.3, {
        "ccc.f_n": [60.0, 80.0], "ccc.damping": [[200.0, 230.0], [180.0, 200.0]], "ccc.zeta": [0.8, 1.0]}),
    _settings("paper003_helix_first_order_f15_10.yaml", 0.3, {"ccc.f_n": [12.0, 15.0], "curve.length": [8.0, 10.0]}),
    # the realistic machine of the benchmark: encoder, noise of its own seed per run, a sample of delay
    _settings("paper003_mech_helix_natural_local_f15_10.yaml", 0.3, {
        "x/plant.measurement_noise": [1e-7], "x/plant.noise_seed": [1, 2], "x/plant.encoder_resolution": [1e-7],
        "y/plant.command_delay": [1], "ccc.f_n": [12.0, 15.0]}),
    _settings("paper001_caseII_adaptive_tnb.yaml", 0.3, {
        "ccc.alpha": [30.0, 40.0], "ccc.mass0": [[3075.37344, 1144.0], [3000.0, 1100.0]],
        "ccc.coupling": [[11493.98, 84867.6], [5000.0, 40000.0]]}),
    _settings("paper001_mech_mismatch_adaptive_tnb.yaml", 0.3, {"ccc.alpha": [30.0, 40.0],
                                                                "x/plant.mass": [3000.0, 3200.0]}),
    _settings("paper002_butterfly_c3_tvt.yaml", 0.4, {"ccc.kc": [100.0, 140.0], "ccc.min_feedrate": [1e-3, 2e-3],
                                                      "contour_estimator.max_iterations": [2, 10]}),
    _settings("paper002_butterfly_c4_foot_point_ccc.yaml", 0.4, {"ccc.kp": [100.0, 140.0],
                                                                 "contour_estimator.tolerance": [1e-6, 1e-8]}),
    _settings("paper002_mech_feedlag_c3_tvt.yaml", 0.4, {"ccc.kc": [100.0, 140.0], "x/plant.time_constant": [0.02, 0.03]}),
], ids=["natural-local-ellipse", "natural-local-helix", "first-order-figure-eight", "first-order-helix",
        "natural-local-helix-realistic-machine", "adaptive-tnb", "adaptive-tnb-mismatch", "tvt-foot-point",
        "foot-point-ccc", "tvt-feed-lag"])
def test_batch_of_the_frenet_frame_and_foot_point_classes_equals_each_run_alone(text, grid):
    def loops():
        return [build_loop(experiment) for _, experiment in combinations(text, grid)]
    batch = loops()
    assert len(batch) > 2 and batchable(batch)
    _assert_equal_runs(simulate_batch(batch), [simulate(loop) for loop in loops()], tolerance=1e-12)


def _on_spline():
    # a spline through points of the default parabola, driven by the feedrate schedule
    data = yaml.safe_load(shortened(DEFAULT, 0.4))
    x = np.linspace(-0.02, 0.02, 9)
    data["/**"]["ros__parameters"]["curve"] = {"type": "spline", "x": x.tolist(), "y": (50.0 * x * x).tolist()}
    data["/**"]["ros__parameters"]["schedule"] = {"type": "feedrate", "feedrate": 0.02, "acceleration": 0.5}
    return yaml.safe_dump(data)


def _with_random_disturbance():
    data = yaml.safe_load(shortened(DEFAULT, 0.3))
    data["/x/plant"]["ros__parameters"]["disturbance"] = {"type": "random", "std": 1e-4, "seed": 1}
    return yaml.safe_dump(data)


# the tool path of a part program with its jerk-limited feed plan (shared across the batch), a spline, a random
# disturbance of its own seed per run: each member equals its run alone to 1e-12
@pytest.mark.parametrize("text, grid", [
    (shortened(CONFIG / "gcode_example_part.yaml", 1.0), {"ccc.kp": [1.0, 2.0], "contour_estimator.k_prime": [400.0, 500.0]}),
    (_on_spline(), {"ccc.kp": [0.5, 4.0], "x/servo.a": [10.0, 12.5]}),
    (_with_random_disturbance(), {"x/plant.disturbance.seed": [1, 2, 3], "x/plant.disturbance.std": [1e-4, 2e-4]}),
], ids=["gcode-feed-plan", "spline", "random-disturbance"])
def test_batch_of_tool_paths_splines_and_random_disturbances_equals_each_run_alone(text, grid):
    def loops():
        return [build_loop(experiment) for _, experiment in combinations(text, grid)]
    batch = loops()
    assert batchable(batch)
    _assert_equal_runs(simulate_batch(batch), [simulate(loop) for loop in loops()], tolerance=1e-12)


def test_batch_of_in_position_waits_equals_each_run_alone(tmp_path):
    # exact stops that wait for the axes (the in-position clock, stepped per member on its own axis states):
    # members of other gains wait other numbers of steps at each corner, and each equals its run alone to 1e-12,
    # its clock's waits included
    from test_in_position import square_experiment
    path = square_experiment(tmp_path, "paper000_b_ismc_h50_newton", 1e-5, side_mm=2, feed=600, duration=1.2,
                             observer="paper")
    grid = {"x/servo.a": [8.0, 12.5, 20.0], "y/servo.a": [11.1, 20.0]}
    text = path.read_text().replace("file: square.ngc", f"file: {tmp_path / 'square.ngc'}")

    def loops():
        return [build_loop(experiment) for _, experiment in combinations(text, grid)]
    batch, alone = loops(), loops()
    assert batchable(batch) and all(loop.clock is not None for loop in batch)
    singles = [simulate(loop) for loop in alone]
    waits = [loop.clock.waits for loop in alone]
    assert len({tuple(w) for w in waits}) > 1 and all(len(w) >= 2 for w in waits)
    _assert_equal_runs(simulate_batch(batch), singles, tolerance=1e-12)
    assert [loop.clock.waits for loop in batch] == [[]] * len(batch)         # the batch ran on copies


def test_batch_of_ismc_servos_with_the_plan_correction_equals_each_run_alone(tmp_path):
    # a tool path's ISMC estimate carries the reference's filter state (observer_plan_correction, the default
    # there): stacked across members of other gains it gives each member's run alone to 1e-12
    from test_in_position import square_experiment
    path = square_experiment(tmp_path, "paper000_b_ismc_h50_newton", 1e-5, side_mm=2, feed=600, duration=1.2)
    text = path.read_text().replace("file: square.ngc", f"file: {tmp_path / 'square.ngc'}")
    grid = {"x/servo.a": [8.0, 12.5], "y/servo.c": [20.0, 25.0]}

    def loops():
        return [build_loop(experiment) for _, experiment in combinations(text, grid)]
    batch, alone = loops(), loops()
    assert all(servo.observer.plan_correction for loop in batch for servo in loop.servos)
    _assert_equal_runs(simulate_batch(batch), [simulate(loop) for loop in alone], tolerance=1e-12)


def test_a_feed_plan_in_a_batch_gives_each_members_times_as_alone():
    # the plan shared across a batch: a batch of times (members at different spans, as after waits of their
    # own) gives each time's theta, feed and acceleration as the plan alone, bit for bit
    loops = _loops(shortened(CONFIG / "gcode_example_part.yaml", 0.2), ["ccc.kp=1,2,3"])
    plan = stack([loop.schedule for loop in loops])
    alone = loops[0].schedule
    times = np.array([[0.05], [1.7], [3.2]])
    for got, want in zip(plan(times), zip(*(alone(float(t)) for t in times[:, 0]))):
        assert np.array_equal(got[:, 0], np.array(want))


def test_tool_paths_and_feed_plans_batch_only_when_they_are_the_same():
    text = _on_spline()
    assert not batchable(_loops(text, ["curve.closed=false,true"]))
    part = shortened(CONFIG / "gcode_example_part.yaml", 0.2)
    assert batch_problem(_loops(part, ["schedule.jerk=10,20"])) == "FeedPlan.limits must be the same across a batch"
    assert batch_problem(_loops(part, ["schedule.feed_override=80,100"])) == \
        "FeedPlan.limits must be the same across a batch"
    assert batch_problem(_loops(part, ["schedule.exact_stop_dwell=0,0.1"])) == \
        "FeedPlan._span must be the same across a batch"


def test_every_scenario_file_can_run_as_a_batch():
    # every class a scenario of config/ is built of has a batch path (the MPCC's steps each member's own QP):
    # sweeps, maps and the benchmark's tuning run none of them one by one for want of one
    from contouring_ros.config import load_experiment
    problems = {}
    for path in sorted(CONFIG.glob("*.yaml")):
        experiment = load_experiment(path)
        problem = batch_problem([build_loop(experiment), build_loop(experiment)])
        if problem:
            problems[path.name] = problem
    assert problems == {}


def test_an_mpcc_batch_gives_each_member_its_run_alone_bit_for_bit():
    """The MPCC's batch (core/mpc.py ContouringBatch): the members' QPs are rows of one computation (members of
    another horizon, delay or velocity estimate rows of another), and a batch of different weights, limits
    (one reached), velocity estimates and delays gives each run alone, to the bit."""
    text = shortened(CONFIG / "mpcc_ellipse.yaml", 0.3)
    variants = [text, text.replace("q_contour: 1.0e6", "q_contour: 1.0e5"),
                text.replace("r_rate: 1.0e-6", "r_rate: 1.0e-4").replace("command_limit: [10.0]", "command_limit: [2.0]"),
                text.replace("r_rate: 1.0e-6", "r_rate: 1.0e-6\n    velocity_estimate: model"),
                text.replace("horizon: 20", "horizon: 19\n    command_delay: 1")]     # the same preview
    loops = [build_loop(parse_experiment(variant, "mpcc_ellipse.yaml")) for variant in variants]
    batch = simulate_batch(loops)
    for loop, batched in zip(loops, batch):
        alone = simulate(copy.deepcopy(loop))
        np.testing.assert_array_equal(batched.command, alone.command)
        np.testing.assert_array_equal(batched.position, alone.position)
    assert not np.array_equal(batch[0].command, batch[1].command)      # the members differ
    assert not np.array_equal(batch[0].command, batch[2].command)
    assert not np.array_equal(batch[0].command, batch[3].command)
    assert not np.array_equal(batch[0].command, batch[4].command)
    assert all(len(loop.controller.solve_times) == 0 for loop in loops)    # the loops themselves untouched


def test_foot_point_search_batch_counts_each_members_backsteps_and_caps_as_alone():
    text, grid = _settings("paper002_butterfly_c4_foot_point_ccc.yaml", 0.3,
                           {"contour_estimator.max_iterations": [1, 2, 10], "contour_estimator.tolerance": [1e-6, 1e-9]})
    alone = [build_loop(experiment) for _, experiment in combinations(text, grid)]
    for loop in alone:
        simulate(loop)
    batch = [build_loop(experiment) for _, experiment in combinations(text, grid)]
    curve, schedule, plants, servos, estimator, controller = _stacked(batch)
    from contouring_ros.core.interpolation import reference
    caps = [loop.estimator.cap_reached for loop in alone]
    assert min(caps) == 0 < max(caps)            # some members hit their cap, some never
    # the stacked estimator steps each member's own position from its own previous foot point
    position = np.array([[0.021, 0.001]] * len(batch))
    ref = reference(curve, schedule, np.full((len(batch), 1), 0.0))
    import dataclasses
    ref = dataclasses.replace(ref, position=ref.position[:, 0])
    estimate = estimator.step_batch(ref, position)
    for j, loop in enumerate(batch):
        one = loop.estimator.step(reference(loop.curve, loop.schedule, 0.0), position[j])
        assert estimate.theta[j, 0] == one.theta and estimator.iterations[j, 0] == loop.estimator.iterations
        np.testing.assert_array_equal(estimate.vector[j], one.vector)
        assert estimator.cap_reached[j, 0] == loop.estimator.cap_reached


def test_natural_local_and_foot_point_batches_give_the_exact_distance_to_a_line():
    # on a straight line the natural local cubic is the line itself (kappa = 0) and the foot point search
    # lands on the true foot point: both estimates are the exact distance, for every member
    from contouring_ros.core.curves import Line
    from contouring_ros.core.estimators import FootPointSearchEstimator, NaturalLocalEstimator
    from contouring_ros.core.interpolation import Reference
    lines = [Line([0.0, 0.0, 0.0], [0.1, 0.05, 0.02]), Line([0.0, 0.0, 0.0], [0.02, 0.1, -0.03])]
    rng = np.random.default_rng(0)
    theta = np.array([[0.03], [0.06]])
    offsets = rng.normal(scale=1e-3, size=(2, 3))
    foot = np.stack([line.point(float(t)) for line, t in zip(lines, theta[:, 0])])
    direction = np.stack([line.direction for line in lines])
    normal = offsets - np.sum(offsets * direction, axis=1, keepdims=True) * direction     # off the line
    along = np.array([[2e-3], [-1e-3]])
    position = foot + normal + along * direction
    curve = stack(lines)
    ref = Reference(theta=theta, theta_dot=np.zeros((2, 1)), theta_ddot=np.zeros((2, 1)), position=foot,
                    velocity=np.zeros((2, 3)), acceleration=np.zeros((2, 3)))
    for estimator in (stack([NaturalLocalEstimator(line) for line in lines]),
                      stack([FootPointSearchEstimator(line) for line in lines])):
        estimate = estimator.step_batch(ref, position)
        np.testing.assert_allclose(estimate.vector, -normal, atol=1e-15)
        np.testing.assert_allclose(estimate.signed, np.linalg.norm(normal, axis=1), rtol=1e-12)
        np.testing.assert_allclose(estimate.theta, theta + along, rtol=1e-12)
    assert curve.direction.shape == (2, 3)


def test_frenet_frame_of_a_batch_equals_each_parameters_frame():
    from contouring_ros.core.curves import Helix
    from contouring_ros.core.geometry import frenet_frame
    helices = [Helix(0.02, 0.01, 0.005, 3.0, 10.0), Helix(0.03, 0.01, -0.002, 2.0, 8.0)]
    theta, rate, acc = np.array([[0.4], [2.5]]), np.array([[1.0], [0.5]]), np.array([[0.0], [0.2]])
    frame = frenet_frame(stack(helices), theta, rate, acc)
    for j, helix in enumerate(helices):
        one = frenet_frame(helix, theta[j, 0], rate[j, 0], acc[j, 0])
        for name, value in vars(one).items():
            # the rotation's acceleration takes d kappa / dt by a central difference over 1e-5 of the
            # parameter range, which magnifies a last-bit difference of cos on an array and on one float
            tolerance = 1e-10 if name == "rotation_acceleration" else 1e-13
            np.testing.assert_allclose(np.asarray(getattr(frame, name))[j].reshape(np.shape(value)), value,
                                       rtol=tolerance, atol=tolerance * np.max(np.abs(value)), err_msg=name)


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


class _Unbatched(NoCoupling):
    """A controller of one's own (as a plugin's) that does not say it has a batch path."""

    batchable = False


@pytest.fixture
def unbatched_controller():
    """The controller type ``unbatched`` (a :class:`_Unbatched`) registered for one test."""
    CONTROLLERS.register("unbatched", {}, lambda s, c: _Unbatched(c.n_axes))
    yield yaml.safe_dump({**yaml.safe_load(shortened(DEFAULT, 0.2)), "/ccc": {"ros__parameters": {"type": "unbatched"}}})
    del CONTROLLERS._entries["unbatched"]


def test_loops_of_a_class_without_batch_path_are_not_batchable(unbatched_controller):
    loops = _loops(unbatched_controller, ["x/servo.a=10,12.5"])
    assert batch_problem(loops) == "_Unbatched has no batch path" and not batchable(loops)


@pytest.fixture
def newton_batches_from_two(monkeypatch):
    """The Newton estimate batches from two members (below its batch_minimum a sweep runs it one by one)."""
    from contouring_ros.core.estimators import NewtonEstimator
    monkeypatch.setattr(NewtonEstimator, "PURE_BATCH_MINIMUM", 2)
    monkeypatch.setattr(NewtonEstimator, "COMPILED_BATCH_MINIMUM", 2)


def test_sweep_vectorises_each_structure(newton_batches_from_two):
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


def test_sweep_runs_alone_what_has_no_batch_path_and_says_why(unbatched_controller):
    rows = run_sweep(unbatched_controller, parse_grid(["x/servo.a=10,11,12.5,15"]), workers=1)
    assert not any(row.vectorised for row in rows)
    assert {row.alone for row in rows} == {"_Unbatched has no batch path"}     # said, for the CLI to print


def _mce(loop):
    from contouring_ros.records.scoring import score_run
    return score_run(loop.curve, simulate(loop)).mce


def test_sweep_batches_each_structure_apart_when_numbers_change_it(newton_batches_from_two):
    # 0 branch-check samples means no branch check: a different structure from the same-shaped file
    text = shortened(DEFAULT, 0.2)
    rows = run_sweep(text, parse_grid(["ccc.kp=0.5,1,2,4", "contour_estimator.branch_check_samples=0,256"]), workers=1)
    assert len(rows) == 8 and all(row.vectorised for row in rows)


# ------------------------------------------------------------------------------------------ mixed batches


def _scenario_loops(duration=0.3, *, y_servo_pid=False):
    """Loops of four structures along paper 000's h = 50 path (ISMC or PID + feedforward servos, the Newton or
    the tangent-line estimate, the unit-vector or the variable-gain CCC), two members each, interleaved."""
    names = ["paper000_b_ismc_h50_newton.yaml", "paper000_b_ismc_h50_vgccc.yaml", "paper000_a_pidff_h50_newton.yaml",
             "paper000_a_pidff_h50_vgccc.yaml"]
    texts = []
    for name in names:
        data = yaml.safe_load(shortened(CONFIG / name, duration))
        if name.endswith("vgccc.yaml"):
            data["/contour_estimator"]["ros__parameters"] = {"type": "tangent_line"}
        if y_servo_pid and "ismc" in name:     # one axis of another class than the other
            data["/y/servo"]["ros__parameters"] = {"law": "pid_feedforward", "kp": 8.0, "ki": 0.0, "kd": 0.0,
                                                   "gain": 10.0, "time_constant": 0.045}
        texts.append(yaml.safe_dump(data))
    grid = ["ccc.kp=1,2"]
    groups = [_loops(text, grid) for text in texts]
    return [group[j] for j in range(2) for group in groups]      # A B C D A B C D: no class on contiguous rows


@pytest.mark.parametrize("y_servo_pid", [False, True], ids=["same-axes", "axes-of-two-classes"])
def test_a_mixed_batch_gives_each_member_what_a_batch_of_its_own_structure_gives(y_servo_pid):
    from contouring_ros.core.batch import MixedControllers, MixedEstimators, structure
    loops = _scenario_loops(y_servo_pid=y_servo_pid)
    assert len({structure(loop) for loop in loops}) == 4 and batch_problem(loops) is not None
    _, _, plants, servos, estimator, controller = _stacked(loops, mixed=True)
    assert isinstance(estimator, MixedEstimators) and isinstance(controller, MixedControllers)
    mixed = simulate_batch(loops, mixed=True)
    by_structure = {}
    for j, loop in enumerate(_scenario_loops(y_servo_pid=y_servo_pid)):
        by_structure.setdefault(structure(loop), []).append((j, loop))
    for members in by_structure.values():
        own = simulate_batch([loop for _, loop in members])
        for (j, _), run in zip(members, own):
            for name, value in vars(run).items():
                np.testing.assert_array_equal(getattr(mixed[j], name), value, err_msg=name)
    # and the members differ where their classes do: the variable-gain rows are not the unit-vector rows
    assert not np.array_equal(mixed[0].correction, mixed[1].correction)


def test_a_mixed_sweep_gives_each_run_what_the_sweep_by_structure_gives():
    from contouring_ros.studies.sweep import simulate_loops
    loops = _scenario_loops()
    other = _loops(shortened(CONFIG / "paper000_b_ismc_h100_newton.yaml", 0.3), ["ccc.kp=1,2"])  # another curve
    mixed, alone, failures = simulate_loops(loops + other, mixed=True)
    plain, _, _ = simulate_loops(_scenario_loops() + _loops(shortened(CONFIG / "paper000_b_ismc_h100_newton.yaml",
                                                                       0.3), ["ccc.kp=1,2"]))
    assert not any(failures)
    for run, reference in zip(mixed, plain):
        np.testing.assert_allclose(run.position, reference.position, rtol=0, atol=1e-12)


def test_runs_with_and_without_the_eso_disturbance_compensation_share_a_batch_and_differ():
    # paper 004's "without ESO" file only switches d^ off in (24): one batch runs both, each as it runs alone
    def saddle_loops():
        return [loop for name in ("paper004_saddle_eso.yaml", "paper004_saddle_no_eso.yaml")
                for loop in _loops(shortened(CONFIG / name, 0.3), [])]
    loops = saddle_loops()
    assert batch_problem(loops) is None
    together = simulate_batch(loops)
    _assert_equal_runs(together, [simulate(loop) for loop in saddle_loops()])
    assert not np.allclose(together[0].position, together[1].position, rtol=0, atol=1e-9)


def test_benchmark_combinations_give_their_runs_alone_numbers_in_a_batch(capsys):
    """A tuning's points run in batches of whatever size its rounds have: every member must give its run
    alone's numbers bit for bit (tools/check_batches.py over every scenario is the full check). These
    scenarios hold the classes whose batch path once parted in the last bit: the osculating circle, the
    natural-local frames, the ESO's observer, the feedrate schedule's theta_ddot, the task-frame PD."""
    check = load_tool("check_batches")
    code = check.main(["--scenarios", "paper003_ellipse", "paper001_mech_coupling", "paper004_screw_eso", "--points", "2"])
    out = capsys.readouterr().out
    assert code == 0, out
    checked = int(out.rsplit("\n", 2)[-2].split(" combinations checked")[0].split()[-1])
    assert checked >= 20 and " checked, 0 differ or fail," in out, out
