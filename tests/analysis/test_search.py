"""The tuning's global search (IPOP-CMA-ES over the unit box) on functions whose minimum is known, and the
rule that says whether independent searches agree."""
import math

import numpy as np
import pytest

from contouring_ros.studies.search import IPOPCMAES, Poll, agreement, ipop_cmaes, run_side_by_side
from contouring_ros.studies.tuning import Protocol
from conftest import load_tool

PROTOCOL = Protocol()


def search(objective, start, budget, seed):
    """The benchmark's search (its population, first step, design and poll) on ``objective``."""
    return ipop_cmaes(objective, start, budget, seed, PROTOCOL.popsize, PROTOCOL.step, design=PROTOCOL.design,
                      polish=round(PROTOCOL.polish * budget), polish_step=PROTOCOL.polish_step)

VALLEY_MINIMUM = np.array([0.7, 0.3, 0.55])
WITHIN_5_PERCENT = math.log10(1.05)      # the tuning's objective is log10 of a TACE: 5% of it is this


def valley(points):
    """log10 of a TACE-like error over a narrow curved valley (1:1000 across it) whose only minimum, 1 (log 0),
    is at VALLEY_MINIMUM."""
    out = []
    for x in points:
        d = np.asarray(x) - VALLEY_MINIMUM
        along, across = d[0] + d[1], d[1] - d[0] - 2.0 * (d[0] + d[1]) ** 2
        out.append(float(math.log10(1.0 + along ** 2 + 1e3 * across ** 2 + 10.0 * d[2] ** 2)))
    return out


SHALLOW, DEEP = np.array([0.2, 0.25, 0.2]), np.array([0.75, 0.8, 0.7])


def basins(points):
    """log10 of a TACE-like error with two basins: a broad one around the start (floor 2) and a narrower,
    deeper one elsewhere (floor 1, log 0)."""
    out = []
    for x in points:
        x = np.asarray(x)
        out.append(float(math.log10(min(2.0 + 20.0 * np.sum((x - SHALLOW) ** 2), 1.0 + 15.0 * np.sum((x - DEEP) ** 2)))))
    return out


#: a search's budget on the valley: 54 generations of the benchmark's population after its design
VALLEY_BUDGET = PROTOCOL.design + 54 * PROTOCOL.popsize


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_it_follows_a_narrow_valley_to_its_minimum(seed):
    trace = search(valley, [0.1, 0.9, 0.1], VALLEY_BUDGET, seed)
    point, value = trace.best
    assert trace.evaluations <= VALLEY_BUDGET
    assert valley([[0.1, 0.9, 0.1]])[0] > 3.0 and value < WITHIN_5_PERCENT      # 1442x the floor at the start
    d = point - VALLEY_MINIMUM
    assert abs(d[1] - d[0] - 2.0 * (d[0] + d[1]) ** 2) < 0.01                  # on the valley's floor


@pytest.mark.parametrize("seed", [1, 2, 3, 4])
def test_restarts_with_growing_populations_find_the_deeper_of_two_basins(seed):
    """Started in the broad basin, the search finds the deeper one (its design's quasi-random points
    reach it, and restarts from elsewhere), within the benchmark's budget of a search."""
    trace = search(basins, SHALLOW, PROTOCOL.evaluations, seed)
    point, value = trace.best
    assert basins([SHALLOW])[0] == pytest.approx(math.log10(2.0))
    assert value < WITHIN_5_PERCENT and np.max(np.abs(point - DEEP)) < 0.05


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_the_poll_walks_a_narrow_curved_valley_to_its_minimum(seed):
    """From a point on the valley's floor 51x its minimum's value, the pattern search alone (its coordinate
    steps are all across the curved floor) reaches within 5% of the minimum in 400 evaluations."""
    d = np.array([-0.2, -0.2, 0.0])
    for _ in range(50):                         # onto the floor: d1 - d0 = 2 (d0 + d1)^2
        d[1] = d[0] + 2.0 * (d[0] + d[1]) ** 2
    start = VALLEY_MINIMUM + d
    poll = Poll(start, valley([start])[0], PROTOCOL.polish_step, None, np.random.default_rng(seed))
    spent = 0
    while not poll.done and spent < 400:
        points = poll.ask()
        values = valley(points)
        spent += len(points)
        assert all(0.0 <= v <= 1.0 for x in points for v in x)
        poll.tell(points, values)
    assert valley([start])[0] > math.log10(50.0) and poll.value < WITHIN_5_PERCENT


def test_the_last_share_of_a_search_polls_its_best_point_and_never_loses_it():
    budget, polish = 200, 50
    search = IPOPCMAES(SHALLOW, budget, 1, 8, 0.25, polish=polish)
    best_before = None
    while not search.done:
        if search.polishing and best_before is None:
            best_before = search.trace.best[1]
            assert search.trace.evaluations == budget - polish       # the global phase ended where the poll begins
        search.tell(basins(search.ask()))
    assert best_before is not None and search.trace.evaluations <= budget
    assert search.trace.best[1] <= best_before
    # a poll ends once its step is below the resolution, with the budget unspent where that comes first
    flat = IPOPCMAES([0.5, 0.5], 400, 1, 8, 0.25, polish=300)
    while not flat.done:
        flat.tell([0.0 for _ in flat.ask()])
    assert flat.polishing and flat.trace.evaluations < 400


def test_restarts_double_the_population():
    trace = ipop_cmaes(basins, SHALLOW, 400, 1, popsize=8)
    assert len(trace.populations) >= 2 and trace.populations[:2] == [8, 16]


def test_the_box_and_the_budget_are_kept_and_the_seed_decides_every_draw():
    seen = []

    def slope(points):
        seen.extend(points)
        return [-float(x[0]) for x in points]
    trace = search(slope, [0.5, 0.5], 100, 7)
    assert trace.evaluations == len(seen) == 100
    assert all(0.0 <= v <= 1.0 for x in seen for v in x)
    assert trace.best[0][0] > 0.99
    again = search(slope, [0.5, 0.5], 100, 7)
    assert [list(p) for p in again.points] == [list(p) for p in trace.points]
    other = search(slope, [0.5, 0.5], 100, 8)
    assert [list(p) for p in other.points] != [list(p) for p in trace.points]


def test_searches_side_by_side_share_each_round_and_end_as_they_would_alone():
    alone = [ipop_cmaes(valley, [0.1, 0.9, 0.1], 120, seed) for seed in (1, 2)]
    together = [IPOPCMAES([0.1, 0.9, 0.1], 120, seed) for seed in (1, 2)]
    rounds = []

    def objective(asked):
        rounds.append([len(points) for points in asked])
        return [valley(points) for points in asked]
    run_side_by_side(together, objective)
    assert all(len(r) == 2 for r in rounds[:5])          # both searches' populations in one call
    for a, b in zip(alone, together):
        assert b.trace.values == a.values


def test_a_short_search_is_not_converged_and_long_ones_are():
    starts = [[0.1, 0.9, 0.1], [0.9, 0.1, 0.9], [0.5, 0.95, 0.05]]
    short = [ipop_cmaes(valley, start, 12, seed).best[1] for seed, start in enumerate(starts, 1)]
    long = [search(valley, start, VALLEY_BUDGET, seed).best[1] for seed, start in enumerate(starts, 1)]
    # compared as the tuning compares its searches: by the TACE, 10^value
    assert not agreement([10.0 ** v for v in short]).converged
    assert agreement([10.0 ** v for v in long]).converged


def test_the_agreement_rule():
    assert agreement([1.0, 1.04, 1.049]).converged
    assert agreement([1.0, 1.04, 1.06]) .agreed == 2 and not agreement([1.0, 1.04, 1.06]).converged
    four = agreement([2.0, 1.0, 1.03, 1.01])
    assert four.converged and four.agreed == 3 and four.searches == 4 and four.spread == 2.0
    nothing = agreement([math.inf, math.nan, math.inf])
    assert not nothing.converged and nothing.agreed == 0
    partial = agreement([1.0, 1.0, 1.0, math.inf])
    assert partial.converged and partial.spread == math.inf
    assert "3 of 4 searches within 5% of the best" in partial.describe()


def test_checkpoint_status_lists_the_values_a_rows_searches_were_compared_by():
    """tools/checkpoint_status.py: a row whose searches found robust points lists their nominal TACE; a row
    where none did lists the lowest objective each search reached, as a TACE, which the agreement judged (not
    the nominal TACE nor the worst case of its not-robust choice, which can lie far apart at one optimum)."""
    from contouring_ros.studies.tuning import Evaluation, Outcome, Tuned
    status = load_tool("checkpoint_status")

    def evaluation(search, tace, worst, admissible, objective=None):
        failure = "" if admissible else "not robust: worst case over the perturbations"
        objective = math.log10(tace * 1e6) if objective is None else objective
        return Evaluation({}, Outcome(tace=tace, failure=failure), objective, admissible, worst=worst, search=search)

    fragile = Tuned(evaluations=[evaluation(0, 1e-7, 2e-6, False, 0.5), evaluation(0, 2e-7, 1.3e-6, False, 0.3),
                                 evaluation(1, 0.7e-7, 1.31e-6, False, 0.9),
                                 evaluation(1, 3e-7, math.nan, False, 0.31)])
    what, values = status.agreement_values(fragile)
    assert what.startswith("lowest objective") and values == pytest.approx([10 ** 0.3 * 1e-6, 10 ** 0.31 * 1e-6])
    robust = Tuned(evaluations=[evaluation(0, 1e-7, 2e-7, True), evaluation(0, 0.5e-7, 5e-6, False),
                                evaluation(1, 1.2e-7, 2e-7, True), evaluation(2, 0.9e-7, 1e-6, False)])
    what, values = status.agreement_values(robust)
    assert what == "nominal TACE" and values == [1e-7, 1.2e-7, math.inf]


def test_a_segment_tells_a_stop_on_a_slope_from_another_basin():
    """tools/tune_row.py --segments: a search that stopped where an admissible straight path still falls to the
    best is 'on a slope'; one with a rise or an inadmissible point between is not."""
    verdict = load_tool("tune_row").segment_verdict
    assert verdict([0.40, 0.39, 0.385, 0.37, 0.36], [True] * 5).startswith("on a slope")
    assert "1.11x" in verdict([0.40, 0.39, 0.385, 0.37, 0.36], [True] * 5)
    assert verdict([0.40, 0.39, 0.392, 0.37, 0.36], [True] * 5).startswith("on a slope")     # 0.5%: within 1%
    rise = verdict([1.11, 1.5, 2.1, 1.3, 0.36], [True] * 5)
    assert rise.startswith("over a rise") and "89%" in rise
    barrier = verdict([0.40, 0.39, 0.38, 0.37, 0.36], [True, True, False, True, True])
    assert barrier.startswith("over a barrier") and "1 of 5" in barrier
