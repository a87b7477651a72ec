"""Feed hold and resume at the experiment's events (contouring_ros/core/feed_control.py): the reference stops on
the path within the plan's bounds, rests, and the rest of the path is planned afresh from there."""
import numpy as np
import pytest

import contouring_ros as cr
from contouring_ros.core.feed_control import parse_feed_events
from contouring_ros.errors import ConfigError
from conftest import CONFIG

EXAMPLE = str(CONFIG / "gcode_example_part.yaml")
A, J, TS = 1.0, 10.0, 1e-3          # the example part's path bounds and sample time


def test_feed_events_are_read_into_steps_and_bad_ones_refused():
    assert parse_feed_events(["hold 1.2", "resume 1.8", "hold 3"], TS) == \
        [(1200, "hold", None), (1800, "resume", None), (3000, "hold", None)]
    for events, fragment in [(["resume 1"], "a hold comes next"), (["hold 2", "resume 1"], "must rise"),
                             (["pause 1"], "expected 'hold T'"), (["override 250% 1"], "0 to 200 %"),
                             (["override fast 1"], "not a percentage"), (["hold x"], "not a time")]:
        with pytest.raises(ValueError, match=fragment):
            parse_feed_events(events, TS)
    with pytest.raises(ConfigError) as error:
        cr.simulate(EXAMPLE, {"feed_events": ["hold 1", "hold 2"]})
    assert "feed_events" in str(error.value) and "\n" not in str(error.value)


@pytest.fixture(scope="module")
def runs():
    return cr.simulate(EXAMPLE), cr.simulate(EXAMPLE, {"feed_events": ["hold 2.5", "resume 3.2"]})


def test_a_hold_stops_on_the_path_rests_resumes_and_finishes(runs):
    plain, held = runs
    result, control = held.result, held.loop.feed_control
    (hold, what, start), (resume, again, rest) = control.events
    assert (hold, what, resume, again) == (2500, "hold", 3200, "resume")
    start_of = {b.line: b.start for b in held.curve.blocks}
    assert start_of[9] < start < rest < start_of[10]             # on the arc of N50, stopped within it
    theta = result.theta
    assert np.all(theta[control.events[0][0]:resume] <= rest) and np.all(theta[resume - 20:resume] == rest)
    assert theta[-1] == held.curve.domain[1]                    # and finished the program
    errors = held.exact_contour_error()
    assert errors[hold:resume].max() <= plain.scores().mce      # the stop stays on the path
    feed = np.diff(theta) / TS
    acceleration = np.diff(feed) / TS
    assert feed.min() >= 0.0 and np.abs(acceleration).max() <= A * (1 + 1e-9)
    assert np.abs(np.diff(acceleration) / TS).max() <= J * (1 + 1e-6)
    waited = (resume - hold) * TS
    assert held.scores().travel_time == pytest.approx(plain.scores().travel_time + waited, abs=0.15)
    assert held.scores().travel_time > plain.scores().travel_time + 0.5


def test_a_resume_before_the_stop_ends_waits_for_it_and_holds_repeat():
    run = cr.simulate(EXAMPLE, {"feed_events": ["hold 2.5", "resume 2.501", "hold 4.0", "resume 4.3"]})
    (hold, _, _), (resume, _, rest), (second, what, _), (again, _, _) = run.loop.feed_control.events
    assert resume > hold + 5 and run.result.theta[resume] == rest      # resumed from rest, not on the way
    assert what == "hold" and again - second == 300
    assert run.result.theta[-1] == run.curve.domain[1]


@pytest.mark.graph
@pytest.mark.slow
def test_the_graph_holds_and_resumes_as_the_simulation_does(tmp_path):
    from conftest import assert_graph_equals_simulation, example_part_with_feed_events
    from contouring_ros.run.runner import run_graph
    path = example_part_with_feed_events(tmp_path, ["hold 0.3", "resume 0.6", "hold 2.5", "resume 2.7"], "held")
    assert_graph_equals_simulation(path, run_graph(path, tmp_path / "held.mcap"))


def test_feed_png_marks_each_hold_where_it_came(runs, tmp_path):
    from contouring_ros.records.figures import figures
    from contouring_ros.records.bag_writer import write_simulation
    from contouring_ros.records.scoring import read_run
    _, held = runs
    bag = write_simulation(tmp_path / "held.mcap", held.experiment, held.result)
    top = figures([("held", read_run(bag))])["feed"].axes[0]
    marks = [text for text in top.texts if text.get_text() == "hold 2.5 s"]
    assert len(marks) == 1 and marks[0].xy[0] == pytest.approx(held.result.theta[2500] * 1e3)     # mm
