"""Feed override at the experiment's events (contouring_ros/core/feed_control.py): the rest of the path is planned
afresh with the new feeds from the state of the reference, within the acceleration and jerk bounds."""
import numpy as np
import pytest

import contouring_ros as cr
from contouring_ros.core.feed_control import parse_feed_events
from contouring_ros.core.feed_planning import scurve_time
from conftest import CONFIG

EXAMPLE = str(CONFIG / "gcode_example_part.yaml")
A, J, TS = 1.0, 10.0, 1e-3          # the example part's path bounds and sample time
STEPS = ["override 50% 1.0", "override 150% 2.5"]


@pytest.fixture(scope="module")
def stepped():
    return cr.simulate(EXAMPLE, {"feed_events": STEPS})


def limits(run, override):
    """Each block's feed limit under ``override`` (a fraction), from the run's own plan."""
    return np.array([limit.feed for limit in run.loop.schedule.rest_of_path(0.0, override).limits])


def test_an_override_step_keeps_feed_under_override_times_f_and_every_bound(stepped):
    result, control = stepped.result, stepped.loop.feed_control
    assert [(k, what) for k, what, _ in control.events] == [(1000, "override 50%"), (2500, "override 150%")]
    theta = result.theta
    feed = np.linalg.norm(result.reference_velocity, axis=1)
    starts = np.array([b.start for b in stepped.curve.blocks])
    block = np.clip(np.searchsorted(starts, theta, side="right") - 1, 0, len(starts) - 1)
    full, half, more = (limits(stepped, f)[block] for f in (1.0, 0.5, 1.5))
    slack = 1 + 1e-9
    # before: the plan's feeds; after each step, at most the higher of the two while the feed comes down
    # (one jerk-limited change of speed from the acceleration it had), then at most the new override's
    settle = int(np.ceil((A / J + scurve_time(0.5 * full.max(), A, J)) / TS))
    assert np.all(feed[:1000] <= full[:1000] * slack)
    assert np.all(feed[1000:2500] <= full[1000:2500] * slack)
    assert np.all(feed[1000 + settle:2500] <= half[1000 + settle:2500] * slack)
    assert np.all(feed[2500:] <= more[2500:] * slack)
    # and the override took effect: 50 % of F, then above F where 150 % of it is allowed
    assert feed[1000 + settle:2500].max() == pytest.approx(half[1000 + settle:2500].max(), rel=1e-6)
    assert np.any(feed[2500:] > 1.4 * full[2500:])
    path_feed = np.diff(theta) / TS
    acceleration = np.diff(path_feed) / TS
    assert path_feed.min() >= 0.0 and np.abs(acceleration).max() <= A * (1 + 1e-9)
    assert np.abs(np.diff(acceleration) / TS).max() <= J * (1 + 1e-6)
    assert theta[-1] == stepped.curve.domain[1]                      # and finished the program
    plain = cr.simulate(EXAMPLE)
    assert stepped.exact_contour_error().max() <= 1.5 * plain.scores().mce


def test_an_override_of_zero_stops_on_the_path_and_the_next_one_resumes():
    run = cr.simulate(EXAMPLE, {"feed_events": ["override 0% 1.0", "override 100% 1.5"]})
    control, theta = run.loop.feed_control, run.result.theta
    (stop, what, start), (again, _, _), (resume, how, rest) = control.events
    assert (stop, what, again, resume, how) == (1000, "override 0%", 1500, 1500, "resume")
    assert np.all(theta[1200:1500] == rest) and rest > start
    assert theta[-1] == run.curve.domain[1]
    acceleration = np.diff(theta, 2) / TS**2
    assert np.abs(acceleration).max() <= A * (1 + 1e-9)


def test_an_override_during_a_hold_sets_the_feed_of_the_resume():
    run = cr.simulate(EXAMPLE, {"feed_events": ["hold 1.0", "override 50% 1.2", "resume 1.5"]})
    feed = np.linalg.norm(run.result.reference_velocity, axis=1)
    lines = limits(run, 1.0)[0]                 # F1200 of the first blocks, 20 mm/s
    assert feed[:1000].max() == pytest.approx(lines) and feed[1500:].max() == pytest.approx(0.5 * lines)


@pytest.mark.graph
@pytest.mark.slow
def test_the_graph_overrides_as_the_simulation_does(tmp_path):
    from conftest import assert_graph_equals_simulation, example_part_with_feed_events
    from contouring_ros.run.runner import run_graph
    path = example_part_with_feed_events(tmp_path, ["override 50% 0.8", "override 150% 1.6"], "override")
    assert_graph_equals_simulation(path, run_graph(path, tmp_path / "override.mcap"))


def test_feed_png_marks_each_override_where_it_came(stepped, tmp_path):
    from contouring_ros.records.figures import figures
    from contouring_ros.records.bag_writer import write_simulation
    from contouring_ros.records.scoring import read_run
    bag = write_simulation(tmp_path / "override.mcap", stepped.experiment, stepped.result)
    top = figures([("override", read_run(bag))])["feed"].axes[0]
    for label, step in (("50% 1 s", 1000), ("150% 2.5 s", 2500)):
        marks = [text for text in top.texts if text.get_text() == label]
        assert len(marks) == 1 and marks[0].xy[0] == pytest.approx(stepped.result.theta[step] * 1e3)     # mm
    # the dashed limit follows the override: F1200 of the first lines, 600 from the 50 % step, 1800 on N40's F1200
    # line after the 150 % step, each from where the reference was then
    limits = [patch.get_data() for patch in top.patches]
    assert [float(data.values[0]) for data in limits] == pytest.approx([1200.0, 600.0, 1800.0])
    assert [float(data.edges[0]) for data in limits[1:]] == pytest.approx(
        [stepped.result.theta[1000] * 1e3, stepped.result.theta[2500] * 1e3])


def live_theta(commands: dict, events=(), steps: int = 4000) -> tuple:
    """theta of each step of the example part's reference with the timed ``events`` (the axes never in position: the in-position waits
    run to their timeout) with ``commands`` {step: [(what, percent), ...]} given to the FeedControl as the
    realtime interpolator's services and topic give them, while the step before was the latest computed;
    and the answers."""
    from contouring_ros.config import load_experiment
    from contouring_ros.experiment.build import build_clock, build_feed_control, build_path
    experiment = load_experiment(EXAMPLE)
    curve, schedule, _ = build_path(experiment)
    clock = build_clock(experiment, curve, schedule)
    control = build_feed_control(experiment, curve, schedule, clock, None, live=True)
    control.queue = parse_feed_events(events, TS)            # the file's timed events
    theta, answers = [], []
    for k in range(steps):
        for what, percent in commands.get(k, ()):
            answers.append(control.command(what, percent))
        theta.append(float(control.reference(k).theta))
    return np.array(theta), answers


def test_commands_while_running_act_as_the_same_timed_events():
    timed, _ = live_theta({}, ["hold 1.0", "override 50% 1.4", "resume 1.6", "override 150% 2.6"])
    live, answers = live_theta({1000: [("hold", None)], 1400: [("override", 50.0)], 1600: [("resume", None)],
                                2600: [("override", 150.0)]})
    assert all(ok for ok, _ in answers) and answers[0][1] == "hold at step 1000"
    np.testing.assert_array_equal(live, timed)
    plain, _ = live_theta({})
    assert not np.array_equal(live, plain)


def test_commands_that_cannot_act_are_refused_with_one_line():
    _, answers = live_theta({10: [("resume", None), ("override", 250.0), ("hold", None), ("hold", None)]}, steps=20)
    assert [ok for ok, _ in answers] == [False, False, True, False]
    assert answers[0][1] == "resume refused: no feed hold to resume"
    assert "0 to 200 %" in answers[1][1] and answers[3][1] == "hold refused: the feed is held already"
