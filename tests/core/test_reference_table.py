"""The reference table: runs along one path (curve, schedule, sample time) share each step's reference,
computed once, and get the numbers they would compute themselves, bit for bit."""
import copy
import pickle

import numpy as np
import pytest

from contouring_ros.config import build_loop, parse_experiment
from contouring_ros.core.batch import simulate_batch
from contouring_ros.core.geometry import frenet_frame
from contouring_ros.core.interpolation import at_reference, reference, reference_ahead, step_time
from contouring_ros.core.simulation import simulate
from contouring_ros.experiment.build import build_path
from contouring_ros.studies.sweep import combinations
from contouring_ros.experiment.settings import parse_grid
from conftest import CONFIG, DEFAULT, shortened


def _experiments(text, specs):
    return [experiment for _, experiment in combinations(text, parse_grid(specs))]


def _loops(experiments, table=True):
    loops = [build_loop(e) for e in experiments]
    if not table:
        for loop in loops:
            loop.reference_table = None
    return loops


def _assert_identical(runs, others):
    for run, other in zip(runs, others, strict=True):
        for name, value in vars(other).items():
            assert np.array_equal(getattr(run, name), value), name


# a uniform schedule (the default experiment), feedrate schedules on the butterfly and the helix, servos
# that read the reference ahead (ZPETC), a controller that does (MPCC), three axes (the saddle); each grid
# varies gains and plants only, so that every run is on one path
@pytest.mark.parametrize("name, specs", [
    ("paper000_b_ismc_h50_newton.yaml", ["ccc.kp=0.5,4", "y/plant.time_constant=0.03,0.045"]),
    ("paper002_butterfly_c3_tvt.yaml", ["ccc.kc=100,140"]),
    ("paper002_butterfly_zpetc.yaml", ["x/servo.kp=50,80"]),
    ("mpcc_ellipse.yaml", ["ccc.q_contour=1e5,1e6"]),
    ("paper004_saddle_eso.yaml", ["x/servo.k=50,80"]),
    # the Frenet frames and derivatives at the reference point that at_reference keeps per step
    ("paper003_helix_natural_local_f15_10.yaml", ["ccc.f_n=12,15"]),
    ("paper001_caseII_adaptive_tnb.yaml", ["ccc.alpha=30,40"]),
    ("paper002_butterfly_c2_osculating_circle.yaml", ["ccc.kp=100,140"]),
    ("paper002_butterfly_c1_tangent_line.yaml", ["ccc.kp=100,140"]),
], ids=["uniform-newton", "feedrate-butterfly", "zpetc-preview", "mpcc-preview", "saddle-3-axes", "task-frame-helix",
        "adaptive-tnb", "osculating-circle", "tangent-line"])
def test_runs_reading_the_table_equal_runs_computing_their_reference(name, specs):
    experiments = _experiments(shortened(CONFIG / name, 0.3), specs)
    loops = _loops(experiments)
    assert loops[0].reference_table is not None
    assert all(loop.reference_table is loops[0].reference_table for loop in loops)
    computed = [simulate(loop) for loop in _loops(experiments, table=False)]
    _assert_identical([simulate(loop) for loop in loops], computed)          # the first fills the table
    _assert_identical([simulate(loop) for loop in _loops(experiments)], computed)   # the others read it
    _assert_identical(simulate_batch(_loops(experiments)), simulate_batch(_loops(experiments, table=False)))


def test_a_table_entry_is_the_reference_of_its_step_and_read_only():
    experiment = parse_experiment(shortened(CONFIG / "paper002_butterfly_c3_tvt.yaml", 0.2))
    curve, schedule, table = build_path(experiment)
    ts = experiment.sample_time
    for k in (150, 3, 0, 199):                  # in any order
        ref, expected = table.at(k), reference(curve, schedule, step_time(k, ts))
        for name in ("theta", "theta_dot", "theta_ddot", "position", "velocity", "acceleration"):
            assert np.array_equal(getattr(ref, name), getattr(expected, name)), name
        assert np.array_equal(table.ahead(k, 4), reference_ahead(curve, schedule, k, step_time(k, ts), 4, ts).position)
        with pytest.raises(ValueError):
            ref.position[0] = 1.0
        with pytest.raises(ValueError):
            table.row(k).position[0, 0] = 1.0


def test_only_runs_along_the_same_path_share_a_table(tmp_path):
    text = shortened(DEFAULT, 0.2)
    gains = _experiments(text, ["ccc.kp=0.5,4"])
    assert build_path(gains[0]) is build_path(gains[1])
    other_curve, other_schedule = (_experiments(text, [spec])[0] for spec in ("curve.h=40", "schedule.duration=1.5"))
    tables = {id(build_path(e)[2]) for e in (gains[0], other_curve, other_schedule)}
    assert len(tables) == 3
    # a part program is read from its file, and its exact stops give each run its own reference times
    part = parse_experiment((CONFIG / "gcode_example_part.yaml").read_text(), str(CONFIG / "gcode_example_part.yaml"))
    assert build_path(part)[2] is None and build_loop(part).reference_table is None


def test_a_table_is_shared_by_copies_and_starts_afresh_in_another_process():
    loop = build_loop(parse_experiment(shortened(DEFAULT, 0.1)))
    table = loop.reference_table
    table.at(20)
    assert copy.deepcopy(loop).reference_table is table
    again = pickle.loads(pickle.dumps(table))
    assert again is not table and np.array_equal(again.at(20).position, table.at(20).position)


def test_a_plugin_curve_gets_no_table(monkeypatch):
    import dataclasses
    from contouring_ros.config import CURVES
    experiment = parse_experiment(shortened(DEFAULT, 0.1))
    parabola = CURVES.entry("parabola")
    monkeypatch.setitem(CURVES._entries, "parabola", dataclasses.replace(parabola, origin="a_plugin_package"))
    assert build_path(experiment)[2] is None


def test_what_is_computed_at_a_tabled_reference_is_computed_once_per_step_and_read_only():
    experiment = parse_experiment(shortened(CONFIG / "paper003_helix_natural_local_f15_10.yaml", 0.1))
    curve, schedule, table = build_path(experiment)
    calls = []

    def frame(*arguments):
        calls.append(arguments)
        return frenet_frame(*arguments)
    ref = table.at(40)
    arguments = (curve, float(ref.theta), float(ref.theta_dot), float(ref.theta_ddot))
    first, again = at_reference(ref, frame, *arguments), at_reference(table.at(40), frame, *arguments)
    assert again is first and len(calls) == 1
    expected = frenet_frame(*arguments)
    assert np.array_equal(first.rotation_acceleration, expected.rotation_acceleration)
    with pytest.raises(ValueError):
        first.rotation[0, 0] = 1.0
    at_reference(table.at(41), frame, curve, float(table.at(41).theta), 0.0, 0.0)      # another step: its own
    assert len(calls) == 2
    # a reference that is not the table's (a node's, a batch's) is computed each time
    alone = reference(curve, schedule, step_time(40, experiment.sample_time))
    at_reference(alone, frame, *arguments)
    at_reference(alone, frame, *arguments)
    assert len(calls) == 4


def test_a_batch_along_a_path_reads_its_curve_and_schedule_as_they_are():
    from contouring_ros.core.batch import stack
    loop = build_loop(parse_experiment(shortened(DEFAULT, 0.1)))
    assert stack([loop.curve, loop.curve]) is loop.curve
    assert stack([loop.schedule, loop.schedule]) is loop.schedule
    plant = loop.plants[0]           # a plant's state is the batch's own
    assert stack([plant, plant]) is not plant
