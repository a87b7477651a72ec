"""The contouring benchmark: pairings, the fair tuning's rules, the rows, the intervals and the ratios."""
import csv
import dataclasses
import math
import types

import numpy as np
import pytest
from scipy.stats import qmc

from contouring_ros.studies import benchmark, benchmark_parts, benchmark_report, loops, objective, outcomes, summaries, tuner, tuning
from contouring_ros.studies.gains import _set_gain
from contouring_ros.studies.machine import (REALISTIC, SATURATION_MARGIN, draw_settings, fit_to_machine, machine_settings,
                                           perturbations)
from contouring_ros.studies.benchmark import lower_or_higher, plan, run_benchmark, scenario_families, select_families
from contouring_ros.cli import main
from contouring_ros.errors import ConfigError
from contouring_ros.studies.tuning import Protocol
from conftest import ROOT, load_tool

SMALL = "paper003_mech_ellipse"      # one scenario of two files, two combinations
FAST = Protocol(evaluations=6, popsize=4, design=0, draws=2, searches=1, max_searches=1)


def test_scenarios_group_the_files_of_one_experiment_and_pick_the_proposed_file():
    families = {f.name: f for f in scenario_families()}
    h50 = families["paper000_h50"]
    assert sorted(h50.files) == ["paper000_a_pidff_h50_newton", "paper000_a_pidff_h50_vgccc",
                                 "paper000_b_ismc_h50_newton", "paper000_b_ismc_h50_vgccc", "paper000_zpetc_h50"]
    assert h50.proposed == "paper000_b_ismc_h50_newton" and h50.from_time == 0.3
    assert families["paper002_butterfly"].proposed == "paper002_butterfly_c3_tvt"
    assert {f.paper for f in families.values()} == {"000", "001", "002", "003", "004"}
    assert select_families(list(families.values()), ["paper003_*"]) == \
        [f for f in families.values() if f.paper == "003"]
    # by default the papers' own experiments; the claims' mechanism scenarios on request
    default = select_families(list(families.values()), None)
    assert default and all("_mech_" not in f.name for f in default)
    assert {f.paper for f in default} == {"000", "001", "002", "003", "004"}
    with pytest.raises(ConfigError, match="no scenario matches"):
        select_families(list(families.values()), ["paper999_*"])


def test_pairings_that_cannot_be_made_are_listed_with_a_reason():
    families = {f.name: f for f in scenario_families()}
    combos, excluded = plan(families["paper004_saddle"])
    reasons = {(e.estimator, e.controller): e.reason for e in excluded}
    assert "planar contour (2 axes)" in reasons[("osculating_circle", "variable_gain")]
    assert "needs 'direct' servos" in reasons[("newton", "tvt")]
    assert {"newton", "foot_point_search", "natural_local"} <= {c.estimator for c in combos}
    assert all(e.reason for e in excluded)
    assert not {(c.estimator, c.controller) for c in combos} & set(reasons)
    # every gain of a PID contour controller is tuned, the ones that are 0 in the file too
    vg = next(c for c in combos if c.controller == "variable_gain")
    assert vg.gain_keys == ("kp", "ki", "kd")
    combos, excluded = plan(families["paper003_ellipse"])
    assert {(c.estimator, c.controller, c.sections["/ccc"]["approximation"]) for c in combos
            if c.controller == "task_frame_pd"} == \
        {("tangent_line", "task_frame_pd", "first_order"), ("natural_local", "task_frame_pd", "natural_local")}


def test_pairings_skip_what_cannot_differ_and_bound_the_reference_methods():
    """A controller that reads no estimate runs once per servo set; a servo set with a feedforward that
    reads the reference ahead (ZPETC) is paired with no CCC and the proposed one; a learning controller
    with the scenario's own estimator and first servo set it can drive; the MPCC only with direct servos."""
    families = {f.name: f for f in scenario_families()}
    combos, excluded = plan(families["paper001_caseIII"])
    own = "osculating_circle"
    assert [c.estimator for c in combos if c.controller == "adaptive_tnb" and c.servo == "pid"] == [own]
    assert sorted(c.label for c in combos if c.servo == "zpetc") == \
        [f"{own} + adaptive_tnb / zpetc", f"{own} + none / zpetc"]
    ilc = [c for c in combos if c.controller == "ilc"]
    assert [(c.estimator, c.servo) for c in ilc] == [(own, "pid")] and ilc[0].sections["/ccc"]["passes"] == 4
    assert len({c.estimator for c in combos if c.controller == "variable_gain" and c.servo == "pid"}) > 1
    assert any(e.controller == "mpcc" and "needs 'direct' servos" in e.reason for e in excluded)
    combos, _ = plan(families["paper003_ellipse"])
    mpcc = [c for c in combos if c.controller == "mpcc"]
    assert [(c.estimator, c.servo, c.gain_keys) for c in mpcc] == [("natural_local", "direct",
                                                                     ("horizon", "q_contour", "q_lag", "r_rate"))]


def test_a_method_that_models_its_drive_is_given_the_realistic_machine():
    families = {f.name: f for f in scenario_families()}
    family = families["paper000_h50"]
    data = family.data[family.proposed]
    machine = machine_settings(data, "realistic", (2.0, 3.0))
    sections = {"/x/servo": {"law": "zpetc", "kp": 8.0, "ki": 90.0, "gain": 10.3, "time_constant": 0.04},
                "/y/servo": {"law": "ismc"}, "/ccc": {"type": "mpcc", "command_limit": None}}
    fitted = benchmark.fit_to_machine(data, sections, machine)
    assert fitted["/x/servo"]["command_delay"] == machine["x/plant.command_delay"] == 1
    assert "command_delay" not in fitted["/y/servo"]                     # the ISMC has no delay model
    assert fitted["/ccc"]["command_delay"] == 1
    assert fitted["/ccc"]["command_limit"] == [machine["x/plant.saturation"], machine["y/plant.saturation"]] \
        == [4.0, 6.0]
    assert fitted["/ccc"]["velocity_estimate"] == "model"        # the machine's velocity is the encoder's
    assert "command_delay" not in sections["/x/servo"]                   # the caller's sections are kept
    kept = benchmark.fit_to_machine(data, dict(sections, **{"/ccc": {"type": "mpcc", "command_limit": [7.0]}}),
                                    machine)
    assert kept["/ccc"]["command_limit"] == [7.0]                         # a limit the file sets stays


def test_a_learning_controller_is_judged_by_its_last_pass():
    from contouring_ros.experiment.ros_yaml import read_yaml
    from contouring_ros.studies.learning import simulate_passes
    path = ROOT / "config" / "ilc_ellipse.yaml"
    data = read_yaml(path.read_text(), str(path))
    settings = {"ccc.passes": 3}
    last, = outcomes.run_outcomes(data, {}, [settings], 0.5, "ilc")
    first, = outcomes.run_outcomes(data, {}, [{"ccc.passes": 1}], 0.5, "ilc")
    passes = simulate_passes(outcomes.experiment_for(data, {}, settings, "ilc"))
    assert len(passes) == 3
    expected = outcomes._figures(*passes[-1], 0.5, ())
    assert last.tace == expected.tace and last.mce == expected.mce
    assert last.tace < 0.5 * first.tace                                  # it learned


def test_parts_run_apart_are_reported_together(small_run, tmp_path):
    families, rows = small_run
    part = benchmark.Part(families, rows, FAST, 60.0, 100.0, 2, "contouring-ros benchmark --scenarios x", "here")
    first = benchmark_parts.save_part(part, tmp_path / "a.pkl")
    benchmark_parts.save_part(part, tmp_path / "b.pkl")
    loaded = benchmark_parts.load_parts([first])
    assert [r.label for r in loaded[0].rows] == [r.label for r in rows]
    assert loaded[0].rows[0].figure("tace") == rows[0].figure("tace")
    _, direct, _ = benchmark_report.write_outputs([part], tmp_path / "direct")       # the table the run itself writes
    _, saved, _ = benchmark_report.write_outputs(loaded, tmp_path / "saved")
    assert saved.read_bytes() == direct.read_bytes()
    assert main(["benchmark", "--from-parts", str(first), str(tmp_path / "b.pkl"), "--out", str(tmp_path)]) == 0
    text = (tmp_path / "benchmark.md").read_text()
    assert "Generated in 2 parts" in text and "(here)" in text
    (tmp_path / "bad.pkl").write_text("not a part")
    assert main(["benchmark", "--from-parts", str(tmp_path / "bad.pkl"), "--out", str(tmp_path)]) == 2


def test_a_method_rerun_alone_takes_its_rows_place_in_an_earlier_full_run(small_run):
    import copy
    import dataclasses
    families, rows = small_run
    full = benchmark.Part(families, rows, FAST, 60.0, 100.0, 2, "full")
    alone = run_benchmark(families, FAST, workers=2, methods=("tangent_line",))
    proposed = [r for r in alone if r.combination and benchmark.is_proposed_combination(families[0], r.combination)]
    assert len(proposed) == 1 and proposed[0].combination.estimator != "tangent_line"   # run for the ratios
    assert all(r is proposed[0] or (r.combination or r.excluded).estimator == "tangent_line" for r in alone)
    part = benchmark.Part(families, alone, FAST, 10.0, 20.0, 2, "methods", methods=("tangent_line",))
    merged_families, merged = benchmark_parts.merged_rows([full, part])
    assert sorted(r.label for r in merged) == sorted(r.label for r in rows)          # nothing lost, none twice
    replaced = {r.label for r in alone}
    assert all((r in alone) == (r.label in replaced) for r in merged)
    assert all(r.reference is proposed[0] for r in merged if r.combination)
    assert [d.tace for d in proposed[0].tuned.draws] == \
        [d.tace for d in next(r for r in rows if r.is_proposed).tuned.draws]          # the same tuning
    # a part whose proposed combination tuned otherwise ran other code: refused, naming the scenario
    other = copy.deepcopy(part)
    mine = next(r for r in other.rows if r.combination and benchmark.is_proposed_combination(other.families[0], r.combination))
    mine.tuned.draws[0] = dataclasses.replace(mine.tuned.draws[0], tace=1.5 * mine.tuned.draws[0].tace)
    with pytest.raises(ConfigError, match=f"{families[0].name}'s proposed combination"):
        benchmark_parts.merged_rows([full, other])
    with pytest.raises(ConfigError, match=r"^--methods zpetc_nowhere: no estimator, controller or servo set"):
        run_benchmark(families, FAST, workers=1, methods=("zpetc_nowhere",))


# ------------------------------------------------------------------------------------ the protocol


def test_a_plugin_without_a_space_is_searched_in_the_log_box_of_its_raw_gains():
    from contouring_ros.core.tuning_space import log_box
    section = {"kp": 2.0, "ki": 0.0, "kd": 0.0, "coupling": [0.0, 0.0]}
    space = log_box(section, ("kp", "ki", "kd", "coupling"), 4.0)
    anchors = {d.name: (d.low * d.high) ** 0.5 for d in space.dimensions}
    assert anchors == pytest.approx({"kp": 2.0, "ki": 60.0, "kd": 2e-3, "coupling": 1.0})
    # the lowest end of a span means off; elsewhere the gain is 10^x
    values, gains = space.decode([0.0, 0.5, 1.0, 0.5])
    assert gains["kp"] == 0.0 and gains["ki"] == pytest.approx(60.0) and gains["kd"] == pytest.approx(2e-3 * 1e4)
    # a per-axis list keeps its proportions
    section = {"coupling": [1.0, 3.0]}
    _set_gain(section, "coupling", 6.0)
    assert section["coupling"] == [2.0, 6.0]


def test_the_objective_penalises_noise_saturation_and_divergence():
    protocol = Protocol(saturation_share=0.01)
    quiet = tuning.Outcome(tace=1e-6, noise=1.0, saturated=0.0)
    assert objective.objective(quiet, 2.0, protocol) == (0.0, True)
    loud = tuning.Outcome(tace=1e-7, noise=20.0, saturated=0.0)
    value, admissible = objective.objective(loud, 2.0, protocol)
    assert not admissible and value > 0.0          # 10x lower error does not buy 10x the noise
    saturated = tuning.Outcome(tace=1e-7, noise=1.0, saturated=0.2)
    assert objective.objective(saturated, 2.0, protocol)[1] is False
    assert objective.objective(tuning.Outcome(failure="diverged"), 2.0, protocol) == (100.0, False)


def test_machine_settings_put_the_plants_on_a_realistic_machine_and_keep_what_the_file_sets():
    families = {f.name: f for f in scenario_families()}
    data = families["paper000_h50"].data["paper000_b_ismc_h50_newton"]
    assert machine_settings(data, "ideal") == {}
    settings = machine_settings(data, "realistic", (0.01, 0.02))
    for axis in ("x", "y"):
        for key, value in REALISTIC.items():
            assert settings[f"{axis}/plant.{key}"] == value
    assert settings["x/plant.saturation"] == pytest.approx(SATURATION_MARGIN * 0.01)
    assert settings["x/plant.noise_seed"] != settings["y/plant.noise_seed"]
    # paper 003's XY stage states its +-10 V limit: kept
    stage = families["paper003_ellipse"].data["paper003_ellipse_natural_local_fn100"]
    assert not any(k.endswith(".saturation") for k in machine_settings(stage, "realistic", (1.0, 1.0)))
    with pytest.raises(ValueError, match="machine"):
        machine_settings(data, "perfect")


def test_robustness_and_draws_vary_every_plant_parameter_and_are_the_same_for_every_method():
    families = {f.name: f for f in scenario_families()}
    data = families["paper004_saddle"].data["paper004_saddle_eso"]
    checks = perturbations(data, 0.2)
    assert len(checks) == 6                        # mass, damping, gain; each -20% and +20%
    assert checks[0]["x/plant.mass"] == pytest.approx(0.8 * 5.8) and checks[1]["x/plant.mass"] == pytest.approx(1.2 * 5.8)
    assert draw_settings(data, 3, 0.1) == draw_settings(data, 3, 0.1)
    assert draw_settings(data, 3, 0.1) != draw_settings(data, 4, 0.1)
    factors = [draw_settings(data, j, 0.1)["x/plant.mass"] / 5.8 for j in range(20)]
    assert all(0.9 <= f <= 1.1 for f in factors)
    assert "x/plant.disturbance.phase" in draw_settings(data, 1, 0.1)


def test_a_diverged_draw_makes_the_ratio_interval_reach_infinity_not_nan():
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        values = np.array([0.5, 0.6, 0.7, 0.8, 0.9, 1.0, np.inf, np.inf])
        assert benchmark._infinite_aware(values, 97.5) == math.inf
        assert benchmark._infinite_aware(values, 2.5) == pytest.approx(0.5 + 0.025 * 7 * 0.1)    # numpy's linear
        assert benchmark._infinite_aware(values, 50.0) == pytest.approx(0.85)
        assert benchmark._infinite_aware(np.array([1.0, 2.0, 3.0]), 97.5) == np.percentile([1.0, 2.0, 3.0], 97.5)
    assert lower_or_higher(1.46, math.inf) == "higher"


def test_intervals_verdicts_and_fronts():
    assert summaries.interval([1.0, 2.0, 3.0, float("nan")])[0] == 2.0
    assert all(math.isnan(v) for v in summaries.interval([]))
    assert lower_or_higher(0.2, 0.8) == "lower" and lower_or_higher(1.1, 3.0) == "higher"
    assert lower_or_higher(0.5, 1.5) == "undecided"
    assert lower_or_higher(0.1, 0.4, threshold=0.5) == "lower" and lower_or_higher(1.0, 1.0) == "same"
    front = summaries.pareto_front([(1.0, 5.0), (2.0, 3.0), (3.0, 4.0), (0.5, 9.0), (4.0, 1.0)])
    assert front == [(0.5, 9.0), (1.0, 5.0), (2.0, 3.0), (4.0, 1.0)]


# --------------------------------------------------------------------------------- a small benchmark


@pytest.fixture(scope="module")
def small_run():
    families = select_families(scenario_families(), [SMALL])
    return families, run_benchmark(families, FAST, workers=2)


def test_the_findings_written_for_the_default_run_are_shown_only_under_its_protocol(small_run):
    families, rows = small_run
    notes = {families[0].paper: "FINDINGS OF THE DEFAULT RUN"}
    default = benchmark_report.benchmark_report(rows, families, Protocol(), "here", notes=notes)
    other = benchmark_report.benchmark_report(rows, families, Protocol(searches=4), "here", notes=notes)
    assert "FINDINGS OF THE DEFAULT RUN" in default and "are left out" not in default
    assert "FINDINGS OF THE DEFAULT RUN" not in other and "notes.yaml) are left out" in other


def test_one_row_per_scenario_and_combination(small_run, tmp_path):
    families, rows = small_run
    combos, excluded = plan(families[0])
    assert len(rows) == len(combos) + len(excluded)
    path = benchmark_report.write_csv(rows, tmp_path / "benchmark.csv")
    table = list(csv.DictReader(path.open()))
    keys = [(r["scenario"], r["estimator"], r["controller"], r["servo"]) for r in table]
    assert len(keys) == len(rows) == len(set(keys))
    assert all(r["status"].startswith("cannot be paired: ") for r in table if r["controller"] == "tvt")
    tuned = [r for r in table if r["gains"]]
    assert len(tuned) == 2 and all(r["gains"].startswith('{"f_t": ') for r in tuned)
    assert all(int(r["evaluations"]) <= FAST.evaluations for r in tuned)


def test_every_tuned_row_keeps_the_constraints_and_the_proposed_ratio_is_one(small_run):
    families, rows = small_run
    proposed = [r for r in rows if r.is_proposed]
    assert len(proposed) == 1
    row = proposed[0]
    assert (row.combination.estimator, row.combination.controller) == ("natural_local", "task_frame_pd")
    assert row.ratio("tace") == (1.0, 1.0, 1.0)
    for r in rows:
        if not r.ok:
            continue
        assert r.tuned.nominal.noise <= r.bound.noise_limit
        assert r.tuned.nominal.saturated <= FAST.saturation_share
        assert len(r.tuned.draws) == FAST.draws
        # the file's gains are the first evaluation: the tuned result is never worse when they are admissible
        first = r.tuned.evaluations[0]
        if first.admissible:
            assert r.tuned.nominal.tace <= first.outcome.tace
    # the machine is the realistic one
    assert rows[0].bound.machine["x/plant.command_delay"] == 1


def test_cli_writes_the_report_the_table_and_the_figures(tmp_path):
    assert main(["benchmark", "--scenarios", SMALL, "--budget", "3", "--draws", "1", "--out", str(tmp_path)]) == 0
    text = (tmp_path / "benchmark.md").read_text()
    assert "## Protocol" in text and "--budget 3" in text and f"### {SMALL}" in text
    assert "[95%]" in text
    # each combination's CPU time, summed per controller
    time_table = text.split("## Where the time went")[1].split("\n## ")[0]
    assert "| task_frame_pd | 2 |" in time_table and "CPU time of each combination's tuning" in time_table
    assert (tmp_path / "benchmark_heatmap.png").stat().st_size > 10_000
    assert (tmp_path / "benchmark_pareto_paper003.png").stat().st_size > 10_000
    assert len((tmp_path / "benchmark.csv").read_text().splitlines()) > 10
    for option in ("--budget", "--draws", "--searches"):      # refused as the options are read: exit 2
        with pytest.raises(SystemExit) as refused:
            main(["benchmark", option, "0", "--out", str(tmp_path)])
        assert refused.value.code == 2


def test_quick_robustness_agrees_with_the_margins_and_the_ms_bound_refuses_before_running():
    import control
    from contouring_ros.core.margins import margins, quick_robustness
    for k in (100.0, 800.0, 1900.0, 2100.0):          # K Ts/(z-1): stable while K Ts < 2
        loop = control.tf([k * 1e-3], [1.0, -1.0], 1e-3)
        ms, stable = quick_robustness(loop)
        assert stable == (k * 1e-3 < 2.0)
        if stable:
            assert ms == pytest.approx(margins(loop, 1e-3).ms, rel=1e-3)
    # a PID contour controller pushed far beyond the drive's loop: its coupled loop is refused unrun
    families = {f.name: f for f in scenario_families()}
    family = families["paper002_butterfly"]
    data = family.data["paper002_butterfly_c4_foot_point_ccc"]
    combo = next(c for c in plan(family)[0] if c.label == "foot_point_search + variable_gain / pid_feedforward")
    sections = dict(combo.sections, **{"/ccc": dict(combo.sections["/ccc"], kp=1e6, ki=0.0, kd=0.0)})
    experiment = outcomes.experiment_for(data, sections, {}, "test")
    ms, stable, allowed = loops.loop_robustness(experiment)
    assert not ms <= allowed
    search = tuner.Tuning(data, combo.sections, combo.gain_keys, {}, math.inf, family.from_time, Protocol(), "test")
    beyond, = search.measure([([], {}, {"kp": 1e6, "ki": 0.0, "kd": 0.0})])
    assert not beyond.admissible
    assert beyond.outcome.failure.startswith("refused: its linear loop is unstable" if not stable else "Ms ")


def test_runs_together_equal_the_runs_one_by_one(monkeypatch):
    """run_outcomes batches the runs of one structure (sweep.simulate_experiments): same figures as alone
    (the Newton estimate's batch is made to run with 3 members, below its batch_minimum)."""
    from contouring_ros.core.estimators import NewtonEstimator
    monkeypatch.setattr(NewtonEstimator, "PURE_BATCH_MINIMUM", 2)
    monkeypatch.setattr(NewtonEstimator, "COMPILED_BATCH_MINIMUM", 2)
    families = {f.name: f for f in scenario_families()}
    family = families["paper000_h50"]
    data = family.data[family.proposed]
    machine = machine_settings(data, "realistic", (0.05, 0.05))
    settings = [dict(machine, **c) for c in perturbations(data, 0.2)[:3]]
    together = outcomes.run_outcomes(data, {}, settings, family.from_time, "test")
    alone = [outcomes.run_outcomes(data, {}, [s], family.from_time, "test")[0] for s in settings]
    assert len({round(o.tace, 15) for o in together}) == 3           # the perturbations differ
    for a, b in zip(together, alone):
        assert a.ok and b.ok
        for name in ("tace", "mce", "noise", "saturated", "effort"):
            assert getattr(a, name) == pytest.approx(getattr(b, name), rel=1e-9, abs=1e-15)


def _small_tune(**options):
    families = select_families(scenario_families(), [SMALL])
    family = families[0]
    data = family.data[family.proposed]
    combo = next(c for c in plan(family)[0] if c.estimator == "natural_local")
    return tuner.tune(data, combo.sections, combo.gain_keys, {}, math.inf, family.from_time,
                       dataclasses.replace(Protocol(evaluations=8, popsize=4, design=0, draws=1, searches=1,
                                                    max_searches=1, selection_draws=0, budget_growth=1),
                                           **options.pop("protocol", {})),
                       "test", **options)


def test_the_robustness_floor_and_every_point_that_could_be_chosen_checked(monkeypatch):
    # the paper's own design degrading as much is enough: with no limit every checked point is robust and the
    # tuned point is the admissible one of lowest TACE
    tuned = _small_tune(robust_floor=math.inf)
    admissible = [e for e in tuned.evaluations if e.admissible]
    assert tuned.ok and tuned.nominal.tace == min(e.outcome.tace for e in admissible)
    family = select_families(scenario_families(), [SMALL])[0]
    checks = perturbations(family.data[family.proposed], Protocol().perturbation)
    assert len(checks) == 6                                   # mass, damping, gain; -20% and +20%
    ran = [e for e in tuned.evaluations if e.outcome.ok]
    checked = [e for e in ran if math.isfinite(e.worst)]
    assert checked and all(e.worst >= 0 for e in checked)
    assert tuned.robustness_runs == len(checks) * len(checked)
    # a point left unchecked could not have been chosen: a penalty makes it inadmissible anyway, or its
    # nominal TACE is not below the choice's
    for e in ran:
        if not math.isfinite(e.worst):
            assert not e.admissible
            assert e.objective > math.log10(e.outcome.tace * 1e6) or e.outcome.tace >= tuned.nominal.tace
    # ... so checking every point gives the same choice
    measure = tuner.Tuning.measure
    monkeypatch.setattr(tuner.Tuning, "STAGES", (math.inf,))
    monkeypatch.setattr(tuner.Tuning, "measure", lambda self, points, groups=None, best=None:
                        measure(self, points))
    everything = _small_tune(robust_floor=math.inf)
    assert everything.gains == tuned.gains and everything.nominal.tace == tuned.nominal.tace
    assert all(math.isfinite(e.worst) for e in everything.evaluations if e.outcome.ok)
    monkeypatch.undo()
    # no point robust (its worst case within 0.001x its own error): said so, and the point given is the
    # one whose worst case is the lowest
    tuned = _small_tune(protocol={"robust_factor": 1e-3})
    assert tuned.status.startswith("not robust") and not tuned.ok
    checked = [e for e in tuned.evaluations if math.isfinite(e.worst) and e.quiet]
    best = min(checked, key=lambda e: e.worst)
    assert tuned.gains == best.gains and tuned.robust_worst == pytest.approx(best.worst / best.outcome.tace)


def test_a_point_given_as_not_robust_met_every_other_constraint():
    """Where no point is robust, the point given is the quiet, unsaturated one of lowest worst case; a point
    over the noise bound is never given, however low its worst case: with none quiet, no point is."""
    def fragile(worst, quiet):
        return tuning.Evaluation({"kp": worst}, tuning.Outcome(tace=1e-6, failure="not robust: ..."), 0.0, False,
                                 worst=worst, quiet=quiet)
    noisy, quiet_high, quiet_low = fragile(2e-6, False), fragile(9e-6, True), fragile(5e-6, True)
    assert tuner.chosen_point([noisy, quiet_high, quiet_low]) == (quiet_low, False)
    assert tuner.chosen_point([noisy]) == (None, False)
    refused = [tuning.Evaluation({}, tuning.Outcome(failure=f"diverged at t = {t:g} s (step {k}): far"), 100.0, False)
               for t, k in ((0.3, 300), (0.4, 400))]
    search = tuner.Tuning.choose(types.SimpleNamespace(protocol=Protocol(), constraints=objective.Constraints(Protocol(), 1.0)),
                                 [noisy] + refused)
    assert search.chosen is None and search.status.endswith("(diverged; not robust)")    # each kind once
    judged = tuning.Evaluation({}, tuning.Outcome(), 0.0, False)
    nominal, perturbed = tuning.Outcome(tace=1e-6, noise=2.0, saturated=0.0), [tuning.Outcome(tace=1e-3)]
    objective.Constraints(Protocol(), 1.0).judge(judged, nominal, perturbed, None)     # noise 2x the bound 1
    assert judged.outcome.failure.startswith("not robust") and not judged.quiet
    objective.Constraints(Protocol(), 3.0).judge(judged, nominal, perturbed, None)
    assert judged.outcome.failure.startswith("not robust") and judged.quiet


def test_several_searches_keep_the_robust_one_with_the_lowest_nominal_error():
    # a search that goes where its seed says: seed 1 to one point of the box, seed 2 to another
    def seeded(objective_many, start, budget, seed):
        objective_many([[0.3 + 0.15 * seed] * len(start)])

    def small(**protocol):
        return _small_tune(robust_floor=math.inf, optimiser=seeded, protocol=protocol)
    one, both = small(seed=1), small(searches=2, max_searches=2)
    assert one.ok and both.ok
    assert both.search_tace[0] == one.nominal.tace
    assert both.nominal.tace == min(both.search_tace) and both.search == both.search_tace.index(both.nominal.tace)
    assert both.search_evaluations == [2, 1]                   # search 0 also ran the file's gains
    assert both.agreement.searches == 2 and not both.converged     # 2 searches cannot make 3 agree


def test_the_points_a_kept_one_is_picked_from_are_near_the_best_and_apart():
    def point(tace, unit, admissible=True, gains=None):
        gains = gains if gains is not None else {"kp": unit[0], "ki": unit[1]}
        return tuning.Evaluation(gains, tuning.Outcome(tace=tace), 0.0, admissible, unit=unit)
    best = point(1.00, [0.5, 0.5])
    same_place = point(1.01, [0.505, 0.5])         # within the spacing of the best: one neighbourhood
    elsewhere = point(1.04, [0.1, 0.9])
    too_high = point(1.06, [0.9, 0.1])              # beyond the 5% tolerance
    refused = point(1.02, [0.9, 0.9], admissible=False)
    same_gains = point(1.03, [0.8, 0.2], gains=best.gains)     # another unit point of the best's gains
    evaluations = [too_high, elsewhere, refused, same_place, best, same_gains]
    assert tuner.selection_candidates(evaluations, 1.0, 0.05, 8, 0.02) == [best, elsewhere]
    assert tuner.selection_candidates(evaluations, 1.0, 0.05, 8, 0.0) == [best, same_place, elsewhere]
    assert tuner.selection_candidates(evaluations, 1.0, 0.05, 1, 0.0) == [best]
    assert tuner.median_tace([tuning.Outcome(tace=1.0), tuning.Outcome(failure="diverged"),
                              tuning.Outcome(tace=3.0)]) == 3.0


def test_the_kept_point_is_the_one_of_lowest_median_over_draws_of_its_own(monkeypatch):
    """Of the admissible points within the agreement of the best nominal TACE, the kept one has the lowest
    median TACE over the selection draws, which are not the report's draws."""
    used = []

    def recorded(data, j, mismatch):
        used.append(j)
        return draw_settings(data, j, mismatch)
    monkeypatch.setattr(tuner, "draw_settings", recorded)
    tuned = _small_tune(robust_floor=math.inf, protocol=dict(evaluations=40, design=8, draws=2, selection_draws=3,
                                                             agreement=0.5))
    assert tuned.ok and len(tuned.selection) >= 2
    nominals, medians = zip(*tuned.selection)
    best = min(e.outcome.tace for e in tuned.evaluations if e.admissible)
    assert nominals[0] == best and max(nominals) <= 1.5 * best
    kept = tuned.selection[medians.index(min(medians))]
    assert tuned.nominal.tace == kept[0]
    assert sorted(set(used)) == [0, 1, 2, 3, 4]      # the selection's draws 2-4 after the report's 0-1
    assert len(tuned.draws) == 2
    assert tuned.selection_runs == 3 * len(tuned.selection)


def test_searches_run_until_they_agree_and_report_it():
    """Independent searches of a small loop: the row is converged exactly when 3 end within 5% of the
    best; a deliberately short search is not."""
    tuned = _small_tune(robust_floor=math.inf, protocol=dict(evaluations=60, design=8, searches=3, max_searches=4))
    assert tuned.agreement.searches >= 3
    assert tuned.converged == (tuned.agreement.agreed >= 3)
    short = _small_tune(robust_floor=math.inf, protocol=dict(evaluations=2, design=0, searches=3, max_searches=3))
    assert short.agreement.searches == 3 and not short.converged


def test_searches_that_do_not_agree_get_longer_searches_up_to_the_growth_cap():
    """Protocol.budget_growth: after max_searches, rounds of `searches` new searches with 2x, 4x, ... the
    evaluations while they do not agree; none once they do, none past the cap. (A stand-in for the searches:
    each ends at a value that depends on its budget, apart below 40 evaluations, together from 40 on.)"""
    from types import SimpleNamespace
    assert Protocol(evaluations=10, budget_growth=8).budgets() == [20, 40, 80]
    assert Protocol(evaluations=10, budget_growth=6).budgets() == [20, 40]
    assert Protocol(evaluations=10, budget_growth=1).budgets() == []
    assert Protocol(evaluations=10, searches=1, max_searches=2).budgets() == []     # could never agree: a quick look
    assert Protocol(evaluations=10).budgets() == [20, 40]                            # the default: up to 4x
    asked = []

    def search(self, indices, optimiser=None, evaluations=None):
        budget = self.protocol.evaluations if evaluations is None else evaluations
        asked.append((tuple(indices), budget))
        return [SimpleNamespace(value=1.0 + (0.0 if budget >= 40 else 0.3 * i), penalised=math.inf)
                for i in indices]

    def grown(growth):
        asked.clear()
        stand_in = SimpleNamespace(protocol=Protocol(evaluations=10, searches=3, max_searches=4, budget_growth=growth),
                                   space=SimpleNamespace(dimensions=[1]))
        stand_in.search = search.__get__(stand_in)
        stand_in.more = tuner.Tuning.more.__get__(stand_in)
        return tuner.Tuning.search_until_agreed(stand_in)
    found = grown(16)           # 10 and 20 evaluations disagree, 40 agree: no round of 80 or 160
    assert asked == [((0, 1, 2), 10), ((3,), 10), ((4, 5, 6), 20), ((7, 8, 9), 40)]
    assert tuner.searches_agreement(found, Protocol()).converged
    grown(2)                    # the cap: one round of 2x, still apart, and no more
    assert asked == [((0, 1, 2), 10), ((3,), 10), ((4, 5, 6), 20)]
    grown(1)
    assert asked == [((0, 1, 2), 10), ((3,), 10)]


def test_the_report_counts_converged_rows_and_names_the_others():
    from types import SimpleNamespace
    from contouring_ros.studies.search import agreement
    family = SimpleNamespace(name="scenario")

    def row(values):
        a = agreement(values)
        return SimpleNamespace(tuned=SimpleNamespace(agreement=a, search_tace=values, status=status),
                               converged=a.converged, family=family, label="est + ccc / servo")
    status = "ok"
    rows = [row([1e-6, 1.01e-6, 1.02e-6]), row([1e-6, 3e-6, 1.5e-6, 2e-6, 1.2e-6, 4e-6])]
    text = benchmark_report.convergence_text(rows)
    assert "1 of 2 tuned rows converged (50%); searches" in text and "at most 6" in text
    assert "scenario est + ccc / servo (1 of 6 agree, spread 4x: 1, 1.2, 1.5, 2, 3, 4)" in text
    status = "not robust: ..."
    text = benchmark_report.convergence_text(rows + [row([1e-6, 1.01e-6, 1.02e-6])])
    assert "2 of 3 tuned rows converged (67%), 1 of them rows without an admissible point" in text


def test_the_kept_search_prefers_robust_then_the_lowest_worst_case():
    def search(tace, status="ok", worst=math.nan):
        chosen = tuning.Evaluation({}, tuning.Outcome(tace=tace), 0.0, status == "ok", worst)
        return tuning.Search(chosen, status, worst / tace if math.isfinite(worst) else math.nan)
    robust_high, robust_low, fragile = search(2e-6), search(1e-6), search(1e-8, "not robust: ...", 9e-6)
    assert tuner.best_search([robust_high, fragile, robust_low]) is robust_low      # never the fragile point
    assert tuner.best_search([robust_low, search(1e-6)]) is robust_low               # a tie: the earlier
    worse = search(1e-8, "not robust: ...", 5e-5)
    assert tuner.best_search([worse, fragile]) is fragile                             # lowest worst case
    none = tuning.Search(None, "no admissible gain: every point diverged")
    assert tuner.best_search([none, tuning.Search(None, "no admissible gain: other")]) is none
    assert tuner.best_search([none, fragile]) is fragile


def test_searches_without_an_admissible_point_are_compared_by_what_they_minimised():
    """Two searches at one optimum of the objective (a point just beyond the noise bound) agree, however far
    apart the worst cases of their not-robust choices; a third elsewhere does not; one robust choice makes the
    row compared by nominal TACE, where the others count as finding nothing."""
    def fragile(worst, lowest):
        chosen = tuning.Evaluation({}, tuning.Outcome(tace=1e-6), 1.5, False, worst)
        return tuning.Search(chosen, "not robust: ...", worst / 1e-6, lowest=lowest)
    at_one_optimum = [fragile(9e-6, -0.140), fragile(3e-5, -0.141), fragile(2e-5, -0.139)]
    what, values = tuner.compared_values(at_one_optimum)
    assert what.startswith("lowest objective") and values[0] == pytest.approx(10 ** -0.14 * 1e-6)
    assert tuner.searches_agreement(at_one_optimum, tuning.Protocol()).converged
    apart = at_one_optimum[:2] + [fragile(9e-6, 0.3)]
    assert not tuner.searches_agreement(apart, tuning.Protocol()).converged
    robust = tuning.Search(tuning.Evaluation({}, tuning.Outcome(tace=2e-6), 0.3, True, 3e-6), "ok", 1.5,
                           lowest=0.3)
    what, values = tuner.compared_values(at_one_optimum + [robust])
    assert what == "nominal TACE" and values == [math.inf] * 3 + [2e-6]
    assert tuning.Search(None, "no admissible gain: every point diverged").penalised == math.inf


def test_the_lowest_objective_counts_only_points_that_ran():
    def evaluation(objective):
        return tuning.Evaluation({}, tuning.Outcome(tace=1e-6), objective, False)
    assert tuner.lowest_objective([evaluation(100.0), evaluation(0.5), evaluation(-0.2)]) == -0.2
    assert tuner.lowest_objective([evaluation(100.0), evaluation(objective.UNSTABLE)]) == math.inf


def test_two_runs_compared_row_by_row_name_what_a_protocol_change_moved(tmp_path):
    """tools/compare_benchmarks.py: a row whose error doubled, a verdict that flipped, a status that changed
    and a new best combination are each counted and named; a run against itself changes nothing."""
    tool = load_tool("compare_benchmarks")
    reference = ROOT / "reports" / "benchmark.csv"
    a = tool.read_rows(reference)
    same = tool.compare(a, tool.read_rows(reference), say=lambda line: None)
    assert same["status_changed"] == same["verdicts_changed"] == 0 and same["best_same"] == same["scenarios"]
    assert same["within10"] == same["compared"] > 100 and same["median"] == 1.0
    with open(reference, newline="") as stream:
        rows = list(csv.DictReader(stream))
    tuned = [r for r in rows if r["status"] == "ok" and r["tace_verdict"] == "higher" and r["proposed"] != "yes"]
    tuned[0]["tace_median_um"] = str(2.5 * float(tuned[0]["tace_median_um"]))
    tuned[1]["tace_verdict"] = "lower"
    tuned[2]["status"] = "not robust: the test's"
    # a row that is not yet its scenario's best other becomes it
    promoted = next(r for r in tuned[3:] if tool.best_other(a, r["scenario"])
                    != f"{r['estimator']} + {r['controller']} / {r['servo']}")
    for r in rows:
        if r["scenario"] == promoted["scenario"] and r["status"] == "ok" and r["proposed"] != "yes":
            r["tace_ratio"] = r["mce_ratio"] = "5"
    promoted["tace_ratio"] = promoted["mce_ratio"] = "0.01"
    changed = tmp_path / "changed.csv"
    with open(changed, "w", newline="") as stream:
        writer = csv.DictWriter(stream, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    lines = []
    figures = tool.compare(a, tool.read_rows(changed), say=lines.append)
    assert figures["worse2"] == 1 and figures["verdicts_changed"] == 1 and figures["status_changed"] == 1
    assert figures["best_same"] == figures["scenarios"] - 1
    text = "\n".join(lines)
    assert f"{tuned[1]['estimator']} + {tuned[1]['controller']} / {tuned[1]['servo']}: higher" in text
    assert "ok -> not robust" in text and "(changed)" in text


def _realistic_tuning(scenario: str, pick, peak_command: tuple) -> tuple:
    """(data, machine, Tuning) of the combination of ``scenario`` whose label ``pick`` accepts, on the realistic
    machine whose actuator limits follow ``peak_command`` (machine_settings), without a noise bound."""
    family = {f.name: f for f in scenario_families()}[scenario]
    data = family.data[family.proposed]
    combo = next(c for c in plan(family)[0] if pick(c.label))
    machine = machine_settings(data, "realistic", peak_command)
    sections = fit_to_machine(data, combo.sections, machine)
    return data, machine, tuner.Tuning(data, sections, combo.gain_keys, machine, math.inf, family.from_time,
                                       Protocol(), "test")


def test_a_linear_pid_contour_controller_is_searched_at_a_chosen_ms():
    """Where the coupled loops are linear, a PID contour controller's space is its PI corner, its derivative
    time and the Ms its loops reach: every point of the box is a loop at that Ms (the exact check agrees,
    and Ms 2 is the bound's edge), and the file's gains map back to themselves."""
    data, machine, search = _realistic_tuning("paper001_caseIII", lambda label: label == "tangent_line + variable_gain / pid",
                                              (1.0, 1.0))
    assert [d.name for d in search.space.dimensions] == ["f_c", "t_d", "ms", "gain_range"]
    rng = np.random.default_rng(3)
    for u in [list(rng.uniform(0.05, 1.0, 4)) for _ in range(6)] + [[0.6, 0.6, 1.0, 0.0], [0.6, 0.6, 1.0, 1.0]]:
        values, gains = search.space.decode(u)
        ms, stable, allowed = loops.loop_robustness(
            outcomes.experiment_for(data, search.with_gains(gains), machine, "test"))
        if gains["kp"] > 0:          # a target below the drive's own Ms leaves the controller off
            assert stable and ms <= values["ms"] * allowed / tuning.MS_LIMIT * (1 + 1e-3)
            if values["gain_range"] == 0:      # the lowest range's top: the bound reached (the cap is far above)
                assert ms == pytest.approx(values["ms"] * allowed / tuning.MS_LIMIT, rel=1e-3)
        back = search.space.point(search.with_gains(gains))
        assert back["f_c"] == pytest.approx(values["f_c"], rel=1e-9) and back["t_d"] == pytest.approx(values["t_d"], rel=1e-9)
        if gains["kp"] > 0 and back["ms"] == pytest.approx(values["ms"], rel=1e-4):     # the gains come back
            again = search.space.decode(search.space.start(search.with_gains(gains)))[1]
            assert again["kp"] == pytest.approx(gains["kp"], rel=1e-3)
    assert values["ms"] == pytest.approx(tuning.MS_LIMIT)


def test_a_contour_pid_around_a_pid_feedforward_servo_is_offered_its_higher_range_of_gains():
    """Around paper 002's PID + feedforward servos the coupled loops' Ms is not monotone in the contour PID's
    gain scale: at f_c 41 Hz, t_d 5.1 ms it keeps Ms 2 up to a scale near kp 11, exceeds it beyond, and keeps
    it again near kp 300. Both ranges' tops are stable loops at the bound; a scale between them is beyond it;
    the low error lies in the higher range (the lower's top gives about 20x the TACE), and its gains map back
    to it."""
    data, machine, search = _realistic_tuning(
        "paper002_butterfly", lambda label: label == "foot_point_search + variable_gain / pid_feedforward", (0.0, 0.0))
    found = {}
    for gain_range in (0, 1):
        values = {"f_c": 41.0, "t_d": 5.1e-3, "ms": 2.0, "gain_range": gain_range}
        unit = [d.position(values[d.name]) for d in search.space.dimensions]
        found[gain_range] = search.space.decode(unit) + (unit,)
    low, high = found[0][1], found[1][1]
    assert 5 < low["kp"] < 20 and high["kp"] > 10 * low["kp"]
    for gains in (low, high):
        ms, stable, allowed = loops.loop_robustness(outcomes.experiment_for(data, search.with_gains(gains), machine, "test"))
        assert stable and ms == pytest.approx(2.0 * allowed / tuning.MS_LIMIT, rel=2e-3)
    between = {k: v * math.sqrt(high["kp"] / low["kp"]) for k, v in low.items()}
    ms, _, allowed = loops.loop_robustness(outcomes.experiment_for(data, search.with_gains(between), machine, "test"))
    assert ms > 1.5 * 2.0 * allowed / tuning.MS_LIMIT
    assert search.space.point(search.with_gains(high))["gain_range"] == 1
    for r in (0, 1):          # the Ms at its bound is at a bound; the range is a choice, never one
        assert search.space.at_bound(found[r][2]) == ["ms at the upper bound"]
    assert search.space.point(search.with_gains(low))["gain_range"] == 0
    ran = search.measure([(found[r][2], found[r][0], found[r][1]) for r in (0, 1)])
    assert ran[1].outcome.ok and ran[1].outcome.tace * 10 < ran[0].outcome.tace


@pytest.mark.parametrize("scenario", ["paper000_h50", "paper001_caseIII"])
def test_the_zpetc_pid_is_searched_at_a_chosen_ms_of_each_axis_loop(scenario):
    """The ZPETC's PID (its feedback loop is linear: core/margins.axis_loop) is searched by its PI corner, its
    derivative time and the Ms each axis' loop reaches: every point either has a stable loop on every axis
    at that Ms (the highest gain of the lowest stable range, also where the loop is unstable at small gains,
    as a PI on paper 001's almost double-integrating axes is), or none and is refused unrun; the file's gains
    map back to themselves; the Ms bound holds for the servo's own loop (no allowance for a drive already
    beyond it: its gains are the ones tuned)."""
    data, machine, search = _realistic_tuning(scenario, lambda label: label.endswith("none / zpetc"), (1.0, 1.0))
    assert [d.name for d in search.space.dimensions] == ["servo f_c", "servo t_d", "servo ms"] and search.servo_tuned
    stable_points, conditionally = 0, 0
    for u in qmc.Sobol(3, seed=5).random(16):
        values, gains = search.space.decode(list(u))
        if not all(v for k, v in gains.items() if k.endswith(".kp")):
            with pytest.raises(ConfigError, match="kp or ki must be positive"):
                outcomes.experiment_for(data, search.with_gains(gains), machine, "test")
            continue
        experiment = outcomes.experiment_for(data, search.with_gains(gains), machine, "test")
        ms, stable, allowed = loops.loop_robustness(experiment, servo_tuned=True)
        assert stable and allowed == tuning.MS_LIMIT
        assert ms == pytest.approx(values["servo ms"], rel=2e-3)
        stable_points += 1
        small = outcomes.experiment_for(data, search.with_gains({k: 1e-3 * v for k, v in gains.items()}), machine, "test")
        conditionally += not loops.loop_robustness(small, servo_tuned=True)[1]
    assert stable_points >= 4 and (conditionally >= 1 or scenario == "paper000_h50")
    file_point = search.space.point(search.validated)
    _, file_gains = search.space.decode(search.space.start(search.validated))
    if file_point["servo ms"] > 1.2:          # inside the box: the file's gains come back
        for axis in ("x",):
            assert file_gains[f"{axis}/servo.kp"] == pytest.approx(search.validated[f"/{axis}/servo"]["kp"], rel=1e-3)


def test_a_stopped_benchmark_goes_on_from_its_checkpoints(tmp_path, capsys):
    from contouring_ros.studies.checkpoints import SUFFIX, Checkpoints, row_key
    families = select_families(scenario_families(), [SMALL])
    kept = Checkpoints(tmp_path / "rows", tuning.Tuned)
    first = run_benchmark(families, FAST, workers=2, checkpoints=kept)
    tuned = [r for r in first if r.tuned is not None]
    assert kept.taken == 0 and len(list((tmp_path / "rows").glob(f"*{SUFFIX}"))) == len(tuned) > 0
    again = Checkpoints(tmp_path / "rows", tuning.Tuned)
    second = run_benchmark(families, FAST, workers=1, checkpoints=again)
    assert again.taken == len(tuned)                   # nothing tuned again
    # tools/checkpoint_status.py says what a run has kept so far, per scenario
    status = load_tool("checkpoint_status")
    assert status.main([str(tmp_path / "rows"), "--rows"]) == 0
    said = capsys.readouterr().out
    assert f"{SMALL}: {len(tuned)} rows kept" in said and all(r.combination.label in said for r in tuned)
    # tools/check_tuning.py takes the rows to check from the same folder: each kept row's nominal TACE
    check = load_tool("check_tuning")
    reported = check.reported_rows(str(tmp_path / "rows"))
    assert {(SMALL, r.combination.label) for r in tuned if r.tuned.nominal is not None} == set(reported)
    for r in tuned:
        if r.tuned.nominal is not None:
            assert float(reported[(SMALL, r.combination.label)]["tace_um"]) == pytest.approx(
                r.tuned.nominal.tace * 1e6, rel=1e-3)
    assert [r.label for r in second] == [r.label for r in first]
    assert [r.figure("tace") for r in second] == [r.figure("tace") for r in first]
    # a row is taken only for the same inputs: another protocol, machine or experiment is another key
    data = {"x": [1.0, 2.0]}
    assert row_key(data, FAST) == row_key({"x": [1.0, 2.0]}, FAST)
    assert row_key(data, FAST) != row_key(data, dataclasses.replace(FAST, draws=3))
    assert row_key(data, FAST) != row_key({"x": [1.0, 2.5]}, FAST)
    # a row file under another row's name, or a damaged one, is named, not taken or tuned over
    one, other = sorted((tmp_path / "rows").glob(f"*{SUFFIX}"))[:2]
    one.write_bytes(other.read_bytes())
    with pytest.raises(ConfigError, match=f"--checkpoints {one}: holds the row of another key"):
        run_benchmark(families, FAST, workers=1, checkpoints=Checkpoints(tmp_path / "rows", tuning.Tuned))
    damaged = one
    damaged.write_bytes(b"not a row")
    with pytest.raises(ConfigError, match=f"^--checkpoints {damaged}: not a row kept by --checkpoints: not gzip "
                                          "data \\(remove it to tune that row again\\)$"):
        run_benchmark(families, FAST, workers=1, checkpoints=Checkpoints(tmp_path / "rows", tuning.Tuned))
    assert main(["benchmark", "--from-parts", str(damaged), "--checkpoints", str(tmp_path), "--out",
                 str(tmp_path)]) == 2


def test_rows_tuned_side_by_side_share_their_rounds_and_tune_as_alone():
    """SharedBatches: the rows of a scenario, each in its thread, run each round's runs in one mixed batch; each
    row ends where it ends tuned alone (its runs' numbers up to the last digits of a batch against a run alone),
    in fewer rounds than the rows' rounds added up, and each row's CPU time is its share."""
    from contouring_ros.studies import shared_batches
    family = select_families(scenario_families(), [SMALL])[0]
    data = family.data[family.proposed]
    data = {**data, "/**": {"ros__parameters": {**data["/**"]["ros__parameters"], "duration": 0.5}}}
    protocol = Protocol(evaluations=12, popsize=4, design=4, draws=1, searches=2, max_searches=2)
    combos = plan(family)[0]
    assert len(combos) == 2 and combos[0].estimator != combos[1].estimator

    def task(combo):
        return lambda: tuner.tune(data, combo.sections, combo.gain_keys, {}, math.inf, 0.0, protocol, "test")

    alone, rounds_alone = [], 0
    for combo in combos:
        one = shared_batches.SharedBatches()
        alone += one.run([task(combo)])
        rounds_alone += one.rounds
    rounds = []
    for _ in range(2):
        shared = shared_batches.SharedBatches()
        together = shared.run([task(combo) for combo in combos])
        rounds.append((shared.rounds, [[e.objective for e in t.evaluations] for t in together]))
        assert all(cpu > 0 for cpu in shared.cpu)
        for mine, theirs in zip(together, alone):
            assert len(mine.evaluations) == len(theirs.evaluations) == 2 * 12
            for a, b in zip(mine.evaluations, theirs.evaluations):
                assert a.gains == pytest.approx(b.gains, rel=1e-6)
                assert a.outcome.tace == pytest.approx(b.outcome.tace, rel=1e-6, abs=1e-15)
            assert mine.search_tace == pytest.approx(theirs.search_tace, rel=1e-6)
    assert rounds[0] == rounds[1]                       # the same rounds, the same numbers, run after run
    assert rounds[0][0] <= 0.75 * rounds_alone      # about the longer row's, not the two rows' added up
    assert shared_batches.current_batches() is None     # outside the tasks, runs are this thread's own


def test_a_task_that_fails_lets_the_others_end_and_is_raised_after_them():
    from contouring_ros.studies import shared_batches
    from contouring_ros.studies.sweep import simulate_loops
    from contouring_ros.experiment.build import build_loop
    from contouring_ros.api import load_experiment
    loop = build_loop(load_experiment(str(benchmark.CONFIG_DIR / "paper000_b_ismc_h50_newton.yaml")))
    loop.n_steps = 20
    ended = []

    def fine():
        for _ in range(3):
            simulate_loops([loop])
        ended.append("fine")
        return "fine"

    def broken():
        simulate_loops([loop])
        raise RuntimeError("broken task")

    with pytest.raises(RuntimeError, match="broken task"):
        shared_batches.SharedBatches().run([fine, broken])
    assert ended == ["fine"]
