"""The in-position check at exact stops (core/interpolation.py, InPositionClock): the reference waits at a
corner until every axis is in position; the wait's numbers, its purpose, and the graph's identity with the
in-process simulation."""
import re
from types import SimpleNamespace

import numpy as np
import pytest

from contouring_ros.config import build_loop, load_experiment
from contouring_ros.core.curves import ToolPath
from contouring_ros.core.feed_planning import FeedPlan
from contouring_ros.core.gcode import parse_program
from contouring_ros.core.interpolation import SETTLE, InPositionClock
from contouring_ros.core.simulation import simulate
from contouring_ros.records.scoring import score_run
from conftest import CONFIG

TS = 1e-3


def test_the_clock_runs_with_the_steps_until_a_stop_then_holds_until_in_position():
    schedule = SimpleNamespace(stops=np.array([[0.0105, 0.01]]))
    curve = SimpleNamespace(point=lambda s: np.column_stack([s, np.zeros_like(s)]))
    clock = InPositionClock(schedule, curve, [1e-5, 2e-5], TS, 0.5, delay=2)
    assert [clock.time(k) for k in range(11)] == [k * TS for k in range(11)]       # k Ts exactly
    assert clock.time(11) == 0.0105                                # arrives at the stop: rests on the corner
    far, near, still = [0.00995, 0.0], [0.009995, 1.5e-5], [0.0, 0.0]
    assert clock.time(12, far, still) == 0.0105                    # 50 um short in x
    assert clock.time(13, near, [1e-5 / SETTLE * 1.01, 0.0]) == 0.0105     # within, but passing through
    assert clock.time(14, near, still) == pytest.approx(0.0115)   # in position: the plan runs on
    assert clock.time(15, far, still) == pytest.approx(0.0125)
    assert clock.waits == [(0, 3)]
    timeout = InPositionClock(schedule, curve, [1e-5, 1e-5], TS, 0.005, delay=2)
    times = [timeout.time(k, far, still) for k in range(25)]
    assert times[11:16] == [0.0105] * 5 and times[16] == pytest.approx(0.0115)   # gives up after 5 steps


def test_the_plan_lists_its_exact_stops_with_their_corners():
    path = ToolPath.from_program(parse_program("G1 X10 F1200\nY10\nG64 P0.01\nX0\nY0\nG9 X-5\nY-5\nG4 P0.2\n"
                                               "X-10"))
    plan = FeedPlan(path, 1.0, 20.0)
    # the two corners of the default exact stop (G61), then G64 blends round (0, 10) and (0, 0); G9 stops at
    # the end of its block, the dwell after its block
    corners = [path.point(s) for s in plan.stops[:, 1]]
    np.testing.assert_allclose(corners, [[0.01, 0.0], [0.01, 0.01], [-0.005, 0.0], [-0.005, -0.005]], atol=1e-12)
    for t, s in plan.stops:
        assert plan(t) == (pytest.approx(s), 0.0, 0.0)


def square_experiment(tmp_path, base, window, side_mm=50, feed=3000, duration=None, observer=True):
    """A square of side ``side_mm`` at F``feed`` (mm/min) then an arc, on the axes of scenario ``base``, with
    the in-position window ``window`` [m]; ``observer`` False: its ISMC servos without the disturbance
    estimate of paper 000 eq. 24-26; "paper": with the estimate as the paper gives it (eq. 25 without the plan
    correction a tool path gets by default, observer_plan_correction)."""
    (tmp_path / "square.ngc").write_text(f"G21 G90 G17\nG1 X{side_mm} Y0 F{feed}\nY{side_mm}\nX0\nY0\n"
                                         f"G2 X{side_mm / 2.5} Y0 R{side_mm / 5}\nM30\n")
    text = (CONFIG / f"{base}.yaml").read_text()
    text = re.sub(r"curve: \{[^}]*\}", "curve: {type: gcode, file: square.ngc}", text)
    text = re.sub(r"schedule: \{[^}]*\}", "schedule: {type: feedrate, acceleration: 1.0, jerk: 10.0}", text)
    text = re.sub(r"    duration: [0-9.]+\n", "", text)
    if observer == "paper":
        text = text.replace("observer: true", "observer: true\n    observer_plan_correction: false")
    elif not observer:
        text = text.replace("observer: true", "observer: false")
    given = f"    duration: {duration}\n" if duration else ""
    text = text.replace("    sample_time:", f"    in_position: [{window}]\n{given}    sample_time:", 1)
    path = tmp_path / f"square_{window}_{observer}.yaml"
    path.write_text(text)
    return path


def test_waiting_in_position_lowers_the_contour_error_round_the_corners(tmp_path):
    """On the ISMC axes of paper 000 (b) with the paper's disturbance estimate the axes lag 0.2 mm as the
    reference stops at a corner; moving on at once cuts the corner, waiting until they are in position does
    not."""
    runs = {}
    for window in (0.0, 1e-5):
        loop = build_loop(load_experiment(square_experiment(tmp_path, "paper000_b_ismc_h50_newton", window,
                                                            observer="paper")))
        result = simulate(loop)
        runs[window] = loop, result, score_run(loop.curve, result)
    (plain_loop, plain, plain_scores), (loop, waited, scores) = runs[0.0], runs[1e-5]
    assert plain_loop.clock is None and len(loop.clock.waits) == 4
    assert all(steps > 50 for _, steps in loop.clock.waits)          # the ISMC axes take over 50 ms to settle
    assert scores.mce < 0.6 * plain_scores.mce
    # the wait shows in time: the reference reaches the program's end that much later
    end = [result.time[np.argmax(result.theta >= loop.curve.domain[1] - 1e-9)] for result in (plain, waited)]
    assert end[1] - end[0] == pytest.approx(sum(steps for _, steps in loop.clock.waits) * TS, abs=5 * TS)


def test_the_papers_disturbance_estimate_reads_the_plans_jerk_as_a_load():
    """Paper 000 eq. 24-26 differentiates the velocity through c / (s + c) but subtracts the command T
    unfiltered, so on the exact axis of eq. 2 xi - D = (tau / k)(c s / (s + c) - s) V: zero at constant acceleration
    (the paper's parabola, R2'' = 2 h theta'^2), -(tau / k) J / c once a jerk J has lasted a few 1 / c. With
    paper 000 (b)'s x axis (k 10.3, tau 40 ms, c = d = 25) and the feed plan's 10 m/s^3 that is 1.55e-3
    command units, ten times the load bound 1.5e-4 the estimate is there to remove."""
    from contouring_ros.core.servo import DisturbanceObserver
    k, tau, c, load = 10.3, 0.040, 25.0, 1.5e-4
    decay = np.exp(-TS / tau)
    for jerk, acceleration in ((0.0, 0.04), (10.0, 0.0), (-10.0, 0.0)):
        observer = DisturbanceObserver(c, c, k, tau, TS, velocity=0.0, acceleration=acceleration)
        observer.estimate = observer.previous_command = load
        velocity = 0.0
        for i in range(301):                             # 0.3 s: c t = 7.5, both filters settled
            estimate = observer.update(velocity)
            # the feedforward (tau R'' + R') / k less the load, held over the step on the exact axis of eq. 2,
            # tau V' + V = k (T + D)
            command = (tau * (acceleration + jerk * i * TS) + velocity) / k - load
            velocity = decay * velocity + (1.0 - decay) * k * (command + load)
            observer.previous_command = command
        # plus A Ts / k: eq. 25 sampled pairs V_k with the command held over the step before
        expected = -(tau / k) * jerk / c + (acceleration + jerk * 0.3) * TS / k
        assert estimate - load == pytest.approx(expected, rel=0.02), (jerk, estimate)


def _estimate_error(jerk: float, acceleration: float, plan_correction: bool) -> float:
    """Delta - D after 0.3 s on the exact axis of eq. 2 (paper 000 (b)'s x axis) driven by the feedforward of a
    reference of constant ``jerk`` from ``acceleration``, the observer given that reference."""
    from contouring_ros.core.servo import DisturbanceObserver
    k, tau, c, load = 10.3, 0.040, 25.0, 1.5e-4
    decay = np.exp(-TS / tau)
    observer = DisturbanceObserver(c, c, k, tau, TS, velocity=0.0, acceleration=acceleration,
                                   plan_correction=plan_correction)
    observer.estimate = observer.previous_command = load
    velocity = ref_vel = 0.0
    for i in range(301):
        ref_acc = acceleration + jerk * i * TS
        estimate = observer.update(velocity, ref_vel, ref_acc)
        command = (tau * ref_acc + velocity) / k - load
        velocity = decay * velocity + (1.0 - decay) * k * (command + load)
        ref_vel += ref_acc * TS + jerk * TS * TS / 2
        observer.previous_command = command
    return estimate - load


def test_the_plan_correction_removes_the_jerk_read_as_load_and_leaves_constant_acceleration_alone():
    """observer_plan_correction adds eq. 25's filter mismatch computed on the reference: under the plan's
    10 m/s^3 the estimate's error falls from about (tau / k) J / c = 1.3e-3 to under 15% of it (what is left
    is the A Ts / k of the sampled pairing, here at A = 3 m/s^2); at the paper's constant acceleration it
    is the paper's estimate. A flipped sign of the correction doubles the error instead."""
    for jerk in (10.0, -10.0):
        paper, corrected = _estimate_error(jerk, 0.0, False), _estimate_error(jerk, 0.0, True)
        assert abs(paper) > 1.2e-3 and abs(corrected) < 0.15 * abs(paper), (jerk, paper, corrected)
    paper, corrected = _estimate_error(0.0, 0.04, False), _estimate_error(0.0, 0.04, True)
    assert abs(corrected) <= abs(paper) + 1e-7 and abs(paper) < 5e-6, (paper, corrected)


def test_exact_stop_corners_on_the_ismc_axes_come_from_the_disturbance_estimate(tmp_path):
    """The 50 mm square at F3000 (acceleration 1, jerk 10) on paper 000 (b)'s ISMC axes with the in-position
    check: with the paper's disturbance estimate the axes overshoot each corner by over 40 um while the
    reference rests there and wait about 200 steps; the same ISMC (eq. 22) without the estimate keeps every
    corner within 5 um and is in position within 2 steps. The overshoot is the estimate's, not the
    integral sliding surface's or the clock's. With the plan correction (a tool path's default) the estimate
    stays and the corners are as without it."""
    from contouring_ros.records.blocks import block_results
    corners = {}
    for observer in ("paper", False, True):
        loop = build_loop(load_experiment(square_experiment(tmp_path, "paper000_b_ismc_h50_newton", 1e-5,
                                                            observer=observer)))
        rows = block_results(loop.curve, simulate(loop), loop.schedule)
        corners[observer] = [row.max_contour_error for row in rows[1:4]], [steps for _, steps in loop.clock.waits]
    (paper, paper_waits), (plain, plain_waits) = corners["paper"], corners[False]
    assert min(paper) > 40e-6 and min(paper_waits) > 150, corners
    assert max(plain) < 5e-6 and max(plain_waits) <= 2, corners
    corrected, corrected_waits = corners[True]        # the estimate kept, the plan's jerk not read as load
    assert max(corrected) < 5e-6 and max(corrected_waits) <= 2, corners


@pytest.mark.graph
@pytest.mark.slow
@pytest.mark.parametrize("observer", ["paper", True])
def test_the_graph_waits_as_the_simulation_does(tmp_path, observer):
    """The interpolator node takes every axis state and waits at each exact stop on the states of the
    step it is paced by: the graph records what the in-process simulation computes, bit for bit (with the
    paper's estimate, whose axes wait, and with the plan correction a tool path's servos get by default)."""
    from conftest import assert_graph_equals_simulation as _assert_identical
    from contouring_ros.run.runner import run_graph
    path = square_experiment(tmp_path, "paper000_b_ismc_h50_newton", 1e-5, side_mm=2, feed=600, duration=1.2,
                             observer=observer)
    loop = build_loop(load_experiment(path))
    simulate(loop)
    assert len(loop.clock.waits) >= 2
    assert all(steps > 5 for _, steps in loop.clock.waits) if observer == "paper" else True
    _assert_identical(path, run_graph(path, tmp_path / "square.mcap"))
