"""The contouring benchmark: the tuning rule, the pairings, the rows and the ratios to the proposed method."""
import csv
import math
from types import SimpleNamespace

import pytest

from contouring_ros import benchmark
from contouring_ros.benchmark import Point, factors, plan, run_benchmark, scenario_families, select, select_families
from contouring_ros.cli import main
from contouring_ros.errors import ConfigError

SMALL = "paper003_mech_ellipse"      # one scenario of two files, two combinations: 6 runs at budget 3


def scores(tace, effort=1.0, mce=None):
    return SimpleNamespace(tace=tace, mce=mce if mce is not None else 3 * tace, rms=tace, effort_rms=(effort, effort))


def point(factor, tace, effort=1.0, failure=""):
    s = None if failure else scores(tace, effort)
    return Point(factor, s, s, failure)


def test_select_picks_the_admissible_point_with_the_lowest_steady_state_tace():
    points = [point(0.1, 5.0), point(1.0, 2.0), point(10.0, 3.0)]
    assert select(points, effort_limit=1.1) == (1, "")
    # the steady state decides, not the whole run
    points[2] = Point(10.0, scores(9.0), scores(1.0))
    assert select(points, effort_limit=1.1)[0] == 2


def test_the_effort_bound_excludes_an_over_effort_point():
    points = [point(0.1, 5.0, effort=1.0), point(1.0, 2.0, effort=1.0), point(10.0, 0.5, effort=1.2)]
    assert select(points, effort_limit=1.1)[0] == 1
    assert select(points, effort_limit=1.3)[0] == 2
    index, why = select([point(1.0, 1.0, effort=2.0)], effort_limit=1.1)
    assert index is None and "over the effort bound" in why


def test_diverged_runs_never_win():
    points = [point(0.1, 5.0), point(1.0, 0.0, failure="diverged at t = 0.1 s (step 100): x left its bound")]
    assert select(points, effort_limit=math.inf)[0] == 0
    index, why = select([point(1.0, 0.0, failure="diverged at t = 0.1 s (step 100): x")], math.inf)
    assert index is None and why.startswith("diverged at every grid point")


def test_factors_span_the_log_grid_and_keep_the_file_gains():
    assert factors(5) == pytest.approx([0.01, 0.1, 1.0, 10.0, 100.0])
    assert factors(3) == pytest.approx([0.01, 1.0, 100.0])
    assert factors(1) == [1.0]
    assert 1.0 in factors(4) and len(factors(4)) == 5


def test_scenarios_group_the_files_of_one_experiment_and_pick_the_proposed_file():
    families = {f.name: f for f in scenario_families()}
    h50 = families["paper000_h50"]
    assert sorted(h50.files) == ["paper000_a_pidff_h50_newton", "paper000_a_pidff_h50_vgccc",
                                 "paper000_b_ismc_h50_newton", "paper000_b_ismc_h50_vgccc"]
    assert h50.proposed == "paper000_b_ismc_h50_newton" and h50.from_time == 0.3
    assert families["paper002_butterfly"].proposed == "paper002_butterfly_c3_tvt"
    assert {f.paper for f in families.values()} == {"000", "001", "002", "003", "004"}
    assert select_families(list(families.values()), ["paper003_*"]) == \
        [f for f in families.values() if f.paper == "003"]
    with pytest.raises(ConfigError, match="no scenario matches"):
        select_families(list(families.values()), ["paper999_*"])


def test_pairings_that_cannot_be_made_are_listed_with_a_reason():
    families = {f.name: f for f in scenario_families()}
    combos, excluded = plan(families["paper004_saddle"])
    reasons = {(e.estimator, e.controller): e.reason for e in excluded}
    assert "planar contour (2 axes)" in reasons[("osculating_circle", "variable_gain")]
    assert "needs 'direct' servos" in reasons[("newton", "tvt")]
    # an estimator the scenario does not use starts from its section in another paper's files
    assert {"newton", "foot_point_search", "natural_local"} <= {c.estimator for c in combos}
    assert all(e.reason for e in excluded)
    assert not {(c.estimator, c.controller) for c in combos} & set(reasons)
    combos, excluded = plan(families["paper003_ellipse"])
    # the task-frame PD acts on its own approximation's estimate: the first-order section with the tangent line
    assert {(c.estimator, c.controller, c.sections["/ccc"]["approximation"]) for c in combos} == \
        {("tangent_line", "task_frame_pd", "first_order"), ("natural_local", "task_frame_pd", "natural_local")}
    assert any("acts on the errors" in e.reason for e in excluded if e.controller == "task_frame_pd")


@pytest.fixture(scope="module")
def small_run():
    families = select_families(scenario_families(), [SMALL])
    span, benchmark.SPAN = benchmark.SPAN, 3.0      # factors 1/3, 1, 3: fast, and none of them diverges
    try:
        return families, run_benchmark(families, budget=3, workers=2)
    finally:
        benchmark.SPAN = span


def test_one_row_per_scenario_and_combination(small_run, tmp_path):
    families, rows = small_run
    combos, excluded = plan(families[0])
    assert len(rows) == len(combos) + len(excluded)
    path = benchmark.write_csv(rows, tmp_path / "benchmark.csv")
    table = list(csv.DictReader(path.open()))
    keys = [(r["scenario"], r["estimator"], r["controller"], r["servo"]) for r in table]
    assert len(keys) == len(rows) == len(set(keys))
    assert all(r["status"].startswith("cannot be paired: ") for r in table if r["controller"] == "tvt")
    tuned = [r for r in table if r["status"] == "ok"]
    assert len(tuned) == 2 and all(r["gains"].startswith('{"f_t": ') for r in tuned)


def test_the_proposed_combination_has_ratio_one_and_the_tuning_rule_holds(small_run):
    families, rows = small_run
    proposed = [r for r in rows if r.is_proposed]
    assert len(proposed) == 1
    row = proposed[0]
    assert (row.combination.estimator, row.combination.controller, row.combination.servo) == \
        ("natural_local", "task_frame_pd", "direct")
    assert row.ratio("tace") == 1.0 and row.ratio("mce") == 1.0 and row.ratio("effort") == 1.0
    limit = benchmark.EFFORT_BOUND * row.published.effort
    for r in rows:
        if r.point is None:
            continue
        assert r.point.effort <= limit
        admissible = [p for p in r.points if p.steady is not None and p.effort <= limit]
        assert r.point.steady.tace == min(p.steady.tace for p in admissible)
    # the file's own gains are one of the grid points: the tuned proposed method is no worse than published
    assert row.point.steady.tace <= row.published.steady.tace


def test_cli_writes_the_report_the_table_and_the_heatmap(tmp_path, capsys):
    assert main(["benchmark", "--scenarios", SMALL, "--budget", "1", "--out", str(tmp_path)]) == 0
    text = (tmp_path / "benchmark.md").read_text()
    assert "## Fairness rules" in text and "--budget 1" in text and f"| {SMALL} |" in text
    assert (tmp_path / "benchmark_heatmap.png").stat().st_size > 10_000
    assert len((tmp_path / "benchmark.csv").read_text().splitlines()) > 10
    assert main(["benchmark", "--budget", "0", "--out", str(tmp_path)]) == 2
