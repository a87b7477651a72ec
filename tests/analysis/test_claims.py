"""Each paper's claims (config/claims/paper<N>.yaml): every claim row measured under both readings on the ideal
machine and held to its stated ideal ratio; the stated realistic-machine verdicts agree with the stated
intervals, and one claim's paired draws on the realistic machine fall within its stated interval; every CCC
lowers the contour error on its paper's mechanism scenario by its stated factor; the verdict rule, the interval
verdict, the robustness label, steady-state scores and the regime map machinery on known cases."""
import json
import math
import subprocess
import sys

import numpy as np
import pytest

from contouring_ros.records.bag_writer import write_simulation
from contouring_ros.studies.claims import SCALES, ScenarioScores, ccc_helps_scores, evaluate, plan_pair
from contouring_ros.studies.claims_file import (Claim, Decisive, MapAxis, Pair, RegimeMap, claim_files, claim_verdict,
                                                interval_verdict, load_claims, robustness, scenario_experiment)
from contouring_ros.studies.claims_maps import draw_map, map_ratios
from contouring_ros.studies.paper import CONFIG_DIR
from contouring_ros.studies.summaries import interval
from contouring_ros.config import WHOLE_COMMAND_CONTROLLERS, build_loop, parse_experiment
from contouring_ros.core.metrics import score
from contouring_ros.core.simulation import simulate
from contouring_ros.errors import ConfigError, Diverged, ScoreError
from contouring_ros.records.scoring import score_run
from conftest import DEFAULT, ROOT, shortened

FILES = claim_files()
CLAIMS = [(paper.paper, c) for paper in map(load_claims, FILES) for c in paper.claims]
HELPS = [entry for paper in map(load_claims, FILES) for entry in paper.ccc_helps]


@pytest.fixture(scope="module")
def scores():
    """Every scenario the claims name, simulated once for the whole module."""
    cache = ScenarioScores()
    cache.need([(name, None, c.from_time) for _, c in CLAIMS for reading in ("faithful", "mechanism")
                if c.pair(reading) for name in (c.pair(reading).proposed, c.pair(reading).baseline)]
               + [(e.scenario, None, e.from_time) for e in HELPS] + [(e.scenario, e.without, e.from_time) for e in HELPS])
    return cache


def test_verdict_rule():
    assert claim_verdict(0.05, 0.069) == "holds"
    assert claim_verdict(0.30, 0.069) == "holds"            # 70% of the way: 1 - 0.30 >= 0.75 * 0.931
    assert claim_verdict(0.35, 0.069) == "holds weaker"
    assert claim_verdict(0.96, 0.069) == "does not hold"
    assert claim_verdict(1.04, 0.5) == "does not hold"
    assert claim_verdict(1.2, 0.5) == "reversed"
    assert claim_verdict(None, 0.5) == "not testable"
    assert claim_verdict(math.nan, 0.5) == "not testable"
    assert claim_verdict(0.9625, None) == "lowers"          # no paper figure: only 'lowers' or not, whatever the size
    assert claim_verdict(1.0, None) == "does not lower"
    assert claim_verdict(None, None) == "not testable"


def test_the_interval_verdict_is_given_only_where_the_interval_crosses_no_threshold():
    paper = 0.069                                     # holds where r <= 1 - 0.75 * 0.931 = 0.302
    _, low, high = interval([0.20, 0.25, 0.28, 0.31, 0.33])       # made up: crosses 0.302
    assert claim_verdict(low, paper) == "holds" and claim_verdict(high, paper) == "holds weaker"
    assert interval_verdict(low, high, paper) == "undecided"
    _, low, high = interval([0.40, 0.45, 0.5, 0.6])                # inside 'holds weaker'
    assert interval_verdict(low, high, paper) == "holds weaker"
    assert interval_verdict(0.9, 1.01, 0.5) == "undecided"         # crosses 0.95
    assert interval_verdict(1.06, 1.5, 0.5) == "reversed"
    assert interval_verdict(None, None, 0.5) == "not testable"
    assert interval_verdict(math.nan, 0.9, 0.5) == "not testable"
    assert interval_verdict(0.90, 0.99, None) == "lowers"          # no paper figure: entirely below 1
    assert interval_verdict(1.0, 1.2, None) == "does not lower"    # entirely at or above 1
    assert interval_verdict(0.98, 1.02, None) == "undecided"


def test_the_sensitivity_label_is_robust_only_where_no_scaled_verdict_flips():
    same = {("K", 0.7): "holds", ("K", 1.4): "holds", ("T", 0.7): "holds", ("T", 1.4): "holds"}
    assert robustness("holds", same) == ("robust", [])
    flipped = {**same, ("K", 0.7): "holds weaker"}
    assert robustness("holds", flipped) == ("knife-edge", ["K x0.7: holds weaker"])
    assert robustness("not testable", same)[0] == "not testable"
    assert robustness("holds", {})[0] == "not testable"


def test_the_sensitivity_runs_scale_both_files_alike_on_the_same_machine():
    """plan_pair: the machine is made from the proposed file and put under both; each decisive key is the
    file's (or the machine's) value x0.7 and x1.4 in both files; the draws are paired (same seeds)."""
    claim = next(c for _, c in CLAIMS if c.id == "ellipse_natural_local_vs_first_order")
    claim = Claim(**{**claim.__dict__, "decisive": (Decisive("B", ("x/plant.damping",)),
                                                     Decisive("limit", ("x/plant.saturation",)),
                                                     Decisive("gain", ("ccc.f_t",), only="proposed"))})
    plan = plan_pair(claim, claim.mechanism, peak=(1.0, 1.0), draws=3)
    assert len(plan.draws) == 3 and all(p["x/plant.noise_seed"] == b["x/plant.noise_seed"] for p, b in plan.draws)
    assert plan.draws[1][0]["x/plant.mass"] == plan.draws[1][1]["x/plant.mass"] != plan.draws[2][0]["x/plant.mass"]
    assert plan.nominal == (plan.machine, plan.machine) and plan.machine["x/plant.command_delay"] == 1
    for factor in SCALES:
        proposed, baseline = plan.scaled[("B", factor)]
        assert proposed["x/plant.damping"] == baseline["x/plant.damping"] == pytest.approx(750.59 * factor)
        assert plan.scaled[("limit", factor)][1]["x/plant.saturation"] == pytest.approx(10.0 * factor)
        proposed, baseline = plan.scaled[("gain", factor)]
        assert proposed["ccc.f_t"] == pytest.approx(15.0 * factor) and "ccc.f_t" not in baseline


def test_every_paper_has_claims_and_maps():
    papers = {paper for paper, _ in CLAIMS}
    assert papers == {"000", "001", "002", "003", "004"}
    for paper, claim in CLAIMS:
        assert 1 <= sum(1 for p, _ in CLAIMS if p == paper) <= 3
        assert claim.maps, f"{paper}/{claim.id} has no regime map"
        assert claim.reason.count(". ") <= 3, f"{paper}/{claim.id}: the reason is more than three sentences"
        assert claim.faithful is not None
        assert claim.decisive, f"{paper}/{claim.id} names no decisive parameter"
        assert claim.adds and "\n" not in claim.adds, f"{paper}/{claim.id}: say in one line what its mechanism adds"
        for name in (claim.mechanism.proposed, claim.mechanism.baseline):
            header = (CONFIG_DIR / f"{name}.yaml").read_text().split("\n")[:3]
            assert any(line.startswith("# Adds beyond the paper: ") for line in header), name


@pytest.mark.parametrize("paper, claim", CLAIMS, ids=[f"{p}-{c.id}" for p, c in CLAIMS])
def test_claim_row_is_measured_as_stated_on_the_ideal_machine(paper, claim: Claim, scores):
    result = evaluate([claim], scores, machine="ideal", sensitivity=False)[0]
    tolerance = claim.expected.get("tolerance", 0.1)
    for reading in ("faithful", "mechanism"):
        if claim.pair(reading) is None:
            continue
        ours, expected = result.ideal_ratio(reading), claim.expected.get(f"ideal_{reading}_ratio")
        assert ours is not None, f"{reading}: no ratio (a run diverged?)"
        assert expected is not None, f"{reading}: the claims file states no expected ideal ratio"
        assert abs(ours / expected - 1.0) <= tolerance, f"{reading}: ideal ratio {ours:.4g}, stated {expected}"


@pytest.mark.parametrize("paper, claim", CLAIMS, ids=[f"{p}-{c.id}" for p, c in CLAIMS])
def test_the_stated_verdicts_follow_from_the_stated_intervals(paper, claim: Claim):
    """The realistic machine's median, interval and verdict as the file states them (measured by
    `python -m contouring_ros.studies.claims --yaml`, 8 draws) agree with the interval verdict rule."""
    for reading in ("faithful", "mechanism"):
        if claim.pair(reading) is None:
            continue
        median, (low, high) = claim.expected[f"{reading}_ratio"], claim.expected[f"{reading}_interval"]
        assert low <= median <= high
        assert interval_verdict(low, high, claim.paper_ratio) == claim.verdict[reading], reading


def test_the_realistic_draws_fall_within_the_stated_interval():
    """One claim on the realistic machine with 2 of its 8 paired draws (the full 8 for every claim take minutes):
    each draw's ratio lies within the stated 2.5-97.5% interval (widened by the tolerance, as 2 of 8 draws can
    sit just outside the interpolated percentiles), and the seed-0 ratio of each scaled parameter is measured."""
    claim = next(c for _, c in CLAIMS if c.id == "newton_ccc_vs_vgccc")
    result = evaluate([claim], draws=2)[0]
    tolerance = claim.expected.get("tolerance", 0.1)
    for reading in ("faithful", "mechanism"):
        low, high = claim.expected[f"{reading}_interval"]
        ratios = result.draw_ratios(reading)
        assert len(ratios) == 2
        for ratio in ratios:
            assert low * (1 - tolerance) <= ratio <= high * (1 + tolerance), (reading, ratios, low, high)
        scaled = result.scaled_ratios(reading)
        assert len(scaled) == len(claim.decisive) * len(SCALES) and all(r is not None for r in scaled.values())
        assert result.robustness(reading)[0] in ("robust", "knife-edge")


@pytest.mark.parametrize("entry", HELPS, ids=[f"{e.paper}-{e.scenario}" for e in HELPS])
def test_each_ccc_lowers_the_contour_error_on_its_mechanism_scenario(entry, scores):
    with_ccc, without = ccc_helps_scores(entry, scores)
    assert with_ccc * entry.factor <= without, f"with the CCC {with_ccc * 1e6:.4g} um, without {without * 1e6:.4g} um"


@pytest.mark.parametrize("entry", HELPS, ids=[f"{e.paper}-{e.scenario}" for e in HELPS])
def test_the_ccc_check_fails_when_the_ccc_sign_is_flipped(entry):
    """The check above is not a formality: with the correction's sign flipped the CCC no longer lowers the
    contour error by its factor (the ``without`` run, unchanged, is the reference)."""
    experiment = scenario_experiment(entry.scenario)
    loop = build_loop(experiment)
    kind = experiment.controller["type"]
    if kind == "tvt":                    # its output is the whole velocity command: flip the contour term
        loop.controller.kc = -loop.controller.kc
    elif kind == "task_frame_pd":        # the whole command too: flip the normal (and binormal) PD gains of eq. 24
        assert loop.controller.kp[1:].min() > 0
        loop.controller.kp[1:] *= -1.0
        loop.controller.kd[1:] *= -1.0
    elif kind in WHOLE_COMMAND_CONTROLLERS:
        pytest.fail(f"{kind} computes the whole command: say here how its contour action is flipped")
    else:
        step = loop.controller.step
        loop.controller.step = lambda *args: -step(*args)
    try:
        flipped = getattr(score_run(loop.curve, simulate(loop), entry.from_time), entry.metric)
    except Diverged:
        return                        # flipped, the loop diverges: the check fails, as it must
    without = build_loop(scenario_experiment(entry.scenario, entry.without))
    baseline = getattr(score_run(without.curve, simulate(without), entry.from_time), entry.metric)
    assert not flipped * entry.factor <= baseline


# --------------------------------------------------------------------------------------- steady-state scores


def _default_run(duration=0.6):
    experiment = parse_experiment(shortened(DEFAULT, duration), "default")
    loop = build_loop(experiment)
    return experiment, loop, simulate(loop)


def test_scores_from_a_time_cover_only_the_later_samples():
    _, loop, run = _default_run()
    whole, errors = score(loop.curve, run.time, run.position, run.reference_position, run.estimate_vector,
                          run.command, theta=run.theta)
    later = score_run(loop.curve, run, from_time=0.3)
    kept = run.time >= 0.3 - 1e-12
    assert later.steps == kept.sum() == 301 and later.from_time == 0.3
    assert later.mce == pytest.approx(errors[kept].max(), rel=1e-12)
    assert later.tace == pytest.approx(errors[kept].mean(), rel=1e-12)
    assert later.rms == pytest.approx(np.sqrt(np.mean(errors[kept] ** 2)), rel=1e-12)
    assert later.mce < whole.mce          # the start-up spike is left out
    assert later.travel_time == whole.travel_time == pytest.approx(0.6)   # the path's time, not the part scored
    with pytest.raises(ScoreError, match="no samples at t >= 5"):
        score_run(loop.curve, run, from_time=5.0)


def test_score_command_from_keeps_the_json_keys(tmp_path):
    experiment, loop, run = _default_run()
    bag = write_simulation(tmp_path / "run.mcap", experiment, run)
    cli = [sys.executable, "-m", "contouring_ros.cli", "score", str(bag), "--json"]
    whole = json.loads(subprocess.run(cli, capture_output=True, text=True, cwd=ROOT, check=True).stdout)["run"]
    later = json.loads(subprocess.run(cli + ["--from", "0.3"], capture_output=True, text=True, cwd=ROOT,
                                      check=True).stdout)["run"]
    assert set(later) == set(whole) and later["from_time"] == 0.3 and whole["from_time"] == 0.0
    assert later["mce"] == pytest.approx(score_run(loop.curve, run, 0.3).mce, rel=1e-12)
    assert later["tracking_max_by_axis"].keys() == {"x", "y"} and later["units"]["mce"] == "m"
    assert later["travel_time"] == whole["travel_time"] == pytest.approx(0.6)
    bad = subprocess.run(cli + ["--from", "9"], capture_output=True, text=True, cwd=ROOT)
    assert bad.returncode == 2 and bad.stderr.count("\n") == 1 and "no samples at t >= 9" in bad.stderr


# --------------------------------------------------------------------------------------- regime maps


def test_a_regime_map_is_the_ratio_of_the_two_runs_cell_by_cell(tmp_path, monkeypatch):
    claim = Claim(paper="000", id="test", claim="", paper_figure="", paper_ratio=0.5, metric="tace", from_time=0.1,
                  faithful=Pair("paper000_b_ismc_h50_newton", "paper000_b_ismc_h50_vgccc"), mechanism=None,
                  expected={}, verdict={}, reason="")
    spec = RegimeMap("faithful", MapAxis("T", ("schedule.duration", "duration"), (0.3, 0.4)),
                     MapAxis("h", ("curve.h",), (50.0, 200.0)))
    ratios = map_ratios(claim, spec, workers=1)
    assert ratios["tace"].shape == (2, 2)
    for j, h in enumerate((50.0, 200.0)):
        for i, duration in enumerate((0.3, 0.4)):
            settings = {"schedule.duration": duration, "duration": duration, "curve.h": h}
            tace = []
            for name in (claim.faithful.proposed, claim.faithful.baseline):
                loop = build_loop(scenario_experiment(name, settings))
                tace.append(score_run(loop.curve, simulate(loop), 0.1).tace)
            assert ratios["tace"][j, i] == pytest.approx(tace[0] / tace[1], rel=1e-9)
    png = draw_map(claim, spec, ratios, tmp_path / "maps" / "map.png")
    assert png.stat().st_size > 10000


def test_a_claims_file_with_a_mistake_is_refused_naming_the_key(tmp_path):
    path = tmp_path / "paper009.yaml"
    path.write_text('paper: "009"\ntitle: t\nreadings: []\nclaims:\n  - id: a\n    claim: c\n    paper_figure: f\n'
                    '    paper_ratio: 0.5\n    metric: tace_um\n    faithful: null\n    expected: {}\n'
                    '    verdict: {}\n    reason: r\n')
    with pytest.raises(ConfigError, match=r"paper009.yaml: claims\[0\].metric: expected one of mce"):
        load_claims(path)
    path.write_text(path.read_text().replace("tace_um", "tace").replace("faithful: null",
                                                                         "faithful: {proposed: nope, baseline: x}"))
    with pytest.raises(ConfigError, match=r"claims\[0\].faithful.proposed: no scenario file config/nope.yaml"):
        load_claims(path)
